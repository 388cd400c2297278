"""Softness against the rigid grasp (Table III of *Picking up Soft 3D Objects with Two Fingers*).

The paper reports that the deformable objects need about 10 % less total
normal force than rigid bodies of the same shapes (Table III: 2.68 vs 2.96 N,
4.35 vs 4.82, 1.01 vs 1.16, 0.96 vs 1.09) "because … smaller normal force is
needed to generate enough friction for deformable objects due to increased
contact area".  This study runs fem_grasp's pickup on each paper object at
Young's moduli over three decades (3 kPa – 3 MPa; everything else from the
shipped scene) and compares the finger forces at lift-off with the rigid
two-point grasp at the same contacts (``result.rigid``: the least total
normal force of two Coulomb point contacts holding the resting shape), with
three force measures:

* ``normal``: Σ f·n̂ over both contact patches (Table III's measure, as
  fem_grasp reports it); for the rigid grasp f_i·n̂_i + f_j·n̂_j;
* ``grip``: the squeeze force along each finger's squeeze direction,
  Σ_f (Σ_k f_k)·d̂_f;
* ``resultant``: |Σ_k f_k| per finger, summed over the two fingers.

and the diagnostics that explain them:

* ``wrap`` = Σ f·n̂ / Σ_f |(Σ_k f_k)·n̄_f|, n̄_f the patch's force-weighted mean
  normal: > 1 when normal forces on a curved patch partly cancel (a wrapped
  patch pays normal force that no resultant shows);
* ``tilt``: the angle between the patch's mean normal and the rigid contact
  normal at p_i (p_j), degrees — how much of the weight the normals carry;
* ``utilisation`` = Σ|f_t| / (μ Σ f·n̂): the friction mobilised at lift-off (the
  rigid least-force grasp puts at least one contact on its cone);
* ``liftable_excess`` = w at the passing lift test / mg (the lift test passes
  at w ≥ mg in steps of h, and each finger must keep a sticking contact).

fem_grasp's squeeze increment is taken at the scene's own modulus and scaled
by E_scene / E above it (displacements scale with 1/E; fem_grasp's default
increment has a floor of 0.1 % of the maximum squeeze, which at 1–3 MPa would
put the first lift test far beyond the squeeze the weight needs).

``python -m verification softness [--objects …] [--youngs …] [--fine] [--json PATH] [--plot PATH]``
(``--fine``: also a mesh graded to R/4 under the fingertips, about 2,500 vertices; the shipped meshes are
graded to R/2, and the answer depends on that resolution).  A stage of the full report too; its section:
:mod:`.report`.
"""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from .._common.run import Stages
from .report import checks, section

log = logging.getLogger(__name__)

PAPER_OBJECTS = ("tomato", "orange", "steam_bun", "football")
#: Young's moduli of the study, pascals (three decades around the scenes' 10–20 kPa).
YOUNGS = (3e3, 1e4, 3e4, 1e5, 3e5, 1e6, 3e6)
#: Table III as printed: (deformable, rigid) total normal force, newtons.
TABLE_III = {"tomato": (2.68, 2.96), "orange": (4.35, 4.82), "steam_bun": (1.01, 1.16), "football": (0.96, 1.09)}
#: Vertex count of the finer graded mesh (R/4 within 2R of the fingertips).
FINE_VERTICES = 2500


def outward_normals(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """(n, 3) area-weighted outward unit normals at the surface vertices (zero inside), from the boundary faces."""
    p = np.asarray(points, float)
    t = np.asarray(tets, dtype=np.int64)
    faces = np.concatenate([t[:, [0, 1, 2]], t[:, [0, 1, 3]], t[:, [0, 2, 3]], t[:, [1, 2, 3]]])
    opposite = np.concatenate([t[:, 3], t[:, 2], t[:, 1], t[:, 0]])
    key = np.sort(faces, axis=1)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    bnd = counts[inv.reshape(-1)] == 1
    f, o = faces[bnd], opposite[bnd]
    nf = np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]])  # twice the area, either orientation
    flip = np.einsum("ki,ki->k", nf, p[o] - p[f[:, 0]]) > 0  # pointing towards the tet's own fourth vertex
    nf[flip] *= -1
    out = np.zeros_like(p)
    for j in range(3):
        np.add.at(out, f[:, j], nf)
    norm = np.linalg.norm(out, axis=1)
    out[norm > 0] /= norm[norm > 0, None]
    return out


