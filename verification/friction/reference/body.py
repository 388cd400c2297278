"""The elastic body of the frictional-contact reference, condensed onto its surface.

The reference (:mod:`verification.friction.compare`) solves the same
linear-elastic problem as fem_grasp — P1 tetrahedra, small strain, gravity
(paper §II-A/B, ``K Δ = F + G``) — but builds it from dolfinx's assembly
(:class:`verification.dolfinx.reference.DolfinxModel`: K from ∫σ(u):ε(v), G the
consistent P1 load, both in fem_grasp's node-major numbering) and reduces it
with its own linear algebra:

* **Static condensation onto the surface.**  Only surface nodes are ever
  loaded by a contact.  With the DOFs split into surface (s) and interior (i),
  the interior block K_ii is positive definite (the surface, held, fixes every
  rigid motion), so

      S = K_ss − K_si K_ii⁻¹ K_is,     g = G_s − K_si K_ii⁻¹ G_i,

  and the surface displacement obeys ``S u_s = f_s + λ g`` (λ the gravity load
  factor, f_s the contact forces on the object).  The interior follows from
  ``u_i = K_ii⁻¹ (λ G_i − K_is u_s)``.
* **The six rigid modes.**  S is singular with null space the surface rows R_s
  of Theorem 1's rigid fields (K R = 0 makes S R_s = 0).  With Q an
  orthonormal basis of R_s, every solution is ``u_s = H (f_s + λ g) + Q a``
  with H = S⁺ the Moore–Penrose inverse (computed as (S + σQQᵀ)⁻¹ − QQᵀ/σ)
  and a ∈ ℝ⁶ the rigid part, and it exists only when the load is balanced:
  ``Qᵀ (f_s + λ g) = 0`` (force and torque equilibrium about the reference
  positions, exactly the full body's, since R_sᵀ g = Rᵀ G).

Nothing here comes from fem_grasp except the mesh it is given (points and
tetrahedra of the posed body) and the material numbers.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as spla

log = logging.getLogger(__name__)

#: Relative size of the smallest retained eigenvalue of the rigid-mode Gram matrix: Q spans six modes only when
#: the surface is not degenerate (a flat or collinear surface would lose rotations).
RIGID_RANK_TOL = 1e-10


def surface_nodes(tets: np.ndarray) -> np.ndarray:
    """Sorted nodes of the boundary faces (triangles used by exactly one tetrahedron).

    Parameters
    ----------
    tets : (t, 4) int

    Returns
    -------
    (s,) int array
    """
    t = np.asarray(tets, dtype=np.int64)
    faces = np.concatenate([t[:, [0, 1, 2]], t[:, [0, 1, 3]], t[:, [0, 2, 3]], t[:, [1, 2, 3]]])
    faces = np.sort(faces, axis=1)
    uniq, counts = np.unique(faces, axis=0, return_counts=True)
    return np.unique(uniq[counts == 1])


def rigid_fields(points: np.ndarray, center: np.ndarray) -> np.ndarray:
    """(3k, 6) the six rigid displacement fields of Theorem 1 at ``points`` (rotations about ``center``)."""
    p = np.asarray(points, float) - np.asarray(center, float)
    k = len(p)
    r = np.zeros((k, 3, 6))
    r[:, 0, 0] = r[:, 1, 1] = r[:, 2, 2] = 1.0
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    r[:, 1, 3], r[:, 2, 3] = -z, y
    r[:, 0, 4], r[:, 2, 4] = z, -x
    r[:, 0, 5], r[:, 1, 5] = -y, x
    return r.reshape(3 * k, 6)


def _factor(mat: sp.spmatrix):
    """A solve function for a sparse SPD matrix: CHOLMOD when scikit-sparse is present, else SuperLU."""
    mat = sp.csc_matrix(mat)
    try:
        from sksparse.cholmod import cholesky

        f = cholesky(mat)
        return lambda b: f(b)
    except ImportError:  # pragma: no cover - depends on the environment
        lu = spla.splu(mat)
        return lambda b: lu.solve(np.asarray(b, float))


@dataclass
class CondensedBody:
    """A P1 body under gravity, condensed onto its surface (module notes).

    Attributes
    ----------
    points : (n, 3) reference node positions (the posed body), metres
    tets : (t, 4) tetrahedra
    surface : (s,) surface nodes, sorted
    slot : (n,) position of each node in ``surface`` (−1 for interior nodes)
    H : (3s, 3s) S⁺, the surface compliance on balanced loads, m/N
    Q : (3s, 6) orthonormal rigid modes on the surface
    hg : (3s,) H g, the surface displacement of gravity at λ = 1 (m)
    qg : (6,) Qᵀ g, gravity's share of the six equilibrium equations (N)
    weight : mg, newtons (−Σ G_z)
    diameter : largest extent of the bounding box, metres
    seconds : wall time of assembly and condensation
    """

    points: np.ndarray
    tets: np.ndarray
    surface: np.ndarray
    slot: np.ndarray
    H: np.ndarray
    Q: np.ndarray
    hg: np.ndarray
    qg: np.ndarray
    weight: float
    diameter: float
    seconds: float
    _interior: object = field(default=None, repr=False)

    @property
    def n_surface(self) -> int:
        return len(self.surface)

    def surface_displacements(self, nodes: np.ndarray, forces: np.ndarray, load: float, rigid: np.ndarray
                              ) -> np.ndarray:
        """(s, 3) u_s = H (f + λ g) + Q a for forces (k, 3) at surface ``nodes`` (repeats allowed, summed)."""
        slots = self.slot[np.asarray(nodes, dtype=np.int64)]
        dofs = (3 * slots[:, None] + np.arange(3)).ravel()
        u = self.H[:, dofs] @ np.asarray(forces, float).reshape(-1) + load * self.hg + self.Q @ rigid
        return u.reshape(-1, 3)

    def full_displacements(self, surface_disp: np.ndarray, load: float) -> np.ndarray:
        """(n, 3) the whole field from the surface displacements: u_i = K_ii⁻¹ (λ G_i − K_is u_s)."""
        solve, k_is, g_i, interior_dofs, surface_dofs = self._interior
        n = len(self.points)
        u = np.zeros(3 * n)
        us = np.asarray(surface_disp, float).reshape(-1)
        u[surface_dofs] = us
        if len(interior_dofs):
            u[interior_dofs] = solve(load * g_i - k_is @ us)
        return u.reshape(n, 3)


def condense(points: np.ndarray, tets: np.ndarray, young: float, poisson: float, density: float,
             gravity: float) -> CondensedBody:
    """Assemble K and G with dolfinx and condense them onto the surface (module notes).

    Parameters
    ----------
    points, tets : the posed mesh (fem_grasp's node numbering is kept)
    young, poisson : E (Pa) and ν
    density, gravity : ρ (kg/m³) and g (m/s²); gravity acts along −z

    Returns
    -------
    CondensedBody
    """
    from fem_grasp import TetMesh

    from ...dolfinx.reference import DolfinxModel

    t0 = time.perf_counter()
    points = np.asarray(points, float)
    tets = np.asarray(tets, dtype=np.int64)
    n = len(points)
    model = DolfinxModel(TetMesh(points, tets))
    K = model.stiffness(young, poisson).tocsr()
    G = model.gravity_loads(density, gravity)
    surf = surface_nodes(tets)
    slot = np.full(n, -1, dtype=np.int64)
    slot[surf] = np.arange(len(surf))
    sd = (3 * surf[:, None] + np.arange(3)).ravel()
    interior = np.setdiff1d(np.arange(n), surf)
    idd = (3 * interior[:, None] + np.arange(3)).ravel()
    k_ss = K[sd][:, sd].toarray()
    g_s = G[sd].copy()
    if len(idd):
        k_ii = K[idd][:, idd]
        k_is = K[idd][:, sd]
        solve = _factor(k_ii)
        x = solve(k_is.toarray())  # K_ii⁻¹ K_is, (3i, 3s)
        S = k_ss - k_is.T @ x
        g_i = G[idd].copy()
        g_s = g_s - x.T @ g_i  # K_si K_ii⁻¹ G_i = (K_ii⁻¹ K_is)ᵀ G_i
    else:
        S, solve, k_is, g_i = k_ss, None, sp.csr_matrix((0, len(sd))), np.zeros(0)
    S = 0.5 * (S + S.T)
    center = points.mean(axis=0)
    R = rigid_fields(points[surf], center)
    u_, sv, _ = la.svd(R, full_matrices=False)
    if sv.min() < RIGID_RANK_TOL * sv.max():
        raise ValueError("the surface nodes do not span the six rigid modes (degenerate mesh)")
    Q = u_
    sigma = float(np.trace(S)) / S.shape[0]
    A = S + sigma * (Q @ Q.T)
    c = la.cho_factor(A)
    H = la.cho_solve(c, np.eye(A.shape[0])) - (Q @ Q.T) / sigma
    H = 0.5 * (H + H.T)
    hg = H @ g_s
    qg = Q.T @ g_s
    weight = float(-G[2::3].sum())
    diameter = float(np.ptp(points, axis=0).max())
    seconds = time.perf_counter() - t0
    log.info("condensed body: %d nodes, %d on the surface, %.2f s", n, len(surf), seconds)
    return CondensedBody(points, tets, surf, slot, H, Q, hg, qg, weight, diameter, seconds,
                         (solve, k_is, g_i, idd, sd))
