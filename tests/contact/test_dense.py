"""The kernels' dense LU (fem_grasp.contact.kernels.dense): LAPACK's factors, as scipy's, compiled and in plain Python."""

import numpy as np
import pytest
import scipy.linalg

from fem_grasp.contact.kernels import dense, jit
from tests.contact.test_jit import in_plain_python

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
    run, info = _factor_and_solve, lambda a: dense.lu_factor(a)[2]
    if jit.ENABLED:
        import numba

        dense.lu_solve(np.eye(1), np.zeros(1, np.int64), np.ones(1))  # puts the compiled kernels in place
        run, info = numba.njit(run), numba.njit(info)
    return [tuple(np.asarray(v) for v in run(a, b)) for a, b in _systems()], int(info(np.ones((4, 4))))


@pytest.mark.parametrize("mode", ["compiled", "plain"])
def test_the_factors_are_scipys_and_the_solutions_agree(mode, tmp_path):
    if mode == "compiled" and not jit.ENABLED:
        pytest.skip("numba is not installed: only the plain-Python kernels exist here")
    results, singular = (factor_and_solve() if mode == "compiled" or not jit.ENABLED
                         else in_plain_python("factor_and_solve", tmp_path, "tests.contact.test_dense"))
    for (lu, piv, info, x), (a, b) in zip(results, _systems()):
        ref_lu, ref_piv = scipy.linalg.lu_factor(a)
        assert info == 0
        # The same LAPACK routine; OpenBLAS blocks it by its thread count, which the plain-Python subprocess need not
        # share with this one: factors to round-off, the same pivots.
        np.testing.assert_allclose(lu, ref_lu, rtol=0, atol=FACTOR_AGREEMENT * np.abs(ref_lu).max())
        np.testing.assert_array_equal(piv, ref_piv)
        ref = scipy.linalg.lu_solve((ref_lu, ref_piv), b)
        np.testing.assert_allclose(x, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    assert singular > 0  # an exactly zero pivot is reported (the callers stop before dividing by it)
