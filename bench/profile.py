"""Where a pickup spends its time: ``python -m bench.profile SCENE``.

Runs one shipped scene's pickup (``fem-grasp run SCENE``) under cProfile and
counts, around the two solvers that dominate it:

* the return mappings (:func:`fem_grasp.contact.relaxation.relax_contacts`) of the
  lift test and of implicit increments: calls that find a static state and
  calls that fail, with their times;
* the slip systems of the event tracking
  (``solve`` of :class:`~fem_grasp.contact.slip_system.CompiledSlipSystem`, or of
  :class:`~fem_grasp.contact.slip_system.MixedSlipSystem` on the reference path): Newton solves and
  Newton-homotopy paths, by outcome;
* the trial states of the event tracking (:meth:`fem_grasp.contact.tracking.Tracker.trial`,
  one slip-system solve and surface field each) per event.

Prints the phase times, the counters and the functions with the largest
cumulative time.  Profiling slows the run by 1.5–2×; compare runs of one
invocation, or phases within one run.  ``--free-blas`` leaves OpenBLAS its
threads during tracking (by default ``tracking.run`` limits BLAS to one).
``--after-first`` profiles a second pickup of the same body, after an unprofiled first one (the body's
factorisation and compliance columns, the kernels' loading): where a pickup's own time goes.
``--orange N`` profiles the pickup of ``make bench``'s scaling section at
about N vertices instead of a scene (``--sort tottime`` lists the functions
by their own time).
"""

from __future__ import annotations

import argparse
import collections
import cProfile
import io
import pstats
import time
from typing import Any


