"""Where draws of one level's mesh differ: in the squeeze's force, or in where the lift test first holds mg.

Remeshed levels of the accuracy loop (``refinement = "remesh"``) are each a new gmsh mesh, and meshes of one spacing
differ by a few per cent in ρ* (docs/accuracy.md, "The draw of a level's mesh").  This script runs a scene's loop
with remeshed levels (``--refinement nested``: the default's nested levels, whose draw is level 0's alone) on
several draws of its meshes, as ``python -m bench.bench --only accuracy`` does (gmsh's inputs rounded to grids 2,
4, … times as coarse: a move of at most a millionth of a spacing), and compares, on each draw's last level:

* the squeeze: Σ f·n̂ over both fingers at five depths that every draw squeezed through (the elastic and contact
  response of the mesh, node contact and all);
* the lift test: ρ*, the force at lift-off, and the depth over which the liftable weight w(ρ) stayed one step h
  below mg before it reached mg (the plateau: how slowly w approaches mg);
* the lift: the share of the weight finger 1 carries at lift-off (half, for a grasp held alike by both fingers);
* the rest: the tilt of the hull facet the last level rests on (§III-A places the body rigidly on a stable facet of
  its convex hull), from the body's given orientation towards finger 1's horizontal squeeze direction, in degrees:
  a smooth body rests with its centre of mass above its lowest point (the paper shapes as given: upright), and a
  mesh's facet tilts it from there by up to about the facet's size over the radius of curvature.

Usage::

    python scripts/draw_scatter.py                      # tomato and orange, five draws each
    python scripts/draw_scatter.py steam_bun --draws 3
    python scripts/draw_scatter.py tomato --lift-test-step 0.0125   # the lift test in steps of mg/80

Prints one block per scene.  Needs gmsh (the ``mesh`` extra); a draw takes what the default takes.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from typing import Any, Sequence

import numpy as np

#: Depths of the squeeze compared across draws: this many, from this fraction of the shallowest ρ* up to it.
DEPTHS, FIRST_DEPTH = 5, 0.3


def draw_worker(name: str, draw: int, lift_test_step: float | None = None,
                refinement: str = "remesh") -> dict[str, Any]:
    """One draw of a scene's run with ``refinement``'s levels: the last level's squeeze (ρ, Σ f·n̂) at every event,
    its w(ρ) points, ρ*, the force at lift-off and the weight each finger carries there; ``lift_test_step``: the
    lift test's step h as a fraction of the weight instead of the scene's."""
    from fem_grasp.io.scene import Scene
    from fem_grasp.mesh import gmsh_session

    gmsh_session.POINT_QUANTUM *= 2.0 ** draw
    scene = Scene.load(name).with_(refinement=refinement)
    if lift_test_step is not None:
        if scene.weight is None:
            raise SystemExit(f"{name}: --lift-test-step needs a scene that states its weight ([material] weight)")
        scene = scene.with_(lift_test_step=lift_test_step * scene.weight)
    result = scene.run(cache_dir=None)
    squeeze = [(float(snap.squeeze_depth), sum(f.normal_sum for f in snap.finger_forces(result.directions)))
               for snap in result.snapshots if snap.phase == "squeeze"]
    levels = (result.accuracy or {}).get("levels") or [{}]
    fingers = result.finger_forces if result.success else None
    return {"name": name, "draw": draw, "vertices": levels[-1].get("vertices"), "success": bool(result.success),
            "squeeze_depth": float(result.squeeze_depth), "finger_force": float(result.finger_normal_force),
            "weight": float(result.body.weight), "liftable": [list(map(float, p)) for p in result.liftable],
            "squeeze": squeeze, "finger_vertical": [f.vertical for f in fingers] if fingers else None,
            "rest_tilt": rest_tilt(result.rest.pose.rotation, result.directions[0])}


def rest_tilt(rotation: np.ndarray, direction: np.ndarray) -> float:
    """The resting facet's tilt (degrees) along a squeeze direction's horizontal part: the angle of the facet's
    outward normal (the body's downward direction it was turned from, Rᵀ(−ẑ)) from −ẑ, towards that direction."""
    normal = np.asarray(rotation).T @ np.array([0.0, 0.0, -1.0])
    towards = np.array([direction[0], direction[1], 0.0])
    return float(np.degrees(np.arcsin(normal @ towards / np.linalg.norm(towards))))


def _spread(values: np.ndarray) -> float:
    """(largest − smallest) / mean, per cent."""
    return float(100.0 * np.ptp(values) / np.mean(values))


def summary(draws: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """The spreads across draws (module notes), from :func:`draw_worker`'s records of one scene."""
    rho = np.array([d["squeeze_depth"] for d in draws])
    force = np.array([d["finger_force"] for d in draws])
    top = float(rho.min())
    depths = np.linspace(FIRST_DEPTH * top, top, DEPTHS)
    curves = []
    for d in draws:
        pts = np.array(sorted(d["squeeze"]))
        curves.append(np.interp(depths, pts[:, 0], pts[:, 1]))
    curves = np.array(curves)
    plateaus = []  # from the first depth tested at the last weight below mg (a lower bound: tests start near ρ*)
    for d in draws:
        below = [(r, w) for r, w in d["liftable"] if w < d["weight"] * (1 - 1e-12) and r <= d["squeeze_depth"]]
        top_weight = max((w for _, w in below), default=None)
        start_depth = min((r for r, w in below if w == top_weight), default=d["squeeze_depth"])
        plateaus.append((d["squeeze_depth"] - start_depth) / d["squeeze_depth"])
    shares = [d["finger_vertical"][0] / sum(d["finger_vertical"]) for d in draws if d.get("finger_vertical")]
    tilts = [d["rest_tilt"] for d in draws if d.get("finger_vertical") and d.get("rest_tilt") is not None]
    return {"finger1_share": shares, "rest_tilt": tilts, "draws": len(draws),
            "vertices": [d["vertices"] for d in draws],
            "squeeze_depth_mm": (1e3 * rho).tolist(),
            "squeeze_depth_spread": _spread(rho), "finger_force_spread": _spread(force),
            "depths_mm": (1e3 * depths).tolist(), "squeeze_force_spread": [_spread(c) for c in curves.T],
            "plateau": plateaus}


def main(argv: Sequence[str] | None = None) -> int:
    from fem_grasp.grasp.options import REFINEMENTS

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="*", default=["tomato", "orange"])
    parser.add_argument("--draws", type=int, default=5, help="draws per scene (default 5)")
    parser.add_argument("--lift-test-step", type=float, metavar="FRACTION",
                        help="the lift test's step h as a fraction of the weight (default: the scene's, mg/20)")
    parser.add_argument("--refinement", choices=REFINEMENTS, default="remesh",
                        help="the levels' refinement (default remesh: every level a new draw)")
    parser.add_argument("--worker", nargs=2, metavar=("NAME", "DRAW"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        print(json.dumps(draw_worker(args.worker[0], int(args.worker[1]), args.lift_test_step, args.refinement)))
        return 0
    if args.draws < 2:
        parser.error("--draws must be at least 2 (a spread needs two draws)")
    from fem_grasp.errors import SceneError
    from fem_grasp.io.scene import Scene

    for name in args.scenes:
        try:
            Scene.load(name)
        except SceneError as exc:
            parser.error(str(exc))
    for name in args.scenes:
        draws = []
        for draw in range(args.draws):  # each in a process of its own: the rounding grid is the process's
            step = [] if args.lift_test_step is None else ["--lift-test-step", repr(args.lift_test_step)]
            run = subprocess.run([sys.executable, __file__, "--worker", name, str(draw), *step,
                                  "--refinement", args.refinement],
                                 capture_output=True, text=True)
            if run.returncode != 0:
                tail = "\n".join(run.stderr.strip().splitlines()[-5:])
                raise SystemExit(f"{name}, draw {draw}: the run failed (exit {run.returncode}):\n{tail}")
            draws.append(json.loads(run.stdout.strip().splitlines()[-1]))
        s = summary(draws)
        print(f"{name}: {s['draws']} draws, last level {min(s['vertices'])}–{max(s['vertices'])} vertices")
        print(f"  rho* (mm)                 {', '.join(f'{r:.3f}' for r in s['squeeze_depth_mm'])}: spread "
              f"{s['squeeze_depth_spread']:.1f} %; force at lift-off spread {s['finger_force_spread']:.1f} %")
        print(f"  squeeze force at rho (mm) {', '.join(f'{r:.2f}' for r in s['depths_mm'])}: spread "
              f"{', '.join(f'{x:.1f}' for x in s['squeeze_force_spread'])} %")
        shares = ", ".join(f"{100 * x:.1f}" for x in s["finger1_share"])
        print(f"  finger 1's share of the weight at lift-off {shares} %")
        tilts = ", ".join(f"{t:+.2f}" for t in s["rest_tilt"])
        print(f"  the last level's resting tilt towards finger 1's squeeze direction {tilts} deg")
        print(f"  w(rho) at its last weight below mg over at least the last "
              f"{', '.join(f'{100 * p:.1f}' for p in s['plateau'])} % of rho* (per draw)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
