"""Convergence of the pickup answer: ``python -m verification.converge [--quick]`` (``make converge``).

For the four paper scenes (tomato, orange, steam bun, football) and the foam
block, each with its shipped scene's settings, the answer of Algorithm 1 of
*Picking up Soft 3D Objects with Two Fingers* — the verdict, the squeeze depth
ρ* at which the lift starts, the finger forces at lift-off (per finger: the
resultant's norm, its component along the finger's squeeze direction and its
vertical component; Σ f·n̂ over both patches), the contact-patch node counts
and the liftable weight w(ρ) — is computed under

``uniform``
    uniform refinement from the paper's resolution (Table I's vertex count;
    the foam block's 6 × 8 × 6 grid) upwards, ×2 in vertices per level
    (``fem_grasp.mesh.shapes.paper_mesh(name, N)``; the box: its grid divisions × k);
``graded``
    grading at the fingertips: spacing R/2, R/4, R/8 (and R/16 for the orange and the box) within 1.25 R of
    the two finger contact points (placed by the scene's rule on the
    paper-resolution mesh), growing at :data:`fem_grasp.mesh.remesh.DEFAULT_GRADING`
    to the paper-resolution spacing (:class:`fem_grasp.mesh.shapes.Refinement`);
``graded_table``
    the same, and the same spacing around the resting contact patch on the table;
``step`` / ``h``
    the squeeze increment, then the lift-test step h, halved repeatedly on one
    mesh (the uniform level at 4× the paper's vertex count; the box's ×2 grid);
``seed``
    five meshes of the same spacing (gmsh's ``Mesh.RandomSeed``; the box's
    grid jittered) at the paper's resolution (and at 4× for the orange; the box's ×2 grid),
    for the scatter at a fixed h;
``reference``
    the finest uniform level that ran, with the squeeze increment and h halved
    twice: the reference every other run's error is measured against;
``adaptive``
    :func:`fem_grasp.grasp.accuracy.converged_pickup` at 2 % (the answers at 10 % and 5 % are that run stopped
    earlier: the loop is deterministic);
``quick``
    the scene's ``[quick]`` variant, one run (its error is what the scene states as ``expected_error``).

Each run is a subprocess (its own memory, a time cap, peak memory measured)
whose record is cached as JSON under ``verification/out/converge/cache`` (a
cache hit needs the same case; records say the code digest they were made
with, and ``--stale`` recomputes those from other code).  A series stops at
its first level that exceeds the time cap.  The analysis (``converge.json``)
gives per object the tables, the converged estimates (Richardson where three
levels are monotone with an observed order, else the finest level with a
band), each run's error against the reference, the cheapest resolution for
10 %, 5 % and 2 %, the seed scatter, and a diagnosis of every verdict flip and
every non-monotone jump (a slow independent lift test: weights raised in
steps of h/8 from zero at every squeeze increment, to show whether a state
the lift test missed exists).  Plots: error against run time (log–log) for ρ*
and the finger force, and w(ρ) of the uniform levels overlaid.

The full study takes hours on two cores (``--quick``: minutes).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import logging
import math
import os
import resource
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

log = logging.getLogger("verification.converge")

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = ROOT / "verification" / "out" / "converge"
OBJECTS = ("tomato", "orange", "steam_bun", "football", "foam_block")
#: Version of the case records (bump when a record's fields change meaning).
RECORD_FORMAT = 1
#: Spacing relative to R of the graded series.
GRADED_INNER = (1 / 2, 1 / 4, 1 / 8, 1 / 16)
#: Radius of the refined ball about each finger contact point, × R: the contact patches at lift-off reach
#: 0.8–0.95 R from the first contact point on the 4.6k-vertex orange.
GRADED_RADIUS = 1.25

CONFIGS: dict[str, dict[str, Any]] = {
    "full": {
        "uniform_factors": [1, 2, 4, 8, 16, 32, 64], "uniform_extra": {"orange": [52000]},
        "uniform_max_vertices": 60000,
        "box_factors": [1, 2, 3, 4, 5, 6],
        "graded_inner": list(GRADED_INNER[:3]), "graded_table_inner": [1 / 2, 1 / 4],
        "step_divisors": [1, 2, 4, 8], "h_divisors": [1, 2, 4], "steps_factor": 4, "box_steps_factor": 2,
        "seeds": 5, "seed_factors": [1], "seed_factors_extra": {"orange": [4]}, "box_seed_factors": [1, 2],
        "graded_inner_extra": {"orange": [1 / 16], "foam_block": [1 / 16]},
        "reference_divisors": [1, 2, 4], "reference_max_seconds": 900,
        "adaptive_target": 0.02, "adaptive_max_levels": 2, "adaptive_timeout": 5400, "early_levels": 4,
        "case_timeout": 2400, "memory_gib": 9.0, "diagnose_max_seconds": 150,
    },
    "quick": {
        "uniform_factors": [1, 2, 4], "uniform_extra": {}, "uniform_max_vertices": 5000,
        "box_factors": [1, 2],
        "graded_inner": [1 / 2, 1 / 4], "graded_table_inner": [1 / 2],
        "step_divisors": [1, 2], "h_divisors": [1, 2], "steps_factor": 2, "box_steps_factor": 1,
        "seeds": 3, "seed_factors": [1], "box_seed_factors": [1],
        "reference_divisors": [1, 2], "reference_max_seconds": 120,
        "adaptive_target": 0.10, "adaptive_max_levels": 1, "adaptive_timeout": 600, "early_levels": 2,
        "case_timeout": 300, "memory_gib": 6.0, "diagnose_max_seconds": 30,
    },
}


# ================================================================ scenes & meshes
def scene_of(name: str, quick: bool = False):
    from fem_grasp.io.scene import load_scene, resolve_scene

    return load_scene(resolve_scene(name), quick=quick)


def base_mesh(scene):
    """The scene's own mesh (the committed paper mesh, the box grid)."""
    return scene.load_mesh()


def paper_vertices(scene) -> int:
    """Table I's vertex count, or the box grid's."""
    from fem_grasp.mesh.shapes import PAPER_SHAPES

    if scene.object.kind == "paper":
        return PAPER_SHAPES[scene.object.paper].vertices
    nx, ny, nz = scene.object.divisions
    return (nx + 1) * (ny + 1) * (nz + 1)


def geometry_of(scene):
    from fem_grasp.mesh import remesh

    if scene.object.kind == "paper":
        return remesh.PaperGeometry(scene.object.paper)
    if scene.object.kind == "box":
        lx, ly, lz = scene.object.box
        return remesh.BoxGeometry((-lx / 2, -ly / 2, 0.0), (lx / 2, ly / 2, lz))
    raise ValueError(f"no geometry for scene {scene.name}")


def paper_size(name: str, vertices: int) -> float:
    """The uniform gmsh size at which ``shapes.paper_mesh(name, vertices)`` lands."""

    from fem_grasp.mesh import shapes

    spec = shapes.PAPER_SHAPES[name]
    algorithm = "meshadapt" if vertices <= shapes.AUTO_MESHADAPT_MAX_VERTICES else "frontal-delaunay"
    sizes: dict[int, float] = {}

    def builder(h: float):
        out = spec.build(h, algorithm)
        sizes[id(out[0])] = h
        return out

    h0 = (spec.volume / vertices) ** (1.0 / 3.0)
    points, _ = shapes.mesh_with_vertex_count(builder, vertices, 0.05, initial_size=float(f"{h0:.6g}"))
    return sizes[id(points)]


