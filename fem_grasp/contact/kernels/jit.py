"""Optional compilation of scalar inner loops with numba; fem_grasp imports and runs without it.

Functions decorated with :func:`jit` are written in the subset of Python
that numba compiles (scalars, ``math``, indexing, loops) and take their
arrays as either numpy arrays (compiled) or nested lists (plain Python,
where list indexing is several times cheaper than numpy's per-element
access).  :func:`as_kernel_data` converts to whichever form is in use.

numba itself (~0.13 s to import) is imported at the first call of a kernel,
not with fem_grasp: that call replaces every kernel in its module's
namespace by its compiled version (``cache=True``: compiled once per
installation, then loaded from ``__pycache__``; ``nogil=True``: other Python
threads run meanwhile), so that kernels calling kernels are compiled together.

Set ``FEM_GRASP_NO_JIT=1`` before importing fem_grasp to run the plain
Python versions even when numba is installed (the tests compare the two).

Compilation ahead of the first pickup: each kernel module lists the kernels it
exports to Python (``ENTRY_POINTS``), and the modules that call them register
a sample call with :func:`warm_up_sample`; :func:`fem_grasp.contact.warm_up`
runs the samples (``make setup`` does, once per installation).
"""

from __future__ import annotations

import functools
import importlib.metadata
import importlib.util
import logging
import os
from pathlib import Path
from typing import Any, Callable

import numpy as np

__all__ = ["ENABLED", "OPTIONS", "as_kernel_data", "backend_name", "jit", "kernel_modules", "sample_contacts",
           "warm_up_sample", "warm_up_samples"]

log = logging.getLogger(__name__)

#: Whether :func:`jit` compiles (numba is installed and FEM_GRASP_NO_JIT is not set).
ENABLED: bool = importlib.util.find_spec("numba") is not None and not os.environ.get("FEM_GRASP_NO_JIT")

_kernels: list[tuple[dict, str, Callable]] = []  # (module namespace, name, Python function)
#: Every module that defines a kernel (each lists the kernels it exports to Python as ``ENTRY_POINTS``).
_kernel_modules: set[str] = set()
#: Calls that compile the kernels with the argument types the package uses (:func:`warm_up_sample`).
_samples: list[Callable[[], Any]] = []


#: The options every kernel is compiled with.  numba's cache does not record them (an entry is keyed by the
#: kernel's source and argument types), so entries cached under other options are removed once
#: (:func:`_drop_stale_cache`): kernels cached before ``nogil`` would otherwise hold the GIL for good.
OPTIONS = {"cache": True, "nogil": True}
#: The file in this package's ``__pycache__`` naming the :data:`OPTIONS` its cached kernels were compiled with.
OPTIONS_MARKER = "fem_grasp-kernel-options.txt"


def _drop_stale_cache(folder: Path) -> None:
    """Remove numba's cached kernels in ``folder`` unless its marker names :data:`OPTIONS` (then write it)."""
    marker = folder / OPTIONS_MARKER
    tag = repr(sorted(OPTIONS.items()))
    try:
        if marker.read_text() == tag:
            return
    except OSError:
        pass
    try:
        for entry in [*folder.glob("*.nbi"), *folder.glob("*.nbc")]:
            entry.unlink()
        folder.mkdir(exist_ok=True)
        marker.write_text(tag)
    except OSError:  # a read-only installation: numba caches in the user's folder, from fresh files
        pass


def _compile_all() -> None:
    """Put the compiled version of every kernel in place of its stub (numba compiles lazily, per signature)."""
    try:
        import numba
    except ImportError as exc:  # pragma: no cover - found but broken installation
        log.warning("numba could not be imported (%s): the inner loops run as plain Python on arrays", exc)
        numba = None
    if numba is not None:
        _drop_stale_cache(Path(__file__).parent / "__pycache__")
    for namespace, name, fn in _kernels:
        namespace[name] = fn if numba is None else numba.njit(**OPTIONS)(fn)
    _kernels.clear()


def jit(fn: Callable) -> Callable:
    """``numba.njit(cache=True, nogil=True)`` when :data:`ENABLED` (numba imported at the first call), else ``fn``.

    ``nogil``: a compiled kernel releases the GIL, so that a second lift test in a helper thread
    (:class:`~fem_grasp.grasp.lift_test.SpeculativeTest`) runs on the other core.
    """
    _kernel_modules.add(fn.__module__)
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


def kernel_modules() -> tuple[str, ...]:
    """The modules that define kernels (imported so far), sorted."""
    return tuple(sorted(_kernel_modules))


def warm_up_sample(sample: Callable[[], Any]) -> Callable[[], Any]:
    """Register ``sample`` (a decorator): a call of the package's own code that reaches kernels with the argument
    types of a real pickup, so that :func:`fem_grasp.contact.warm_up` compiles what a pickup will call."""
    _samples.append(sample)
    return sample


def sample_contacts() -> dict[str, np.ndarray]:
    """The two contacts every warm-up sample uses: one on the table (z = 0), one on a fingertip of radius 1 cm
    centred 2 cm up, loaded out of their cones (``up``, ``centre``, ``positions``, ``forces``, ``mu``)."""
    centre = np.array([0.0, 0.0, 0.02])
    return {"up": np.array([0.0, 0.0, 1.0]), "centre": centre,
            "positions": np.array([[0.0, 0.0, 0.0], centre - [0.0, 0.0, 0.01]]),
            "forces": np.array([[0.8, 0.0, 1.0], [0.0, 0.8, 1.0]]), "mu": np.array([0.5, 0.5])}


def warm_up_samples() -> tuple[Callable[[], Any], ...]:
    """Every registered :func:`warm_up_sample`, in registration order."""
    return tuple(_samples)
