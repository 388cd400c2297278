"""Compliance of a free body: a generalised inverse of the singular stiffness K.

K has the six rigid modes of Theorem 1 as its null space.  Holding six DOFs
that block every rigid motion ("grounding") leaves a non-singular matrix K_g,
factorised once per body.  Its inverse padded with zeros, X, satisfies
K X F = F for every load F orthogonal to the rigid modes, which is all the
bordered system (3) needs: the paper's A = Σ v̄ v̄ᵀ/λ and D may be replaced by
X_cc and (XG)_c without changing the contact forces (DESIGN.md, "Eq. (3) is a
Dirichlet problem").  Columns of X are computed the first time a node enters
contact and cached, so every later contact set costs a small dense solve.
"""

from __future__ import annotations

import logging
from typing import Callable

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as spla

log = logging.getLogger(__name__)


def factorize(matrix: sp.spmatrix) -> Callable[[np.ndarray], np.ndarray]:
    """Factorise a sparse symmetric positive-definite matrix; return its solve function.

    Uses CHOLMOD (scikit-sparse) when installed, otherwise SciPy's SuperLU in
    symmetric mode.
    """
    matrix = sp.csc_matrix(matrix)
    try:  # optional accelerator
        from sksparse.cholmod import cholesky  # type: ignore

        factor = cholesky(matrix)
        return lambda b: factor(b)
    except ImportError:
        pass
    lu = spla.splu(matrix, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    return lu.solve


def grounding_dofs(points: np.ndarray, modes: np.ndarray) -> np.ndarray:
    """Six DOFs whose fixing removes all rigid motion, chosen for good conditioning.

    Candidates are the 9 DOFs of three well-spread nodes (far from the centre,
    far from the first, far from the line of the two); a pivoted QR of the
    rigid modes restricted to them picks the six most independent.
    """
    c = points.mean(axis=0)
    a = int(np.argmax(np.sum((points - c) ** 2, axis=1)))
    b = int(np.argmax(np.sum((points - points[a]) ** 2, axis=1)))
    ab = points[b] - points[a]
    ab /= np.linalg.norm(ab)
    rel = points - points[a]
    off = rel - np.outer(rel @ ab, ab)
    d = int(np.argmax(np.sum(off**2, axis=1)))
    cand = (3 * np.array([a, b, d])[:, None] + np.arange(3)).ravel()
    _, _, piv = la.qr(modes[cand].T, pivoting=True, mode="economic")
    return np.sort(cand[piv[:6]])


class Compliance:
    """Generalised inverse X of K, applied and cached column by column.

    Parameters
    ----------
    stiffness : (3n, 3n) sparse matrix
    points : (n, 3) reference coordinates
    modes : (3n, 6) rigid modes spanning the null space of ``stiffness``
    """

    def __init__(self, stiffness: sp.spmatrix, points: np.ndarray, modes: np.ndarray) -> None:
        n = stiffness.shape[0]
        self.n_dofs = n
        self.ground = grounding_dofs(points, modes)
        free = np.ones(n, dtype=bool)
        free[self.ground] = False
        self.free = np.flatnonzero(free)
        k = sp.csr_matrix(stiffness)
        self._solve = factorize(k[self.free][:, self.free])
        self._columns: dict[int, np.ndarray] = {}
        log.debug("factorised K with %d DOFs grounded at %s", n, self.ground)

    def apply(self, load: np.ndarray) -> np.ndarray:
        """X @ load for one (3n,) vector or a (3n, k) block."""
        load = np.asarray(load, dtype=float)
        out = np.zeros_like(load)
        out[self.free] = self._solve(np.ascontiguousarray(load[self.free]))
        return out

    def node_columns(self, nodes: np.ndarray) -> np.ndarray:
        """(3n, 3m) columns of X for the DOFs of ``nodes``, computed once per node."""
        new = [int(k) for k in dict.fromkeys(np.asarray(nodes).tolist()) if int(k) not in self._columns]
        if new:
            rhs = np.zeros((self.n_dofs, 3 * len(new)))
            for j, k in enumerate(new):
                rhs[3 * k : 3 * k + 3, 3 * j : 3 * j + 3] = np.eye(3)
            cols = self.apply(rhs)
            for j, k in enumerate(new):
                self._columns[k] = cols[:, 3 * j : 3 * j + 3]
        return np.concatenate([self._columns[int(k)] for k in nodes], axis=1)

    @property
    def cached_nodes(self) -> int:
        return len(self._columns)
