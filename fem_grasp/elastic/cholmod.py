"""CHOLMOD's supernodal Cholesky called through ctypes: solves that release the GIL.

scikit-sparse's wrapper holds the GIL for the whole of a solve, so a thread solving compliance columns
stopped every other Python thread (a pure-Python loop beside it ran 15 times slower).  ctypes releases
the GIL around every foreign call: with this binding the columns of the likely next contacts are solved
on the second core while the tracking goes on (:meth:`~fem_grasp.elastic.compliance.Compliance.solve_ahead`),
and two lift tests solve their columns at once.  The factor is CHOLMOD's with its default settings, the
same as scikit-sparse's: its solves agree with scikit-sparse's bit for bit (``tests/elastic/test_cholmod.py``) up
to :data:`SOLVE_COLUMNS` right-hand sides, and wider blocks are solved in blocks of that many.

Each thread solves with a ``cholmod_common`` of its own (CHOLMOD keeps a solve's workspace and status
there); the factor itself is only read by a solve.  The library is Debian's ``libcholmod`` (SuiteSparse
5, CHOLMOD 3) or any CHOLMOD 3 to 5, found by :func:`ctypes.util.find_library`; the structs declared
here (``cholmod_sparse``, ``cholmod_dense`` and the heads of ``cholmod_factor`` and ``cholmod_common``) have kept
their layout across those versions, and ``cholmod_common`` is given more room than any of them needs.  CHOLMOD
prints nothing: its failures are this module's exceptions.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
import threading
from typing import Callable

import numpy as np
import scipy.sparse as sp

__all__ = ["CholmodFactor", "NotPositiveDefiniteError", "library"]

log = logging.getLogger(__name__)

#: Bytes reserved for a ``cholmod_common`` (2,664 in CHOLMOD 3.0; a few kB in CHOLMOD 5).
COMMON_BYTES = 1 << 16
#: A solve takes at most this many right-hand sides at once: 600 columns of the steam bun's 5,652-vertex level took
#: 1.3 s in one block and 0.64 s in blocks of 128 (CHOLMOD's workspace for a wide block outgrows the caches).
SOLVE_COLUMNS = 128
#: CHOLMOD major versions whose structs match those declared here.
SUPPORTED_MAJOR = (3, 4, 5)
_CHOLMOD_A = 0  # cholmod_solve's system: A x = b
_REAL, _DOUBLE, _INT = 1, 0, 0  # xtype, dtype, itype


class NotPositiveDefiniteError(np.linalg.LinAlgError):
    """The matrix given to :class:`CholmodFactor` is not positive definite."""


class _Sparse(ctypes.Structure):
    _fields_ = [("nrow", ctypes.c_size_t), ("ncol", ctypes.c_size_t), ("nzmax", ctypes.c_size_t),
                ("p", ctypes.c_void_p), ("i", ctypes.c_void_p), ("nz", ctypes.c_void_p), ("x", ctypes.c_void_p),
                ("z", ctypes.c_void_p), ("stype", ctypes.c_int), ("itype", ctypes.c_int), ("xtype", ctypes.c_int),
                ("dtype", ctypes.c_int), ("sorted", ctypes.c_int), ("packed", ctypes.c_int)]


class _Dense(ctypes.Structure):
    _fields_ = [("nrow", ctypes.c_size_t), ("ncol", ctypes.c_size_t), ("nzmax", ctypes.c_size_t),
                ("d", ctypes.c_size_t), ("x", ctypes.c_void_p), ("z", ctypes.c_void_p), ("xtype", ctypes.c_int),
                ("dtype", ctypes.c_int)]


class _CommonHead(ctypes.Structure):
    """The first fields of ``cholmod_common``, up to ``print`` (the same from CHOLMOD 1 to 5)."""
    _fields_ = [("dbound", ctypes.c_double), ("grow0", ctypes.c_double), ("grow1", ctypes.c_double),
                ("grow2", ctypes.c_size_t), ("maxrank", ctypes.c_size_t), ("supernodal_switch", ctypes.c_double),
                ("supernodal", ctypes.c_int), ("final_asis", ctypes.c_int), ("final_super", ctypes.c_int),
                ("final_ll", ctypes.c_int), ("final_pack", ctypes.c_int), ("final_monotonic", ctypes.c_int),
                ("final_resymbol", ctypes.c_int), ("zrelax", ctypes.c_double * 3), ("nrelax", ctypes.c_size_t * 3),
                ("prefer_zomplex", ctypes.c_int), ("prefer_upper", ctypes.c_int),
                ("quick_return_if_not_posdef", ctypes.c_int), ("prefer_binary", ctypes.c_int),
                ("print", ctypes.c_int)]


#: CHOLMOD's defaults of those fields after ``cholmod_start``: where they read so, the layout is the one declared.
_COMMON_DEFAULTS = {"grow0": 1.2, "grow1": 1.2, "grow2": 5, "maxrank": 8, "supernodal_switch": 40.0,
                    "zrelax": (0.8, 0.1, 0.05), "nrelax": (4, 16, 48), "prefer_upper": 1, "print": 3}
#: CHOLMOD prints nothing (``print`` 0; at its default 3 it wrote "CHOLMOD warning: matrix not positive definite"
#: to standard output, in the middle of a command's output): every failure raises an exception of its own here
#: (:class:`NotPositiveDefiniteError`, or RuntimeError for want of memory), which says what CHOLMOD would have.
_PRINT_NOTHING = 0


class _FactorHead(ctypes.Structure):
    """The first fields of ``cholmod_factor``: its order and where the factorisation stopped."""
    _fields_ = [("n", ctypes.c_size_t), ("minor", ctypes.c_size_t)]


_LIBRARY: ctypes.CDLL | None = None
_LIBRARY_TRIED = False
_LIBRARY_LOCK = threading.Lock()


def library() -> ctypes.CDLL | None:
    """The CHOLMOD shared library with the signatures used here, or None when none of a supported version loads."""
    global _LIBRARY, _LIBRARY_TRIED
    with _LIBRARY_LOCK:
        if not _LIBRARY_TRIED:
            _LIBRARY_TRIED = True
            _LIBRARY = _load()
    return _LIBRARY


def _load() -> ctypes.CDLL | None:
    names = [n for n in (ctypes.util.find_library("cholmod"), "libcholmod.so.3", "libcholmod.so") if n]
    for name in names:
        try:
            lib = ctypes.CDLL(name)
            lib.cholmod_version.restype = ctypes.c_int
            lib.cholmod_version.argtypes = [ctypes.c_void_p]
            code = int(lib.cholmod_version(None))
        except (OSError, AttributeError):
            continue
        if code // 1000 not in SUPPORTED_MAJOR:
            log.debug("CHOLMOD %s in %s is not a supported version %s", code, name, SUPPORTED_MAJOR)
            continue
        void_p = ctypes.c_void_p
        lib.cholmod_start.argtypes = [void_p]
        lib.cholmod_finish.argtypes = [void_p]
        lib.cholmod_analyze.restype = void_p
        lib.cholmod_analyze.argtypes = [ctypes.POINTER(_Sparse), void_p]
        lib.cholmod_factorize.restype = ctypes.c_int
        lib.cholmod_factorize.argtypes = [ctypes.POINTER(_Sparse), void_p, void_p]
        lib.cholmod_solve.restype = ctypes.POINTER(_Dense)
        lib.cholmod_solve.argtypes = [ctypes.c_int, void_p, ctypes.POINTER(_Dense), void_p]
        lib.cholmod_free_dense.argtypes = [ctypes.POINTER(ctypes.POINTER(_Dense)), void_p]
        lib.cholmod_free_factor.argtypes = [ctypes.POINTER(void_p), void_p]
        log.debug("CHOLMOD %d.%d from %s", code // 1000, code % 1000, name)
        return lib
    return None


def _new_common(lib: ctypes.CDLL) -> ctypes.Array:
    common = ctypes.create_string_buffer(COMMON_BYTES)
    lib.cholmod_start(common)
    head = _CommonHead.from_buffer(common)
    read = {k: tuple(v) if isinstance(v, ctypes.Array) else v for k, v in
            ((k, getattr(head, k)) for k in _COMMON_DEFAULTS)}
    if read == _COMMON_DEFAULTS:
        head.print = _PRINT_NOTHING
    else:  # another layout: leave CHOLMOD's printing as it is
        log.debug("cholmod_common does not start as expected (%s): CHOLMOD's warnings stay on", read)
    return common


class CholmodFactor:
    """The Cholesky factor of a sparse symmetric positive-definite matrix; :meth:`solve` in any thread.

    Parameters
    ----------
    matrix : (N, N) sparse symmetric matrix (its lower triangle is read)

    Raises
    ------
    RuntimeError
        When no supported CHOLMOD library loads (:func:`library`), or CHOLMOD fails for want of memory.
    NotPositiveDefiniteError
        When the matrix is not positive definite.
    """

    def __init__(self, matrix: sp.spmatrix) -> None:
        lib = library()
        if lib is None:
            raise RuntimeError("no CHOLMOD library of a supported version could be loaded")
        self._lib = lib
        lower = sp.tril(sp.csc_matrix(matrix), format="csc")
        lower.sort_indices()
        n = lower.shape[0]
        self.n = n
        indptr = np.ascontiguousarray(lower.indptr, dtype=np.int32)
        indices = np.ascontiguousarray(lower.indices, dtype=np.int32)
        data = np.ascontiguousarray(lower.data, dtype=float)
        a = _Sparse(n, n, lower.nnz, indptr.ctypes.data, indices.ctypes.data, None, data.ctypes.data, None,
                    -1, _INT, _REAL, _DOUBLE, 1, 1)
        self._lock = threading.Lock()
        self._common = _new_common(lib)  # the factor's own: analyse, factorise, free
        self._commons: dict[int, ctypes.Array] = {}  # each solving thread's
        self._factor = ctypes.c_void_p(lib.cholmod_analyze(ctypes.byref(a), self._common))
        self._release = _releaser(lib, self._factor, self._common, self._commons)
        if not self._factor.value:
            raise RuntimeError(f"CHOLMOD could not analyse the {n}×{n} matrix (out of memory?)")
        lib.cholmod_factorize(ctypes.byref(a), self._factor, self._common)
        head = ctypes.cast(self._factor, ctypes.POINTER(_FactorHead)).contents
        if head.minor < head.n:
            raise NotPositiveDefiniteError(f"the matrix is not positive definite (CHOLMOD stopped at column "
                                           f"{head.minor} of {head.n})")

    def _thread_common(self) -> ctypes.Array:
        key = threading.get_ident()
        common = self._commons.get(key)
        if common is None:
            with self._lock:
                common = self._commons[key] = _new_common(self._lib)
        return common

    def solve(self, b: np.ndarray) -> np.ndarray:
        """x with A x = b for a (N,) vector or an (N, k) block (returned in Fortran order), in blocks of at most
        :data:`SOLVE_COLUMNS` columns; releases the GIL."""
        b = np.asarray(b, dtype=float)
        if b.shape[0] != self.n:
            raise ValueError(f"expected {self.n} rows, got shape {b.shape}")
        block = np.asfortranarray(b.reshape(self.n, -1))
        k = block.shape[1]
        out = np.empty((self.n, k), order="F")
        common = self._thread_common()
        for start in range(0, k, SOLVE_COLUMNS):
            part = block[:, start:start + SOLVE_COLUMNS]
            width = part.shape[1]
            rhs = _Dense(self.n, width, self.n * width, self.n, part.ctypes.data, None, _REAL, _DOUBLE)
            x = self._lib.cholmod_solve(_CHOLMOD_A, self._factor, ctypes.byref(rhs), common)
            if not x:
                raise RuntimeError("CHOLMOD's solve failed (out of memory?)")
            try:
                values = ctypes.cast(x.contents.x, ctypes.POINTER(ctypes.c_double))
                out[:, start:start + width] = np.ctypeslib.as_array(values, shape=(width, self.n)).T
            finally:
                self._lib.cholmod_free_dense(ctypes.byref(x), common)
        return out.reshape(b.shape) if b.ndim == 1 else out

    __call__ = solve

    def __del__(self) -> None:
        release = getattr(self, "_release", None)
        if release is not None:
            release()


def _releaser(lib: ctypes.CDLL, factor: ctypes.c_void_p, own: ctypes.Array, commons: dict) -> Callable[[], None]:
    """What frees a factor and its workspaces; a closure, so that it still works at interpreter exit, when the
    module's globals (``ctypes`` among them) may already be gone."""
    byref = ctypes.byref

    def release() -> None:
        if factor.value:
            lib.cholmod_free_factor(byref(factor), own)
        for common in [*commons.values(), own]:
            lib.cholmod_finish(common)

    return release
