"""The answer at the placement rule's own grasp: uniform meshes with the grasp points as nodes, and the loop beside.

The placement rule grasps at the surface points extreme along ∓d̂ at the centre of mass's height.  A mesh can
only grasp at its nodes, which lie up to half a spacing from those points, and the pickup answer moves with the
grasp: the fingertips' normals tilt, and the friction must carry a different share of the weight.  A reference
for the rule's grasp therefore has the points as nodes of every mesh.  The convergence study's references
(``python -m verification converge``) grasp at each mesh's own nodes instead, 1.4-2.3 mm from the points on the
tomato and 4.1-4.6 mm on the orange, and differ from the references this script computes by 5.3 % / 11 %
(ρ* / Σ f·n̂) and 7.6 % / 12 %.

For one shipped paper scene this script takes the rule's points as the accuracy loop finds them (its level 0 on
the shipped mesh, :func:`fem_grasp.grasp.accuracy.placement_target`), meshes the object uniformly at a few vertex
counts with those points embedded as nodes, runs the pickup there at the scene's squeeze increment and at
fractions of it, and runs the accuracy loop twice: as shipped (every level, level 0 included, has the points as
nodes) and with ``embed_points=False`` (each level grasps at its surface nodes nearest the points, level 0 at the
shipped mesh's).  Every loop answer is compared with the finest pinned run.

Usage::

    python scripts/pinned_reference.py tomato
    python scripts/pinned_reference.py orange --vertices 9600 19200 38400 --divisions 1 4 --accuracy 0.05

Prints one row per mesh and increment, then one per loop.  Needs gmsh (the ``mesh`` extra).
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any, Iterator, Sequence

import numpy as np

from fem_grasp.elastic.body import Body
from fem_grasp.grasp.answer import answer_of
from fem_grasp.grasp.estimates import relative_change
from fem_grasp.grasp.pickup import pickup
from fem_grasp.io.scene import load_scene, resolve_scene
from fem_grasp.mesh.remesh import PaperGeometry, nearest_surface_nodes

ROOT = Path(__file__).resolve().parents[1]
#: Vertex counts of the uniform meshes (gmsh lands within ~20 % of them).
DEFAULT_VERTICES = (7840, 15680, 31360)
#: Divisions of the scene's squeeze increment at every mesh.
DEFAULT_DIVISIONS = (1, 4)


def pct(x: float | None) -> str:
    return "unknown" if x is None or not np.isfinite(x) else f"{100 * x:.1f} %"


def rule_points(scene: Any, accuracy: float) -> tuple[np.ndarray, float]:
    """(2, 3) the points the accuracy loop grasps at (the rule's, on the geometry; the shipped mesh's frame) and the
    scene's squeeze increment on the shipped mesh, from a loop that stops at its level 0 there."""
    plain = replace(scene.geometry(), embed_points=False)  # level 0 on the shipped mesh itself
    level0 = pickup(scene.body(None), scene.pickup_options().replace(accuracy=accuracy, geometry=plain,
                                                                     max_finger_contacts=1))
    return (np.asarray(level0.accuracy["contact_points"], float),
            float(level0.accuracy["levels"][0]["resolution"]))


def pinned_series(scene: Any, points: np.ndarray, increment: float, vertices: Sequence[int],
                  divisions: Sequence[int]) -> Iterator[dict[str, Any]]:
    """The pickup on uniform meshes of ``scene``'s object with ``points`` as nodes, grasped there, at each squeeze
    increment ``increment / d``: one dict per run (``vertices``, ``increment``, ``answer``, ``finger_points``, the
    positions of the nodes the fingers first touch)."""
    pinned = replace(scene.geometry(), embed_points=True)
    body, opts = scene.body(None), scene.pickup_options()
    for n in vertices:
        mesh = pinned.build(pinned.size_for_vertices(n), embed=points)
        lv_body = Body(mesh, body.young, body.poisson, weight=body.weight, gravity=body.gravity)
        contacts = tuple(int(k) for k in nearest_surface_nodes(mesh, points))
        for d in divisions:
            t0 = time.perf_counter()
            res = pickup(lv_body, opts.replace(contacts=contacts, step=increment / d))
            yield {"vertices": len(mesh.points), "increment": increment / d,
                   "answer": answer_of(res, time.perf_counter() - t0),
                   "finger_points": mesh.points[[int(k) for k in res.finger_nodes]]}


