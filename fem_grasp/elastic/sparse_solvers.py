"""The sparse direct solvers that factorise a body's grounded stiffness K_g once (:func:`factorize`).

:class:`~fem_grasp.elastic.compliance.Compliance` solves with the factor for the columns of its generalised
inverse; which solver does so changes their round-off, never the answer.

``"cholmod"``
    Supernodal Cholesky from SuiteSparse: the system's CHOLMOD library called
    directly (:mod:`~fem_grasp.elastic.cholmod`; Debian's ``libcholmod3``),
    whose solves release the GIL, or where that does not load, through
    scikit-sparse (optional extra ``fem_grasp[cholmod]``).  About ten times
    faster than SuperLU on 3D elasticity, with far less fill.
``"superlu"``
    SciPy's SuperLU in symmetric mode: always available.
``"mumps"``
    MUMPS Cholesky through petsc4py (Debian's, which comes with dolfinx).
    Never chosen automatically: it loads PETSc into the process.

The solver is chosen, in order, by the ``solver`` argument, the environment
variable ``FEM_GRASP_SOLVER`` (``cholmod``, ``superlu``, ``mumps`` or
``auto``), and otherwise automatically: CHOLMOD when importable, else SuperLU.
"""

from __future__ import annotations

import atexit
import contextlib
import logging
import os
import threading
import weakref
from typing import Callable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import MissingExtraError

__all__ = ["SOLVERS", "SOLVER_ENV", "cholmod_available", "choose_solver", "factorize", "solve_lock"]

log = logging.getLogger(__name__)

#: Sparse solvers of :func:`factorize`.
SOLVERS = ("cholmod", "superlu", "mumps")
#: Environment variable naming the solver (``auto`` or one of :data:`SOLVERS`).
SOLVER_ENV = "FEM_GRASP_SOLVER"


def cholmod_available() -> bool:
    """True when a CHOLMOD library loads (:mod:`~fem_grasp.elastic.cholmod`) or scikit-sparse's wrapper imports."""
    from .cholmod import library

    if library() is not None:
        return True
    try:
        import sksparse.cholmod  # type: ignore # noqa: F401
    except ImportError:
        return False
    return True


def choose_solver(solver: str | None = None) -> str:
    """The sparse solver to use: ``solver`` if given, else ``$FEM_GRASP_SOLVER``, else CHOLMOD or SuperLU.

    Raises
    ------
    ValueError
        For an unknown solver name.
    MissingExtraError
        When CHOLMOD is asked for explicitly but scikit-sparse is not installed (an ImportError).
    """
    source = "solver argument"
    if solver is None:
        solver = os.environ.get(SOLVER_ENV, "").strip().lower() or "auto"
        source = f"${SOLVER_ENV}"
    if solver == "auto":
        return "cholmod" if cholmod_available() else "superlu"
    if solver not in SOLVERS:
        raise ValueError(f"unknown sparse solver {solver!r} ({source}); choose 'auto' or one of {SOLVERS}")
    if solver == "cholmod" and not cholmod_available():
        raise MissingExtraError("the CHOLMOD solver needs a CHOLMOD library (3.x to 5.x) that loads, such as Debian's "
                                "libcholmod3 (apt install libsuitesparse-dev), or the 'cholmod' extra (scikit-sparse): "
                                "pip install \"fem_grasp[cholmod]\"; or choose 'superlu'", extra="cholmod",
                                name="sksparse")
    return solver


#: Every live CHOLMOD factor, by the id of the solve function that owns it (see _cholmod).
_LIVE_FACTORS: dict[int, object] = {}
#: One scikit-sparse solve at a time: it works in its factor's shared workspace (``Common``), so two threads (a
#: speculative lift test beside the squeeze's) take turns; the ctypes binding gives each thread a ``Common``.
_SOLVE_LOCK = threading.Lock()


def _keep_factors_at_exit() -> None:
    """At interpreter exit, leave the live factors to the operating system (see _cholmod)."""
    import ctypes

    for factor in _LIVE_FACTORS.values():
        ctypes.pythonapi.Py_IncRef(ctypes.py_object(factor))


atexit.register(_keep_factors_at_exit)


