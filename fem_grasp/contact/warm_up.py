"""Compile the contact kernels before the first pickup (``make setup`` calls :func:`warm_up` once).

numba compiles a kernel at its first call, for the argument types of that call, and caches the result
(``cache=True``: once per installation, about 20 s on 2 cores).  :func:`warm_up` runs every sample call
registered with :func:`~fem_grasp.contact.kernels.jit.warm_up_sample` by the modules that call kernels
(the return mapping, the slip systems), so no pickup pays the compilation; :func:`entry_points` names what
each kernel module exports to Python, which the tests check has been compiled.
"""

from __future__ import annotations

import importlib
import time

from . import relaxation, slip_system, tracking  # noqa: F401 - importing them registers their samples
from .kernels import jit

__all__ = ["entry_points", "warm_up"]


def warm_up() -> float:
    """Compile every kernel now, through the registered samples; seconds taken (0 without numba)."""
    if not jit.ENABLED:
        return 0.0
    t0 = time.perf_counter()
    for sample in jit.warm_up_samples():
        sample()
    return time.perf_counter() - t0


def entry_points() -> dict[str, tuple[str, ...]]:
    """Each kernel module's kernels called from Python (its ``ENTRY_POINTS``): what :func:`warm_up` must reach."""
    return {name: tuple(importlib.import_module(name).ENTRY_POINTS) for name in jit.kernel_modules()}
