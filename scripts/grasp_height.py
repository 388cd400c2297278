"""How ρ* depends on the height at which the fingers grasp: the accuracy loop at a few heights about the rule's.

The placement rule grasps at the surface points extreme along ∓d̂ near the centre of mass's height
(:func:`fem_grasp.grasp.placement.extreme_points`).  This script moves that grasp up and down the object's side:
for each offset it takes the extreme points of the geometry's surface at the rule's height plus the offset,
meshes the scene's object at its own mesh's spacing with those points as nodes, and runs the accuracy loop there
(every level grasps at the same points, :mod:`fem_grasp.grasp.accuracy`).  Where ρ* changes by more than its
error over a millimetre or two, the pickup answer is a property of the grasp's height as much as of the object,
and a mesh whose nodes lie elsewhere answers another grasp.

Usage::

    python scripts/grasp_height.py                       # the steam bun, offsets -1.5 ... +3 mm, at 5 %
    python scripts/grasp_height.py tomato --offsets -2 0 2 --accuracy 0.1

Prints one row per height: the offset and the points' height, the levels' ρ*, the answer with its estimated
error, and the time.  Needs gmsh (the ``mesh`` extra).
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from typing import Sequence

import numpy as np

from fem_grasp.elastic.body import Body
from fem_grasp.grasp.pickup import pickup
from fem_grasp.grasp.placement import extreme_points
from fem_grasp.io.scene import load_scene, resolve_scene
from fem_grasp.mesh.remesh import BoxGeometry, PaperGeometry, nearest_surface_nodes, patch_refinement

#: Offsets of the grasp's height from the rule's, millimetres.
DEFAULT_OFFSETS = (-1.5, 0.0, 0.75, 1.5, 2.25, 3.0)


def grasp_points(geometry, height: float, direction: np.ndarray, sample: float) -> np.ndarray:
    """(2, 3) the surface points extreme along ∓d̂ within a thin band about ``height`` (the frame of the mesh)."""
    pts = np.asarray(geometry.surface_points(sample), float)
    z = pts[:, 2]
    band = 0.5 * sample / float(z.max() - z.min())  # half a sample spacing, as a share of the height range
    i, j = extreme_points(pts, height, direction, band=max(band, 1e-6))
    return pts[[i, j]]


def pct(x: float | None) -> str:
    return "unknown" if x is None or not np.isfinite(x) else f"{100 * x:.1f} %"


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", nargs="?", default="steam_bun", help="a shipped paper scene (default steam_bun)")
    ap.add_argument("--offsets", nargs="+", type=float, default=list(DEFAULT_OFFSETS),
                    help="grasp heights relative to the rule's, mm")
    ap.add_argument("--accuracy", type=float, default=0.05, help="the loop's target (default 0.05)")
    args = ap.parse_args(argv)

    scene = load_scene(resolve_scene(args.scene))
    geometry = scene.geometry()
    if not isinstance(geometry, (PaperGeometry, BoxGeometry)):
        ap.error(f"{args.scene}: no geometry to place points on (a paper shape or a box is needed)")
    if isinstance(geometry, PaperGeometry):
        geometry = replace(geometry, embed_points=True)  # every level grasps at the points, as nodes
    body = scene.body(None)
    opts = scene.pickup_options()
    direction = np.asarray(opts.directions[0], float)
    level0 = pickup(body, opts.replace(accuracy=0.05, geometry=geometry, max_finger_contacts=1))  # level 0 only
    rule = np.asarray(level0.accuracy["contact_points"], float)
    first = level0.accuracy["levels"][0]  # the loop's level 0: its spacing at the patches and elsewhere
    inner, outer = float(first["inner_size"]), float(first["outer_size"])
    print(f"{args.scene}: the rule grasps at height {1e3 * rule[:, 2].mean():.2f} mm (the given mesh's spacing "
          f"{1e3 * inner:.2g} mm at the patches); the accuracy loop at {100 * args.accuracy:g} % at each height")
    print(f"{'offset mm':>9} {'height mm':>9}  {'levels: rho* mm':<34} {'rho* mm':>8} {'error':>7} "
          f"{'force N':>8} {'error':>7} {'s':>5}")
    for off in args.offsets:
        pts = grasp_points(geometry, float(rule[:, 2].mean()) + 1e-3 * off, direction, inner / 8.0)
        mesh = geometry.build(outer, [patch_refinement(pts, inner, 1.5 * inner, outer)], embed=pts)
        lv_body = Body(mesh, body.young, body.poisson, weight=body.weight, gravity=body.gravity)
        contacts = tuple(int(k) for k in nearest_surface_nodes(mesh, pts))
        t0 = time.perf_counter()
        res = pickup(lv_body, opts.replace(accuracy=args.accuracy, geometry=geometry, contacts=contacts))
        seconds = time.perf_counter() - t0
        acc = res.accuracy
        levels = ", ".join(f"{1e3 * lv['squeeze_depth']:.2f}" + ("" if lv["success"] else " (not)")
                           for lv in acc["levels"])
        err = acc["estimated_error"]
        verdict = "" if res.success else " (not picked up)"
        print(f"{off:9.2f} {1e3 * pts[:, 2].mean():9.2f}  {levels:<34} {1e3 * res.squeeze_depth:8.3f} "
              f"{pct(err.get('squeeze_depth')):>7} {acc['levels'][-1]['finger_force']:8.3f} "
              f"{pct(err.get('finger_force')):>7} {seconds:5.0f}{verdict}  ({acc['note']})", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
