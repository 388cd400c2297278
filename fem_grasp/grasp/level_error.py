"""The error a level of the accuracy loop states for its answer (:mod:`fem_grasp.grasp.accuracy`).

A level's answer (a :class:`~fem_grasp.grasp.answer.GraspAnswer`) is compared with the level before it: the
error it states is :data:`TWO_LEVEL_SAFETY` times their difference or, from the third level on, the larger of
that and the uncertainty of the last three levels (:func:`three_level_errors`, the procedure of Eça and
Hoekstra in :mod:`fem_grasp.grasp.estimates`), plus the resolution of ρ* (:func:`estimated_error`).  The
arithmetic on plain numbers is :mod:`~fem_grasp.grasp.estimates`; this module reads it off the levels' answers.

The verdict has no error of its own but can be unsettled (:func:`unsettled_verdict`): when the last two levels
disagree on it, when both fail and the largest weight the fingers held lies within its estimated error of
the object's weight, or when both lift it at a ρ* within its estimated error of the deepest squeeze.  On fine
meshes the fingertips hold more (a P1 patch is too stiff, and too few nodes touch):
of the coverage study's random objects at 5 %, two whose last two levels failed with the largest weight held
one or two steps h below mg were lifted by the finer reference, and the bare difference of that weight between
the levels (one step, 5 % of mg) would have called one of those failures converged at 10 %.
"""

from __future__ import annotations

from typing import Any, Sequence

from .answer import GraspAnswer, failure_kind, passed
from .estimates import sequence_uncertainty

__all__ = ["LIFT_ATTEMPT_FAILURES", "TWO_LEVEL_SAFETY", "estimated_error", "force_factor", "found_by_lift_test",
           "three_level_errors", "unsettled_verdict"]

#: Failures (:func:`~fem_grasp.grasp.answer.failure_kind`) whose ρ is the depth of the last lift attempt: the lift
#: test passed there and the simulated lift did not hold (Algorithm 1 steps 5-6).
LIFT_ATTEMPT_FAILURES = ("lift failed", "slides on the finger", "still on the table")


def found_by_lift_test(ans: Any) -> bool:
    """Whether the answer's ρ is a depth at which the lift test passed — ρ*, or the last lift attempt of a pickup
    whose lift failed — and so found up to one resolution late; not where a squeeze stopped at the deepest
    squeeze (a setting) or at an event."""
    return ans.squeeze_depth > 0 and (passed(ans) or failure_kind(ans.reason) in LIFT_ATTEMPT_FAILURES)