def main(argv: list[str] | None = None) -> dict[str, Any]:
    ap = argparse.ArgumentParser(prog="python -m bench.profile", description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", nargs="?", help="a shipped scene name or a scene file")
    ap.add_argument("--orange", type=int, metavar="N",
                    help="instead of a scene, the scaling section's uniform orange of about N vertices "
                         "(make bench; its rest is computed before profiling)")
    ap.add_argument("--sort", default="cumulative", choices=("cumulative", "tottime"),
                    help="order of the cProfile table (default cumulative)")
    ap.add_argument("--quick", action="store_true", help="the scene's quick variant")
    ap.add_argument("--top", type=int, default=25, help="functions to list (default 25)")
    ap.add_argument("--free-blas", action="store_true", help="do not limit BLAS to one thread while tracking")
    ap.add_argument("--after-first", action="store_true",
                    help="profile a second pickup of the same body (the first, timed but not profiled, pays the "
                         "body's factorisation, compliance columns and kernel loading)")
    args = ap.parse_args(argv)
    if (args.scene is None) == (args.orange is None):
        ap.error("give a scene or --orange N")

    import contextlib

    from fem_grasp.contact import implicit_step, relaxation, tracking
    from fem_grasp.grasp.pickup import pickup
    from fem_grasp.io.scene import load_scene, resolve_scene

    relax_stats: dict[str, list[float]] = collections.defaultdict(lambda: [0, 0.0])
    slip_stats: dict[tuple[str, str, str], list[float]] = collections.defaultdict(lambda: [0, 0.0])
    relax = implicit_step.relax_contacts  # (called by the tracker's implicit step)
    # The slip systems the trackers build (compiled where numba is installed; the homotopy of a compiled system is
    # its reference's, counted once, as the compiled system's).
    compiled = tracking.Tracker.default_settings.compiled_trials
    compiled = tracking.COMPILED_TRIALS if compiled is None else compiled
    system = tracking.CompiledSlipSystem if compiled else tracking.MixedSlipSystem
    solve = system.solve
    trial = tracking.Tracker.trial
    trials = [0]

    def counted_trial(*a: Any, **k: Any) -> Any:
        trials[0] += 1
        return trial(*a, **k)

    def counted_relax(*a: Any, **k: Any) -> Any:
        t0 = time.perf_counter()
        key = "found a static state"
        try:
            return relax(*a, **k)
        except relaxation.RelaxationFailure:
            key = "failed"
            raise
        finally:
            relax_stats[key][0] += 1
            relax_stats[key][1] += time.perf_counter() - t0

    def counted_solve(self: Any, *a: Any, methods: Any = ("newton", "homotopy"), **k: Any) -> Any:
        t0 = time.perf_counter()
        outcome = "root"
        try:
            return solve(self, *a, methods=methods, **k)
        except tracking.SlipFailure:
            outcome = "no root"
            raise
        finally:
            key = ("+".join(methods), "free direction" if self.free else "great circle", outcome)
            slip_stats[key][0] += 1
            slip_stats[key][1] += time.perf_counter() - t0

    # The whole-trial kernel's Newton from zero slip on the first form (the solves that never reach ``solve``).
    from fem_grasp.contact.kernels import slip_trial
    from fem_grasp.contact.warm_up import warm_up

    warm_up()  # compiled now: a kernel's first call would put the compiled kernels over the counting wrapper
    newton_trial = slip_trial.newton_trial

    def counted_newton_trial(*a: Any) -> Any:
        t0 = time.perf_counter()
        out = newton_trial(*a)
        if out[0] != slip_trial.TRIAL_NO_DIRECTION:
            key = ("newton", "free direction" if a[18] else "great circle",
                   "no root" if out[0] == slip_trial.TRIAL_NO_ROOT else "root")
            slip_stats[key][0] += 1
            slip_stats[key][1] += time.perf_counter() - t0
        return out

    limit = getattr(tracking, "one_blas_thread", None)
    implicit_step.relax_contacts = counted_relax
    system.solve = counted_solve
    slip_trial.newton_trial = counted_newton_trial
    tracking.Tracker.trial = counted_trial
    if args.free_blas and limit is not None:
        tracking.one_blas_thread = contextlib.nullcontext
    if args.orange:
        from bench.bench import SCALING_YOUNG, orange_body
        from bench.meshes import cached_mesh
        from fem_grasp import rest
        from fem_grasp.grasp.objects import PAPER_PLACEMENT_RULE
        from fem_grasp.grasp.pickup import DEFAULT_FRICTION

        name = f"orange of {args.orange} vertices"
        body = orange_body(cached_mesh("orange", args.orange), SCALING_YOUNG)
        mu = DEFAULT_FRICTION
        kwargs = {"mu_finger": mu, "mu_table": mu, "rest_state": rest(body, mu),
                  "placement_rule": PAPER_PLACEMENT_RULE}
    else:
        scene = load_scene(resolve_scene(args.scene), quick=args.quick)
        name = scene.name + (" (quick)" if args.quick else "")
        body = scene.body()
        kwargs = scene.pickup_kwargs()
    prof = cProfile.Profile()
    first = None
    t0 = time.perf_counter()
    try:
        if args.after_first:
            pickup(body, **kwargs)
            first = time.perf_counter() - t0
            relax_stats.clear()
            slip_stats.clear()
            trials[0] = 0
            t0 = time.perf_counter()
        prof.enable()
        res = pickup(body, **kwargs)
    finally:
        prof.disable()
        implicit_step.relax_contacts = relax
        system.solve = solve
        slip_trial.newton_trial = newton_trial
        tracking.Tracker.trial = trial
        if limit is not None:
            tracking.one_blas_thread = limit
    wall = time.perf_counter() - t0

    print(f"scene {name}: {'picked up' if res.success else res.reason}; "
          f"{len(res.events)} events; {wall:.1f} s under cProfile"
          f"{' (BLAS threads free)' if args.free_blas else ''}"
          f"{f', after a first pickup of {first:.2f} s (not profiled)' if first is not None else ''}")
    print("phases: " + ", ".join(f"{k} {v:.2f} s" for k, v in res.timings.items()))
    print(f"trial states (Tracker.trial): {trials[0]}, {trials[0] / max(len(res.events), 1):.1f} per event")
    print("return mappings (relax_contacts):")
    for key, (n, t) in sorted(relax_stats.items()):
        print(f"  {key:>22s}: {int(n):5d} calls, {t:7.2f} s, {t / max(n, 1) * 1e3:7.1f} ms each")
    print(f"slip systems ({system.__name__}.solve):")
    for (meth, form, outcome), (n, t) in sorted(slip_stats.items(), key=lambda kv: -kv[1][1]):
        print(f"  {meth:>8s} {form:>14s} {outcome:>7s}: {int(n):6d} calls, {t:7.2f} s")
    out = io.StringIO()
    pstats.Stats(prof, stream=out).sort_stats(args.sort).print_stats(args.top)
    print(out.getvalue())
    return {"wall_s": wall, "first_s": first, "timings": res.timings, "trials": trials[0], "events": len(res.events), "relax": dict(relax_stats),
            "slip": {"/".join(k): v for k, v in slip_stats.items()}}


if __name__ == "__main__":
    main()
