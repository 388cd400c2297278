"""The kernels' dense LU (fem_grasp.contact.kernels.dense): LAPACK's factors, as scipy's, compiled and in plain Python."""

import numpy as np
import pytest
import scipy.linalg

from fem_grasp.contact.kernels import dense, jit
from tests.helpers import in_plain_python

SIZES = (1, 7, 60, 300)
#: LU factors from two processes, relative to the largest: LAPACK's dgetrf in both, blocked by OpenBLAS according to
#: its thread count (seen: 6e-11 relative on single entries, 1.6e-12 of the largest, at 300 unknowns).
FACTOR_AGREEMENT = 1e-11


def _systems():
    rng = np.random.default_rng(11)
    return [(rng.normal(size=(n, n)), rng.normal(size=n)) for n in SIZES]


def _factor_and_solve(a, b):
    lu, piv, info = dense.lu_factor(a)
    return lu, piv, info, dense.lu_solve(lu, piv, b)


def factor_and_solve():
    """(factors, pivots, info, solution) of random systems of 1 to 300 unknowns, and the info of a singular
    matrix, in the current kernel mode (compiled: inside a compiled function, where lu_factor is numba's binding)."""
    run, info = _in_kernel_mode(_factor_and_solve), _in_kernel_mode(lambda a: dense.lu_factor(a)[2])
    return [tuple(np.asarray(v) for v in run(a, b)) for a, b in _systems()], int(info(np.ones((4, 4))))


def _in_kernel_mode(fun):
    """``fun`` compiled where the kernels are (inside it, lu_factor is numba's binding), else as it is."""
    if not jit.ENABLED:
        return fun
    import numba

    dense.lu_solve(np.eye(1), np.zeros(1, np.int64), np.ones(1))  # puts the compiled kernels in place
    return numba.njit(fun)


def pivot_margin(a: np.ndarray) -> float:
    """The smallest relative gap, over the steps of Gaussian elimination with partial pivoting, between the pivot's
    magnitude and the next largest candidate's: how far the pivot order is from a tie that round-off could decide."""
    a = np.array(a, float)
    margin = np.inf
    for k in range(len(a) - 1):
        col = np.abs(a[k:, k])
        top2 = np.sort(col)[-2:]
        margin = min(margin, float((top2[1] - top2[0]) / top2[1]))
        p = k + int(np.argmax(col))
        a[[k, p]] = a[[p, k]]
        a[k + 1:, k:] -= np.outer(a[k + 1:, k] / a[k, k], a[k, k:])
    return margin


def test_the_test_systems_pivot_far_from_any_tie():
    """The pivots are compared exactly below: that is sound only because no pivot choice of these systems is
    within many orders of magnitude of round-off of a tie (so any CPU, blocking or summation order picks them)."""
    for a, _ in _systems():
        assert pivot_margin(a) > 1e4 * FACTOR_AGREEMENT