def lift_off_measures(res: Any) -> dict[str, Any]:
    """Force measures at lift-off of a successful fem_grasp result and of its rigid grasp (module notes)."""
    final = res.final
    table = res.table
    nrm = final.normals(table)
    d = [np.asarray(v, float) / np.linalg.norm(v) for v in res.directions]
    mu = res.mu_finger
    out: dict[str, Any] = {"normal": 0.0, "grip": 0.0, "resultant": 0.0, "fingers": []}
    n_rigid = []
    for f, name in enumerate(("finger1", "finger2")):
        fv = np.asarray(final.contact_forces[name], float)
        nv = np.asarray(nrm[name], float)
        fn = np.einsum("ki,ki->k", fv, nv)
        ft = np.linalg.norm(fv - fn[:, None] * nv, axis=1)
        F = fv.sum(axis=0)
        nbar = (fn[:, None] * nv).sum(axis=0)
        nbar = nbar / np.linalg.norm(nbar) if np.linalg.norm(nbar) > 0 else nbar
        out["normal"] += float(fn.sum())
        out["grip"] += float(F @ d[f])
        out["resultant"] += float(np.linalg.norm(F))
        out["fingers"].append({"contacts": int(len(fv)), "sliding": int(np.sum(final.sliding[name])),
                               "normal": float(fn.sum()), "resultant": float(np.linalg.norm(F)),
                               "grip": float(F @ d[f]), "mean_normal": nbar.tolist(),
                               "normal_of_resultant": float(abs(F @ nbar)),
                               "utilisation": float(ft.sum() / (mu * fn.sum())) if fn.sum() > 0 else math.nan})
        n_rigid.append(nbar)
    out["wrap"] = out["normal"] / max(sum(x["normal_of_resultant"] for x in out["fingers"]), 1e-300)
    out["utilisation"] = float(np.mean([x["utilisation"] for x in out["fingers"]]))
    rg = res.rigid
    rigid: dict[str, Any] = {"feasible": bool(rg is not None and rg.feasible)}
    if rigid["feasible"]:
        normals = -outward_normals(res.rest.positions, res.body.mesh.tets)[list(res.finger_nodes)]
        fr = np.asarray(rg.forces, float)
        rigid.update(normal=float(rg.total_normal_force), grip=float(fr[0] @ d[0] + fr[1] @ d[1]),
                     resultant=float(np.linalg.norm(fr[0]) + np.linalg.norm(fr[1])),
                     utilisation=float(np.mean([np.linalg.norm(fr[k] - (fr[k] @ normals[k]) * normals[k])
                                                / (mu * (fr[k] @ normals[k])) for k in range(2)])))
        out["tilt"] = [float(np.degrees(np.arccos(np.clip(n_rigid[k] @ normals[k], -1, 1)))) for k in range(2)]
    out["rigid"] = rigid
    return out


def fine_mesh(name: str, vertices: int = FINE_VERTICES, radius: float = 0.01):
    """The paper object at about ``vertices``, graded to R/4 within 2R of the fingertips (gmsh)."""
    from fem_grasp import objects, shapes

    uniform = shapes.paper_mesh(name, vertices)
    centres = objects.finger_contact_points(uniform, name, radius)
    refine = shapes.Refinement(tuple(tuple(float(x) for x in c) for c in centres), 2.0 * radius, 0.25 * radius, radius)
    return shapes.paper_mesh(name, vertices, refine=refine)


def run_one(name: str, young: float, mesh: Any | None = None, step: float | None = None) -> dict[str, Any]:
    """fem_grasp's pickup of a paper scene at modulus ``young`` (optionally on another mesh, with another squeeze
    increment) and its measures."""
    from fem_grasp import Body, pickup
    from fem_grasp.io.scene import load_scene, resolve_scene

    sc = load_scene(resolve_scene(name))
    m = sc.load_mesh() if mesh is None else mesh
    kw = {"weight": sc.weight} if sc.weight is not None else {"density": sc.density}
    body = Body(m, young, sc.poisson, gravity=sc.gravity, **kw)
    t0 = time.perf_counter()
    pk = sc.pickup_kwargs()
    if step is not None:
        pk["step"] = step
    res = pickup(body, **pk)
    row: dict[str, Any] = {"object": name, "young": young, "vertices": int(m.n_points), "success": bool(res.success),
                           "reason": res.reason, "squeeze_depth": float(res.squeeze_depth), "step": float(res.step),
                           "radius": float(res.finger_radius),
                           "seconds": time.perf_counter() - t0, "weight": float(res.body.weight),
                           "lift_test_step": float(sc.lift_test_step or 0.05 * res.body.weight)}
    passed = [w for r, w in res.liftable if r == res.squeeze_depth]
    row["liftable_excess"] = float(passed[-1] / res.body.weight) if passed else math.nan
    if res.success:
        row.update(lift_off_measures(res))
        rg = row["rigid"]
        if rg["feasible"]:
            row["ratio"] = {k: row[k] / rg[k] for k in ("normal", "grip", "resultant")}
    return row


