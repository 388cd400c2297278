"""Optional compilation of scalar inner loops with numba; fem_grasp imports and runs without it.

Functions decorated with :func:`jit` are written in the subset of Python
that numba compiles (scalars, ``math``, indexing, loops) and take their
arrays as either numpy arrays (compiled) or nested lists (plain Python,
where list indexing is several times cheaper than numpy's per-element
access).  :func:`as_kernel_data` converts to whichever form is in use.

Set ``FEM_GRASP_NO_JIT=1`` before importing fem_grasp to run the plain
Python versions even when numba is installed (the tests compare the two).
"""

from __future__ import annotations

import logging
import os
from typing import Any, Callable

import numpy as np

__all__ = ["ENABLED", "jit", "as_kernel_data", "backend_name"]

log = logging.getLogger(__name__)

try:  # pragma: no cover - depends on the installation
    import numba
except ImportError:  # pragma: no cover
    numba = None

#: Whether :func:`jit` compiles (numba is installed and FEM_GRASP_NO_JIT is not set).
ENABLED: bool = numba is not None and not os.environ.get("FEM_GRASP_NO_JIT")


def jit(fn: Callable) -> Callable:
    """``numba.njit(cache=True)`` when :data:`ENABLED`, else ``fn`` unchanged."""
    if not ENABLED:
        return fn
    return numba.njit(cache=True)(fn)


def as_kernel_data(a: np.ndarray, dtype: Any = float) -> Any:
    """A copy of ``a``: a contiguous array when compiled, (nested) Python lists otherwise."""
    a = np.array(a, dtype=dtype, order="C")
    return a if ENABLED else a.tolist()


def backend_name() -> str:
    """'numba x.y.z' or 'python' (for benchmark and log lines)."""
    return f"numba {numba.__version__}" if ENABLED else "python"
