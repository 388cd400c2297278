"""A rigid fingertip pressed into an elastic block: the node contact against weighted-gap contacts, and Hertz.

Set-up
------
A rigid sphere of radius R (the fingertip) is pressed by δ into the flat top
z = 0 of an elastic block.  By symmetry a quarter x, y ≥ 0 is meshed (gmsh,
refined at the first point of contact, the origin); the symmetry planes carry
rollers, the bottom is clamped.  Contact is frictionless and, as in Hertz's
theory, along z: with w the downward displacement of the top and
h(r) = R − (R² − r²)^½ the sphere's height above its lowest point, a point
of the top is in contact where w = δ − h and free where w ≥ δ − h.  The
unknowns are the candidate nodes' z displacements; fem_grasp's K is
condensed onto them (the Schur complement, as the paper's C), so w = X p for
downward nodal forces p, X the condensed compliance.

Three discretisations of the contact condition are compared:

* **node contact** (the paper's, and fem_grasp's): each node k on its own,
  p_k ≥ 0, g_k = w_k − (δ − h_k) ≥ 0, p_k g_k = 0.  Between contact nodes
  the P1 facets cut into the sphere (h is curved, the facets are flat);
* **weighted gap** (mortar, Wohlmuth, Acta Numerica 2011; Popp et al.,
  IJNME 2009–2010): the gap integrated against each node's hat function N_k
  over the top, g̃_k = ∫ N_k (w − δ + h) dA = (M w)_k − δ A_k + ∫ N_k h dA
  (M the surface mass matrix, A_k = ∫ N_k dA, ∫ N_k h dA by a degree-4 rule),
  with nodal pressures λ_k ≥ 0, forces p = M λ, λ_k g̃_k = 0: a node
  activates when its patch penetrates on average, so the facets no longer cut
  in.  The force is Σ_k A_k λ_k;
* **dual weighted gap** (the dual mortar of those papers): the gap weighed by
  the dual basis Φ_k = 4 N_k − 1 on each triangle, biorthogonal to the hat
  functions, so that the gap's w part is A_k w_k and the forces A_k λ_k sit
  on the nodes: the node contact against the sphere's dual-weighted heights
  h̄_k = ∫ Φ_k h dA / A_k.

All are linear complementarity problems with a symmetric positive definite
matrix (X, M X M, X), solved exactly by a primal–dual active-set iteration.
Hertz: F = (4/3) E* R^½ δ^3/2, a = (R δ)^½ for a half-space; the block is
finite, so the study measures each discretisation against a fine mesh of the
same block (the mean of its three answers, which agree to a few tenths of a
per cent), and Hertz is shown for scale.  Five gmsh seeds per spacing give
the scatter that moving the nodes alone causes.

``python -m verification hertz`` runs it after the sphere between planes (:mod:`verification.hertz`).
"""

from __future__ import annotations

import logging
import time
from typing import Any

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp

from fem_grasp import Body, TetMesh

from ..dolfinx.linalg import factorized
from ._mesh import graded_mesh, hertz_force

__all__ = ["BlockIndentation", "INDENTER_CONFIGS", "METHODS", "complementarity", "dual_moments", "indenter_study",
           "quarter_block", "top_triangles", "triangle_moments"]

log = logging.getLogger(__name__)

#: The symmetric Strang–Fix rule of degree 4 on a triangle: barycentric points and weights (summing to 1).
_A, _B, _C, _D = 0.816847572980459, 0.091576213509771, 0.108103018168070, 0.445948490915965
QUADRATURE_POINTS = np.array([[_A, _B, _B], [_B, _A, _B], [_B, _B, _A], [_C, _D, _D], [_D, _C, _D], [_D, _D, _C]])
QUADRATURE_WEIGHTS = np.array([0.109951743655322] * 3 + [0.223381589678011] * 3)


def quarter_block(size: float, depth: float, contact_size: float, far_size: float, refine_radius: float,
                  seed: int = 1) -> TetMesh:
    """gmsh mesh of the block [0, size]² × [−depth, 0], edge length ``contact_size`` within ``refine_radius`` of
    the origin (the top's first point of contact), growing to ``far_size`` at twice that distance."""
    return graded_mesh(lambda occ: occ.addBox(0.0, 0.0, -depth, size, size, depth), (0.0, 0.0, 0.0),
                       contact_size, far_size, refine_radius, seed=seed)


def top_triangles(mesh: TetMesh, tol: float) -> np.ndarray:
    """(t, 3) the boundary triangles of ``mesh`` lying in the plane z = 0 (to ``tol``)."""
    tets = mesh.tets
    faces = np.sort(np.concatenate([tets[:, [0, 1, 2]], tets[:, [0, 1, 3]], tets[:, [0, 2, 3]], tets[:, [1, 2, 3]]]),
                    axis=1)
    unique, counts = np.unique(faces, axis=0, return_counts=True)
    boundary = unique[counts == 1]
    return boundary[(np.abs(mesh.points[boundary][:, :, 2]) <= tol).all(axis=1)]