def _cholmod(matrix: sp.csc_matrix) -> Callable[[np.ndarray], np.ndarray]:
    """CHOLMOD's factorisation and its solve function: through ctypes (:mod:`~fem_grasp.elastic.cholmod`, whose
    solves release the GIL) where a CHOLMOD library loads, else through scikit-sparse.

    scikit-sparse's ``Factor`` frees itself through its ``Common`` in ``__dealloc__``; if the garbage
    collector breaks a reference cycle that holds a factor by clearing the factor first, the ``Common``
    is gone by then and the process crashes (at exit, or at any collection).  So each factor is also
    held by the module's registry until the solve function that owns it is collected (a weakref
    finalizer, which the collector runs before it clears anything): a factor is then never garbage
    itself, and dies by reference counting with its ``Common`` intact.  At exit the factors still
    alive are kept for the operating system to reclaim.
    """
    from .cholmod import CholmodFactor, library

    if library() is not None:
        direct = CholmodFactor(matrix)

        def solve_direct(b: np.ndarray) -> np.ndarray:
            return direct.solve(b)

        solve_direct.factor = direct  # type: ignore[attr-defined]
        solve_direct.releases_gil = True  # type: ignore[attr-defined]
        return solve_direct
    from sksparse.cholmod import cholesky  # type: ignore

    factor = cholesky(matrix)

    def solve(b: np.ndarray) -> np.ndarray:
        return factor(np.asarray(b, dtype=float))

    solve.factor = factor  # type: ignore[attr-defined]
    _LIVE_FACTORS[id(solve)] = factor
    weakref.finalize(solve, _LIVE_FACTORS.pop, id(solve), None).atexit = False
    return solve


def _superlu(matrix: sp.csc_matrix) -> Callable[[np.ndarray], np.ndarray]:
    lu = spla.splu(matrix, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    return lu.solve


def _mumps(matrix: sp.csc_matrix, block: int = 256) -> Callable[[np.ndarray], np.ndarray]:
    from petsc4py import PETSc

    csr = matrix.tocsr()
    csr.sort_indices()
    mat = PETSc.Mat().createAIJ(size=csr.shape, comm=PETSc.COMM_SELF,
                                csr=(csr.indptr.astype(PETSc.IntType), csr.indices.astype(PETSc.IntType),
                                     csr.data.astype(PETSc.ScalarType)))
    mat.assemble()
    mat.setOption(PETSc.Mat.Option.SYMMETRIC, True)
    ksp = PETSc.KSP().create(PETSc.COMM_SELF)
    ksp.setOperators(mat)
    ksp.setType("preonly")
    pc = ksp.getPC()
    pc.setType("cholesky")
    pc.setFactorSolverType("mumps")
    ksp.setUp()
    x, b = mat.createVecRight(), mat.createVecLeft()

    def solve(rhs: np.ndarray) -> np.ndarray:
        rhs = np.asarray(rhs, dtype=float)
        if rhs.ndim == 1:
            b.array[:] = rhs
            ksp.solve(b, x)
            return x.array.copy()
        out = np.empty_like(rhs)
        factor = ksp.getPC().getFactorMatrix()
        for start in range(0, rhs.shape[1], block):
            cols = np.asfortranarray(rhs[:, start:start + block])
            bmat = PETSc.Mat().createDense(cols.shape, array=cols, comm=PETSc.COMM_SELF)
            xmat = PETSc.Mat().createDense(cols.shape, comm=PETSc.COMM_SELF)
            xmat.setUp()
            factor.matSolve(bmat, xmat)
            out[:, start:start + block] = xmat.getDenseArray()
            bmat.destroy()
            xmat.destroy()
        return out

    solve.keep = (mat, ksp, x, b)  # type: ignore[attr-defined]  # PETSc objects live with the closure
    return solve


def factorize(matrix: sp.spmatrix, solver: str | None = None) -> Callable[[np.ndarray], np.ndarray]:
    """Factorise a sparse symmetric positive-definite matrix; return its solve function.

    Parameters
    ----------
    matrix : (N, N) sparse SPD matrix
    solver : {"cholmod", "superlu", "mumps", "auto"}, optional
        Default: ``$FEM_GRASP_SOLVER``, else CHOLMOD when scikit-sparse is
        installed, else SuperLU (module notes).

    Returns
    -------
    solve : callable
        ``solve(b)`` for a (N,) vector or an (N, k) block of right-hand sides.
    """
    name = choose_solver(solver)
    matrix = sp.csc_matrix(matrix)
    if matrix.shape[0] != matrix.shape[1]:
        raise ValueError(f"cannot factorise a non-square {matrix.shape} matrix")
    log.debug("%s factorisation of %d DOFs, %d non-zeros", name, matrix.shape[0], matrix.nnz)
    return {"cholmod": _cholmod, "superlu": _superlu, "mumps": _mumps}[name](matrix)


def solve_lock(solve: Callable[[np.ndarray], np.ndarray]) -> contextlib.AbstractContextManager:
    """What a thread holds while it solves with ``solve`` (a :func:`factorize` result): nothing for the ctypes
    CHOLMOD binding, whose solves release the GIL and give each thread a workspace; else the one lock that
    makes threads take turns (scikit-sparse solves in its factor's shared workspace)."""
    return contextlib.nullcontext() if getattr(solve, "releases_gil", False) else _SOLVE_LOCK