def jittered(mesh, seed: int, amount: float = 0.15):
    """A box grid with every node moved by up to ``amount`` × the grid spacing, staying on its faces.

    Interior nodes move in 3D, face nodes within their face, edge and corner
    nodes stay (so the box keeps its shape and its face-centre nodes their
    position only if they stay: the contacts are re-found by position).
    """
    from fem_grasp.mesh.tetmesh import TetMesh

    p = mesh.points.copy()
    lo, hi = p.min(axis=0), p.max(axis=0)
    h = np.array([np.diff(np.unique(p[:, i])).min() for i in range(3)])
    tol = 1e-9 * float(np.linalg.norm(hi - lo))
    on = (np.abs(p - lo) <= tol) | (np.abs(p - hi) <= tol)  # (n, 3) on a face normal to axis i
    rng = np.random.default_rng(seed)
    move = rng.uniform(-amount, amount, p.shape) * h
    move[on] = 0.0  # a face node keeps its coordinate across the face
    move[on.sum(axis=1) >= 2] = 0.0  # edges and corners stay
    return TetMesh(p + move, mesh.tets)


def finger_points(scene, mesh) -> np.ndarray:
    """(2, 3) the finger contact points the scene would use on ``mesh`` (mesh frame)."""
    from fem_grasp.grasp import objects

    if scene.contacts is not None:
        return base_mesh(scene).points[list(scene.contacts)]
    return objects.finger_contact_points(mesh, scene.object.paper, scene.finger_radius, young=scene.young,
                                         rule=scene.placement_rule, max_squeeze=scene.max_squeeze)


def table_points(scene, mesh) -> np.ndarray:
    """Reference positions of the resting table contacts on ``mesh``."""
    from fem_grasp.elastic.body import Body
    from fem_grasp.grasp.rest import rest

    body = Body(mesh, scene.young, scene.poisson, **({"weight": scene.weight} if scene.weight else
                                                      {"density": scene.density}))
    rs = rest(body, scene.mu_table)
    return mesh.points[rs.contact_nodes]


def build_mesh(spec: dict[str, Any], scene) -> tuple[Any, dict[str, Any]]:
    """The mesh of one case (module notes)."""
    from fem_grasp.mesh import gmsh_session, remesh, shapes
    from fem_grasp.mesh.tetmesh import TetMesh

    series = spec["series"]
    box = scene.object.kind == "box"
    geo = geometry_of(scene)
    info: dict[str, Any] = {}
    if series == "quick":
        mesh = scene.load_mesh()
    elif series in ("uniform", "step", "h", "reference"):
        if box:
            k = spec["factor"]
            mesh = geo.grid([d * k for d in scene.object.divisions])
        else:
            mesh = shapes.paper_mesh(scene.object.paper, spec["target"])
    elif series == "seed":
        if box:
            k = spec["factor"]
            mesh = jittered(geo.grid([d * k for d in scene.object.divisions]), spec["seed"])
        else:
            size = paper_size(scene.object.paper, spec["target"])
            saved = gmsh_session.GMSH_OPTIONS["Mesh.RandomSeed"]
            gmsh_session.GMSH_OPTIONS["Mesh.RandomSeed"] = int(spec["seed"])
            try:
                alg = "meshadapt" if spec["target"] <= shapes.AUTO_MESHADAPT_MAX_VERTICES else "frontal-delaunay"
                mesh = TetMesh(*shapes.PAPER_SHAPES[scene.object.paper].build(size, alg))
            finally:
                gmsh_session.GMSH_OPTIONS["Mesh.RandomSeed"] = saved
            info["size"] = size
    elif series in ("graded", "graded_table"):
        r = scene.finger_radius
        n0 = paper_vertices(scene)
        if box:
            coarse = geo.grid(scene.object.divisions)
            outer = float(np.min(np.subtract(geo.upper, geo.lower) / np.asarray(scene.object.divisions)))
        else:
            coarse = shapes.paper_mesh(scene.object.paper, n0)
            outer = paper_size(scene.object.paper, n0)
        inner = spec["inner"] * r
        centres = finger_points(scene, coarse)
        refs = [shapes.Refinement(tuple(map(tuple, centres)), GRADED_RADIUS * r, inner,
                                  max(outer - inner, 0.0) / remesh.DEFAULT_GRADING + 1e-12)]
        if series == "graded_table":
            refs.append(remesh.patch_refinement(table_points(scene, coarse), inner, max(outer, 2 * inner), outer))
        mesh = geo.build(outer, refs, embed=centres if box else None)
        info.update(outer=outer, inner=inner, centres=centres.tolist())
    else:
        raise ValueError(f"unknown series {series!r}")
    return mesh, info


def pickup_kwargs(spec: dict[str, Any], scene, mesh) -> dict[str, Any]:
    from fem_grasp.mesh import remesh

    kw = scene.pickup_kwargs()
    if scene.contacts is not None:
        pts = base_mesh(scene).points[list(scene.contacts)]
        kw["contacts"] = tuple(int(k) for k in remesh.nearest_surface_nodes(mesh, pts))
    if spec.get("step") is not None:
        kw["step"] = float(spec["step"])
    if spec.get("h") is not None:
        kw["lift_test_step"] = float(spec["h"])
    return kw


def body_of(scene, mesh):
    from fem_grasp.elastic.body import Body

    return Body(mesh, scene.young, scene.poisson, gravity=scene.gravity,
                **({"weight": scene.weight} if scene.weight is not None else {"density": scene.density}))


# ================================================================ one case
#: Sources that do not change a pickup's answer: files, the CLI, the search, the accuracy loop (its records carry
#: their levels).  Paths relative to the package.
_DIGEST_SKIP = {"grasp/accuracy.py", "cli.py", "paper.py", "progress.py", "__main__.py"}
_DIGEST_SKIP_DIRS = ("io/", "batch/")


def code_digest() -> str:
    """Digest of the fem_grasp sources a pickup runs (records made with other code are flagged, ``--stale``
    reruns them)."""
    h = hashlib.sha256()
    pkg = ROOT / "fem_grasp"
    for f in sorted(pkg.rglob("*.py")):
        rel = f.relative_to(pkg).as_posix()
        if rel not in _DIGEST_SKIP and not rel.startswith(_DIGEST_SKIP_DIRS) and not rel.endswith("__init__.py"):
            h.update(rel.encode() + b"\0" + f.read_bytes())
    return h.hexdigest()[:12]


def case_key(spec: dict[str, Any]) -> str:
    return hashlib.sha256(json.dumps([RECORD_FORMAT, spec], sort_keys=True).encode()).hexdigest()[:16]


def _bracket(liftable: list) -> list[float] | None:
    """(ρ of the last lift test that did not pass, ρ* ) — ρ* is known to within this interval."""
    if len(liftable) < 2:
        return None
    return [float(liftable[-2][0]), float(liftable[-1][0])]