def study(objects: tuple[str, ...] = PAPER_OBJECTS, youngs: tuple[float, ...] = YOUNGS, fine: bool = False,
          fine_youngs: tuple[float, ...] | None = None, shipped: bool = True) -> dict[str, Any]:
    """The whole study: rows for every object and modulus on the shipped meshes (unless not ``shipped``) and on
    the finer graded mesh (when ``fine``)."""
    from fem_grasp.io.scene import load_scene, resolve_scene

    rows = []
    for name in objects:
        # The squeeze increment at the scene's own modulus, scaled by E_scene / E above it: displacements scale
        # with 1/E, and fem_grasp's default increment is held above 0.1 % of the maximum squeeze, which at
        # 1–3 MPa is many times the squeeze the weight needs (the first lift test would come far too late).
        e0 = load_scene(resolve_scene(name)).young
        step0 = run_one(name, e0)["step"]
        for mesh_label, mesh in ([("shipped", None)] if shipped else []) + ([("graded R/4", "fine")] if fine else []):
            if mesh == "fine":
                try:
                    mesh = fine_mesh(name)
                except Exception as exc:  # noqa: BLE001 - gmsh missing or the count not reached
                    log.warning("no finer mesh for %s: %s", name, exc)
                    continue
            for e in (youngs if mesh is None else (fine_youngs or youngs)):
                rows.append(dict(run_one(name, e, mesh, step=step0 * min(1.0, e0 / e)), mesh=mesh_label))
                log.info("%s %s E = %.3g: %s", name, mesh_label, e, rows[-1].get("ratio"))
    return {"rows": rows, "youngs": list(youngs), "table_iii": TABLE_III, "objects": list(objects)}


def conclusions(s: dict[str, Any]) -> dict[str, Any]:
    """Per measure and mesh: how many (object, E) runs have the deformable force below the rigid one, and the
    range of the ratios; the paper's ratios for reference."""
    out: dict[str, Any] = {"paper_ratio": {k: v[0] / v[1] for k, v in TABLE_III.items()}}
    for mesh in sorted({r["mesh"] for r in s["rows"]}):
        rows = [r for r in s["rows"] if r["mesh"] == mesh and "ratio" in r]
        for k in ("normal", "grip", "resultant"):
            vals = [r["ratio"][k] for r in rows]
            out[f"{mesh}/{k}"] = {"below_rigid": sum(v < 1 for v in vals), "runs": len(vals),
                                  "min": min(vals, default=math.nan), "max": max(vals, default=math.nan),
                                  "paper_like": sum(0.8 <= v <= 0.95 for v in vals)}
    return out


def plot(s: dict[str, Any], path: str | Path) -> Path:
    """Deformable / rigid force against E for each object and measure (matplotlib)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    objs = s["objects"]
    fig, axes = plt.subplots(1, len(objs), figsize=(3.6 * len(objs), 3.4), sharey=True)
    axes = np.atleast_1d(axes)
    styles = {"normal": ("C0", "Σ f·n̂"), "grip": ("C1", "grip along d̂"), "resultant": ("C2", "|Σ f| per finger")}
    for ax, name in zip(axes, objs):
        for mesh, ls in (("shipped", "-"), ("graded R/4", "--")):
            rows = sorted((r for r in s["rows"] if r["object"] == name and r["mesh"] == mesh and "ratio" in r),
                          key=lambda r: r["young"])
            for k, (c, label) in styles.items():
                if rows:
                    ax.plot([r["young"] for r in rows], [r["ratio"][k] for r in rows], ls, color=c, marker="o",
                            ms=3, label=f"{label} ({mesh})")
        paper = TABLE_III[name][0] / TABLE_III[name][1]
        ax.axhline(paper, color="k", lw=0.8, ls=":", label=f"paper {paper:.2f}")
        ax.axhline(1.0, color="grey", lw=0.6)
        ax.set_xscale("log")
        ax.set_title(name)
        ax.set_xlabel("E (Pa)")
    axes[0].set_ylabel("deformable / rigid, at lift-off")
    axes[-1].legend(fontsize=6, loc="best")
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=130)
    plt.close(fig)
    return out


#: The moduli and meshes of the full report's study and of its quick run.
CONFIGS: dict[str, dict[str, Any]] = {
    "full": {"objects": PAPER_OBJECTS, "youngs": YOUNGS, "fine": True, "fine_youngs": (1e4, 1e5, 1e6)},
    "quick": {"objects": ("football",), "youngs": (1e4, 1e6), "fine": False},
}
#: Stages of :func:`run`.
STAGES = 1


def run(quick: bool, out_dir: Path, stages: Stages) -> tuple[dict[str, Any], dict[str, str]]:
    """The study as a stage of the report, with its figure; returns its part of the summary and its picture."""
    cfg = CONFIGS["quick" if quick else "full"]
    part: dict[str, Any] = {"config": cfg}
    images: dict[str, str] = {}

    def one() -> None:
        soft = study(tuple(cfg["objects"]), tuple(cfg["youngs"]), cfg.get("fine", False), cfg.get("fine_youngs"))
        soft["conclusions"] = conclusions(soft)
        part["softness"] = soft
        images["softness"] = plot(soft, out_dir / "softness.png").name

    stages.run("softness against the rigid grasp", one)
    return part, images


__all__ = ["CONFIGS", "PAPER_OBJECTS", "STAGES", "TABLE_III", "YOUNGS", "checks", "conclusions", "lift_off_measures",
           "plot", "run", "run_one", "section", "study"]
