"""Dense LU factors for the compiled kernels: LAPACK's dgetrf (sgetrf in single precision), and solves with them.

The kernels' Newton iterations solve dense systems of tens to a few hundred
unknowns, the return mapping's polish reusing one factorisation for several
steps (chord steps).  scipy's ``lu_factor`` cannot be called from compiled code,
and an LU written in the kernels is several times slower than LAPACK's beyond
a hundred unknowns (690 µs against 200 µs at 150; the steam bun's polishes
reach 300).  :func:`lu_factor` calls LAPACK's dgetrf — scipy's ``lu_factor``
itself without numba, numba's own binding of the same routine (the one behind
its ``np.linalg.inv``) when compiled — so the factors are scipy's (bit for bit at the same BLAS thread count;
OpenBLAS blocks the factorisation by its threads, so across processes they agree to round-off);
:func:`lu_solve` applies them (row swaps and two triangular solves, O(n²)), :func:`lu_solve_transposed` solves
with Aᵀ, and :func:`inverse_norm1_estimate` estimates ‖A⁻¹‖₁ from them as LAPACK's condition estimate does.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from .jit import ENABLED, jit

__all__ = ["ENTRY_POINTS", "inverse_norm1_estimate", "lu_factor", "lu_solve", "lu_solve_transposed"]

#: The kernel the warm-up must reach (through the kernels that call it; :func:`lu_factor` is compiled into them).
ENTRY_POINTS = ("lu_solve", "lu_solve_transposed", "inverse_norm1_estimate")


def lu_factor(a: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """(LU factors, 0-based pivots, info) of a square matrix by LAPACK's dgetrf, or sgetrf for a float32 matrix
    (factors in the matrix's precision; info > 0: an exactly zero pivot U[info−1, info−1]; the factors are then
    incomplete)."""
    if a.shape[0] == 0:  # older scipy's dgetrf refuses an empty matrix (its leading dimension 0)
        return np.array(a), np.zeros(0, np.int64), 0
    getrf = scipy.linalg.lapack.sgetrf if a.dtype == np.float32 else scipy.linalg.lapack.dgetrf
    lu, piv, info = getrf(a)
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
        dtype = np.float32 if str(a.dtype) == "float32" else np.float64

        def impl(a):
            n = a.shape[0]
            lu = np.empty((n, n), dtype).T  # Fortran order, as LAPACK keeps it
            lu[:, :] = a
            piv = np.zeros(max(n, 1), np.int32)
            info = 0
            if n:
                info = getrf(kind, n, n, lu.ctypes, n, piv.ctypes)
            return lu, piv[:n].astype(np.int64) - 1, info

        return impl


@jit
def lu_solve(lu, piv, b):
    """x with A x = b from :func:`lu_factor`'s factors of A (scipy's ``lu_solve``: the row swaps, then L and U), in
    b's precision whatever the factors' (single-precision factors of a double-precision system: see the polish).

    Column by column, as LAPACK's reference dtrsv: the factors are in Fortran order, so each step reads one column
    contiguously (four times faster than row by row at 840 unknowns, where the polish of a fine patch solves)."""
    n = lu.shape[0]
    x = b.copy()
    for k in range(n):
        q = piv[k]
        if q != k:
            tmp = x[k]
            x[k] = x[q]
            x[q] = tmp
    for k in range(n):  # L, unit diagonal
        xk = x[k]
        for i in range(k + 1, n):
            x[i] -= lu[i, k] * xk
    for k in range(n - 1, -1, -1):  # U
        x[k] /= lu[k, k]
        xk = x[k]
        for i in range(k):
            x[i] -= lu[i, k] * xk
    return x


@jit
def lu_solve_transposed(lu, piv, b):
    """x with Aᵀ x = b from :func:`lu_factor`'s factors of A (PA = LU: Uᵀ, then Lᵀ, then the row swaps undone)."""
    n = lu.shape[0]
    x = b.copy()
    for k in range(n):  # Uᵀ: lower triangular, column k of U is row k of Uᵀ (contiguous)
        s = x[k]
        for i in range(k):
            s -= lu[i, k] * x[i]
        x[k] = s / lu[k, k]
    for k in range(n - 1, -1, -1):  # Lᵀ, unit diagonal
        s = x[k]
        for i in range(k + 1, n):
            s -= lu[i, k] * x[i]
        x[k] = s
    for k in range(n - 1, -1, -1):
        q = piv[k]
        if q != k:
            tmp = x[k]
            x[k] = x[q]
            x[q] = tmp
    return x


@jit
def inverse_norm1_estimate(lu, piv):
    """An estimate of ‖A⁻¹‖₁ from :func:`lu_factor`'s factors of A: Hager's method with Higham's refinements, as
    LAPACK's dlacn2 (what dgecon, and so scipy's condition estimate, uses): at most five solves with A and with
    Aᵀ and one more, O(n²), against n solves for ‖A⁻¹‖₁ itself.  A lower bound, in practice within a factor of a
    few and most often exact (N. J. Higham, ACM TOMS 14, 1988)."""
    n = lu.shape[0]
    if n == 0:
        return 0.0
    x = np.full(n, 1.0 / n)
    est = 0.0
    j_prev = -1
    for it in range(5):
        y = lu_solve(lu, piv, x)
        norm = _norm1(y)
        if it > 0 and norm <= est:
            break
        est = norm
        xi = np.empty(n)
        for i in range(n):
            xi[i] = 1.0 if y[i] >= 0.0 else -1.0
        z = lu_solve_transposed(lu, piv, xi)
        j = 0
        for i in range(1, n):
            if abs(z[i]) > abs(z[j]):
                j = i
        if it > 0 and (j == j_prev or abs(z[j]) <= abs(z[j_prev])):
            break
        j_prev = j
        x = np.zeros(n)
        x[j] = 1.0
    # Higham's alternating vector guards against the cases where the iteration stops early.
    alt = np.empty(n)
    for i in range(n):
        alt[i] = (-1.0) ** i * (1.0 + i / max(n - 1, 1))
    return max(est, 2.0 * _norm1(lu_solve(lu, piv, alt)) / (3.0 * n))


@jit
def _norm1(v):
    out = 0.0
    for x in v:
        out += abs(x)
    return out
