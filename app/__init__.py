"""robomach's app: the CLI, the REST API, the pendant page and the viser workbench, over the
core library (``robomach_core``, which sets one BLAS thread before numpy loads)."""

import robomach_core  # noqa: F401  (first, for its BLAS thread setting)
