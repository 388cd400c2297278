"""Optional compilation of scalar inner loops with numba; fem_grasp imports and runs without it.

Functions decorated with :func:`jit` are written in the subset of Python
that numba compiles (scalars, ``math``, indexing, loops) and take their
arrays as either numpy arrays (compiled) or nested lists (plain Python,
where list indexing is several times cheaper than numpy's per-element
access).  :func:`as_kernel_data` converts to whichever form is in use.

numba itself (~0.13 s to import) is imported at the first call of a kernel,
not with fem_grasp: that call replaces every kernel in its module's
namespace by its compiled version (``cache=True``: compiled once per
installation, then loaded from ``__pycache__``), so that kernels calling
kernels are compiled together.

Set ``FEM_GRASP_NO_JIT=1`` before importing fem_grasp to run the plain
Python versions even when numba is installed (the tests compare the two).
"""

from __future__ import annotations

import functools
import importlib.metadata
import importlib.util
import logging
import os
from typing import Any, Callable

import numpy as np

__all__ = ["ENABLED", "jit", "as_kernel_data", "backend_name", "warm_up"]

log = logging.getLogger(__name__)

#: Whether :func:`jit` compiles (numba is installed and FEM_GRASP_NO_JIT is not set).
ENABLED: bool = importlib.util.find_spec("numba") is not None and not os.environ.get("FEM_GRASP_NO_JIT")

_kernels: list[tuple[dict, str, Callable]] = []  # (module namespace, name, Python function)


def _compile_all() -> None:
    """Put the compiled version of every kernel in place of its stub (numba compiles lazily, per signature)."""
    try:
        import numba
    except ImportError as exc:  # pragma: no cover - found but broken installation
        log.warning("numba could not be imported (%s): the inner loops run as plain Python on arrays", exc)
        numba = None
    for namespace, name, fn in _kernels:
        namespace[name] = fn if numba is None else numba.njit(cache=True)(fn)
    _kernels.clear()


def jit(fn: Callable) -> Callable:
    """``numba.njit(cache=True)`` when :data:`ENABLED` (numba imported at the first call), else ``fn``."""
    if not ENABLED:
        return fn
    namespace, name = fn.__globals__, fn.__name__
    _kernels.append((namespace, name, fn))

    @functools.wraps(fn)
    def first_call(*args: Any) -> Any:
        _compile_all()
        return namespace[name](*args)

    return first_call


def as_kernel_data(a: np.ndarray, dtype: Any = float) -> Any:
    """A copy of ``a``: a contiguous array when compiled, (nested) Python lists otherwise."""
    a = np.array(a, dtype=dtype, order="C")
    return a if ENABLED else a.tolist()


def backend_name() -> str:
    """'numba x.y.z' or 'python' (for benchmark and log lines)."""
    return f"numba {importlib.metadata.version('numba')}" if ENABLED else "python"


def warm_up() -> float:
    """Compile every kernel now, through each of its entry points from Python; seconds taken.

    numba caches what it compiles, so this costs once per installation (``make setup`` calls it; about
    18 s on a 2-core EPYC); without it the first pickup pays the compilation.
    """
    import time

    from . import gauss_seidel as gs
    from ..relaxation import _SlideGeometry, relax_contacts
    from ..tracking import FINGER1, TABLE, MixedSlipSystem

    if not ENABLED:
        return 0.0
    t0 = time.perf_counter()
    up = np.array([0.0, 0.0, 1.0])
    stiffness = 100.0 * np.eye(6)
    forces = np.array([[0.8, 0.0, 1.0], [0.0, 0.8, 1.0]])
    mu = np.array([0.5, 0.5])
    centre = np.array([0.0, 0.0, 0.02])
    positions = np.array([[0.0, 0.0, 0.0], centre - [0.0, 0.0, 0.01]])
    # The return mapping: its sweep, and what its Newton polish and its end call per contact.
    relax_contacts(stiffness, forces, positions, [None, centre], up, mu, 1.0)
    records = gs.contact_records(positions, [None, centre], up, np.stack([np.eye(3), np.eye(3)]))
    _SlideGeometry(records, mu).projections(np.zeros((2, 2)))
    gs.outside_sphere(records[1], 0.0, 0.0, 0.0)
    gs.motion(records[1], 0.0, 0.0)
    # The slip systems of both forms: Newton, and the residual and Jacobian called on their own.
    for free in (False, True):
        system = MixedSlipSystem(stiffness, forces, np.zeros((2, 3)), np.array([0, 1]), np.array([TABLE, FINGER1]),
                                 mu, np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]), positions - [np.zeros(3), centre],
                                 up, 0.01, free)
        system._newton(system.x0 / system.xscale, 1e-12)  # root or not: only the compilation matters
        system.residual(system.x0)
        system.jacobian(system.x0)
    return time.perf_counter() - t0


#: The kernels called from Python (the others are compiled into them): what :func:`warm_up` must reach.
ENTRY_POINTS = {"fem_grasp.contact.kernels.gauss_seidel": ("sweep", "motion", "slide_projections", "outside_sphere"),
                "fem_grasp.contact.kernels.slip_newton": ("residual", "jacobian", "newton")}
