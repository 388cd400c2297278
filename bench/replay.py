"""Capture a scene's return mappings and replay them: the check behind changes to the relaxation.

``python -m bench.replay capture SCENE`` runs the scene's pickup and records
every call of :func:`fem_grasp.contact.relaxation.relax_contacts` (its arguments and
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
    from fem_grasp.contact import implicit_step, relaxation  # the implicit step is what calls relax_contacts
    from fem_grasp.grasp.pickup import pickup
    from fem_grasp.io.scene import load_scene, resolve_scene

    calls: list[tuple] = []
    original = implicit_step.relax_contacts

    def recorded(*args: Any, **kwargs: Any):
        try:
            res = original(*args, **kwargs)
        except relaxation.RelaxationFailure as exc:
            calls.append((args, kwargs, ("fail", str(exc))))
            raise
        calls.append((args, kwargs, ("ok", res.status.copy(), res.sweeps, res.forces.copy())))
        return res

    implicit_step.relax_contacts = recorded
    try:
        scene = load_scene(resolve_scene(scene_name), quick=quick)
        result = pickup(scene.body(), **scene.pickup_kwargs())
    finally:
        implicit_step.relax_contacts = original
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_bytes(pickle.dumps(calls))
    ok = sum(c[2][0] == "ok" for c in calls)
    print(f"scene {scene_name}: picked up {result.success}; {len(calls)} return mappings ({ok} found a state, "
          f"{len(calls) - ok} failed) written to {out}")
    return calls


def _watch_polish(relaxation: Any) -> tuple[list[tuple[bool, list]], Any]:
    """Wrap the relaxation's polish to record, per attempt, whether it converged with its statuses holding and the step fractions
    its line search took (None: no decrease); returns the records and a function that unwraps."""
    polish, backtrack = relaxation._polish, relaxation._backtrack
    records: list[tuple[bool, list]] = []
    steps: list = []

    def watched_backtrack(*args: Any) -> Any:
        found = backtrack(*args)
        steps.append(None if found is None else found[0])
        return found

    def watched_polish(*args: Any, **kwargs: Any) -> Any:
        steps.clear()
        out = polish(*args, **kwargs)
        records.append((out is not None and out.holds, list(steps)))
        return out

    relaxation._polish, relaxation._backtrack = watched_polish, watched_backtrack

    def unwrap() -> None:
        relaxation._polish, relaxation._backtrack = polish, backtrack

    return records, unwrap


def replay(path: Path, force_tol: float = 1e-9, polish_halvings: int | None = None) -> dict[str, Any]:
    """Solve the recorded calls again; times by outcome, the calls whose outcome changed, and how the
    Newton polish of the return mappings fared (``polish_halvings`` overrides the setting of that name for the
    replay)."""
    from fem_grasp.contact import relaxation

    if hasattr(relaxation, "as_kernel_data"):  # the sweeps of fem_grasp.contact.kernels.gauss_seidel
        from fem_grasp.contact.kernels import jit

        backend = f"{jit.backend_name()} sweeps"
    else:
        backend = "the plain-Python sweeps of fem_grasp.contact.relaxation (before fem_grasp.contact.kernels.jit)"
    calls = pickle.loads(path.read_bytes())
    times = {"ok": 0.0, "fail": 0.0}
    changed: list[str] = []
    outcomes = []
    # The polish watched is the numpy one (the compiled kernel runs the same iteration, tests/contact/test_polish.py,
    # but its line search cannot be watched from here): every call runs with these settings, whatever it recorded.
    from fem_grasp.settings import DEFAULT_SETTINGS

    settings = DEFAULT_SETTINGS.replace(compiled_polish=False, **(
        {} if polish_halvings is None else {"polish_halvings": polish_halvings}))
    records, unwrap = _watch_polish(relaxation)
    try:
        for args, kwargs, _ in calls:
            t = time.perf_counter()
            try:
                res = relaxation.relax_contacts(*args, **{**kwargs, "settings": settings})
                now: tuple = ("ok", res.status, res.sweeps, res.forces)
            except relaxation.RelaxationFailure as exc:
                now = ("fail", str(exc))
            times[now[0]] += time.perf_counter() - t
            outcomes.append(now)
    finally:
        unwrap()
    for i, ((_, _, before), now) in enumerate(zip(calls, outcomes)):
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
    converged = [st for ok, st in records if ok]
    failed = [st for ok, st in records if not ok]

    def cut(st: list, first: int | None = None) -> bool:  # a step cut below 1/8, or none decreasing
        return any(x is None or x < 0.125 for x in st[:first])

    polish = {"attempts": len(records), "converged": len(converged),
              "converged_cut_below_eighth": sum(cut(st) for st in converged),
              "failed_cut_below_eighth_in_three_steps": sum(cut(st, 3) for st in failed)}
    print(f"polish (Newton on fixed statuses, steps halved {settings.polish_halvings}"
          f" times at most): {polish['attempts']} attempts, {polish['converged']} converged; a step cut below 1/8 "
          f"in {polish['converged_cut_below_eighth']} that converged, within three steps in "
          f"{polish['failed_cut_below_eighth_in_three_steps']} that failed")
    return {"calls": len(calls), "times": times, "changed": changed, "polish": polish}


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
    run.add_argument("--polish-halvings", type=int,
                     help="halvings of a polish step before the polish gives up (default: the library's)")
    args = ap.parse_args(argv)
    if args.cmd == "capture":
        return capture(args.scene, args.out or OUT / f"relaxations_{args.scene}.pkl", args.quick)
    return replay(args.file, args.force_tol, args.polish_halvings)


if __name__ == "__main__":
    main()
