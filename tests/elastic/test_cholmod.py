"""CHOLMOD called through ctypes (fem_grasp.elastic.cholmod): its solves are scikit-sparse's, in any thread."""

import threading

import numpy as np
import pytest

from fem_grasp import Body
from fem_grasp.elastic import cholmod, sparse_solvers
from fem_grasp.elastic import compliance as cp
from tests.helpers import perturbed_box

pytestmark = pytest.mark.skipif(cholmod.library() is None, reason="no CHOLMOD library of a supported version loads")


@pytest.fixture(scope="module")
def stiffness():
    """A grounded elastic stiffness (a perturbed box), as the compliance factorises it."""
    body = Body(perturbed_box(np.random.default_rng(5), divisions=(5, 4, 4)), 3e4, 0.35, weight=1.0)
    ground = cp.grounding_dofs(body.mesh.points, body.rigid_modes)
    free = np.setdiff1d(np.arange(body.stiffness.shape[0]), ground)
    return body.stiffness[free][:, free].tocsc()


def unit_columns(n, rows):
    b = np.zeros((n, len(rows)))
    b[rows, np.arange(len(rows))] = 1.0
    return b


def test_solves_vectors_and_blocks_to_round_off(stiffness, rng):
    factor = cholmod.CholmodFactor(stiffness)
    b = rng.standard_normal((stiffness.shape[0], cholmod.SOLVE_COLUMNS + 7))  # wider than one block
    for rhs in (b[:, 0], b[:, :7], b, b[:, :0]):
        x = factor.solve(rhs)
        assert x.shape == rhs.shape
        assert np.abs(stiffness @ x - rhs).max(initial=0.0) <= 1e-9 * np.abs(rhs).max(initial=0.0)
    with pytest.raises(ValueError, match="expected"):
        factor.solve(np.ones(3))


def test_the_solves_are_scikit_sparses_bit_for_bit(stiffness):
    """The same library with its default settings: the same factor, the same columns."""
    sksparse = pytest.importorskip("sksparse.cholmod")
    b = unit_columns(stiffness.shape[0], np.arange(0, stiffness.shape[0], 37))
    np.testing.assert_array_equal(cholmod.CholmodFactor(stiffness).solve(b), sksparse.cholesky(stiffness)(b))


def test_a_matrix_that_is_not_positive_definite_is_refused(stiffness, capfd):
    """The negative of a grounded stiffness: CHOLMOD's LL' stops at its first column.  The exception says so, and
    CHOLMOD's own warning line does not reach the output (it wrote one to standard output)."""
    with pytest.raises(cholmod.NotPositiveDefiniteError, match="not positive definite"):
        cholmod.CholmodFactor(-stiffness)
    out, err = capfd.readouterr()
    assert "CHOLMOD" not in out + err


def test_two_threads_solving_at_once_get_what_one_gets_alone(stiffness):
    """Each thread solves with a workspace of its own: the same numbers as one after the other."""
    factor = cholmod.CholmodFactor(stiffness)
    n = stiffness.shape[0]
    blocks = [unit_columns(n, np.arange(k, n, 29)) for k in range(4)]
    alone = [factor.solve(b) for b in blocks]
    got = [None] * len(blocks)

    def work(i):
        for _ in range(3):
            got[i] = factor.solve(blocks[i])

    threads = [threading.Thread(target=work, args=(i,)) for i in range(len(blocks))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for a, g in zip(alone, got):
        np.testing.assert_array_equal(a, g)


def test_the_compliance_uses_the_binding_where_it_loads(stiffness):
    solve = sparse_solvers.factorize(stiffness, "cholmod")
    assert getattr(solve, "releases_gil", False) and isinstance(solve.factor, cholmod.CholmodFactor)
