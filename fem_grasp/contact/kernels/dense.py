"""Dense LU factors for the compiled kernels: LAPACK's dgetrf, and solves with its factors.

The kernels' Newton iterations solve dense systems of tens to a few hundred
unknowns, the return mapping's polish reusing one factorisation for several
steps (chord steps).  scipy's ``lu_factor`` cannot be called from compiled code,
and an LU written in the kernels is several times slower than LAPACK's beyond
a hundred unknowns (690 µs against 200 µs at 150; the steam bun's polishes
reach 300).  :func:`lu_factor` calls LAPACK's dgetrf — scipy's ``lu_factor``
itself without numba, numba's own binding of the same routine (the one behind
its ``np.linalg.inv``) when compiled — so the factors are scipy's (bit for bit at the same BLAS thread count;
OpenBLAS blocks the factorisation by its threads, so across processes they agree to round-off);
:func:`lu_solve` applies them (row swaps and two triangular solves, O(n²)).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from .jit import ENABLED, jit

__all__ = ["ENTRY_POINTS", "lu_factor", "lu_solve"]

#: The kernel the warm-up must reach (through the kernels that call it; :func:`lu_factor` is compiled into them).
ENTRY_POINTS = ("lu_solve",)


def lu_factor(a: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """(LU factors, 0-based pivots, info) of a square matrix by LAPACK's dgetrf (info > 0: an exactly zero pivot
    U[info−1, info−1]; the factors are then incomplete)."""
    if a.shape[0] == 0:  # older scipy's dgetrf refuses an empty matrix (its leading dimension 0)
        return np.array(a, dtype=float), np.zeros(0, np.int64), 0
    lu, piv, info = scipy.linalg.lapack.dgetrf(a)
    return lu, piv.astype(np.int64), int(info)


if ENABLED:
    from numba.extending import overload

    # numba's binding of dgetrf (numba.np.linalg, what np.linalg.inv and det call): not public API, but present
    # from numba 0.2x to 0.60; an import error here names it.
    from numba.np.linalg import _LAPACK, ensure_lapack, get_blas_kind

    @overload(lu_factor)
    def _lu_factor_compiled(a):  # pragma: no cover - compiled
        ensure_lapack()
        getrf = _LAPACK().numba_xxgetrf(a.dtype)
        kind = ord(get_blas_kind(a.dtype, "lu_factor"))

        def impl(a):
            n = a.shape[0]
            lu = np.empty((n, n)).T  # Fortran order, as LAPACK keeps it
            lu[:, :] = a
            piv = np.zeros(max(n, 1), np.int32)
            info = 0
            if n:
                info = getrf(kind, n, n, lu.ctypes, n, piv.ctypes)
            return lu, piv[:n].astype(np.int64) - 1, info

        return impl


@jit
def lu_solve(lu, piv, b):
    """x with A x = b from :func:`lu_factor`'s factors of A (scipy's ``lu_solve``: the row swaps, then L and U)."""
    n = lu.shape[0]
    x = b.copy()
    for k in range(n):
        q = piv[k]
        if q != k:
            tmp = x[k]
            x[k] = x[q]
            x[q] = tmp
    for i in range(n):
        s = x[i]
        for k in range(i):
            s -= lu[i, k] * x[k]
        x[i] = s
    for i in range(n - 1, -1, -1):
        s = x[i]
        for k in range(i + 1, n):
            s -= lu[i, k] * x[k]
        x[i] = s / lu[i, i]
    return x
