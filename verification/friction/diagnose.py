"""Cross-examination: both lift tests on the *same* squeeze state (a diagnostic, not part of the reference).

When fem_grasp and the reference disagree on the liftable weight w(ρ) at some
lift test, the disagreement has two possible sources: their squeeze states
differ (the paths are O(Δρ) apart), or their lift tests answer differently
for the same state.  This module separates them: it takes the reference's
squeeze state at ρ_l, hands it to fem_grasp's own lift test (its
``Tracker.make_state`` and ``LiftTest.update``) and to the reference's, with
the same w(ρ_{l−1}), and reports both answers together with the hanging
states each one reached.

Unlike the reference itself, this module imports fem_grasp's internals
(``fem_grasp.tracking``, ``fem_grasp.lift_test``): it is a cross-examination
tool, and its import paths follow the package's layout.

    python -m verification friction diagnose SCENE [--increments M] [--step-divisor D] [--rho RHO_MM]
"""

from __future__ import annotations

import argparse
import logging
import sys
from typing import Any

from .compare import Case, load_case, start_from_fem_rest
from .reference.contact import FINGER1, FINGER2, SLIP, STICK, StaticState

log = logging.getLogger(__name__)


def fem_lift_test(case: Case, state: StaticState, rho: float, w_prev: float) -> dict[str, Any]:
    """fem_grasp's lift test (its code) on a reference squeeze state; w and the verdict of each trial weight."""
    from fem_grasp.contact.tracking import Tracker
    from fem_grasp.grasp import lift_test as flt

    res = case.result
    posed = res.body
    body = case.ref.body
    hanging = Tracker(posed, radius=res.finger_radius, mu_finger=res.mu_finger, mu_table=res.mu_table, table=None)
    disp = state.positions(body)[body.slot[state.nodes]] - posed.mesh.points[state.nodes]
    st = hanging.make_state(phase="squeeze", squeeze_depth=rho, lift_height=0.0, load=1.0,
                            centers=state.obstacles.centers, nodes=state.nodes, owner=state.owner, disp=disp,
                            sliding=state.status == SLIP)
    lt = flt.LiftTest(hanging, posed.weight, case.scenario.lift_test_step)
    lt.liftable = w_prev
    trials = []
    orig = flt.hang

    def spy(tracker, start, weight, **kw):
        out = orig(tracker, start, weight, **kw)
        if out.state is not None:
            on = [out.state.owner == f for f in (FINGER1, FINGER2)]
            trials.append({"weight": weight, "held": out.held, "reason": out.reason,
                           "contacts": [int(o.sum()) for o in on],
                           "sticking": [int((o & ~out.state.sliding).sum()) for o in on]})
        else:
            trials.append({"weight": weight, "held": out.held, "reason": out.reason})
        return out

    flt.hang = spy
    try:
        w = lt.update(st)
    finally:
        flt.hang = orig
    return {"w": w, "trials": trials}


def ref_lift_test(case: Case, state: StaticState, w_prev: float) -> dict[str, Any]:
    """The reference's lift test on the same state, with the verdict of each trial weight."""
    ref = case.ref
    trials = []
    orig = ref.hang

    def spy(start, weight, depth=3):
        held, why, st = orig(start, weight, depth)
        row = {"weight": weight, "held": held, "reason": why}
        if st is not None:
            on = [st.owner == f for f in (FINGER1, FINGER2)]
            row.update(contacts=[int(o.sum()) for o in on], sticking=[int(((st.status == STICK) & o).sum()) for o in on])
        trials.append(row)
        return held, why, st

    ref.hang = spy
    try:
        w = ref.liftable(state)
    finally:
        del ref.hang
    return {"w": w, "trials": trials}


def cross_examine(case: Case, increments: int, rhos: list[float] | None = None) -> list[dict[str, Any]]:
    """At every lift test where w(ρ) differs (or at ``rhos``), both lift tests on the reference's squeeze state."""
    start, _ = start_from_fem_rest(case)
    out = case.ref.run(start, increments)
    fw = dict(case.result.liftable)
    w_ref = dict(out.liftable)
    rows = []
    prev_ref = 0.0
    for rho, w in out.liftable:
        want = rhos is not None and any(abs(rho - r) <= 2e-3 * r for r in rhos)  # depths given to 4 digits
        differs = rho in fw and abs(fw[rho] - w) > 1e-9 * case.scenario.weight
        if (rhos is None and differs) or want:
            st = case.ref.squeeze_state_at(out, rho, increments)
            rows.append({"rho": rho, "w_prev": prev_ref, "fem_grasp_path": fw.get(rho), "reference_path": w,
                         "fem_grasp_on_reference_state": fem_lift_test(case, st, rho, prev_ref),
                         "reference_on_reference_state": ref_lift_test(case, st, prev_ref)})
        prev_ref = w_ref[rho]
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m verification friction diagnose", description=__doc__.splitlines()[0])
    p.add_argument("scene")
    p.add_argument("--increments", type=int, default=4)
    p.add_argument("--quick", action="store_true")
    p.add_argument("--step-divisor", type=float, default=1.0, help="run fem_grasp at its default step / this")
    p.add_argument("--rho", type=float, action="append", help="lift-test depth to examine, mm (default: where w differs)")
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    case = load_case(args.scene, quick=args.quick)
    if args.step_divisor != 1.0:
        case = load_case(args.scene, quick=args.quick, step=case.result.step / args.step_divisor)
    rows = cross_examine(case, args.increments, None if not args.rho else [r * 1e-3 for r in args.rho])
    for r in rows:
        f, g = r["fem_grasp_on_reference_state"], r["reference_on_reference_state"]
        print(f"ρ = {r['rho'] * 1e3:.4f} mm, w(ρ_prev) = {r['w_prev']:.4g} N: along its own path fem_grasp w = "
              f"{r['fem_grasp_path']}, reference w = {r['reference_path']:.4g}; on the reference's squeeze state: "
              f"fem_grasp's lift test w = {f['w']:.4g}, the reference's w = {g['w']:.4g}")
        for name, d in (("fem_grasp", f), ("reference", g)):
            for t in d["trials"]:
                print(f"    {name:9s} w = {t['weight']:.4g}: {'held' if t['held'] else 'not held'}"
                      f"{' (' + t['reason'] + ')' if t['reason'] else ''}"
                      + (f", contacts {t['contacts']}, sticking {t['sticking']}" if "contacts" in t else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
