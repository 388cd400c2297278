"""Sphere indentation against Hertz theory, with fem_grasp's stiffness matrix.

Set-up
------
An elastic sphere of radius R is squeezed between two rigid, frictionless
planes that each approach its centre by δ.  By symmetry only the octant
x, y, z ≥ 0 is meshed (gmsh, refined around the pole (0, 0, R)); the
symmetry planes carry roller conditions (u_x = 0 on x = 0, u_y = 0 on y = 0,
u_z = 0 on z = 0), which also remove every rigid motion.  The plane z = R − δ
is the rigid indenter.

Contact model: **frictionless** unilateral contact on the nodes.  A surface
node touching the plane has its vertical displacement prescribed so that it
lies on the plane (its tangential motion is free); a node whose reaction
would pull on the plane is released; a free node that would penetrate is
added.  The active set is found by a primal–dual active-set iteration on the
dense Schur complement of fem_grasp's K onto the candidate nodes' vertical
DOFs — the same reduced-stiffness idea as the paper's C.

Hertz: ``F = (4/3) E* R^½ δ^{3/2}``, ``E* = E / (1 − ν²)`` for an elastic sphere
on a rigid plane, contact radius ``a = (R δ)^½``.  Hertz's half-space
idealisation neglects the compliance of the rest of the sphere; that
correction is of relative order (δ/R)^½ and lowers the force.  The report
therefore also extrapolates F/F_Hertz to δ → 0 with a fit in (δ/R)^½.

A second set-up, :mod:`.indenter`, presses a rigid sphere (a fingertip) into an elastic block and compares
the paper's node contact with weighted-gap contacts (mortar and dual mortar) on meshes of several spacings and
gmsh seeds.

``python -m verification hertz [--quick]`` runs both alone (``hertz.html``, ``hertz.json``); it is a stage of the
full report too.  Figure, headline checks and the report's section: :mod:`.report`.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp

from fem_grasp import Body, TetMesh

from .._common.run import Stages
from ..dolfinx.linalg import factorized
from ._mesh import graded_mesh, hertz_force
from .indenter import INDENTER_CONFIGS, indenter_study
from .report import checks as _hertz_checks
from .report import hertz_plot, indenter_checks, indenter_plot, indenter_section
from .report import section as _hertz_section

__all__ = ["CONFIGS", "STAGES", "OctantIndentation", "checks", "hertz_force", "hertz_study", "indenter_study",
           "octant_sphere", "run", "section"]

log = logging.getLogger(__name__)


def octant_sphere(radius: float, pole_size: float, far_size: float, refine_radius: float) -> TetMesh:
    """gmsh mesh of the sphere octant x, y, z ≥ 0, with edge length ``pole_size`` near (0, 0, R).

    The size grows linearly from ``pole_size`` at distance ``refine_radius``
    from the pole to ``far_size`` at distance ``2 × refine_radius``.
    """
    return graded_mesh(lambda occ: occ.addSphere(0.0, 0.0, 0.0, radius, -1, 0.0, np.pi / 2, np.pi / 2),
                       (0.0, 0.0, radius), pole_size, far_size, refine_radius)


class OctantIndentation:
    """Frictionless indentation of the sphere octant by the plane z = R − δ.

    Parameters
    ----------
    mesh : TetMesh of the octant (:func:`octant_sphere`)
    radius : R
    young, poisson : material
    max_delta : largest indentation to be asked for; sets the candidate contact nodes
    """

    def __init__(self, mesh: TetMesh, radius: float, young: float, poisson: float, max_delta: float) -> None:
        t0 = time.perf_counter()
        self.mesh, self.radius = mesh, radius
        self.young, self.poisson = young, poisson
        p = mesh.points
        tol = 1e-9 * radius
        k = Body(mesh, young, poisson, density=1.0).stiffness
        n3 = 3 * mesh.n_points
        fixed = np.zeros(n3, dtype=bool)
        for axis in range(3):
            fixed[3 * np.flatnonzero(np.abs(p[:, axis]) <= tol) + axis] = True
        surf = mesh.surface_nodes
        gap = radius - p[surf, 2]
        cand = surf[(gap <= 1.1 * max_delta) & (p[surf, 2] > tol)]
        self.candidates = cand[np.argsort(radius - p[cand, 2])]
        self.gap0 = radius - p[self.candidates, 2]  # initial gap to the plane z = R
        c_dofs = 3 * self.candidates + 2
        if fixed[c_dofs].any():
            raise RuntimeError("a candidate contact DOF is a symmetry DOF")
        is_c = np.zeros(n3, dtype=bool)
        is_c[c_dofs] = True
        free = np.flatnonzero(~fixed & ~is_c)
        k = sp.csr_matrix(k)
        solve = factorized(k[free][:, free])
        kfc = k[free][:, c_dofs].toarray()
        x = solve(kfc)
        self.schur = k[c_dofs][:, c_dofs].toarray() - kfc.T @ x
        self.schur = 0.5 * (self.schur + self.schur.T)
        self.setup_seconds = time.perf_counter() - t0
        log.info("octant indentation: %d vertices, %d candidate nodes, set-up %.1f s", mesh.n_points,
                 len(self.candidates), self.setup_seconds)

    def solve(self, delta: float, max_iter: int = 100) -> dict:
        """Contact state for indentation ``delta``.

        Returns
        -------
        dict
            ``force`` (total load on the whole sphere, N), ``contact_radius``
            (largest horizontal distance of an active node from the axis),
            ``n_active``, ``iterations``, and the complementarity residuals
            ``max_tension`` and ``max_penetration`` (relative to the force and δ).
        """
        s = self.schur
        target = self.gap0 - delta  # u_z that puts the node on the plane (negative: pushed down)
        n = len(target)
        scale = float(np.mean(np.diag(s)))
        active = target < 0
        seen = set()
        for it in range(1, max_iter + 1):
            u = np.zeros(n)
            u[active] = target[active]
            ina = ~active
            if ina.any():
                u[ina] = -np.linalg.solve(s[np.ix_(ina, ina)], s[np.ix_(ina, active)] @ u[active])
            f = s @ u  # force on the object (z); pressure p = −f ≥ 0 on active nodes
            pressure = -f
            new = pressure + scale * (u - target) > 0
            key = new.tobytes()
            if np.array_equal(new, active) or key in seen:
                break
            seen.add(key)
            active = new
        force_octant = float(pressure[active].sum())
        pts = self.mesh.points[self.candidates[active]]
        penetration = np.max(np.where(~active, u - target, -np.inf), initial=0.0)
        tension = np.max(np.where(active, -pressure, -np.inf), initial=0.0)
        return {
            "delta": float(delta),
            "force": 4.0 * force_octant,
            "contact_radius": float(np.sqrt((pts[:, :2] ** 2).sum(axis=1)).max()) if len(pts) else 0.0,
            "n_active": int(active.sum()),
            "iterations": it,
            "max_tension_rel": float(max(tension, 0.0) / max(abs(force_octant), 1e-300)),
            "max_penetration_rel": float(max(penetration, 0.0) / delta),
        }


def hertz_study(pole_sizes: list[float], deltas: list[float], radius: float = 0.037, young: float = 1e5,
                poisson: float = 0.3, refine_radius: float = 0.25, far_size: float = 0.15) -> dict:
    """Force against indentation at several mesh levels, compared with Hertz.

    Parameters
    ----------
    pole_sizes : edge lengths at the pole, as fractions of R
    deltas : indentations as fractions of R
    radius : R in metres
    refine_radius, far_size : mesh grading, fractions of R

    Returns
    -------
    dict with one entry per level (vertices, rows of δ, F, F/F_Hertz, a/a_Hertz),
    the fitted exponent of F against δ and the δ → 0 extrapolation of F/F_Hertz
    on the finest level.
    """
    levels = []
    d = np.asarray(deltas, dtype=float) * radius
    f_h = hertz_force(d, radius, young, poisson)
    for hs in pole_sizes:
        t0 = time.perf_counter()
        mesh = octant_sphere(radius, hs * radius, far_size * radius, refine_radius * radius)
        problem = OctantIndentation(mesh, radius, young, poisson, float(d.max()))
        rows = [problem.solve(x) for x in d]
        force = np.array([r["force"] for r in rows])
        ratio = force / f_h
        a_ratio = np.array([r["contact_radius"] for r in rows]) / np.sqrt(radius * d)
        exponent = float(np.polyfit(np.log(d), np.log(force), 1)[0])
        fit = np.polyfit(np.sqrt(np.asarray(deltas)), ratio, 1)
        levels.append({
            "pole_size_rel": hs, "n_vertices": mesh.n_points, "n_candidates": len(problem.candidates),
            "rows": [dict(r, hertz_force=float(fh), ratio=float(q), radius_ratio=float(ar))
                     for r, fh, q, ar in zip(rows, f_h, ratio, a_ratio)],
            "exponent": exponent, "extrapolated_ratio": float(fit[1]), "sqrt_slope": float(fit[0]),
            "seconds": time.perf_counter() - t0,
        })
        log.info("Hertz h=%.3gR: %d vertices, F/F_H %s, exponent %.3f, extrapolated %.3f", hs, mesh.n_points,
                 np.array2string(ratio, precision=3), exponent, fit[1])
    return {"radius": radius, "young": young, "poisson": poisson, "deltas_rel": list(map(float, deltas)),
            "model": "frictionless, sphere between two rigid planes (octant with symmetry rollers)",
            "levels": levels}


#: Edge lengths at the pole (fractions of R) and indentations (fractions of R) of the full and the quick study.
CONFIGS: dict[str, dict[str, Any]] = {
    "full": {"pole_sizes": [0.04, 0.02, 0.01, 0.007, 0.005], "deltas": [0.0025, 0.005, 0.01, 0.02]},
    "quick": {"pole_sizes": [0.04, 0.02], "deltas": [0.0025, 0.005, 0.01, 0.02]},
}
#: Stages of :func:`run`.
STAGES = 4


def run(quick: bool, out_dir: Path, stages: Stages) -> tuple[dict[str, Any], dict[str, str]]:
    """The study and its figure, then the rigid fingertip pressed into a block (:mod:`.indenter`); returns its part
    of the summary and its pictures."""
    key = "quick" if quick else "full"
    cfg = CONFIGS[key]
    part: dict[str, Any] = {"config": cfg, "indenter_config": INDENTER_CONFIGS[key]}
    images: dict[str, str] = {}
    stages.run("Hertz", lambda: hertz_study(cfg["pole_sizes"], cfg["deltas"]), lambda v: part.__setitem__("hertz", v))
    if "hertz" in part:
        stages.run("Hertz plot", lambda: images.__setitem__(
            "hertz", hertz_plot(part["hertz"], out_dir / "hertz.png").name))
    stages.run("Indenter: node contact or weighted gap", lambda: indenter_study(**INDENTER_CONFIGS[key]),
               lambda v: part.__setitem__("indenter", v))
    if "indenter" in part:
        stages.run("Indenter plot", lambda: images.__setitem__(
            "indenter", indenter_plot(part["indenter"], out_dir / "indenter.png").name))
    return part, images


def checks(part: dict[str, Any]) -> list[dict[str, Any]]:
    """The sphere between planes against Hertz, then the indenter's (:func:`.report.indenter_checks`)."""
    return _hertz_checks(part) + indenter_checks(part)


def section(s: dict[str, Any], images: dict[str, str]) -> str:
    """The report's sections: the sphere between planes, then the rigid fingertip pressed into a block."""
    return "\n".join(p for p in (_hertz_section(s, images), indenter_section(s.get("indenter"), images.get("indenter")))
                     if p)