def three_level_errors(levels: Sequence[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Per quantity (ρ* and Σ f·n̂), :func:`~fem_grasp.grasp.estimates.sequence_uncertainty` of the last three
    levels (records as :meth:`~fem_grasp.grasp.accuracy.AccuracyLevel.to_dict` writes them), when all three
    lifted the object (the verdict the levels compare) at decreasing patch spacings; else empty (a failed
    pickup's ρ* is where the squeeze stopped, not a converging quantity)."""
    last = list(levels)[-3:]
    if len(last) < 3 or not all((lv["success"] or "lift was not run" in lv.get("reason", ""))
                                and (lv.get("squeeze_depth") or 0.0) > 0 for lv in last):
        return {}
    sizes = [float(lv["inner_size"]) for lv in last]
    if not sizes[0] > sizes[1] > sizes[2] > 0:
        return {}
    # each level's quantisation: ρ* up to one resolution late, the force about in proportion
    res = [float(lv.get("resolution") or 0.0) / float(lv["squeeze_depth"]) for lv in last]
    return {q: sequence_uncertainty([float(lv[q]) for lv in last], sizes, [x * abs(float(lv[q])) for x, lv in
                                                                           zip(res, last)])
            for q in ("squeeze_depth", "finger_force")}


#: Roache's factor of safety for an error estimated from two levels (the grid convergence index of a two-grid
#: study, 3; with three levels their uncertainty takes its place): two levels that agree may agree by chance.
#: The coverage study at 20 %, where every level grasps at one placement, converged on two levels on four of nine
#: objects, and their difference alone missed the actual error on two (5.2 % stated against 5.3 %, 14 % against
#: 17 %).
TWO_LEVEL_SAFETY = 3.0


def force_factor(ans: GraspAnswer) -> float:
    """How many times ρ*'s relative error carries into the force read at ρ*: the force's exponent over ρ
    (:func:`~fem_grasp.grasp.answer.force_exponent`), never less than 1 (a force that grows more slowly near the
    lift-off is not relied on to damp the error)."""
    return max(1.0, ans.force_exponent)


def estimated_error(change: dict[str, float], ans: GraspAnswer,
                    three_levels: dict[str, dict[str, Any]] | None = None) -> dict[str, float]:
    """Relative error of a level's answer: :data:`TWO_LEVEL_SAFETY` × its change from the level before — or,
    where the last three levels lifted the object, the larger of that and their uncertainty (``three_levels``,
    :func:`three_level_errors`) — plus, for a level whose ρ the lift test found (:func:`found_by_lift_test`: ρ*,
    or a failed lift's last attempt), its resolution (it is found up to one increment, or sub-increment, late,
    and the finger force grows with ρ*, about in proportion near the lift-off) — and, as it is read at ρ*, at
    least ρ*'s error times the force's exponent over ρ (:func:`~fem_grasp.grasp.answer.force_exponent`, at
    least 1).  The coverage study's seed 4 at 5 % with nested
    levels: ρ* 15.61, 15.81, 16.00 mm stated 4.9 %, 3.8 % short of the reference; its forces 30.63, 28.65,
    28.81 N stated 3.9 %, 5.3 % short: the force errs by more than ρ* does (by 1.0 to 1.7 times on the study's
    lifted objects), as a force growing as ρ^1.5 does.  For ρ* the change itself is
    known only to a resolution (two levels on one grid of depths find the same ρ* wherever theirs lie within one
    step of it), so its part is at least one resolution: ρ*'s estimate is at least two.

    Three levels never state less than the last two would.  Remeshed levels are not in an asymptotic range:
    meshes of one spacing differ by a few per cent in ρ* and the force, as much as two levels do, so a third level
    that seems to converge (an oscillation that contracts, a monotone sequence with an order) may do so by chance.
    Stating the larger of their uncertainty and the last change alone (Eça and Hoekstra's procedure for grids in
    the asymptotic range) understated the error twice in the measurements: a random ellipsoid of the coverage
    study at 20 % (forces 11.19, 12.17, 11.84 N, oscillating: 7.0 % stated, 7.4 % off the finer reference) and a
    draw of the football's meshes (ρ* 4.196, 4.773, 4.721 mm: 2.2 % stated, 3.0 % off).  Where three levels do not
    converge ("scatter") their spread is net of each level's quantisation of ρ*, and where every difference lies
    within it (the tomato's levels at 5 %: 9.42, 9.33, 9.22 mm, each a resolution apart, 2.9 % from the
    reference) that spread is nil although the levels drift.
    """
    q = ans.resolution / ans.squeeze_depth if found_by_lift_test(ans) else 0.0
    three = three_levels or {}
    out = {}
    for k in ("squeeze_depth", "finger_force"):
        two = TWO_LEVEL_SAFETY * change[k]
        mesh = max(two, three[k]["relative"]) if k in three else two
        # Two levels whose ρ* differ by less than a resolution may find the same one (on a common grid of
        # depths they do): the mesh's part of ρ*'s error is stated as at least one resolution.
        out[k] = (max(mesh, q) if k == "squeeze_depth" else mesh) + q
    if passed(ans):
        # The force is read at ρ*: where ρ* is off, so is the force, by its exponent over ρ.
        out["finger_force"] = max(out["finger_force"], force_factor(ans) * out["squeeze_depth"])
    if "max_liftable" in change:  # two failures: the largest weight held (relative to mg), as the others
        out["max_liftable"] = TWO_LEVEL_SAFETY * change["max_liftable"]
    return out


def unsettled_verdict(ans: GraspAnswer, before: GraspAnswer, error: dict[str, float]) -> str:
    """Why the verdict of a level (``ans``, after ``before``, with the ``error`` :func:`estimated_error` states
    for it) is not settled at its resolution; empty when it is (module notes).

    A failure is unsettled when the largest weight held, w_max, is within its estimated error of the weight:
    w_max + error["max_liftable"] · mg ≥ mg.  A success is unsettled when ρ* is within its estimated error of
    the deepest squeeze the pickup makes: a finer mesh whose ρ* lies beyond it does not lift the object.
    """
    if passed(ans) != passed(before):
        return "the last two levels give different verdicts"
    if passed(ans):
        rho, e = ans.squeeze_depth, error.get("squeeze_depth", 0.0)
        if rho * (1.0 + e) < ans.max_squeeze:
            return ""
        return (f"rho* = {1e3 * rho:.4g} mm lies within its estimated error ({100 * e:.2g} %) of the deepest squeeze, "
                f"{1e3 * ans.max_squeeze:.4g} mm: a finer mesh may not lift it")
    if "max_liftable" not in error:
        return ""
    w, mg, e = ans.max_liftable, ans.weight, error["max_liftable"]
    if w + e * mg < mg * (1.0 - 1e-12):
        return ""
    return (f"the fingers held up to {w:.4g} N, and the weight {mg:.4g} N lies within the estimated error of that "
            f"({100 * e:.2g} % of the weight): a finer mesh may lift it")
