"""The sparse direct solvers that factorise a body's grounded stiffness (fem_grasp.elastic.sparse_solvers)."""

import threading

import numpy as np
import pytest
import scipy.sparse as sp

from fem_grasp.elastic import sparse_solvers as ss


def _available():
    out = ["superlu"]
    if ss.cholmod_available():
        out.append("cholmod")
    try:
        import petsc4py  # noqa: F401
        out.append("mumps")
    except ImportError:
        pass
    return out


AVAILABLE = _available()


def spd(rng, n=60):
    a = sp.random(n, n, 0.08, random_state=np.random.RandomState(3))
    return (a @ a.T + sp.eye(n) * 0.5).tocsc()


@pytest.mark.parametrize("solver", AVAILABLE)
def test_factorize_solves_vectors_and_blocks(rng, solver):
    a = spd(rng)
    solve = ss.factorize(a, solver)
    b = rng.standard_normal((a.shape[0], 4))
    for rhs in (b[:, 0], b):
        x = solve(rhs)
        assert x.shape == rhs.shape
        assert np.abs(a @ x - rhs).max() <= 1e-12 * np.abs(rhs).max() * 1e3


def test_explicit_cholmod_without_a_library_says_how_to_install(monkeypatch):
    """Neither a CHOLMOD library that loads nor scikit-sparse: asked for by name, CHOLMOD says how to get it;
    chosen automatically, SuperLU."""
    import sys

    from fem_grasp.elastic import cholmod

    monkeypatch.setattr(cholmod, "_LIBRARY_TRIED", True)
    monkeypatch.setattr(cholmod, "_LIBRARY", None)
    monkeypatch.setitem(sys.modules, "sksparse", None)
    monkeypatch.setitem(sys.modules, "sksparse.cholmod", None)
    with pytest.raises(ImportError, match="libcholmod3.*scikit-sparse"):
        ss.choose_solver("cholmod")
    assert ss.choose_solver("auto") == "superlu"


def test_threads_take_turns_only_with_a_solver_that_shares_its_workspace(rng):
    """SuperLU's solves hold the one solve lock (another thread's solve waits); the ctypes CHOLMOD binding's hold
    nothing (each thread solves in a workspace of its own, the GIL released)."""
    a = spd(rng)

    def another_thread_may_solve() -> bool:
        got = []
        probe = threading.Thread(target=lambda: got.append(ss._SOLVE_LOCK.acquire(timeout=0.05)))
        probe.start()
        probe.join()
        if got[0]:
            ss._SOLVE_LOCK.release()
        return got[0]

    with ss.solve_lock(ss.factorize(a, "superlu")):
        assert not another_thread_may_solve()
    assert another_thread_may_solve()
    solve = ss.factorize(a, "cholmod") if "cholmod" in AVAILABLE else None
    if solve is not None and getattr(solve, "releases_gil", False):
        with ss.solve_lock(solve):
            assert another_thread_may_solve()
