"""Capture a scene's return mappings and replay them: the check behind changes to the relaxation.

``python -m bench.replay capture SCENE`` runs the scene's pickup and records
every call of :func:`fem_grasp.relaxation.relax_contacts` (its arguments and
outcome) to ``bench/out/relaxations_SCENE.pkl``.  ``python -m bench.replay
run FILE`` solves the recorded calls again with the code at hand and prints
the time spent on calls that found a static state and on calls that failed,
and how many calls reached another outcome (statuses, sweep counts, failure
instead of a state, or forces further apart than ``--force-tol`` of the
largest force).  Capture with one version, replay with another, to see that
a change to the sweeps keeps every verdict.
"""

from __future__ import annotations

import argparse
import pickle
import time
from pathlib import Path
from typing import Any

import numpy as np

OUT = Path(__file__).resolve().parent / "out"


def capture(scene_name: str, out: Path, quick: bool = False) -> list[tuple]:
    """Run the scene's pickup, recording each relax_contacts call as (args, kwargs, outcome)."""
    from fem_grasp import relaxation, tracking
    from fem_grasp.pickup import pickup
    from fem_grasp.scene import load_scene, resolve_scene

    calls: list[tuple] = []
    original = tracking.relax_contacts

    def recorded(*args: Any, **kwargs: Any):
        try:
            res = original(*args, **kwargs)
        except relaxation.RelaxationFailure as exc:
            calls.append((args, kwargs, ("fail", str(exc))))
            raise
        calls.append((args, kwargs, ("ok", res.status.copy(), res.sweeps, res.forces.copy())))
        return res

    tracking.relax_contacts = recorded
    try:
        scene = load_scene(resolve_scene(scene_name), quick=quick)
        result = pickup(scene.body(), **scene.pickup_kwargs())
    finally:
        tracking.relax_contacts = original
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_bytes(pickle.dumps(calls))
    ok = sum(c[2][0] == "ok" for c in calls)
    print(f"scene {scene_name}: picked up {result.success}; {len(calls)} return mappings ({ok} found a state, "
          f"{len(calls) - ok} failed) written to {out}")
    return calls


def replay(path: Path, force_tol: float = 1e-9) -> dict[str, Any]:
    """Solve the recorded calls again; times by outcome and the calls whose outcome changed."""
    from fem_grasp import relaxation

    if hasattr(relaxation, "as_kernel_data"):  # the sweeps of fem_grasp.gauss_seidel
        from fem_grasp import jit

        backend = f"{jit.backend_name()} sweeps"
    else:
        backend = "the plain-Python sweeps of fem_grasp.relaxation (before fem_grasp.jit)"
    calls = pickle.loads(path.read_bytes())
    times = {"ok": 0.0, "fail": 0.0}
    changed: list[str] = []
    for i, (args, kwargs, before) in enumerate(calls):
        t = time.perf_counter()
        try:
            res = relaxation.relax_contacts(*args, **kwargs)
            now: tuple = ("ok", res.status, res.sweeps, res.forces)
        except relaxation.RelaxationFailure as exc:
            now = ("fail", str(exc))
        times[now[0]] += time.perf_counter() - t
        if now[0] != before[0]:
            changed.append(f"call {i}: {before[0]} -> {now[0]}")
        elif now[0] == "ok":
            if not np.array_equal(now[1], before[1]) or now[2] != before[2]:
                changed.append(f"call {i}: statuses or sweeps differ ({before[2]} -> {now[2]} sweeps)")
            else:
                scale = max(float(np.abs(before[3]).max()), 1e-300)
                diff = float(np.abs(now[3] - before[3]).max()) / scale
                if diff > force_tol:
                    changed.append(f"call {i}: forces differ by {diff:.1e} of the largest")
    n_ok = sum(c[2][0] == "ok" for c in calls)
    print(f"{path.name}: {len(calls)} calls with {backend}; {n_ok} that found a state "
          f"{times['ok']:.2f} s, {len(calls) - n_ok} that failed {times['fail']:.2f} s; "
          f"{len(changed)} with another outcome")
    for line in changed[:20]:
        print("  " + line)
    return {"calls": len(calls), "times": times, "changed": changed}


def main(argv: list[str] | None = None) -> dict[str, Any] | list:
    ap = argparse.ArgumentParser(prog="python -m bench.replay", description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    cap = sub.add_parser("capture", help="record a scene's return mappings")
    cap.add_argument("scene")
    cap.add_argument("--out", type=Path, help="default bench/out/relaxations_SCENE.pkl")
    cap.add_argument("--quick", action="store_true", help="the scene's quick variant")
    run = sub.add_parser("run", help="replay recorded return mappings")
    run.add_argument("file", type=Path)
    run.add_argument("--force-tol", type=float, default=1e-9)
    args = ap.parse_args(argv)
    if args.cmd == "capture":
        return capture(args.scene, args.out or OUT / f"relaxations_{args.scene}.pkl", args.quick)
    return replay(args.file, args.force_tol)


if __name__ == "__main__":
    main()
