"""The study's cases: the configurations, each case's mesh and pickup settings, the code digest and the case keys.

A *case* is a dict (``{"object": "orange", "series": "uniform", "target": 1200}``) that names one mesh and one
set of pickup settings (module notes of :mod:`verification.converge`); its record is cached under
``case_key(spec)``.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


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
        "adaptive_target": 0.02, "adaptive_max_levels": 2, "adaptive_timeout": 2700, "early_levels": 4,
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
    if series in ("quick", "shipped"):  # the scene's own mesh ([quick]: its coarse one)
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


#: Sources that do not change a pickup's answer: files, the CLI, the search, the accuracy loop (its records carry
#: their levels).  Paths relative to the package.
_DIGEST_SKIP = {"grasp/accuracy.py", "grasp/estimates.py", "paper.py", "progress.py", "__main__.py"}


_DIGEST_SKIP_DIRS = ("io/", "batch/", "cli/")


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


#: Scene keys that describe a run's answer instead of setting its problem: editing them (or any comment)
#: keeps the study's records.
_DIGEST_SKIP_SCENE_KEYS = ("expected_error",)


def scene_problem(path: Path) -> dict[str, Any]:
    """The problem a scene file sets: its parsed TOML (comments gone) less :data:`_DIGEST_SKIP_SCENE_KEYS`."""
    import tomllib

    def strip(d: Any) -> Any:
        if isinstance(d, dict):
            return {k: strip(v) for k, v in d.items() if k not in _DIGEST_SKIP_SCENE_KEYS}
        return d

    return strip(tomllib.loads(Path(path).read_text()))


def scene_digest(name: str) -> str:
    """Digest of what a case's answer depends on besides the code: the problem the shipped scene sets (its
    modulus, weight, friction, …; :func:`scene_problem`) and, for a paper object, its committed mesh.  A record
    made for another problem is never reused, whatever ``--stale`` says (a changed scene is another problem,
    not a stale answer)."""
    from fem_grasp.io.scene import resolve_scene

    h = hashlib.sha256()
    problem = scene_problem(Path(resolve_scene(name)))
    h.update(json.dumps(problem, sort_keys=True, default=repr).encode())
    mesh = ROOT / "fem_grasp" / "scenes" / "meshes" / f"{name}.vtu"
    if mesh.exists():
        h.update(mesh.read_bytes())
    return h.hexdigest()[:12]


def case_key(spec: dict[str, Any]) -> str:
    return hashlib.sha256(json.dumps([RECORD_FORMAT, spec], sort_keys=True).encode()).hexdigest()[:16]


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
        out.append([{"object": name, "series": "shipped"}])
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