def reference_entry(runs: Sequence[dict[str, Any]], points: np.ndarray, weight: float) -> dict[str, Any]:
    """The pinned reference of :func:`pinned_series`' runs: the last run's answer (the finest mesh at the finest
    increment), each quantity with its uncertainty — the relative difference from the next finest mesh at the
    same increment, and for ρ* at least that increment (ρ* is found to within one); None (unknown) with a single
    mesh at that increment — in the form of :mod:`verification.converge.references`."""
    last = runs[-1]
    a, inc = last["answer"], float(last["increment"])
    same = [r["answer"] for r in runs[:-1] if r["increment"] == inc]
    rho_err = force_err = None
    if same and a.success and same[-1].success:
        rho_err = max(relative_change(same[-1].squeeze_depth, a.squeeze_depth), inc / a.squeeze_depth)
        force_err = relative_change(same[-1].finger_force, a.finger_force)
    method = "two finest meshes" if same else "a single mesh"
    return {"success": bool(a.success), "vertices": int(a.n_vertices), "step": inc, "weight": float(weight),
            "max_liftable": float(a.max_liftable),
            "rho": {"value": float(a.squeeze_depth), "error": rho_err, "method": method},
            "force": {"value": float(a.finger_force), "error": force_err, "method": method},
            "points": np.asarray(points, float).tolist(),
            "runs": [{"vertices": int(r["answer"].n_vertices), "increment": float(r["increment"]),
                      "success": bool(r["answer"].success), "rho": float(r["answer"].squeeze_depth),
                      "force": float(r["answer"].finger_force)} for r in runs]}


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", nargs="?", default="tomato", help="a shipped paper scene (default tomato)")
    ap.add_argument("--vertices", nargs="+", type=int, default=list(DEFAULT_VERTICES),
                    help="vertex counts of the pinned uniform meshes")
    ap.add_argument("--divisions", nargs="+", type=int, default=list(DEFAULT_DIVISIONS),
                    help="divisions of the squeeze increment at each mesh (1: the scene's)")
    ap.add_argument("--accuracy", type=float, default=0.05, help="the loops' target (default 0.05)")
    ap.add_argument("--no-loops", action="store_true", help="the pinned meshes only, not the two loops")
    ap.add_argument("--write-reference", action="store_true",
                    help="keep the finest run as the object's pinned reference in verification/converge/"
                         "references.json (what python -m bench.bench --only accuracy measures against)")
    args = ap.parse_args(argv)
    if any(n < 100 for n in args.vertices) or any(d < 1 for d in args.divisions):
        ap.error("--vertices must be at least 100 and --divisions at least 1")

    scene = load_scene(resolve_scene(args.scene))
    if not isinstance(scene.geometry(), PaperGeometry):
        ap.error(f"{args.scene}: not a paper shape (the uniform meshes need its geometry)")
    points, increment = rule_points(scene, args.accuracy)
    print(f"{args.scene}: the rule grasps at {np.round(1e3 * points, 2).tolist()} mm (the frame of the shipped "
          f"mesh); squeeze increment {1e3 * increment:.3f} mm")
    print(f"{'vertices':>8} {'increment mm':>12} {'verdict':>8} {'rho* mm':>8} {'force N':>8} "
          f"{'contacts f1/f2/table':>20} {'s':>6}")
    runs = []
    for run in pinned_series(scene, points, increment, args.vertices, args.divisions):
        a = run["answer"]
        runs.append(run)
        patches = "/".join(str(f["nodes"]) for f in a.fingers) + f"/{a.table_nodes}"
        print(f"{a.n_vertices:8,d} {1e3 * run['increment']:12.3f} {'up' if a.success else 'NOT':>8} "
              f"{1e3 * a.squeeze_depth:8.3f} {a.finger_force:8.3f} {patches:>20} {a.seconds:6.1f}", flush=True)
    body, opts = scene.body(None), scene.pickup_options()
    geometry = scene.geometry()
    pinned = replace(geometry, embed_points=True)  # the default
    entry = reference_entry(runs, points, body.weight)
    ref = runs[-1]["answer"]
    print(f"reference: the finest run, {1e3 * ref.squeeze_depth:.3f} mm ± {pct(entry['rho']['error'])} and "
          f"{ref.finger_force:.3f} N ± {pct(entry['force']['error'])} ({entry['rho']['method']})")
    if args.write_reference:
        sys.path.insert(0, str(ROOT))  # verification/ (the references file) sits beside the package, not in it
        from verification.converge import references

        references.write_pinned(args.scene, entry)
        print(f"written: {args.scene}'s pinned reference in {references.REFERENCES.relative_to(ROOT)}")
    if args.no_loops:
        return 0
    print(f"{'loop':>25} {'levels: rho* mm':<28} {'rho* mm':>8} {'error':>7} {'force N':>8} {'error':>7} "
          f"{'stated':>15} {'s':>5}")
    for label, geo in (("points as nodes (default)", pinned),
                       ("nearest nodes", replace(geometry, embed_points=False))):
        t0 = time.perf_counter()
        res = pickup(body, opts.replace(accuracy=args.accuracy, geometry=geo))
        seconds = time.perf_counter() - t0
        acc = res.accuracy
        last = acc["levels"][-1]
        levels = ", ".join(f"{1e3 * lv['squeeze_depth']:.2f}" + ("" if lv["success"] else " (not)")
                           for lv in acc["levels"])
        err = acc["estimated_error"]
        stated = f"{pct(err.get('squeeze_depth'))} / {pct(err.get('finger_force'))}"
        verdict = "" if res.success == ref.success else "  wrong verdict"
        print(f"{label:>25} {levels:<28} {1e3 * res.squeeze_depth:8.3f} "
              f"{pct(relative_change(res.squeeze_depth, ref.squeeze_depth)):>7} {last['finger_force']:8.3f} "
              f"{pct(relative_change(last['finger_force'], ref.finger_force)):>7} {stated:>15} {seconds:5.0f}{verdict}",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
