"""robomach's core library: the cell, path learning, post-processing, export, machining.

One BLAS thread unless the environment says otherwise. The core's matrices are small (6x6
Jacobians, 3-vectors, (n, 3) paths): OpenBLAS's extra threads never shortened a run, and they
spin between calls. An 18-run machining comparison took 11.4 s either way, with 15.0 s of CPU
against 11.4 s on one thread. It must be set before numpy loads OpenBLAS; processes started from
this one (servers, process-pool workers) inherit it.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
