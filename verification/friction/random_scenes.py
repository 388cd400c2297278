"""Random valid small scenes for the frictional-contact comparison (seeded, reproducible).

Each scene is a TOML file written the way a user would write one (the
comparison reads it as a scene it has never seen): a small box (a grid of at
most 6 × 7 × 6 vertices) or a small ellipsoid meshed here with gmsh (written
as a .vtu beside the scene), a soft material, friction at the fingers and the
table, a fingertip radius, a placement rule, squeeze directions tilted down
by a random angle and a squeeze ratio.  A draw is *valid* when fem_grasp
accepts the scene and reaches the squeeze (a placement exists); invalid draws
are skipped, so the list depends only on the seed.

    python -m verification friction random OUT_DIR [--count 20] [--seed 24]
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

#: Seed of the scenes of the full report (``make verify``).
DEFAULT_SEED = 24
#: Largest vertex count of an ellipsoid draw (a few hundred nodes at most: each comparison stays quick).
MAX_ELLIPSOID_VERTICES = 320


@dataclass(frozen=True)
class Draw:
    """One random scene: its name, TOML text and the mesh file it needs (or None)."""

    name: str
    text: str
    mesh: tuple[str, np.ndarray, np.ndarray] | None = None


def ellipsoid_mesh(axes: tuple[float, float, float], size: float) -> tuple[np.ndarray, np.ndarray]:
    """Tetrahedra of the ellipsoid with semi-axes ``axes`` at edge length ``size`` (gmsh's OpenCASCADE kernel)."""
    import gmsh

    own = not bool(getattr(gmsh, "isInitialized", lambda: False)())
    if own:
        gmsh.initialize([], False)  # no argv, no user gmshrc
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("ellipsoid")
        tag = gmsh.model.occ.addSphere(0, 0, 0, 1.0)
        gmsh.model.occ.dilate([(3, tag)], 0, 0, 0, *axes)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMin", size)
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
        gmsh.model.mesh.generate(3)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        _, elem_nodes = gmsh.model.mesh.getElementsByType(4)
        gmsh.model.remove()
    finally:
        if own:
            gmsh.finalize()
    pts = np.asarray(coords, float).reshape(-1, 3)
    index = {int(t): k for k, t in enumerate(tags)}
    tets = np.array([index[int(t)] for t in elem_nodes], dtype=np.int64).reshape(-1, 4)
    used = np.unique(tets)
    remap = np.full(len(pts), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return pts[used], remap[tets]


def draw(rng: np.random.Generator, k: int) -> Draw:
    """The k-th random scene (module notes)."""
    box = rng.random() < 0.6
    young = 10 ** rng.uniform(math.log10(5e3), math.log10(5e4))
    poisson = rng.uniform(0.2, 0.45)
    mu_f = rng.uniform(0.3, 0.9)
    mu_t = rng.uniform(0.3, 0.9)
    radius = rng.uniform(0.006, 0.015)
    tilt = math.radians(rng.uniform(0.0, 25.0))
    ratio = rng.uniform(0.5, 1.5)
    rule = rng.choice(["centre-of-mass-height", "least-force"])
    d = (math.cos(tilt), math.sin(tilt))
    mesh = None
    if box:
        dims = rng.uniform([0.02, 0.025, 0.02], [0.045, 0.05, 0.04])
        div = rng.integers([3, 4, 3], [6, 7, 6])
        volume = float(np.prod(dims))
        obj = (f"box = [\"{dims[0] * 100:.3f} cm\", \"{dims[1] * 100:.3f} cm\", \"{dims[2] * 100:.3f} cm\"]\n"
               f"divisions = [{div[0]}, {div[1]}, {div[2]}]")
    else:
        axes = tuple(float(x) for x in rng.uniform([0.012, 0.015, 0.012], [0.025, 0.03, 0.022]))
        size = 0.45 * min(axes)
        pts, tets = ellipsoid_mesh(axes, size)
        while len(pts) > MAX_ELLIPSOID_VERTICES:
            size *= 1.15
            pts, tets = ellipsoid_mesh(axes, size)
        volume = 4.0 / 3.0 * math.pi * float(np.prod(axes))
        mesh = (f"random_{k:02d}.vtu", pts, tets)
        obj = f"mesh = \"random_{k:02d}.vtu\""
    density = rng.uniform(400.0, 1100.0)
    weight = density * 9.8 * volume
    text = f"""# Random scene {k} of verification.friction.random_scenes (seeded)
name = "random_{k:02d}"
description = "random {'box' if box else 'ellipsoid'}"

[object]
{obj}

[material]
young = "{young:.1f} Pa"
poisson = {poisson:.3f}
weight = "{weight:.4f} N"

[friction]
finger = {mu_f:.3f}
table = {mu_t:.3f}

[fingers]
radius = "{radius * 1000:.2f} mm"
contacts = "{rule}"
directions = [[0.0, {d[0]:.4f}, {-d[1]:.4f}], [0.0, {-d[0]:.4f}, {-d[1]:.4f}]]
ratio = {ratio:.3f}
"""
    return Draw(f"random_{k:02d}", text, mesh)


def write_draw(out_dir: Path, dr: Draw) -> Path:
    """Write the scene (and its mesh) into ``out_dir``; returns the scene's path."""
    out_dir.mkdir(parents=True, exist_ok=True)
    if dr.mesh is not None:
        import meshio

        name, pts, tets = dr.mesh
        meshio.write(out_dir / name, meshio.Mesh(pts, [("tetra", tets)]))
    path = out_dir / f"{dr.name}.toml"
    path.write_text(dr.text, encoding="utf-8")
    return path


def is_valid(path: Path) -> tuple[bool, str]:
    """fem_grasp accepts the scene and its pickup reaches the squeeze."""
    from .compare import load_case

    try:
        case = load_case(path)
    except Exception as exc:  # noqa: BLE001 - any refusal makes the draw invalid
        return False, f"{type(exc).__name__}: {exc}"
    return True, case.result.reason or "picked up"


def random_scenes(out_dir: str | Path, count: int = 20, seed: int = DEFAULT_SEED, max_draws: int = 200,
                  validate: bool = True) -> list[Path]:
    """``count`` valid random scenes written to ``out_dir`` (module notes); deterministic in ``seed``."""
    out = Path(out_dir)
    rng = np.random.default_rng(seed)
    paths: list[Path] = []
    for k in range(max_draws):
        dr = draw(rng, k)
        path = write_draw(out, dr)
        ok, why = is_valid(path) if validate else (True, "")
        if ok:
            paths.append(path)
            log.info("%s: valid (%s)", dr.name, why)
        else:
            log.info("%s: skipped (%s)", dr.name, why)
            path.unlink()
        if len(paths) >= count:
            break
    return paths


def compare_random(out_dir: str | Path, count: int = 20, seed: int = DEFAULT_SEED,
                   levels: tuple[int, ...] = (1, 4), max_draws: int = 200) -> list[dict]:
    """Draw scenes until ``count`` are valid and run the comparison on each (fem_grasp runs once per draw).

    Returns the summaries of :func:`verification.friction.compare.run_case` (own chain skipped, rest at
    16 increments: the random scenes test the squeeze, lift test and lift).
    """
    from .compare import load_case, run_case

    out = Path(out_dir)
    rng = np.random.default_rng(seed)
    results: list[dict] = []
    for k in range(max_draws):
        dr = draw(rng, k)
        path = write_draw(out, dr)
        try:
            case = load_case(path)
        except Exception as exc:  # noqa: BLE001 - any refusal makes the draw invalid
            log.info("%s: skipped (%s: %s)", dr.name, type(exc).__name__, exc)
            path.unlink()
            continue
        summary = run_case(case, levels=levels, rest_levels=(16,), own_chain=False)
        summary["draw"] = k
        results.append(summary)
        log.info("%s: fem_grasp %s, reference %s, force %.2e", dr.name, summary["verdict_fem_grasp"],
                 summary["verdict_reference"], summary["force_max_finest"])
        if len(results) >= count:
            break
    return results


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m verification friction random", description=__doc__.splitlines()[0])
    p.add_argument("out", type=Path)
    p.add_argument("--count", type=int, default=20)
    p.add_argument("--seed", type=int, default=DEFAULT_SEED)
    p.add_argument("--compare", action="store_true", help="also run the frictional-contact comparison on each")
    p.add_argument("--json", type=Path, help="with --compare: write the summaries here")
    p.add_argument("--increments", type=int, nargs="+", default=[1, 4], help="reference levels M (default 1 4)")
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    if not args.compare:
        for path in random_scenes(args.out, args.count, args.seed):
            print(path)
        return 0
    import json

    from .._common.run import json_safe

    rows = compare_random(args.out, args.count, args.seed, levels=tuple(args.increments))
    for r in rows:
        print(f"{r['scene']}: {r['vertices']} vertices, fem_grasp {r['verdict_fem_grasp']}, reference "
              f"{r['verdict_reference']}, |Δρ*| {r['rho_star_difference'] * 1e3:.3g} mm, force {r['force_max_finest']:.2e}")
    if args.json:
        args.json.write_text(json.dumps(json_safe(rows), indent=1), encoding="utf-8")
    return 0 if all(r["agree"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
