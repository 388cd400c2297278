"""The rigid-body comparison of Table III: least total normal force holding the object.

The paper compares the total finger normal force at lift-off of the soft
object with that needed to pick up "rigid bodies that have identical
shapes".  It does not state its rigid model; ours is:

* the rigid body has the resting shape (deformed positions of the resting
  state) and the initial finger contacts p_i, p_j with the object's inward
  surface normals n̂_i, n̂_j there;
* two **point contacts with Coulomb friction** μ_ℱ, |f_t| ≤ μ f·n̂, exact
  (quadratic) cones, no linearisation;
* the fingers hold the whole weight (the table is gone): f_i + f_j = mg ẑ;
* torque balance about the centre of mass **perpendicular to the grasp
  axis** û = (p_j − p_i)/|p_j − p_i|.  Two point contacts cannot exert a
  torque about the line through them, so the torque about û is left free:
  the object may pivot about the grasp axis (as a pair of point contacts
  allows) until its centre of mass is under it.  The neglected torque is
  reported.

The five equations leave one free parameter, the internal squeeze t along
the grasp axis: f_i = a + t û, f_j = b − t û.  Each friction cone is convex,
so each contact admits an interval of t; the total normal force
f_i·n̂_i + f_j·n̂_j is linear in t, hence least at an end of the intersection
of the two intervals.  This is solved in closed form.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["RigidGrasp", "rigid_grasp"]


@dataclass(frozen=True)
class RigidGrasp:
    """The least-normal-force rigid grasp of :func:`rigid_grasp`.

    Attributes
    ----------
    feasible : whether two point contacts with friction μ can hold the weight
    total_normal_force : f_i·n̂_i + f_j·n̂_j, newtons (inf when infeasible)
    forces : (2, 3) contact forces on the object, newtons (NaN when infeasible)
    squeeze : t, the internal force along the grasp axis, newtons
    axis_torque : torque about the grasp axis left to pivoting, N·m
    reason : why infeasible (empty otherwise)
    """

    feasible: bool
    total_normal_force: float
    forces: np.ndarray
    squeeze: float
    axis_torque: float
    reason: str = ""


def _interval(a: np.ndarray, u: np.ndarray, n: np.ndarray, mu: float) -> tuple[float, float]:
    """The t for which f(t) = a + t u lies in the friction cone about n (may be empty: lo > hi)."""
    an, un = float(a @ n), float(u @ n)
    at, ut = a - an * n, u - un * n
    # q(t) = μ²(an + t un)² − |at + t ut|² ≥ 0 and an + t un ≥ 0.
    qa = mu**2 * un**2 - ut @ ut
    qb = 2.0 * (mu**2 * an * un - at @ ut)
    qc = mu**2 * an**2 - at @ at
    lo, hi = -np.inf, np.inf
    if un > 0:
        lo = -an / un
    elif un < 0:
        hi = -an / un
    elif an < 0:
        return np.inf, -np.inf
    eps = 1e-14 * max(abs(qa), abs(qb), abs(qc), 1e-300)
    if abs(qa) <= eps:
        if abs(qb) <= eps:
            return (lo, hi) if qc >= 0 else (np.inf, -np.inf)
        root = -qc / qb
        return (max(lo, root), hi) if qb > 0 else (lo, min(hi, root))
    disc = qb**2 - 4.0 * qa * qc
    if qa < 0:
        if disc < 0:
            return np.inf, -np.inf
        r1, r2 = sorted([(-qb - np.sqrt(disc)) / (2 * qa), (-qb + np.sqrt(disc)) / (2 * qa)])
        return max(lo, r1), min(hi, r2)
    # qa > 0: q ≥ 0 outside the roots (the double cone); keep the branch with f·n ≥ 0.
    if disc <= 0:
        return lo, hi
    r1, r2 = sorted([(-qb - np.sqrt(disc)) / (2 * qa), (-qb + np.sqrt(disc)) / (2 * qa)])
    if un > 0:
        return max(lo, r2), hi
    return lo, min(hi, r1)


def rigid_grasp(points: np.ndarray, normals: np.ndarray, center: np.ndarray, weight: float, mu: float,
                up: np.ndarray | None = None) -> RigidGrasp:
    """Least total normal force of two frictional point contacts holding a rigid body (module notes).

    Parameters
    ----------
    points : (2, 3) contact points p_i, p_j
    normals : (2, 3) inward unit normals (the directions the fingers push)
    center : (3,) centre of mass
    weight : mg, newtons
    mu : friction coefficient μ_ℱ
    up : (3,), optional, the upward direction (default +z)
    """
    p = np.asarray(points, dtype=float)
    n = np.asarray(normals, dtype=float)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    up = np.array([0.0, 0.0, 1.0]) if up is None else np.asarray(up, float) / np.linalg.norm(up)
    c = np.asarray(center, dtype=float)
    axis = p[1] - p[0]
    length = float(np.linalg.norm(axis))
    if length == 0:
        raise ValueError("the two contact points coincide")
    u = axis / length
    # Unknowns (f_i, f_j): force balance (3 rows) and torque about c perpendicular to û (2 rows).
    e = np.linalg.svd(np.eye(3) - np.outer(u, u))[0][:, :2].T  # (2, 3) basis ⟂ û
    r = p - c

    def cross_matrix(v: np.ndarray) -> np.ndarray:
        return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])

    a_mat = np.zeros((5, 6))
    a_mat[:3, :3] = np.eye(3)
    a_mat[:3, 3:] = np.eye(3)
    a_mat[3:, :3] = e @ cross_matrix(r[0])
    a_mat[3:, 3:] = e @ cross_matrix(r[1])
    # Solved for a unit weight and scaled back at the end: the grasp is linear in mg, and _interval's
    # tolerances compare coefficients of force, force² and 1, so they hold only in units of the weight
    # (in newtons, every grasp of more than 1e7 N was judged infeasible).
    rhs = np.concatenate([up, np.zeros(2)])
    sol, *_ = np.linalg.lstsq(a_mat, rhs, rcond=None)
    a, b = sol[:3], sol[3:]
    lo_i, hi_i = _interval(a, u, n[0], mu)
    lo_j, hi_j = _interval(b, -u, n[1], mu)
    lo, hi = max(lo_i, lo_j), min(hi_i, hi_j)
    if not lo <= hi:
        return RigidGrasp(False, np.inf, np.full((2, 3), np.nan), np.nan, np.nan,
                          f"two point contacts with μ = {mu:g} cannot hold the weight: no internal squeeze puts "
                          "both contact forces inside their friction cones")
    slope = float(u @ n[0] - u @ n[1])
    if slope > 0:
        t = lo
    elif slope < 0:
        t = hi
    else:
        t = lo if np.isfinite(lo) else hi
    if not np.isfinite(t):
        return RigidGrasp(False, np.inf, np.full((2, 3), np.nan), np.nan, np.nan,
                          "the normal force is unbounded below: the contacts do not oppose each other")
    w = float(weight)
    f = w * np.stack([a + t * u, b - t * u])
    total = float(f[0] @ n[0] + f[1] @ n[1])
    torque = float(u @ (np.cross(r[0], f[0]) + np.cross(r[1], f[1])))
    return RigidGrasp(True, total, f, w * float(t), torque)
