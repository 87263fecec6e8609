"""Former home of the compiled kernels, now the :mod:`electroloc_gym.kernels` package (same names)."""

from electroloc_gym.kernels import *  # noqa: F403
from electroloc_gym.kernels import __all__  # noqa: F401
