"""Test configuration: one numeric thread per process (docs/performance.md), headless matplotlib, property
tests with fixed examples."""

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

# Property tests draw the same examples on every run and machine (a fixed seed, like every statistical
# check here): a failure found once is found again, and CI cannot pass or fail by chance.
from hypothesis import settings  # noqa: E402

settings.register_profile("fixed", derandomize=True, database=None)
settings.load_profile("fixed")
