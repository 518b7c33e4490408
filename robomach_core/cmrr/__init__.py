"""Controlled material removal rate (CMRR): feed control that holds the cutting force at a
reference (chapter section 4, the MRR paper, and the Lund adaptive LQ)."""
