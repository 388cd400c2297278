"""The one contact-law checker every result is held to: the resting state, each pickup snapshot, and the tests.

For a configuration of contact nodes on their obstacles (the table 𝒫, the
fingertips ℱ₁, ℱ₂) with forces f_k on the object, :func:`contact_law_figures`
measures, with F_s = mg + max |f_k| the force scale and L the mesh diameter:

* **equilibrium** — contact forces and gravity balance in force and torque
  (:func:`fem_grasp.elastic.equilibrium_residual`, relative);
* **non-penetration** — no surface node lies inside an obstacle it does not
  touch, and every contact node lies on its own obstacle;
* **compressive normals** — f·n̂ ≥ 0 (event B would have released a contact);
* **Coulomb's cone** — a sticking contact inside its cone, |f_t| ≤ μ f·n̂; a
  sliding one on it, |f_t| = μ f·n̂ (paper eqs. 6–7).

Every figure is compared with :data:`CHECK_TOLERANCES`, one table for all
results, and the failures are listed in words.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from ..contact.friction import cone_violation, normal_component
from ..contact.obstacles import OBSTACLES, Obstacle
from ..elastic.body import Body
from ..elastic.response import equilibrium_residual

__all__ = ["CHECK_TOLERANCES", "contact_law_figures"]

#: Tolerances of the checks (F_s = mg + max |f_k|, L = the mesh diameter).  The event thresholds of the
#: tracking (:mod:`fem_grasp.contact.tracking`) sit well inside them.
CHECK_TOLERANCES: dict[str, float] = {
    "equilibrium": 1e-9,  # relative force and torque residuals: round-off of the (3m+6)-square solves
    "penetration": 1e-9,  # × L: a free surface node inside an obstacle (events A fire at 1e-10 L)
    "contact_gap": 1e-9,  # × L: a contact node off its obstacle
    "tensile": 1e-9,  # × F_s: a pulling contact (events B fire at 1e-11 F_s)
    "cone_stick": 1e-8,  # × f·n̂: a sticking contact outside its cone (events C fire at 1e-9 f·n̂) …
    "stick_floor": 2e-7,  # × F_s: … beyond the force floor 1e-7 F_s below which stick/slip is not assessed
    "cone_slide": 1e-8,  # × f·n̂: a sliding contact off its cone …
    "slide_floor": 1e-9,  # × F_s: … beyond round-off of the force scale
}


def contact_law_figures(body: Body, obstacles: Sequence[Obstacle | None], owner: np.ndarray, nodes: np.ndarray,
                        contact_positions: np.ndarray, forces: np.ndarray, sliding: np.ndarray, mu: np.ndarray,
                        surface_nodes: np.ndarray, surface_positions: np.ndarray,
                        tolerances: dict[str, float] | None = None) -> dict[str, Any]:
    """Measure equilibrium, non-penetration and Coulomb's law of one contact configuration (module notes).

    Parameters
    ----------
    body : the posed body (its weight and diameter set the scales)
    obstacles : the obstacles indexed by owner code (:data:`~fem_grasp.contact.obstacles.OBSTACLES`); None
        for one that is absent (no fingertips at rest, no table in the air)
    owner : (m,) owner code of each contact
    nodes : (m,) contact node indices
    contact_positions : (m, 3) deformed positions of the contact nodes
    forces : (m, 3) forces on the object, newtons
    sliding : (m,) whether each contact slides
    mu : (m,) friction coefficient of each contact
    surface_nodes, surface_positions : (s,) the surface nodes and (s, 3) their deformed positions
    tolerances : overrides of :data:`CHECK_TOLERANCES`

    Returns
    -------
    dict
        ``force_residual``, ``torque_residual`` (relative); ``max_penetration``, ``max_contact_gap`` (m);
        ``min_normal_force`` (N, None without contacts); ``max_tensile``, ``max_stick_excess``,
        ``max_slide_error`` (× F_s, net of their f·n̂ allowances); ``max_stick_cone_violation`` and
        ``max_slide_cone_error`` ((|f_t| − μ f·n̂)/f·n̂ and its absolute value; None without such
        contacts); ``n_contacts``, ``n_sliding``; ``ok`` and ``failures`` (messages).
    """
    tol = dict(CHECK_TOLERANCES)
    tol.update(tolerances or {})
    owner = np.asarray(owner, dtype=np.int64)
    nodes = np.asarray(nodes, dtype=np.int64)
    forces = np.asarray(forces, dtype=float).reshape(-1, 3)
    sliding = np.asarray(sliding, dtype=bool)
    mu = np.asarray(mu, dtype=float)
    q = np.asarray(contact_positions, dtype=float).reshape(-1, 3)
    diam = body.mesh.diameter
    f_res, t_res = equilibrium_residual(body, nodes, forces)
    fs = body.weight + float(np.abs(forces).max(initial=0.0))

    normals = np.zeros_like(q)
    gaps = np.zeros(len(q))
    penetration, deepest = 0.0, None  # the deepest free node's depth and the obstacle it is in
    surface_nodes = np.asarray(surface_nodes, dtype=np.int64)
    for code, obstacle in enumerate(obstacles):
        on = owner == code
        if obstacle is None:
            if on.any():
                raise ValueError(f"contacts on {OBSTACLES[code]}, which is absent")
            continue
        if on.any():
            normals[on] = obstacle.inward_normals(q[on])
            gaps[on] = obstacle.signed_distance(q[on])
        free = ~np.isin(surface_nodes, nodes[on])
        if free.any():
            depth = float(-obstacle.signed_distance(surface_positions[free]).min())
            if depth > penetration:
                penetration, deepest = depth, OBSTACLES[code]
    fn = normal_component(forces, normals)
    excess = cone_violation(forces, normals, mu)  # |f_t| − μ f·n̂
    stick = ~sliding
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = excess / fn
    figures: dict[str, Any] = {
        "force_residual": f_res, "torque_residual": t_res,
        "max_penetration": max(penetration, 0.0),
        "max_contact_gap": float(np.abs(gaps).max(initial=0.0)),
        "min_normal_force": float(fn.min()) if len(fn) else None,
        "max_tensile": max(0.0, float((-fn).max(initial=0.0)) / fs),
        "max_stick_excess": (float(((excess - tol["cone_stick"] * np.maximum(fn, 0)) / fs)[stick].max())
                             if stick.any() else -np.inf),
        "max_slide_error": (float(((np.abs(excess) - tol["cone_slide"] * np.maximum(fn, 0)) / fs)[sliding].max())
                            if sliding.any() else 0.0),
        "max_stick_cone_violation": float(rel[stick].max()) if stick.any() else None,
        "max_slide_cone_error": float(np.abs(rel[sliding]).max()) if sliding.any() else None,
        "n_contacts": int(len(nodes)), "n_sliding": int(sliding.sum()),
    }
    failures = []
    if f_res > tol["equilibrium"] or t_res > tol["equilibrium"]:
        failures.append(f"equilibrium residuals {f_res:.3g} (force), {t_res:.3g} (torque)")
    if figures["max_penetration"] > tol["penetration"] * diam:
        where = "below the table" if deepest == "table" else f"inside {deepest}"
        failures.append(f"a node is {figures['max_penetration']:.3g} m {where}")
    if figures["max_contact_gap"] > tol["contact_gap"] * diam:
        worst = OBSTACLES[int(owner[np.argmax(np.abs(gaps))])]
        failures.append(f"a contact node is {figures['max_contact_gap']:.3g} m off {'the ' if worst == 'table' else ''}"
                        f"{worst}")
    if figures["max_tensile"] > tol["tensile"]:
        failures.append(f"a contact pulls ({figures['max_tensile']:.3g} F_s)")
    if figures["max_stick_excess"] > tol["stick_floor"]:
        failures.append(f"a sticking contact is outside its cone by {figures['max_stick_excess']:.3g} F_s")
    if figures["max_slide_error"] > tol["slide_floor"]:
        failures.append(f"a sliding contact is off its cone by {figures['max_slide_error']:.3g} F_s")
    figures["ok"] = not failures
    figures["failures"] = failures
    return figures
