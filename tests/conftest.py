"""Test configuration: one numeric thread per process (docs/performance.md), headless matplotlib."""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
os.environ.setdefault("MPLBACKEND", "Agg")

try:  # pin already-loaded BLAS pools too
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)
except ImportError:  # pragma: no cover
    pass

try:
    import torch

    torch.set_num_threads(1)
except ImportError:  # pragma: no cover
    pass