@pytest.mark.parametrize("mode", ["compiled", "plain"])
def test_the_factors_are_scipys_and_the_solutions_agree(mode):
    if mode == "compiled" and not jit.ENABLED:
        pytest.skip("numba is not installed: only the plain-Python kernels exist here")
    results, singular = (factor_and_solve() if mode == "compiled" or not jit.ENABLED
                         else in_plain_python("tests.contact.test_dense:factor_and_solve"))
    for (lu, piv, info, x), (a, b) in zip(results, _systems()):
        ref_lu, ref_piv = scipy.linalg.lu_factor(a)
        assert info == 0
        # The same LAPACK routine; OpenBLAS blocks it by its thread count, which the plain-Python subprocess need not
        # share with this one: factors to round-off, the same pivots (chosen far from any tie: see above).
        np.testing.assert_allclose(lu, ref_lu, rtol=0, atol=FACTOR_AGREEMENT * np.abs(ref_lu).max())
        np.testing.assert_array_equal(piv, ref_piv)
        ref = scipy.linalg.lu_solve((ref_lu, ref_piv), b)
        np.testing.assert_allclose(x, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    assert singular > 0  # an exactly zero pivot is reported (the callers stop before dividing by it)


def test_an_empty_system_factorises_to_empty_factors():
    """A polish with no unknowns left asks for the factors of a 0 × 0 matrix: empty factors and pivots, info 0, on
    every path (older scipy's dgetrf refuses the empty matrix itself)."""
    from fem_grasp.contact.kernels import dense

    lu, piv, info = dense.lu_factor(np.zeros((0, 0)))
    assert lu.shape == (0, 0) and piv.shape == (0,) and info == 0
    assert dense.lu_solve(lu, piv, np.zeros(0)).shape == (0,)


def _conditioned_systems():
    """Random matrices of 1 to 150 unknowns: plain, with columns scaled over twelve decades, and with two columns
    a hair apart (condition numbers up to ~1e12)."""
    rng = np.random.default_rng(5)
    out = []
    for n in (1, 2, 7, 40, 150):
        for kind in range(3):
            a = rng.normal(size=(n, n))
            if kind == 1:
                a = a @ np.diag(10.0 ** rng.uniform(-6, 6, n))
            elif kind == 2 and n > 1:
                a[:, 0] = a[:, 1] + 1e-9 * rng.normal(size=n)
            out.append(a)
    return out


def test_the_transposed_solve_is_scipys():
    rng = np.random.default_rng(6)
    for a in _conditioned_systems():
        lu, piv, _ = dense.lu_factor(a)
        b = rng.normal(size=len(a))
        ref = scipy.linalg.lu_solve((lu, piv), b, trans=1)
        np.testing.assert_allclose(dense.lu_solve_transposed(lu, piv, b), ref, rtol=0,
                                   atol=1e-9 * np.abs(ref).max())
        np.testing.assert_allclose(a.T @ dense.lu_solve_transposed(lu, piv, b), b, rtol=0,
                                   atol=1e-6 * np.abs(a).sum(axis=0).max() * np.abs(ref).max())


def test_the_inverse_norm_estimate_bounds_the_norm_as_lapacks_does():
    """‖A⁻¹‖₁ estimated from the factors (the homotopy's singularity test): never above the true norm, within the
    factor 4 that Hager's method gives in practice, and within a factor 2 of LAPACK's own estimate (dgecon, the numpy
    reference's test; the same method, which on these systems gives the same number or a smaller one)."""
    for a in _conditioned_systems():
        lu, piv, _ = dense.lu_factor(a)
        est = dense.inverse_norm1_estimate(lu, piv)
        exact = np.abs(np.linalg.inv(a)).sum(axis=0).max()
        anorm = np.abs(a).sum(axis=0).max()
        rcond, info = scipy.linalg.lapack.dgecon(lu, anorm, norm="1")
        assert info == 0
        assert exact / 4 <= est <= exact * (1 + 1e-9)
        assert est >= 0.5 / (rcond * anorm)
    assert dense.inverse_norm1_estimate(np.zeros((0, 0)), np.zeros(0, np.int64)) == 0.0


@pytest.mark.parametrize("mode", ["compiled", "plain"])
def test_single_precision_factors_are_an_lu_of_the_matrix_and_solve_in_double(mode):
    """A float32 matrix is factorised by LAPACK's sgetrf: float32 factors with P A = L U to single precision's
    backward error (a property: another thread count blocks sgetrf otherwise, and its round-off, 6e-8 relative,
    may decide a near-tie of pivots); solving a float64 system with them gives a float64 solution whose defect is
    single precision's, ~cond × 6e-8 of b, not double precision's."""
    if mode == "compiled" and not jit.ENABLED:
        pytest.skip("numba is not installed: only the plain-Python kernels exist here")
    results = (single_factor_and_solve() if mode == "compiled" or not jit.ENABLED
               else in_plain_python("tests.contact.test_dense:single_factor_and_solve"))
    eps = float(np.finfo(np.float32).eps)
    for (lu, piv, info, x), (a, b) in zip(results, _systems()):
        assert info == 0 and lu.dtype == np.float32 and x.dtype == np.float64
        n = len(a)
        pa = a.astype(np.float32).astype(float)
        for k, p in enumerate(piv):  # LAPACK's row interchanges, in order
            pa[[k, p]] = pa[[p, k]]
        lower = np.tril(lu.astype(float), -1) + np.eye(n)
        upper = np.triu(lu.astype(float))
        assert np.abs(pa - lower @ upper).max() <= 10 * n * eps * np.abs(a).max()
        defect = np.linalg.norm(a @ x - b) / np.linalg.norm(b)
        assert defect <= 100 * np.linalg.cond(a) * eps
        assert defect > 1e3 * np.finfo(float).eps or n == 1  # single precision's, not double's


def single_factor_and_solve():
    """:func:`factor_and_solve` with the matrices in single precision and the right-hand sides in double."""
    run = _in_kernel_mode(_factor_and_solve)
    return [tuple(np.asarray(v) for v in run(a.astype(np.float32), b)) for a, b in _systems()]