def run_case(spec: dict[str, Any], record_path: Path | None = None) -> dict[str, Any]:
    """Build the mesh and run the pickup of one case; its record (module notes)."""
    from fem_grasp.grasp import accuracy
    from fem_grasp.grasp.pickup import pickup
    from fem_grasp.mesh import remesh

    scene = scene_of(spec["object"], quick=spec["series"] == "quick")
    rec: dict[str, Any] = {"spec": spec, "format": RECORD_FORMAT, "code": code_digest()}
    if spec["series"] == "adaptive":
        t0 = time.perf_counter()
        body = scene.body()

        def partial(report) -> None:  # a record after every level: a timed-out loop keeps its levels
            if record_path is not None:
                from fem_grasp.io.output import json_safe

                part = dict(rec, partial=True, accuracy=report.to_dict(), seconds=time.perf_counter() - t0)
                record_path.with_suffix(".partial").write_text(json.dumps(json_safe(part), indent=1))

        res = accuracy.converged_pickup(body, solve=pickup, accuracy=spec["target"], geometry=geometry_of(scene),
                                        max_levels=spec.get("max_levels", accuracy.MAX_LEVELS), on_level=partial,
                                        **scene.pickup_kwargs())
        rec["seconds"] = time.perf_counter() - t0
        rec["answer"] = accuracy.answer_of(res, rec["seconds"]).to_dict()
        rec["accuracy"] = res.accuracy
        rec["vertices"] = res.body.n_nodes
        rec["peak_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
        return rec
    t0 = time.perf_counter()
    mesh, info = build_mesh(spec, scene)
    rec["mesh_seconds"] = time.perf_counter() - t0
    rec.update(info)
    kw = pickup_kwargs(spec, scene, mesh)
    t0 = time.perf_counter()
    body = body_of(scene, mesh)
    if spec.get("diagnose"):
        rec["diagnosis"] = diagnose(body, kw, scene)
    res = pickup(body, **kw)
    rec["pickup_seconds"] = time.perf_counter() - t0
    rec["seconds"] = rec["mesh_seconds"] + rec["pickup_seconds"]
    ans = accuracy.answer_of(res, rec["pickup_seconds"])
    rec["answer"] = ans.to_dict()
    rec["vertices"] = mesh.n_points
    rec["tets"] = mesh.n_tets
    rec["spacing"] = remesh.spacing(mesh)
    fin = res.final
    fn = np.concatenate([fin.contact_nodes["finger1"], fin.contact_nodes["finger2"]]) if fin is not None else []
    rec["patch_spacing"] = remesh.spacing(mesh, fn if len(fn) else list(res.finger_nodes))
    rec["bracket"] = _bracket(res.liftable) if res.success else None
    rec["finger_nodes"] = [int(k) for k in res.finger_nodes]
    rec["finger_points"] = mesh.points[[k for k in res.finger_nodes if k >= 0]].tolist()
    rec["lift_attempts"] = [a.to_dict() for a in res.lift_attempts]
    rec["events"] = len(res.events)
    rec["timings"] = dict(res.timings)
    rec["peak_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return rec


# ================================================================ diagnosis
def diagnose(body, kw: dict[str, Any], scene, fraction: float = 0.125) -> dict[str, Any]:
    """Re-run the pickup with a slow, independent lift test beside the library's.

    At every squeeze increment the lift test's hanging configuration is loaded
    from zero in steps of ``fraction`` × h (each settled from the previous one
    by the same return mapping, with its halvings), up to 1.6 mg: the largest
    weight held is the slow w(ρ).  Where the slow w reaches mg at a depth the
    lift test did not pass, a state the test missed exists (a numerical
    failure of the test); where it does not, the discretisation holds less
    (a physical outcome of that mesh).  Also records the finger patch (node
    count, heights) and the reason the slow loading stops at its peak.
    """
    import sys as _sys

    from fem_grasp.grasp import lift_test as lt_mod
    from fem_grasp.grasp.pickup import pickup

    pk = _sys.modules["fem_grasp.grasp.pickup"]
    rows: list[dict[str, Any]] = []
    orig_cls = lt_mod.LiftTest

    class Slow(orig_cls):  # type: ignore[misc, valid-type]
        def update(self, state):  # noqa: D401 - same contract
            w = super().update(state)
            base = lt_mod.hanging_state(self.tracker, state)
            ws, reason, st = 0.0, base.reason, None
            if base.held:
                st, dw, k = base.state, fraction * self.step, 1
                while k * dw <= 1.6 * self.weight:
                    r = lt_mod.hang(self.tracker, st, k * dw)
                    if not r.held:
                        reason = r.reason
                        break
                    st, ws, k = r.state, k * dw, k + 1
            fingers = state.owner != 2
            rows.append({"rho": state.squeeze_depth, "test_w": w, "slow_w": ws, "reason": reason,
                         "finger_contacts": [int((state.owner == f).sum()) for f in (0, 1)],
                         "finger_nodes": state.nodes[fingers].tolist(), "held": _held_patch(self.tracker, st, reason)})
            return w

    kw = dict(kw, lift=False)
    pk.LiftTest = Slow
    try:
        t0 = time.perf_counter()
        res = pickup(body, **kw)
    finally:
        pk.LiftTest = orig_cls
    weight = body.weight
    test_pass = next((r["rho"] for r in rows if r["test_w"] >= weight * (1 - 1e-9)), None)
    slow_pass = next((r["rho"] for r in rows if r["slow_w"] >= weight * (1 - 1e-9)), None)
    peak = max(rows, key=lambda r: r["slow_w"]) if rows else None
    return {"rows": rows, "weight": weight, "test_pass": test_pass, "slow_pass": slow_pass,
            "slow_peak": None if peak is None else peak["slow_w"], "slow_peak_rho": None if peak is None else peak["rho"],
            "peak_reason": None if peak is None else peak["reason"], "peak_patch": None if peak is None else peak["held"],
            "reason": res.reason, "seconds": time.perf_counter() - t0}


def _held_patch(tracker, st, reason: str) -> dict[str, Any] | None:
    """At the largest weight held: per finger its contacts, how many sit above the fingertip's centre (whose
    normal forces push the object up), how many slide, and the vertical force it carries; and the node and
    finger the failing settle names (its "contact k" indexes the held state's contact set)."""
    import re

    if st is None:
        return None
    out: dict[str, Any] = {"fingers": []}
    pos = st.surface_positions[tracker.surface_index[st.nodes]]
    for f in (0, 1):
        on = st.owner == f
        up = (pos[on, 2] - st.centers[f][2]) > 0
        out["fingers"].append({"contacts": int(on.sum()), "above_centre": int(up.sum()),
                               "sliding": int(st.sliding[on].sum()), "vertical": float(st.forces[on, 2].sum())})
    m = re.search(r"contact (\d+)", reason or "")
    if m and int(m.group(1)) < st.n_contacts:
        k = int(m.group(1))
        out["failing_node"] = int(st.nodes[k])
        out["failing_finger"] = int(st.owner[k]) + 1
        out["failing_above_centre"] = bool(pos[k, 2] > st.centers[st.owner[k]][2])
    return out


# ================================================================ the cases
def cases(cfg: dict[str, Any], objects: tuple[str, ...], records: dict[str, dict]) -> list[list[dict[str, Any]]]:
    """Series of cases (each a list, coarse to fine); a later list may depend on earlier records."""
    out: list[list[dict[str, Any]]] = []
    for name in objects:
        scene = scene_of(name)
        box = scene.object.kind == "box"
        n0 = paper_vertices(scene)
        if box:
            uni = [{"object": name, "series": "uniform", "factor": k} for k in cfg["box_factors"]]
        else:
            targets = [n0 * f for f in cfg["uniform_factors"]] + list(cfg["uniform_extra"].get(name, []))
            uni = [{"object": name, "series": "uniform", "target": int(t)} for t in sorted(set(targets))
                   if t <= cfg["uniform_max_vertices"]]
        out.append(uni)
        out.append([{"object": name, "series": "quick"}])
        inner = list(cfg["graded_inner"]) + list(cfg.get("graded_inner_extra", {}).get(name, []))
        out.append([{"object": name, "series": "graded", "inner": i} for i in inner])
        out.append([{"object": name, "series": "graded_table", "inner": i} for i in cfg["graded_table_inner"]])
        factors = cfg["box_seed_factors"] if box else list(cfg["seed_factors"]) + list(
            cfg.get("seed_factors_extra", {}).get(name, []))
        for f in factors:
            key = {"factor": f} if box else {"target": n0 * f}
            # seed 1 is gmsh's default: the uniform level itself (the analysis counts it among the seeds)
            out.append([dict({"object": name, "series": "seed", "seed": s}, **key) for s in range(2, cfg["seeds"] + 1)])
    return out


def dependent_cases(cfg: dict[str, Any], objects: tuple[str, ...], records: dict[str, dict]) -> list[list[dict]]:
    """The step, h and reference series: they need the base step of a uniform record."""
    out = []
    for name in objects:
        scene = scene_of(name)
        box = scene.object.kind == "box"
        n0 = paper_vertices(scene)
        f = cfg["box_steps_factor"] if box else cfg["steps_factor"]
        base = {"object": name, "series": "uniform", **({"factor": f} if box else {"target": n0 * f})}
        rec = records.get(case_key(base))
        if rec and "answer" in rec:
            s0, h0 = rec["answer"]["step"], rec["answer"]["weight"] / 20.0
            key = {k: v for k, v in base.items() if k not in ("series",)}
            out.append([dict(key, series="step", divisor=d, step=s0 / d) for d in cfg["step_divisors"] if d > 1])
            out.append([dict(key, series="h", divisor=d, h=h0 / d) for d in cfg["h_divisors"] if d > 1])
        # reference: the finest uniform level that ran within reference_max_seconds
        uni = [r for r in records.values() if r["spec"]["object"] == name and r["spec"]["series"] == "uniform"
               and "answer" in r and r.get("pickup_seconds", 1e9) <= cfg["reference_max_seconds"]]
        if uni:
            fine = max(uni, key=lambda r: r["vertices"])
            sp = fine["spec"]
            s0, h0 = fine["answer"]["step"], fine["answer"]["weight"] / 20.0
            key = {k: v for k, v in sp.items() if k != "series"}
            out.append([dict(key, series="reference", divisor=d, step=s0 / d, h=h0 / d)
                        for d in cfg["reference_divisors"] if d > 1])
    return out


def adaptive_cases(cfg: dict[str, Any], objects: tuple[str, ...]) -> list[list[dict]]:
    """One run of the loop per object at the finest target: the loop is deterministic, so the answer at a looser
    target is this run stopped at the first level that meets it (:func:`adaptive_at`)."""
    return [[{"object": name, "series": "adaptive", "target": cfg["adaptive_target"],
              "max_levels": cfg["adaptive_max_levels"]}] for name in objects]


def adaptive_at(acc: dict[str, Any], target: float) -> dict[str, Any] | None:
    """What ``pickup(..., accuracy=target)`` returns, read off a run of the loop at a finer target: the first level
    ≥ 1 whose change from the one before is within ``target`` with the same verdict; its cumulative time."""
    levels = acc.get("levels", [])
    seconds = 0.0
    for i, lv in enumerate(levels):
        seconds += (lv.get("seconds") or 0.0) + (lv.get("mesh_seconds") or 0.0)
        ch = lv.get("change")
        if i and ch and levels[i - 1]["success"] == lv["success"] and max(ch.values()) <= target:
            return {"level": lv, "seconds": seconds, "estimated_error": {k: ch[k] for k in ("squeeze_depth",
                                                                                          "finger_force")}}
    return None


# ================================================================ driver
def load_records(cache: Path) -> dict[str, dict]:
    out = {}
    for f in sorted(cache.glob("*.json")):
        try:
            rec = json.loads(f.read_text())
        except (OSError, ValueError):
            continue
        out[f.stem] = rec
    return out


def _worker_env() -> dict[str, str]:
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", PYTHONPATH=str(ROOT))
    return env


def run_series(series: list[dict[str, Any]], cache: Path, records: dict[str, dict], cfg: dict[str, Any],
               stale: bool) -> None:
    """Run the cases of one series in order (coarse to fine), stopping after the first that times out."""
    run_rounds([series], cache, records, cfg, stale)


def run_rounds(all_series: list[list[dict[str, Any]]], cache: Path, records: dict[str, dict], cfg: dict[str, Any],
               stale: bool, levels: int | None = None) -> None:
    """Run many series level by level: the first case of every series, then the second, … (up to ``levels``
    levels); a series stops after its first case that times out (its finer levels would too)."""
    stopped: set[int] = set()
    for i, series in enumerate(all_series):  # a series that timed out before stays stopped
        if any(records.get(case_key(sp), {}).get("timeout") for sp in series):
            stopped.add(i)
    top = max((len(s) for s in all_series), default=0)
    for level in range(top if levels is None else min(levels, top)):
        for i, series in enumerate(all_series):
            if i in stopped or level >= len(series):
                continue
            if not _run_one(series[level], cache, records, cfg, stale):
                stopped.add(i)


def _run_one(spec: dict[str, Any], cache: Path, records: dict[str, dict], cfg: dict[str, Any], stale: bool) -> bool:
    """Run one case unless cached; False when it timed out."""
    digest = code_digest()
    if True:
        key = case_key(spec)
        rec = records.get(key)
        if rec is not None and not (stale and rec.get("code") != digest):
            return not rec.get("timeout")
        path = cache / f"{key}.json"
        timeout = cfg["adaptive_timeout"] if spec["series"] == "adaptive" else cfg["case_timeout"]
        t0 = time.perf_counter()
        print(f"  {spec}", flush=True)
        cmd = [sys.executable, "-m", "verification.converge", "--worker", json.dumps(spec), "--record", str(path),
               "--memory-gib", str(cfg["memory_gib"])]
        try:
            proc = subprocess.run(cmd, cwd=ROOT, env=_worker_env(), timeout=timeout, capture_output=True, text=True)
            if proc.returncode != 0 or not path.exists():
                rec = {"spec": spec, "format": RECORD_FORMAT, "code": digest, "error": proc.stderr[-2000:],
                       "seconds": time.perf_counter() - t0}
                path.write_text(json.dumps(rec, indent=1))
        except subprocess.TimeoutExpired:
            rec = {"spec": spec, "format": RECORD_FORMAT, "code": digest, "timeout": True, "seconds": timeout}
            part = path.with_suffix(".partial")
            if part.exists():  # the adaptive loop's levels so far
                rec.update({k: v for k, v in json.loads(part.read_text()).items() if k in ("accuracy",)})
            path.write_text(json.dumps(rec, indent=1))
        rec = json.loads(path.read_text())
        records[key] = rec
        if "answer" in rec:
            a = rec["answer"]
            print(f"    {rec.get('vertices')} vertices: {'picked up' if a['success'] else 'NOT picked up'} "
                  f"rho {1e3 * a['squeeze_depth']:.3f} mm, finger force {a['finger_force']:.3f} N, "
                  f"{rec['seconds']:.1f} s", flush=True)
        else:
            print(f"    {'timeout' if rec.get('timeout') else 'error'} after {rec['seconds']:.0f} s", flush=True)
        return not rec.get("timeout")


def worker(spec_json: str, record: Path, memory_gib: float) -> int:
    limit = int(memory_gib * 2**30)
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    logging.basicConfig(level=logging.WARNING)
    spec = json.loads(spec_json)
    rec = run_case(spec, record)
    from fem_grasp.io.output import json_safe

    tmp = record.with_suffix(".tmp")
    tmp.write_text(json.dumps(json_safe(rec), indent=1))
    tmp.replace(record)
    return 0


# ================================================================ analysis
def _err(q: float | None, ref: float | None) -> float:
    if q is None or ref is None or not (math.isfinite(q) and math.isfinite(ref)) or ref == 0:
        return math.nan
    return abs(q - ref) / abs(ref)


def _row(rec: dict[str, Any]) -> dict[str, Any]:
    a = rec.get("answer")
    sp = rec["spec"]
    row = {"series": sp["series"], "spec": sp, "vertices": rec.get("vertices"), "seconds": rec.get("seconds"),
           "pickup_seconds": rec.get("pickup_seconds"), "timeout": bool(rec.get("timeout")),
           "error": rec.get("error", "")[-300:] if rec.get("error") else "", "peak_mib": rec.get("peak_mib"),
           "spacing": rec.get("spacing"), "patch_spacing": rec.get("patch_spacing"), "code": rec.get("code")}
    if a:
        row.update(success=a["success"], reason=a["reason"], rho=a["squeeze_depth"], force=a["finger_force"],
                   fingers=a["fingers"], table_nodes=a["table_nodes"], max_liftable=a["max_liftable"],
                   weight=a["weight"], step=a["step"], lift_test_step=a["lift_test_step"], liftable=a["liftable"],
                   bracket=rec.get("bracket"), lift_attempts=len(rec.get("lift_attempts", [])) or None)
    if rec.get("accuracy"):
        row["accuracy"] = rec["accuracy"]
    if rec.get("diagnosis"):
        row["diagnosis"] = {k: v for k, v in rec["diagnosis"].items() if k != "rows"}
        row["diagnosis_rows"] = [{k: v for k, v in r.items() if k != "finger_nodes"} for r in rec["diagnosis"]["rows"]]
    return row


def _level(sp: dict[str, Any]) -> float:
    for k in ("target", "factor", "inner", "divisor", "seed"):
        if k in sp:
            return -sp[k] if k == "inner" else sp[k]
    return 0.0


def analyse(records: dict[str, dict], objects: tuple[str, ...], cfg: dict[str, Any]) -> dict[str, Any]:
    """Tables, estimates, errors against the reference, resolutions per target, scatter, flips."""
    from fem_grasp.grasp.accuracy import estimate

    out: dict[str, Any] = {"objects": {}, "codes": sorted({r.get("code", "?") for r in records.values()})}
    for name in objects:
        # the diagnoses (slow lift tests rerunning a level) are not levels of their own
        recs = [r for r in records.values() if r["spec"]["object"] == name and not r["spec"].get("diagnose")]
        series: dict[str, list[dict]] = {}
        for r in recs:
            series.setdefault(r["spec"]["series"], []).append(_row(r))
        for rows in series.values():
            rows.sort(key=lambda x: _level(x["spec"]))
        obj: dict[str, Any] = {"series": series}
        # --- the reference: the finest uniform level with the increment and h halved (Richardson in the step)
        ref_rows = [r for r in series.get("uniform", []) if "rho" in r]
        reference = None
        if ref_rows:
            fine = max(ref_rows, key=lambda r: r["vertices"])
            chain = [fine] + [r for r in series.get("reference", []) if "rho" in r]
            chain.sort(key=lambda r: -r["step"])
            ok = [r for r in chain if r["success"]]
            if ok:
                reference = {"vertices": fine["vertices"], "levels": [
                    {"step": r["step"], "h": r["lift_test_step"], "rho": r["rho"], "force": r["force"],
                     "bracket": r.get("bracket"), "seconds": r["seconds"]} for r in ok]}
                for q in ("rho", "force"):
                    est = estimate([r[q] for r in ok], [r["step"] for r in ok])
                    # ρ* of each run lies in its bracket (the last failing test, the pass): the finest run's
                    # bracket bounds the quantisation error, whatever the estimate's method.
                    reference[q] = est
                br = ok[-1].get("bracket")
                if br:
                    reference["rho_bracket"] = br
                    est = reference["rho"]
                    if est["method"] != "richardson":
                        # the pass is within one increment of the last failing test: midpoint ± half of it
                        reference["rho"] = {"value": 0.5 * (br[0] + br[1]), "error": (br[1] - br[0]) / (br[0] + br[1]),
                                            "method": "bracket", "order": None}
        obj["reference"] = reference
        rho_ref = reference["rho"]["value"] if reference else None
        f_ref = reference["force"]["value"] if reference else None
        for rows in series.values():
            for r in rows:
                if "rho" in r:
                    wrong = not r["success"]
                    r["rho_error"] = math.inf if wrong else _err(r["rho"], rho_ref)
                    r["force_error"] = math.inf if wrong else _err(r["force"], f_ref)
        # --- estimates per series (Richardson or band), by spacing
        est = {}
        for s in ("uniform", "graded", "graded_table"):
            rows = [r for r in series.get(s, []) if r.get("success")]
            if len(rows) >= 2:
                h = [r["patch_spacing"] for r in rows]
                est[s] = {q: estimate([r[q] for r in rows], h) for q in ("rho", "force")}
        obj["estimates"] = est
        # --- cheapest resolution per target: the first level of a series from which every finer one is within it
        res = {}
        for s in ("uniform", "graded", "graded_table"):
            rows = [r for r in series.get(s, []) if "rho" in r or r["timeout"]]
            res[s] = {}
            for tgt in (0.10, 0.05, 0.02):
                hit = None
                for i, r in enumerate(rows):
                    tail = rows[i:]
                    if all("rho" in t and max(t["rho_error"], t["force_error"]) <= tgt for t in tail):
                        hit = r
                        break
                res[s][f"{tgt:g}"] = None if hit is None else {
                    "vertices": hit["vertices"], "patch_spacing": hit["patch_spacing"], "seconds": hit["seconds"],
                    "rho_error": hit["rho_error"], "force_error": hit["force_error"], "spec": hit["spec"]}
        obj["resolution"] = res
        # --- the adaptive loop's answer at each target (one run at the finest target, read off level by level)
        for r in series.get("adaptive", []):
            acc = r.get("accuracy")
            if not acc:
                continue
            r["targets"] = {}
            for tgt in (0.10, 0.05, 0.02):
                at = adaptive_at(acc, tgt)
                if at is None:
                    r["targets"][f"{tgt:g}"] = None
                    continue
                lv = at["level"]
                r["targets"][f"{tgt:g}"] = {
                    "level": lv["level"], "vertices": lv["vertices"], "seconds": at["seconds"],
                    "success": lv["success"], "rho": lv["squeeze_depth"], "force": lv["finger_force"],
                    "estimated_error": at["estimated_error"],
                    "rho_error": math.inf if not lv["success"] else _err(lv["squeeze_depth"], rho_ref),
                    "force_error": math.inf if not lv["success"] else _err(lv["finger_force"], f_ref)}
        # --- scatter of the seeds (seed 1 is the uniform level of the same size)
        sc = {}
        for r in series.get("seed", []):
            key = str(r["spec"].get("target", r["spec"].get("factor")))
            sc.setdefault(key, []).append(r)
        for r in series.get("uniform", []):
            key = str(r["spec"].get("target", r["spec"].get("factor")))
            if key in sc:
                sc[key].insert(0, r)
        scatter = {}
        for key, rows in sc.items():
            ok = [r for r in rows if r.get("success")]
            vals = {q: [r[q] for r in ok] for q in ("rho", "force")}
            scatter[key] = {"runs": len(rows), "picked_up": len(ok),
                            "vertices": [r["vertices"] for r in rows],
                            **{f"{q}_{stat}": (float(fn(v)) if v else None) for q, v in vals.items()
                               for stat, fn in (("mean", np.mean), ("std", np.std), ("min", np.min),
                                                ("max", np.max))}}
            for q in ("rho", "force"):
                m, s_ = scatter[key][f"{q}_mean"], scatter[key][f"{q}_std"]
                scatter[key][f"{q}_rel_std"] = None if not m else s_ / m
        obj["scatter"] = scatter
        obj["flips"] = flips(series)
        out["objects"][name] = obj
    return out


def flips(series: dict[str, list[dict]], jump: float = 0.05) -> list[dict[str, Any]]:
    """Verdict failures, and steps of ρ* between levels that reverse the trend by more than ``jump``."""
    found = []
    for s in ("uniform", "graded", "graded_table", "seed"):
        rows = [r for r in series.get(s, []) if "rho" in r]
        for i, r in enumerate(rows):
            if not r["success"]:
                found.append({"series": s, "kind": "verdict", "row": r})
                continue
            if s == "seed" or i == 0 or i + 1 >= len(rows):
                continue
            a, b = rows[i - 1], rows[i + 1]
            if not (a.get("success") and b.get("success")):
                continue
            d1, d2 = r["rho"] - a["rho"], b["rho"] - r["rho"]
            if d1 * d2 < 0 and min(abs(d1), abs(d2)) > jump * r["rho"]:
                found.append({"series": s, "kind": "jump", "row": r, "before": a["rho"], "after": b["rho"]})
    return found


def diagnosis_cases(analysis: dict[str, Any], cfg: dict[str, Any]) -> list[dict[str, Any]]:
    """Cases re-run with the slow lift test: every flip cheap enough (``diagnose_max_seconds``)."""
    out = []
    for name, obj in analysis["objects"].items():
        for f in obj["flips"]:
            r = f["row"]
            if r.get("pickup_seconds") and r["pickup_seconds"] <= cfg["diagnose_max_seconds"] and "diagnosis" not in r:
                out.append(dict(r["spec"], diagnose=True))
    return out


def attach_diagnoses(analysis: dict[str, Any], records: dict[str, dict]) -> None:
    for name, obj in analysis["objects"].items():
        for f in obj["flips"]:
            spec = dict(f["row"]["spec"], diagnose=True)
            rec = records.get(case_key(spec))
            if rec and rec.get("diagnosis"):
                d = rec["diagnosis"]
                f["diagnosis"] = {k: v for k, v in d.items() if k != "rows"}
                f["diagnosis"]["rows"] = [{k: v for k, v in r.items() if k != "finger_nodes"} for r in d["rows"]]
                f["diagnosis"]["verdict"] = explain(f, d)


def explain(flip: dict[str, Any], d: dict[str, Any]) -> str:
    """One sentence: was the state there (numerical) or not (physical outcome of the mesh)?"""
    w = d["weight"]
    r = flip["row"]
    peak = d.get("slow_peak") or 0.0
    if flip["kind"] == "verdict":
        if d.get("slow_pass") is not None:
            return (f"numerical: a slow lift test holds mg = {w:.3g} N at ρ = {1e3 * d['slow_pass']:.2f} mm, where the "
                    "library's lift test did not pass: the state exists")
        patch = d.get("peak_patch") or {}
        fg = patch.get("fingers") or []
        where = ""
        if fg:
            where = "; held by " + " and ".join(
                f"finger {i + 1}: {f['contacts']} contacts ({f['above_centre']} above its centre, {f['sliding']} "
                f"sliding) carrying {f['vertical']:.3g} N" for i, f in enumerate(fg))
        if "failing_node" in patch:
            where += (f"; the next weight loses node {patch['failing_node']} of finger {patch['failing_finger']}"
                      f" ({'above' if patch['failing_above_centre'] else 'below'} the fingertip's centre)")
        return (f"physical outcome of this mesh: even loaded in steps of h/8 the fingers hold at most {peak:.3g} N "
                f"= {peak / w:.2f} mg (at ρ = {1e3 * (d.get('slow_peak_rho') or 0):.2f} mm{where}; "
                f"{(d.get('peak_reason') or '')[:140]})")
    tp, sp = d.get("test_pass"), d.get("slow_pass")
    if tp is not None and sp is not None and abs(tp - sp) <= 1.01 * (r.get("step") or 0):
        return (f"the slow lift test passes at {1e3 * sp:.2f} mm too (the library's at {1e3 * tp:.2f} mm): the jump is "
                "in the discretised w(ρ) itself, not in the test")
    if sp is not None:
        return (f"the slow lift test passes at {1e3 * sp:.2f} mm against the library's {1e3 * (tp or math.nan):.2f} mm: "
                "the loading path of the test moves ρ*")
    return f"the slow lift test never holds mg (peak {peak:.3g} N)"


# ================================================================ plots
def plots(analysis: dict[str, Any], out: Path) -> dict[str, str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    images = {}
    names = list(analysis["objects"])
    styles = {"uniform": ("o-", "#1f77b4", "uniform"), "graded": ("s-", "#d62728", "graded at the fingertips"),
              "graded_table": ("^-", "#2ca02c", "graded at the fingertips and the table"),
              "adaptive": ("*", "#9467bd", "adaptive (accuracy = 10/5/2 %)"),
              "seed": ("x", "#7f7f7f", "seeds (same spacing)"), "reference": ("D", "k", "reference (step/2, /4)")}
    fig, axes = plt.subplots(len(names), 2, figsize=(11, 3.2 * len(names)), squeeze=False)
    for i, name in enumerate(names):
        obj = analysis["objects"][name]
        for j, (q, label) in enumerate((("rho", "ρ*"), ("force", "finger force Σ f·n̂"))):
            ax = axes[i][j]
            for r in obj["series"].get("adaptive", []):
                pts = [v for v in (r.get("targets") or {}).values() if v]
                if pts:
                    e = [min(max(v[f"{q}_error"], 1e-4), 2.0) if math.isfinite(v[f"{q}_error"]) else 2.0 for v in pts]
                    ax.loglog([v["seconds"] for v in pts], e, "*", color="#9467bd", ms=10,
                              label="adaptive: pickup(accuracy = 10, 5, 2 %)")
                    for v, ei in zip(pts, e):
                        ax.annotate(f"level {v['level']}", (v["seconds"], ei), fontsize=6, color="#9467bd")
            for s, (mk, col, lab) in styles.items():
                if s == "adaptive":
                    continue
                rows = [r for r in obj["series"].get(s, []) if "rho" in r]
                if not rows:
                    continue
                t = [r["seconds"] for r in rows]
                e = [min(max(r[f"{q}_error"], 1e-4), 2.0) if math.isfinite(r[f"{q}_error"]) else 2.0 for r in rows]
                ax.loglog(t, e, mk, color=col, label=lab, ms=5, fillstyle="none" if s == "seed" else "full")
                for r, ti, ei in zip(rows, t, e):
                    if not r["success"]:
                        ax.annotate("fails", (ti, ei), fontsize=6, color=col)
            for tgt in (0.1, 0.05, 0.02):
                ax.axhline(tgt, color="k", lw=0.5, ls=":")
            ax.set_title(f"{name}: {label}", fontsize=9)
            ax.set_xlabel("run time: meshing + pickup (s)", fontsize=8)
            ax.set_ylabel("relative error vs reference", fontsize=8)
            ax.grid(True, which="both", alpha=0.3)
            if i == 0 and j == 0:
                ax.legend(fontsize=6)
    fig.tight_layout()
    p = out / "converge_error_time.png"
    fig.savefig(p, dpi=100)
    plt.close(fig)
    images["converge_error_time"] = p.name

    fig, axes = plt.subplots(1, len(names), figsize=(3.6 * len(names), 3.4), squeeze=False)
    for i, name in enumerate(names):
        ax = axes[0][i]
        obj = analysis["objects"][name]
        rows = [r for r in obj["series"].get("uniform", []) if "liftable" in r]
        cmap = plt.get_cmap("viridis")
        for k, r in enumerate(rows):
            lv = np.array(r["liftable"]) if r["liftable"] else np.zeros((0, 2))
            if len(lv):
                ax.plot(1e3 * lv[:, 0], lv[:, 1], "-", color=cmap(k / max(len(rows) - 1, 1)), lw=1,
                        label=f"{r['vertices']:,} v" + ("" if r["success"] else " (fails)"))
        ref = [r for r in obj["series"].get("reference", []) if "liftable" in r and r["liftable"]]
        if ref:
            lv = np.array(ref[-1]["liftable"])
            ax.plot(1e3 * lv[:, 0], lv[:, 1], "k--", lw=1, label="reference (finest, step/4)")
        if rows:
            ax.axhline(rows[0]["weight"], color="r", lw=0.8, ls=":", label="weight mg")
        ax.set_title(f"{name}: w(ρ), uniform levels", fontsize=9)
        ax.set_xlabel("squeeze depth ρ (mm)", fontsize=8)
        ax.set_ylabel("liftable weight w (N)", fontsize=8)
        ax.legend(fontsize=5)
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    p = out / "converge_liftable.png"
    fig.savefig(p, dpi=100)
    plt.close(fig)
    images["converge_liftable"] = p.name
    return images


# ================================================================ entry points
def study(quick: bool = False, out: Path = DEFAULT_OUT, objects: tuple[str, ...] = OBJECTS, compute: bool = True,
          stale: bool = False, series_filter: set[str] | None = None) -> dict[str, Any]:
    """Run (or, with ``compute=False``, only read) the study's cases; analyse; plot; return the analysis."""
    cfg = CONFIGS["quick" if quick else "full"]
    cache = out / "cache"
    cache.mkdir(parents=True, exist_ok=True)
    records = load_records(cache)
    t0 = time.perf_counter()

    def want(series: list[dict]) -> bool:
        return bool(series) and (series_filter is None or series[0]["series"] in series_filter)

    if compute:
        # the coarse levels of every series first, then the step, h and reference series, then the fine levels
        main_series = [s for s in cases(cfg, objects, records) if want(s)]
        run_rounds(main_series, cache, records, cfg, stale, levels=cfg["early_levels"])
        run_rounds([s for s in dependent_cases(cfg, objects, records) if want(s)], cache, records, cfg, stale)
        run_rounds(main_series, cache, records, cfg, stale)
        run_rounds([s for s in dependent_cases(cfg, objects, records) if want(s)], cache, records, cfg, stale)
        analysis = analyse(records, objects, cfg)
        for spec in diagnosis_cases(analysis, cfg):
            if series_filter is None or "diagnose" in series_filter or spec["series"] in series_filter:
                run_series([spec], cache, records, dict(cfg, case_timeout=max(cfg["case_timeout"], 1800)), stale)
        for series in adaptive_cases(cfg, objects):
            if want(series):
                run_series(series, cache, records, cfg, stale)
    wanted = {case_key(s) for group in (cases(cfg, objects, records), dependent_cases(cfg, objects, records),
                                         adaptive_cases(cfg, objects)) for series in group for s in series}
    wanted |= {k for k, r in records.items() if r["spec"].get("diagnose")}
    used = {k: r for k, r in records.items() if k in wanted and r["spec"]["object"] in objects}
    analysis = analyse(used, objects, cfg)
    attach_diagnoses(analysis, records)
    analysis["quick"] = quick
    analysis["config"] = cfg
    analysis["seconds"] = time.perf_counter() - t0
    analysis["total_case_seconds"] = float(sum(r.get("seconds") or 0.0 for r in used.values()))
    analysis["images"] = plots(analysis, out)
    from fem_grasp.io.output import json_safe

    (out / "converge.json").write_text(json.dumps(json_safe(analysis), indent=1))
    return analysis


def print_tables(analysis: dict[str, Any]) -> None:
    for name, obj in analysis["objects"].items():
        print(f"\n== {name}")
        ref = obj.get("reference")
        if ref:
            print(f"reference ({ref['vertices']:,} vertices, step/{len(ref['levels'])}): rho* "
                  f"{1e3 * ref['rho']['value']:.3f} mm ± {100 * ref['rho']['error']:.2g} % ({ref['rho']['method']}), "
                  f"finger force {ref['force']['value']:.3f} N ± {100 * ref['force']['error']:.2g} % "
                  f"({ref['force']['method']})")
        for s, rows in obj["series"].items():
            print(f"  {s}:")
            for r in rows:
                if "rho" in r:
                    fg = r["fingers"]
                    print(f"    {str(r['spec'].get('target', r['spec'].get('factor', r['spec'].get('inner', r['spec'].get('divisor', r['spec'].get('seed')))))):>8} "
                          f"{r['vertices'] or 0:>7,} v  {'ok ' if r['success'] else 'NO '} rho {1e3 * r['rho']:7.3f} mm "
                          f"({100 * r['rho_error']:5.1f} %)  F {r['force']:7.3f} N ({100 * r['force_error']:5.1f} %)  "
                          f"|F1| {fg[0]['resultant']:.3f} {fg[0]['along_squeeze']:.3f} {fg[0]['vertical']:.3f}  "
                          f"nodes {fg[0]['nodes']}/{fg[1]['nodes']}/{r['table_nodes']}  {r['seconds']:.1f} s")
                else:
                    print(f"    {r['spec']}: {'timeout' if r['timeout'] else 'error ' + r['error'][-200:]}")
        for f in obj["flips"]:
            d = f.get("diagnosis", {})
            print(f"  flip ({f['series']}, {f['kind']}) at {f['row']['vertices']} vertices: {d.get('verdict', '(not diagnosed)')}")


def markdown(analysis: dict[str, Any]) -> str:
    """The README's tables (``--markdown``): per object the reference, the uniform and graded levels, the cheapest
    resolution for 10 / 5 / 2 %, and the adaptive loop."""
    def pct(x: Any) -> str:
        if x is None or (isinstance(x, float) and math.isnan(x)):
            return "–"
        return "wrong verdict" if math.isinf(x) else f"{100 * x:.1f} %"

    def mm(x: Any) -> str:
        return "–" if x is None else f"{1e3 * x:.2f}"

    def band(est: dict[str, Any]) -> str:
        e = est["error"]
        return (f"{100 * e:.1f} % ({est['method']})" if math.isfinite(e) else
                f"unknown ({est['method']}: one run)")

    lines = []
    for name, obj in analysis["objects"].items():
        ref = obj.get("reference")
        lines.append(f"\n**{name}**" + (
            f" — reference ({ref['vertices']:,} vertices, increments ÷{len(ref['levels']) and round(ref['levels'][0]['step'] / ref['levels'][-1]['step'])}): "
            f"ρ* = {mm(ref['rho']['value'])} mm ± {band(ref['rho'])}, finger force "
            f"{ref['force']['value']:.3f} N ± {band(ref['force'])}" if ref else " — no reference"))
        lines.append("")
        lines.append("| series | level | vertices | spacing at patch (mm) | verdict | ρ* (mm) | error | Σ f·n̂ (N) | error | "
                     "patches f1/f2/table | time (s) |")
        lines.append("|---|---|---|---|---|---|---|---|---|---|---|")
        for s_ in ("uniform", "graded", "graded_table", "step", "h", "quick"):
            for r in obj["series"].get(s_, []):
                sp = r["spec"]
                lvl = next((f"{k} {sp[k]:g}" if k != "inner" else f"R/{1 / sp[k]:g}") for k in
                           ("target", "factor", "inner", "divisor") if k in sp) if s_ != "quick" else "[quick]"
                if "rho" not in r:
                    lines.append(f"| {s_} | {lvl} | {r.get('vertices') or '–'} | – | "
                                 f"{'timeout' if r['timeout'] else 'error'} | | | | | | {r['seconds']:.0f} |")
                    continue
                fg = r["fingers"]
                lines.append(f"| {s_} | {lvl} | {r['vertices']:,} | {mm(r.get('patch_spacing'))} | "
                             f"{'picked up' if r['success'] else 'NOT'} | {mm(r['rho'])} | {pct(r.get('rho_error'))} | "
                             f"{r['force']:.3f} | {pct(r.get('force_error'))} | {fg[0]['nodes']}/{fg[1]['nodes']}/"
                             f"{r['table_nodes']} | {r['seconds']:.0f} |")
        for key, sc in obj.get("scatter", {}).items():
            if sc["rho_mean"] is not None:
                lines.append(f"\nSeeds at {key}: {sc['picked_up']}/{sc['runs']} picked up, ρ* {mm(sc['rho_mean'])} ± "
                             f"{mm(sc['rho_std'])} mm (range {mm(sc['rho_min'])}–{mm(sc['rho_max'])}), finger force "
                             f"{sc['force_mean']:.3f} ± {sc['force_std']:.3f} N.")
            else:
                lines.append(f"\nSeeds at {key}: {sc['picked_up']}/{sc['runs']} picked up.")
    lines.append("\nTime to a 10 % / 5 % / 2 % answer (both ρ* and Σ f·n̂ within the target of the reference):\n")
    lines.append("| object | target | uniform | graded | graded + table | adaptive (levels, its estimate) |")
    lines.append("|---|---|---|---|---|---|")
    for name, obj in analysis["objects"].items():
        ad = next((r for r in obj["series"].get("adaptive", []) if r.get("targets")), None)
        for t in ("0.1", "0.05", "0.02"):
            cells = []
            for s_ in ("uniform", "graded", "graded_table"):
                v = obj["resolution"].get(s_, {}).get(t)
                cells.append("not reached" if v is None else f"{v['seconds']:.0f} s ({v['vertices']:,} v)")
            a = None if ad is None else ad["targets"].get(t)
            if a is None:
                cells.append("not reached" if ad is not None else "–")
            else:
                est = max(a["estimated_error"].values())
                cells.append(f"{a['seconds']:.0f} s ({a['level'] + 1} levels; error {pct(max(a['rho_error'], a['force_error']))}"
                             f", estimate {pct(est)})")
            lines.append(f"| {name} | {100 * float(t):g} % | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m verification.converge", description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a few levels per series (minutes)")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    ap.add_argument("--objects", nargs="+", choices=OBJECTS, default=list(OBJECTS))
    ap.add_argument("--series", nargs="+", help="run only these series (uniform graded graded_table seed step h "
                                               "reference adaptive diagnose); the analysis reads every cached one")
    ap.add_argument("--report-only", action="store_true", help="analyse and plot the cached records; compute nothing")
    ap.add_argument("--stale", action="store_true", help="recompute records made with other fem_grasp sources")
    ap.add_argument("--docs", type=Path, help="also copy the plots into this folder (the README's: docs/)")
    ap.add_argument("--markdown", action="store_true", help="print the README's tables")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument("--record", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("--memory-gib", type=float, default=9.0, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        return worker(args.worker, args.record, args.memory_gib)
    logging.basicConfig(level=logging.WARNING, format="%(asctime)s %(name)s %(levelname)s %(message)s")
    analysis = study(args.quick, args.out, tuple(args.objects), compute=not args.report_only, stale=args.stale,
                     series_filter=set(args.series) if args.series else None)
    print(markdown(analysis)) if args.markdown else print_tables(analysis)
    print(f"\nwrote {args.out / 'converge.json'} and {', '.join(analysis['images'].values())}")
    if args.docs:
        import shutil

        args.docs.mkdir(parents=True, exist_ok=True)
        for name in analysis["images"].values():
            shutil.copy(args.out / name, args.docs / name)
        print(f"copied the plots into {args.docs}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
