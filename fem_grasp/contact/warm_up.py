"""Compile the contact kernels before the first pickup (``make setup`` calls :func:`warm_up` once).

numba compiles a kernel at its first call, for the argument types of that call, and caches the result
(``cache=True``: once per installation, about 20 s on 2 cores).  :func:`warm_up` runs every sample call
registered with :func:`~fem_grasp.contact.kernels.jit.warm_up_sample` by the modules that call kernels
(the return mapping, the slip systems), so no pickup pays the compilation; :func:`entry_points` names what
each kernel module exports to Python, which the tests check has been compiled.

:func:`prepare_kernels` runs at the start of every rest and pickup, and works once per process: with numba
it runs :func:`warm_up` (about a second when numba's cache holds the kernels) and, when that takes longer
than :data:`COMPILE_NOTICE_DELAY` (a cold cache: a fresh installation), logs that the kernels are being
compiled, once, so a first run is not a silent wait; without numba it logs once that the kernels run as
plain Python, about 5x slower, and how to install numba (the ``fast`` extra).
"""

from __future__ import annotations

import importlib
import importlib.util
import logging
import threading
import time

from . import relaxation, slip_system, tracking  # noqa: F401 - importing them registers their samples
from .kernels import jit

__all__ = ["COMPILE_NOTICE_DELAY", "entry_points", "prepare_kernels", "warm_up"]

log = logging.getLogger(__name__)

#: Seconds :func:`prepare_kernels` waits before it logs that numba is compiling (a cached load takes about 1 s).
COMPILE_NOTICE_DELAY = 3.0

_prepared = False
_lock = threading.Lock()


def warm_up() -> float:
    """Compile every kernel now, through the registered samples; seconds taken (0 without numba)."""
    if not jit.ENABLED:
        return 0.0
    t0 = time.perf_counter()
    for sample in jit.warm_up_samples():
        sample()
    return time.perf_counter() - t0


def prepare_kernels() -> None:
    """Once per process, before the first rest or pickup: compile (or load from numba's cache) every kernel, or
    say that they run as plain Python (module notes).  Later calls return at once."""
    global _prepared
    if _prepared:
        return
    with _lock:  # a second thread waits for the first one's compilation
        if _prepared:
            return
        if not jit.ENABLED:
            if importlib.util.find_spec("numba") is None:
                log.warning("numba is not installed: the contact kernels run as plain Python, about 5x slower; "
                            "pip install \"fem_grasp[fast]\" compiles them")
            else:
                log.info("FEM_GRASP_NO_JIT is set: the contact kernels run as plain Python (about 5x slower)")
        else:
            done = threading.Event()

            def notice() -> None:
                if not done.wait(COMPILE_NOTICE_DELAY):
                    log.warning("numba is compiling the contact kernels: once per installation (1-2 min), cached "
                                "for every later run")

            threading.Thread(target=notice, name="fem_grasp-compile-notice", daemon=True).start()
            try:
                seconds = warm_up()
            finally:
                done.set()
            log.info("contact kernels ready (%s) in %.1f s", jit.backend_name(), seconds)
        _prepared = True


def entry_points() -> dict[str, tuple[str, ...]]:
    """Each kernel module's kernels called from Python (its ``ENTRY_POINTS``): what :func:`warm_up` must reach."""
    return {name: tuple(importlib.import_module(name).ENTRY_POINTS) for name in jit.kernel_modules()}