def triangle_moments(xy: np.ndarray, profile) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per triangle of the plane (``xy`` (t, 3, 2)): areas (t,), hat-function moments ∫ N_i profile dA (t, 3) by
    the degree-4 rule, and the P1 mass matrix's element factor ((1 + δ_ij) / 12, times the area)."""
    e1, e2 = xy[:, 1] - xy[:, 0], xy[:, 2] - xy[:, 0]
    area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    points = np.einsum("qi,tic->tqc", QUADRATURE_POINTS, xy)
    moments = area[:, None] * np.einsum("q,tq,qi->ti", QUADRATURE_WEIGHTS, profile(points), QUADRATURE_POINTS)
    return area, moments, (np.ones((3, 3)) + np.eye(3)) / 12.0


def dual_moments(moments: np.ndarray) -> np.ndarray:
    """(t, 3) ∫ Φ_i f dA from the hat-function moments ∫ N_i f dA of :func:`triangle_moments`: the dual basis of
    P1 on a triangle, biorthogonal to the hat functions (∫ Φ_i N_j dA = δ_ij ∫ N_j dA), is Φ_i = 4 N_i − 1, and
    Σ_i N_i = 1."""
    return 4.0 * moments - moments.sum(axis=1, keepdims=True)


def complementarity(a: np.ndarray, b: np.ndarray, max_iter: int = 200) -> tuple[np.ndarray, np.ndarray, int]:
    """λ ≥ 0 with g = a λ − b ≥ 0 and λ·g = 0, for a symmetric positive definite ``a``, by the primal–dual
    active-set iteration (exact once the active set repeats); returns (λ, g, iterations).

    Raises
    ------
    RuntimeError
        When the active sets cycle or do not settle within ``max_iter`` iterations (no answer is returned then)."""
    n = len(b)
    scale = 1.0 / float(np.mean(np.diag(a)))
    active = b > 0
    seen: set[bytes] = set()
    lam, g = np.zeros(n), -np.asarray(b, float)
    for it in range(1, max_iter + 1):
        lam = np.zeros(n)
        if active.any():
            lam[active] = la.solve(a[np.ix_(active, active)], b[active], assume_a="pos", check_finite=False)
        g = a @ lam - b
        new = lam - scale * g > 0
        if np.array_equal(new, active):
            return lam, g, it
        if new.tobytes() in seen:
            raise RuntimeError(f"the active-set iteration cycles (after {it} iterations)")
        seen.add(new.tobytes())
        active = new
    raise RuntimeError(f"the active-set iteration did not settle in {max_iter} iterations")


