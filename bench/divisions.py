"""The passing increment divided (``PickupOptions.step_divisions``) against the finer increment throughout.

``python -m bench.divisions [--divisions D] [--reps N] [SCENE ...]`` (section ``divisions`` of ``make bench``):
per shipped scene, the pickup at its own squeeze increment s, at s with the increment in which the lift test
first passes squeezed again in D sub-increments, and at s/D throughout — ρ*, Σ f·n̂, the largest difference of a
finger's resultant from the s/D run (× mg), the number of lift tests and the median wall time, from one run.
"""

from __future__ import annotations

import argparse
import statistics
import time
from typing import Any

import numpy as np

SCENES = ("tomato", "orange", "steam_bun", "football", "foam_block")


def measure(names: tuple[str, ...] = SCENES, divisions: int = 4, reps: int = 3) -> dict[str, Any]:
    """Per scene and variant ("s", "s divided", "s/D"): ρ*, Σ f·n̂, each finger's resultant, lift tests, median
    seconds (after a first call per scene that is not timed)."""
    from fem_grasp.grasp.pickup import pickup
    from fem_grasp.io.scene import load_scene, resolve_scene

    out: dict[str, Any] = {"divisions": divisions, "reps": reps, "scenes": {}}
    for name in names:
        scene = load_scene(resolve_scene(name))
        body = scene.body(None)
        opts = scene.pickup_options()
        s = pickup(body, opts).step  # also the untimed first call
        variants = {"s": opts.replace(step=s), "s divided": opts.replace(step=s, step_divisions=divisions),
                    f"s/{divisions}": opts.replace(step=s / divisions)}
        rows: dict[str, Any] = {}
        for label, o in variants.items():
            times = []
            for _ in range(reps):
                t0 = time.perf_counter()
                r = pickup(body, o)
                times.append(time.perf_counter() - t0)
            rows[label] = {"success": bool(r.success), "squeeze_depth": float(r.squeeze_depth),
                           "finger_force": float(r.finger_normal_force),
                           "resultants": [np.asarray(f.resultant, float).tolist() for f in (r.finger_forces or [])],
                           "lift_tests": len(r.liftable), "seconds": statistics.median(times)}
        out["scenes"][name] = {"step": s, "weight": float(body.weight), "rows": rows}
    return out


def print_divisions(sec: dict[str, Any]) -> None:
    d = sec["divisions"]
    print(f"\n== divisions: the passing increment in {d} sub-increments against increment s/{d} throughout "
          f"(medians of {sec['reps']})")
    print(f"{'scene':11s} {'variant':11s} {'rho* (mm)':>10s} {'sum f.n (N)':>12s} {'finger |dF|/mg':>15s} "
          f"{'lift tests':>10s} {'time (s)':>9s}")
    for name, sc in sec["scenes"].items():
        fine = sc["rows"][f"s/{d}"]
        for label, row in sc["rows"].items():
            gap = max((float(np.linalg.norm(np.subtract(a, b))) for a, b in zip(row["resultants"], fine["resultants"])),
                      default=float("nan")) / sc["weight"]
            print(f"{name:11s} {label:11s} {1e3 * row['squeeze_depth']:10.4f} {row['finger_force']:12.4f} "
                  f"{gap:15.4f} {row['lift_tests']:10d} {row['seconds']:9.2f}")
        print(f"{'':11s} |rho* divided - rho* s/{d}| = "
              f"{abs(sc['rows']['s divided']['squeeze_depth'] - fine['squeeze_depth']) / (sc['step'] / d):.2f} "
              f"sub-increments")


def main(argv: list[str] | None = None) -> dict[str, Any]:
    ap = argparse.ArgumentParser(prog="python -m bench.divisions", description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="*", default=list(SCENES), help=f"shipped scenes (default: {' '.join(SCENES)})")
    ap.add_argument("--divisions", type=int, default=4)
    ap.add_argument("--reps", type=int, default=3)
    args = ap.parse_args(argv)
    sec = measure(tuple(args.scenes), args.divisions, args.reps)
    print_divisions(sec)
    return sec


if __name__ == "__main__":
    main()
