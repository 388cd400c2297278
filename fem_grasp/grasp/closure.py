"""Force closure of the initial placement on a rigid body (paper Algorithm 1, step 1).

Before squeezing, the paper checks that the two finger contacts p_i, p_j and
the centre of the support triangle △p_q p_r p_s "would be force closure on a
rigid body with the same shape of the resting object" (§III, footnote 1: the
small support triangle is approximated by its centre).  If not, the object
would not be held and Algorithm 1 returns failure at once.

Model
-----
* Three **point contacts with Coulomb friction** on a rigid body: the two
  finger contacts, with the object's inward surface normal at p_i, p_j and
  coefficient μ_ℱ, and the table contact at the triangle centre with normal
  +z and coefficient μ_𝒫.
* Each friction cone |f_t| ≤ μ f·n̂ is replaced by the inscribed pyramid of
  ``edges`` generators ``n̂ + μ(cos a ê₁ + sin a ê₂)`` (a conservative,
  *linearised* cone).
* A generator f at point p gives the wrench ``(f, (p − c) × f / L)`` about the
  centre of mass c, with L the largest distance of a contact from c (the
  torque scale only affects the quality measure, not the decision).
* The grasp is force closure iff the primitive wrenches positively span
  R⁶: they have rank 6 and some strictly positive combination of them
  vanishes.  The latter is the linear programme

      max t  subject to  W λ = 0,  Σ λ_j = 1,  λ_j ≥ t,

  solved with SciPy's HiGHS; closure iff rank W = 6 and t* > 0.
* The quality reported is the Ferrari–Canny ε: the radius of the largest
  ball about the origin inside the convex hull of the primitive wrenches
  (unit normal force per contact), from a 6-D ``scipy.spatial.ConvexHull``.

With three point contacts, torque about the line through the two finger
contacts can only come from the table contact's friction, so a frictionless
table (μ_𝒫 = 0) or frictionless fingers (μ_ℱ = 0) never give closure.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, QhullError

from ..contact.obstacles import tangent_basis

__all__ = ["ClosureResult", "cone_generators", "contact_wrenches", "force_closure",
           "placement_closure"]

log = logging.getLogger(__name__)

#: Number of generators of each linearised friction cone.
DEFAULT_EDGES = 8
#: LP margin t* below which a grasp does not count as force closure.
CLOSURE_TOL = 1e-9


@dataclass(frozen=True)
class ClosureResult:
    """Outcome of :func:`force_closure`.

    Attributes
    ----------
    closed : bool
        Whether the contacts form force closure.
    margin : float
        t* of the linear programme (module notes): the smallest weight of a
        primitive wrench in the best strictly positive null combination, with
        the weights summing to one; 0 when there is none.
    quality : float
        Ferrari–Canny ε (0 without closure).
    rank : int
        Rank of the 6 × k wrench matrix.
    reason : str
        Empty when closed, else why not.
    points, normals : (c, 3) contact points and inward unit normals
    mu : (c,) friction coefficients
    """

    closed: bool
    margin: float
    quality: float
    rank: int
    reason: str
    points: np.ndarray
    normals: np.ndarray
    mu: np.ndarray

    def __bool__(self) -> bool:
        return self.closed


def cone_generators(normal: np.ndarray, mu: float, edges: int = DEFAULT_EDGES) -> np.ndarray:
    """(edges, 3) generators ``n̂ + μ(cos a ê₁ + sin a ê₂)`` of the pyramid inscribed in a friction cone.

    With μ = 0 the cone is its axis and a single generator n̂ is returned.
    """
    n = np.asarray(normal, dtype=float)
    n = n / np.linalg.norm(n)
    if mu == 0:
        return n[None, :]
    e1, e2 = tangent_basis(n)
    a = 2.0 * np.pi * np.arange(edges) / edges
    return n + mu * (np.cos(a)[:, None] * e1 + np.sin(a)[:, None] * e2)


def contact_wrenches(points: np.ndarray, normals: np.ndarray, mu: np.ndarray, center: np.ndarray,
                     length: float | None = None, edges: int = DEFAULT_EDGES) -> np.ndarray:
    """(k, 6) primitive wrenches ``(f, (p − c) × f / L)`` of the linearised friction cones."""
    points = np.atleast_2d(np.asarray(points, dtype=float))
    normals = np.atleast_2d(np.asarray(normals, dtype=float))
    mu = np.broadcast_to(np.asarray(mu, dtype=float), (len(points),))
    center = np.asarray(center, dtype=float)
    if length is None:
        length = float(np.linalg.norm(points - center, axis=1).max())
    length = max(length, np.finfo(float).tiny)
    rows = []
    for p, n, m in zip(points, normals, mu):
        g = cone_generators(n, float(m), edges)
        rows.append(np.hstack([g, np.cross(p - center, g) / length]))
    return np.vstack(rows)


def _ferrari_canny(wrenches: np.ndarray) -> float:
    try:
        hull = ConvexHull(wrenches)
    except (QhullError, ValueError):
        return 0.0
    # Facets n·x + d ≤ 0 inside; the origin's distance to facet j is −d_j (n unit).
    return float(max(0.0, (-hull.equations[:, -1]).min()))


def force_closure(points: np.ndarray, normals: np.ndarray, mu: np.ndarray, center: np.ndarray, *,
                  edges: int = DEFAULT_EDGES, tol: float = CLOSURE_TOL) -> ClosureResult:
    """Whether point contacts with Coulomb friction form force closure on a rigid body.

    Parameters
    ----------
    points : (c, 3) contact points
    normals : (c, 3) unit normals at the contacts pointing *into* the body
        (the direction a contact can push)
    mu : (c,) or float, friction coefficients
    center : (3,) the body's centre of mass (the torque reference)
    edges : generators per linearised friction cone
    tol : LP margin below which closure is refused

    Returns
    -------
    ClosureResult
        See the module notes for the model and the linear programme.
    """
    points = np.atleast_2d(np.asarray(points, dtype=float))
    normals = np.atleast_2d(np.asarray(normals, dtype=float))
    normals = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    mu_arr = np.broadcast_to(np.asarray(mu, dtype=float), (len(points),)).copy()
    if np.any(mu_arr < 0) or not np.isfinite(mu_arr).all():
        raise ValueError(f"friction coefficients must be finite and non-negative, got {mu_arr}")
    w = contact_wrenches(points, normals, mu_arr, center, edges=edges)
    k = len(w)
    rank = int(np.linalg.matrix_rank(w.T, tol=1e-10 * max(1.0, float(np.abs(w).max()))))

    def result(closed: bool, margin: float, quality: float, reason: str) -> ClosureResult:
        return ClosureResult(closed, margin, quality, rank, reason, points, normals, mu_arr)

    if rank < 6:
        frictionless = np.flatnonzero(mu_arr == 0)
        why = (f"contact{'s' if len(frictionless) > 1 else ''} {', '.join(str(int(i) + 1) for i in frictionless)} of "
               f"{len(points)} {'are' if len(frictionless) > 1 else 'is'} frictionless (μ = 0) and push"
               f"{'' if len(frictionless) > 1 else 'es'} only along {'their' if len(frictionless) > 1 else 'its'} "
               "normal" if len(frictionless) else "too few contacts, or contacts in line")
        reason = (f"the contacts can resist only {rank} of the 6 independent directions of force and torque "
                  f"(the {k} edges of their friction cones span {rank} of the 6 wrench dimensions), so some push or "
                  f"twist of the object goes unresisted: {why}")
        return result(False, 0.0, 0.0, reason)
    # Variables (λ_1 … λ_k, t): maximise t.
    c = np.zeros(k + 1)
    c[-1] = -1.0
    a_eq = np.zeros((7, k + 1))
    a_eq[:6, :k] = w.T
    a_eq[6, :k] = 1.0
    b_eq = np.zeros(7)
    b_eq[6] = 1.0
    a_ub = np.hstack([-np.eye(k), np.ones((k, 1))])  # t − λ_j ≤ 0
    b_ub = np.zeros(k)
    bounds = [(0.0, None)] * k + [(None, 1.0)]
    lp = linprog(c, A_ub=a_ub, b_ub=b_ub, A_eq=a_eq, b_eq=b_eq, bounds=bounds, method="highs")
    no_combination = ("the contact forces the friction cones allow cannot balance every push and twist: some force "
                      "or torque on the object would go unresisted (no strictly positive combination of the contact "
                      "wrenches vanishes; the friction cones are too narrow or badly placed)")
    if lp.status == 2:  # infeasible: not even a non-negative combination vanishes
        return result(False, 0.0, 0.0, no_combination)
    if lp.status != 0:
        return result(False, 0.0, 0.0, f"the closure linear programme failed: {lp.message}")
    margin = float(lp.x[-1])
    if margin <= tol:
        return result(False, max(margin, 0.0), 0.0, no_combination)
    quality = _ferrari_canny(w)
    log.debug("force closure: LP margin %.3g, Ferrari–Canny ε %.3g", margin, quality)
    return result(True, margin, quality, "")


def placement_closure(body, positions: np.ndarray, finger_nodes: tuple[int, int], support_triangle: np.ndarray,
                      mu_finger: float, mu_table: float, *, edges: int = DEFAULT_EDGES,
                      up: np.ndarray | None = None) -> ClosureResult:
    """Algorithm 1, step 1: force closure of p_i, p_j and the support-triangle centre.

    Parameters
    ----------
    body : Body
        The posed body (its centre of mass is the torque reference).
    positions : (n, 3)
        The resting shape (deformed positions); the rigid body has this shape.
    finger_nodes : (i, j) node indices of the initial finger contacts
    support_triangle : (3,) node indices of △p_q p_r p_s
    mu_finger, mu_table : friction coefficients μ_ℱ and μ_𝒫
    up : (3,), optional
        The table's upward normal (default +z), the table contact's normal.
    """
    p = np.asarray(positions, dtype=float)
    i, j = (int(k) for k in finger_nodes)
    if i == j:
        return ClosureResult(False, 0.0, 0.0, 0, "both fingers touch the same node", p[[i]], np.zeros((1, 3)),
                             np.array([mu_finger]))
    out = body.mesh.outward_normals(p)
    if not (np.linalg.norm(out[i]) > 0 and np.linalg.norm(out[j]) > 0):
        raise ValueError(f"finger contact nodes {i}, {j} must be surface nodes of the mesh")
    up = np.array([0.0, 0.0, 1.0]) if up is None else np.asarray(up, dtype=float)
    centre = p[np.asarray(support_triangle)].mean(axis=0)
    points = np.stack([p[i], p[j], centre])
    normals = np.stack([-out[i], -out[j], up / np.linalg.norm(up)])
    com = (body.mesh.volumes @ p[body.mesh.tets].mean(axis=1)) / body.mesh.volume
    res = force_closure(points, normals, [mu_finger, mu_finger, mu_table], com, edges=edges)
    if not res.closed and mu_table == 0 and mu_finger > 0:
        from dataclasses import replace

        # two point contacts resist no torque about the line between them; only table friction could
        res = replace(res, reason=res.reason + "; the table is frictionless (μ_P = 0), and two fingertips touching "
                                               "at points cannot stop the object turning about the line between "
                                               "them without the table's friction")
    return res