class BlockIndentation:
    """Frictionless indentation of the quarter block's top by a rigid sphere (module notes).

    Parameters
    ----------
    mesh : TetMesh of the quarter block (:func:`quarter_block`), top at z = 0
    radius : R of the indenting sphere
    young, poisson : the block's material
    candidate_radius : top nodes within this distance of the axis may touch (larger than any contact radius asked
        for, by a few elements: the weighted gap's patches of the outermost candidates are cut)
    """

    def __init__(self, mesh: TetMesh, radius: float, young: float, poisson: float, candidate_radius: float) -> None:
        t0 = time.perf_counter()
        self.mesh, self.radius = mesh, radius
        p = mesh.points
        tol = 1e-9 * float(np.ptp(p, axis=0).max())
        n3 = 3 * mesh.n_points
        fixed = np.zeros(n3, dtype=bool)
        fixed[3 * np.flatnonzero(p[:, 0] <= tol)] = True  # rollers on x = 0 and y = 0
        fixed[3 * np.flatnonzero(p[:, 1] <= tol) + 1] = True
        bottom = np.flatnonzero(p[:, 2] <= p[:, 2].min() + tol)
        fixed[(3 * bottom[:, None] + np.arange(3)).ravel()] = True  # clamped
        top = np.flatnonzero(np.abs(p[:, 2]) <= tol)
        self.candidates = top[np.hypot(p[top, 0], p[top, 1]) <= candidate_radius]
        r = np.hypot(p[self.candidates, 0], p[self.candidates, 1])
        self.heights = radius - np.sqrt(radius**2 - r**2)  # h at the nodes
        dofs = 3 * self.candidates + 2
        free = np.setdiff1d(np.flatnonzero(~fixed), dofs)
        k = sp.csr_matrix(Body(mesh, young, poisson, density=1.0).stiffness)
        k_fc = k[free][:, dofs].toarray()
        schur = k[dofs][:, dofs].toarray() - k_fc.T @ factorized(k[free][:, free])(k_fc)
        self.compliance = np.linalg.inv(0.5 * (schur + schur.T))  # X: w = X p
        self.compliance = 0.5 * (self.compliance + self.compliance.T)
        # The weighted gap's matrices on the top triangles whose three nodes are candidates.
        at = np.full(mesh.n_points, -1, dtype=np.int64)
        at[self.candidates] = np.arange(len(self.candidates))
        tris = top_triangles(mesh, tol)
        local = at[tris[(at[tris] >= 0).all(axis=1)]]
        xy = p[self.candidates][local][:, :, :2]
        area, moments, element = triangle_moments(
            xy, lambda q: radius - np.sqrt(radius**2 - (q**2).sum(axis=-1)))
        m = len(self.candidates)
        rows, cols = np.repeat(local, 3, axis=1).ravel(), np.tile(local, (1, 3)).ravel()
        self.mass = sp.coo_matrix(((area[:, None, None] * element).ravel(), (rows, cols)), shape=(m, m)).toarray()
        self.areas = np.bincount(local.ravel(), np.repeat(area / 3.0, 3), minlength=m)
        self.height_moments = np.bincount(local.ravel(), moments.ravel(), minlength=m)
        self.triangles = local  # (t, 3) positions in ``candidates``
        dual = np.bincount(local.ravel(), dual_moments(moments).ravel(), minlength=m)
        self.dual_heights = np.divide(dual, self.areas, out=np.array(self.heights), where=self.areas > 0)
        self.mortar = self.mass @ self.compliance @ self.mass
        self.setup_seconds = time.perf_counter() - t0

    def node_contact(self, delta: float) -> dict[str, Any]:
        """The paper's node contact at indentation ``delta``: total force (whole block), active nodes, and the
        complementarity residuals relative to the force and to δ."""
        p, g, iterations = complementarity(self.compliance, delta - self.heights)
        return self._answer(p.sum(), p, g, p > 0, delta, iterations)

    def dual_gap(self, delta: float) -> dict[str, Any]:
        """The dual-mortar weighted gap at indentation ``delta`` (module notes), as :meth:`node_contact`: the gap
        weighed by the dual basis Φ_k, biorthogonal to the hat functions, is A_k (w_k − δ + h̄_k) with
        h̄_k = ∫ Φ_k h dA / A_k, and the mortar forces are A_k λ_k on the nodes: the node contact against the
        sphere's dual-weighted heights."""
        p, g, iterations = complementarity(self.compliance, delta - self.dual_heights)
        return self._answer(p.sum(), p, g, p > 0, delta, iterations)

    def weighted_gap(self, delta: float) -> dict[str, Any]:
        """The weighted-gap contact at indentation ``delta`` (module notes), as :meth:`node_contact`."""
        lam, g, iterations = complementarity(self.mortar, delta * self.areas - self.height_moments)
        return self._answer(self.areas @ lam, lam * self.areas, g / np.maximum(self.areas, 1e-300), lam > 0, delta,
                            iterations)

    @staticmethod
    def _answer(force: float, pressures: np.ndarray, gaps: np.ndarray, active: np.ndarray, delta: float,
                iterations: int) -> dict[str, Any]:
        scale = max(abs(float(force)), 1e-300)
        return {"force": 4.0 * float(force), "n_active": int(active.sum()), "iterations": iterations,
                "max_tension_rel": float(max(0.0, -pressures.min(initial=0.0)) / scale),
                "max_penetration_rel": float(max(0.0, -gaps.min(initial=0.0)) / delta),
                "max_complementarity_rel": float(np.abs(pressures * gaps).max(initial=0.0) / (scale * delta))}


#: The contact's methods, in the study's order.
METHODS = ("node", "weighted", "dual")


def _solve_level(contact_size: float, seed: int, d: np.ndarray, geometry: dict[str, float]) -> dict[str, Any]:
    radius, a_max = geometry["radius"], float(np.sqrt(geometry["radius"] * d.max()))
    mesh = quarter_block(geometry["block"], geometry["block"], contact_size * a_max, geometry["far_size"],
                         1.3 * a_max, seed=seed)
    problem = BlockIndentation(mesh, radius, geometry["young"], geometry["poisson"], 1.6 * a_max)
    solvers = {"node": problem.node_contact, "weighted": problem.weighted_gap, "dual": problem.dual_gap}
    rows = {m: [solvers[m](x) for x in d] for m in METHODS}
    return {"vertices": mesh.n_points, "candidates": len(problem.candidates), "rows": rows}


def _swing(errors: np.ndarray, a: np.ndarray) -> float:
    """The largest departure of errors along δ from their own quadratic in the contact radius: the kinks of F(δ)
    as rings of nodes enter contact."""
    return float(np.abs(errors - np.polyval(np.polyfit(a, errors, 2), a)).max())


def indenter_study(contact_sizes: list[float], seeds: int, reference_size: float, deltas: list[float],
                   radius: float = 0.01, young: float = 2e4, poisson: float = 0.3, block: float = 1.0,
                   far_size: float = 0.08) -> dict[str, Any]:
    """Force against indentation for each contact discretisation (:data:`METHODS`), on meshes of several spacings
    and seeds.

    Parameters
    ----------
    contact_sizes : edge lengths at the contact, as fractions of the largest contact radius a_max = (R δ_max)^½
    seeds : gmsh seeds per spacing
    reference_size : the reference mesh's edge length at the contact (fraction of a_max; seed 1)
    deltas : indentations, fractions of R
    radius, young, poisson : R (m), the block's E (Pa) and ν
    block, far_size : the block's side and depth, and its edge length away from the contact, fractions of R

    Returns
    -------
    dict: the reference (each method's forces, their mean and largest relative spread), and per spacing and method
    the relative error against the reference over δ and seeds: mean, largest, RMS, the spread across seeds (the
    largest over δ) and the swing (:func:`_swing`, the largest over seeds)
    """
    d = np.asarray(deltas, dtype=float) * radius
    a = np.sqrt(radius * d)
    geometry = {"radius": radius, "young": young, "poisson": poisson, "block": block * radius,
                "far_size": far_size * radius}
    hertz = hertz_force(d, radius, young, poisson)
    t0 = time.perf_counter()
    ref = _solve_level(reference_size, 1, d, geometry)
    ref_forces = {m: np.array([r["force"] for r in ref["rows"][m]]) for m in METHODS}
    reference = np.mean([ref_forces[m] for m in METHODS], axis=0)
    out: dict[str, Any] = {
        "radius": radius, "young": young, "poisson": poisson, "block_rel": block, "far_size_rel": far_size,
        "deltas_rel": [float(x) for x in deltas], "hertz_force": hertz.tolist(),
        "reference": {"contact_size_rel": reference_size, "vertices": ref["vertices"],
                      "force": reference.tolist(), **{m: ref_forces[m].tolist() for m in METHODS},
                      "methods_differ_rel": float((np.ptp([ref_forces[m] for m in METHODS], axis=0) / reference).max()),
                      "rows": ref["rows"], "seconds": time.perf_counter() - t0},
        "levels": []}
    for size in contact_sizes:
        t0 = time.perf_counter()
        runs = [_solve_level(size, seed, d, geometry) for seed in range(1, seeds + 1)]
        level: dict[str, Any] = {"contact_size_rel": size, "vertices": [r["vertices"] for r in runs],
                                 "candidates": [r["candidates"] for r in runs], "methods": {}}
        for m in METHODS:
            forces = np.array([[row["force"] for row in r["rows"][m]] for r in runs])
            err = forces / reference - 1.0
            level["methods"][m] = {
                "forces": forces.tolist(), "mean_error": float(err.mean()), "max_error": float(np.abs(err).max()),
                "rms_error": float(np.sqrt((err**2).mean())), "seed_spread": float(np.ptp(err, axis=0).max()),
                "swing": max(_swing(e, a) for e in err),
                "max_complementarity_rel": max(row["max_complementarity_rel"] for r in runs for row in r["rows"][m]),
                "max_tension_rel": max(row["max_tension_rel"] for r in runs for row in r["rows"][m]),
                "max_penetration_rel": max(row["max_penetration_rel"] for r in runs for row in r["rows"][m])}
        level["seconds"] = time.perf_counter() - t0
        out["levels"].append(level)
        log.info("indenter h = %.3g a_max: %s", size, "; ".join(
            f"{m} error {100 * s['mean_error']:+.2f} % (RMS {100 * s['rms_error']:.2f} %, "
            f"swing {100 * s['swing']:.2f} %)" for m, s in level["methods"].items()))
    return out


#: Spacings at the contact (fractions of a_max), seeds per spacing, the reference's spacing and the indentations
#: (fractions of R, a/R from 0.045 to 0.14) of the full and the quick study.
INDENTER_CONFIGS: dict[str, dict[str, Any]] = {
    "full": {"contact_sizes": [0.4, 0.28, 0.2, 0.14, 0.1], "seeds": 5, "reference_size": 0.035,
             "deltas": [float(x) for x in np.linspace(0.002, 0.02, 19)]},
    "quick": {"contact_sizes": [0.4, 0.14], "seeds": 2, "reference_size": 0.05,
              "deltas": [float(x) for x in np.linspace(0.002, 0.02, 7)]},
}
