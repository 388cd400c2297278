"""The error of a refinement sequence (fem_grasp.grasp.estimates): Richardson extrapolation and the three-level
uncertainty of the accuracy loop, on sequences whose limit is known."""

import dataclasses
import math

import numpy as np
import pytest

from fem_grasp.grasp.estimates import estimate, observed_order, relative_change, sequence_uncertainty
from fem_grasp.grasp.level_error import TWO_LEVEL_SAFETY, estimated_error, three_level_errors, unsettled_verdict

H = np.array([0.4, 0.2, 0.1])  # patch spacings of three levels, ratio 2 as the loop's


def test_richardson_recovers_the_limit_and_the_order_of_a_smooth_sequence():
    q = 2.0 + 0.3 * H**1.5
    est = estimate(q, H)
    assert est["method"] == "richardson"
    assert est["order"] == pytest.approx(1.5, abs=1e-6)
    assert est["value"] == pytest.approx(2.0, abs=1e-9)
    assert est["error"] == pytest.approx(0.3 * 0.1**1.5 / 2.0, rel=1e-6)  # the finest value's true error


def test_a_non_monotone_sequence_gets_the_finest_value_with_the_scatter_as_band():
    est = estimate([1.0, 1.3, 1.1], [0.4, 0.2, 0.1])
    assert est["method"] == "band" and est["value"] == 1.1
    assert est["error"] == pytest.approx(0.2 / 1.1)
    assert estimate([1.0], [0.1])["error"] == math.inf
    assert relative_change(1.0, 1.0) == 0.0 and relative_change(1.1, 1.0) == pytest.approx(0.1)


def test_observed_order_of_uneven_spacings():
    h = np.array([0.5, 0.3, 0.1])
    assert observed_order(1.0 - 0.2 * h**0.8, h) == pytest.approx(0.8, abs=1e-9)
    assert observed_order([1.0, 1.2, 1.1], h) is None  # not monotone
    assert observed_order([1.0, 1.2, 1.3], [0.1, 0.2, 0.3]) is None  # sizes not decreasing


@pytest.mark.parametrize("p", [0.3, 0.5, 0.7, 1.0, 1.5, 2.0, 3.0, 4.0])
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_three_monotone_levels_bound_the_true_error_of_the_finest(p, sign):
    """q(h) = q∞ + a hᵖ: the stated uncertainty covers |q₃ − q∞| for every order from 0.3 up, within a factor
    of a few, where the last difference alone under-states it for orders below 1."""
    q = 5.0 + sign * 2.0 * H**p
    u = sequence_uncertainty(q, H)
    true = abs(q[2] - 5.0)
    assert u["error"] >= true * (1 - 1e-9)
    assert u["relative"] == pytest.approx(u["error"] / abs(q[2]))
    if p <= 2:
        assert u["error"] <= 12 * true  # not a vacuous bound
    else:  # faster than order 2: taken as the coarsest level outside the asymptotic range, 1.25 × the spread
        assert u["error"] == pytest.approx(1.25 * (max(q) - min(q)))
    if p >= 0.5:
        assert u["method"] == "monotone" and u["order"] == pytest.approx(p, abs=1e-6)
        if p <= 2:
            assert u["error"] <= 1.25 * true * (1 + 1e-9)
    if p < 1:
        assert abs(q[2] - q[1]) < true  # the two-level difference would not cover it


def test_a_plateau_after_a_large_change_states_the_spread_net_of_quantisation():
    """Two levels that nearly agree after a large change (apparent order above 2) are not taken as converged:
    the next level may move as far as these did, less what each level's own resolution explains."""
    q, res = [3.883, 3.628, 3.610], [0.232, 0.194, 0.181]
    u = sequence_uncertainty(q, H, res)
    assert u["method"] == "monotone" and u["order"] > 2
    assert u["spread"] == pytest.approx(3.883 - 3.610 - 0.232)
    assert u["error"] == pytest.approx(1.25 * u["spread"])
    # the same for a force that oscillates with a contraction below 1/4
    f = sequence_uncertainty([0.782, 0.656, 0.662], H, [0.047, 0.035, 0.033])
    assert f["method"] == "oscillating" and f["error"] == pytest.approx(1.25 * (0.782 - 0.656 - 0.047))
    # changes within the coarser level's resolution leave no spread: ρ* equal on the finer two levels
    assert sequence_uncertainty([2.268, 2.013, 2.013], H, [0.252, 0.028, 0.025])["error"] == pytest.approx(
        1.25 * 0.003, abs=1e-12)


def test_levels_that_oscillate_and_contract_state_their_last_difference():
    c = 0.3
    q = [7.0 + 1.5 * (-c) ** k for k in range(3)]
    u = sequence_uncertainty(q, H)
    assert u["method"] == "oscillating" and u["contraction"] == pytest.approx(c)
    assert u["error"] == pytest.approx(abs(q[2] - q[1]))
    assert u["error"] >= 3 * abs(q[2] - 7.0) * (1 - 1e-12)  # three times the alternating series' remainder


@pytest.mark.parametrize("q", [[9.42, 12.68, 8.95],  # a swing wider than the change before it
                               [1.0, 1.8, 2.5],  # converging slower than order 0.5 (contraction 0.875)
                               [1.0, 1.1, 1.3],  # diverging
                               [1.0, 2.0, 1.4]])  # oscillating without halving
def test_levels_that_do_not_converge_state_three_times_their_scatter(q):
    u = sequence_uncertainty(q, H)
    assert u["method"] == "scatter"
    assert u["error"] == pytest.approx(3 * (max(q) - min(q)))
    assert u["error"] > abs(q[2] - q[1])


def test_agreeing_levels_have_no_uncertainty_and_bad_input_is_refused():
    assert sequence_uncertainty([2.0, 2.0, 2.0], H)["error"] == 0.0
    assert sequence_uncertainty([3.0, 2.0, 2.0], H)["error"] == pytest.approx(1.25)  # a plateau after a change
    assert sequence_uncertainty([3.0, 2.0, 2.0], H, [1.0, 0.1, 0.1])["error"] == 0.0  # ... within quantisation
    with pytest.raises(ValueError, match="decrease"):
        sequence_uncertainty([1.0, 1.1, 1.2], [0.1, 0.2, 0.4])
    with pytest.raises(ValueError, match="three"):
        sequence_uncertainty([1.0, 1.1], [0.2, 0.1])


# ---------------------------------------------------------------- in the loop's estimate
def _level(rho_mm: float, force: float, inner: float, success: bool = True) -> dict:
    return {"success": success, "reason": "" if success else "lift test did not pass", "squeeze_depth": 1e-3 * rho_mm,
            "finger_force": force, "inner_size": inner, "resolution": 1e-5}


class _Answer:  # what estimated_error reads of a GraspAnswer
    def __init__(self, rho: float, force_exponent: float = 1.0) -> None:
        self.success, self.reason, self.squeeze_depth, self.resolution = True, "", rho, 1e-5
        self.force_exponent = force_exponent


def test_a_swinging_third_level_raises_the_loops_estimate_above_the_last_difference():
    levels = [_level(9.42, 4.7, 4e-3), _level(12.68, 6.0, 2e-3), _level(9.30, 4.75, 1e-3)]
    three = three_level_errors(levels)
    assert set(three) == {"squeeze_depth", "finger_force"}
    change = {"squeeze_depth": relative_change(12.68e-3, 9.30e-3), "finger_force": relative_change(6.0, 4.75)}
    two = estimated_error(change, _Answer(9.30e-3))
    est = estimated_error(change, _Answer(9.30e-3), three)
    res = 1e-5 / 9.30e-3
    assert three["squeeze_depth"]["method"] == "scatter"
    # three times the spread less one resolution (each level's quantisation), or the two-level estimate where
    # larger (levels that do not converge), plus the resolution
    assert est["squeeze_depth"] == pytest.approx(max(3 * (12.68 - 9.30 - 0.01) / 9.30,
                                                     TWO_LEVEL_SAFETY * change["squeeze_depth"]) + res)
    assert est["squeeze_depth"] > change["squeeze_depth"] + res  # above the last difference
    # two levels alone state the grid convergence index of a two-grid study: three times their difference
    assert two["squeeze_depth"] == pytest.approx(TWO_LEVEL_SAFETY * change["squeeze_depth"] + res)


def test_a_third_level_converging_at_order_one_to_two_states_no_less_than_two_levels_and_failures_get_none():
    levels = [_level(12.0, 6.0, 4e-3), _level(10.5, 5.2, 2e-3), _level(9.9, 4.9, 1e-3)]  # contractions 0.4, 0.375
    three = three_level_errors(levels)
    assert all(u["method"] == "monotone" and 1 < u["order"] < 2 for u in three.values())
    change = {"squeeze_depth": relative_change(10.5, 9.9), "finger_force": relative_change(5.2, 4.9)}
    est = estimated_error(change, _Answer(9.9e-3), three)
    # Eça and Hoekstra would state their extrapolated error; remeshed levels state at least three times the last
    # change, as two levels would
    assert all(three[k]["relative"] < TWO_LEVEL_SAFETY * change[k] for k in change)
    assert est == pytest.approx({k: TWO_LEVEL_SAFETY * v + 1e-5 / 9.9e-3 for k, v in change.items()})
    # faster than order 2 (contraction 0.2): the next level may move as far as these did
    fast = [_level(12.0, 6.0, 4e-3), _level(10.5, 5.2, 2e-3), _level(10.2, 5.05, 1e-3)]
    u = three_level_errors(fast)["squeeze_depth"]
    assert u["order"] > 2 and u["error"] == pytest.approx(1.25 * (12.0e-3 - 10.2e-3 - 1e-5))
    assert three_level_errors(levels[:2]) == {}
    assert three_level_errors(levels[:2] + [_level(20.0, 1.0, 1e-3, success=False)]) == {}


def test_levels_that_oscillate_and_contract_by_chance_state_no_less_than_two_levels_would():
    """A random ellipsoid of the coverage study at 20 % (seed 9): its forces 11.19, 12.17, 11.84 N oscillate and
    contract (0.34), so their uncertainty is about their last difference, 2.8 %; with the resolution that stated
    7.0 % for a force 7.4 % off the finer reference's 11.02 N.  Three times the last change covers it."""
    levels = [dict(_level(11.206, 11.192, 7.75e-3), resolution=0.517e-3),
              dict(_level(12.398, 12.173, 3.88e-3), resolution=0.517e-3),
              dict(_level(12.398, 11.839, 1.94e-3), resolution=0.517e-3)]
    three = three_level_errors(levels)
    assert three["finger_force"]["method"] == "oscillating"
    change = {"squeeze_depth": relative_change(12.398, 12.398), "finger_force": relative_change(12.173, 11.839)}
    ans = _Answer(12.398e-3)
    ans.resolution = 0.517e-3
    est = estimated_error(change, ans, three)
    actual = relative_change(11.839, 11.018)
    assert three["finger_force"]["relative"] + 0.517 / 12.398 < actual  # their uncertainty alone fell short
    assert est["finger_force"] == pytest.approx(TWO_LEVEL_SAFETY * change["finger_force"] + 0.517 / 12.398)
    assert est["finger_force"] >= actual


def test_levels_that_drift_within_their_quantisation_state_no_less_than_two_levels_would():
    """The tomato at 5 %: ρ* 9.421, 9.332, 9.215 mm at resolutions 0.53, 0.118, 0.117 mm.  Every difference lies
    within a resolution, so the spread net of quantisation is nil, and the levels do not contract (scatter); the
    reference (9.49 mm) is 2.9 % away.  The estimate is the two-level one, three times the last change, plus the
    resolution: above that error, where the last change plus the resolution (2.5 %) was not."""
    levels = [dict(_level(9.421, 4.719, 4.7e-3), resolution=0.53e-3),
              dict(_level(9.332, 4.871, 2.4e-3), resolution=0.118e-3),
              dict(_level(9.215, 4.621, 1.2e-3), resolution=0.117e-3)]
    three = three_level_errors(levels)
    assert three["squeeze_depth"]["method"] == "scatter" and three["squeeze_depth"]["spread"] == 0.0
    change = {"squeeze_depth": relative_change(9.332, 9.215), "finger_force": relative_change(4.871, 4.621)}
    ans = _Answer(9.215e-3)
    ans.resolution = 0.117e-3
    est = estimated_error(change, ans, three)
    res = 0.117 / 9.215
    assert est["squeeze_depth"] == pytest.approx(TWO_LEVEL_SAFETY * change["squeeze_depth"] + res)
    assert est["squeeze_depth"] >= relative_change(9.215, 9.49)
    # the force scatters beyond its quantisation: three times its spread, where that is the larger
    assert three["finger_force"]["method"] == "scatter"
    assert est["finger_force"] == pytest.approx(max(TWO_LEVEL_SAFETY * change["finger_force"],
                                                    three["finger_force"]["relative"]) + res)


def test_levels_that_find_the_same_rho_state_at_least_twice_its_resolution():
    """The football at 5 %: its finer levels, on one grid of depths, both found 4.781 mm (0.058 mm steps), 1.8 %
    from its reference; their change is nil, but their true crossings may lie up to a step apart.  ρ* states at
    least one resolution for the change besides the answer's own; the force, not quantised, its change as ever."""
    ans = _Answer(4.781e-3)
    ans.resolution = 0.058e-3
    res = 0.058 / 4.781
    for change in ({"squeeze_depth": 0.0, "finger_force": 0.017}, {"squeeze_depth": 0.002, "finger_force": 0.0}):
        est = estimated_error(change, ans)
        assert est["squeeze_depth"] == pytest.approx(max(TWO_LEVEL_SAFETY * change["squeeze_depth"], res) + res)
        assert est["squeeze_depth"] >= relative_change(4.867, 4.781)
        # the force, read at ρ*, states at least ρ*'s error
        assert est["finger_force"] == pytest.approx(max(TWO_LEVEL_SAFETY * change["finger_force"] + res,
                                                        est["squeeze_depth"]))
    # a change larger than the resolution keeps its factor of three
    big = estimated_error({"squeeze_depth": 0.05, "finger_force": 0.0}, ans)
    assert big["squeeze_depth"] == pytest.approx(0.15 + res)


def test_a_force_read_at_a_drifting_rho_states_rhos_error_times_its_exponent():
    """The coverage study's seed 4 at 5 % with nested levels: ρ* 15.613, 15.809, 16.004 mm (resolutions 0.691,
    0.195, 0.195 mm) drift by a resolution per level towards the reference's 16.64 mm; the forces 30.63, 28.645,
    28.81 N oscillate and contract, and their own estimate (3.9 %) fell short of the reference's 30.43 N (5.3 %).
    The force is read at ρ*, and it grows as a power of ρ*: it states ρ*'s error times that power, at least 1."""
    levels = [dict(_level(15.613, 30.63, 7.7e-3), resolution=0.691e-3),
              dict(_level(15.809, 28.645, 3.85e-3), resolution=0.195e-3),
              dict(_level(16.004, 28.81, 1.93e-3), resolution=0.195e-3)]
    three = three_level_errors(levels)
    change = {"squeeze_depth": relative_change(15.809, 16.004), "finger_force": relative_change(28.645, 28.81)}
    own = max(TWO_LEVEL_SAFETY * change["finger_force"], three["finger_force"]["relative"]) + 0.195 / 16.004
    assert own < relative_change(28.81, 30.43)  # the force's own levels understate it
    for exponent in (0.7, 1.0, 1.5, 2.2):
        ans = _Answer(16.004e-3, force_exponent=exponent)
        ans.resolution = 0.195e-3
        est = estimated_error(change, ans, three)
        assert est["squeeze_depth"] >= relative_change(16.004, 16.64)
        assert est["finger_force"] == pytest.approx(max(1.0, exponent) * est["squeeze_depth"])
    hertz = estimated_error(change, _Answer(16.004e-3, force_exponent=1.5), three)
    assert hertz["finger_force"] >= relative_change(28.81, 30.43)
    # a failure's force is not read at a ρ*: no exponent applies
    failed = _Answer(16.004e-3, force_exponent=3.0)
    failed.success, failed.reason = False, "the lift test did not pass by the maximum squeeze depth"
    assert estimated_error(change, failed)["finger_force"] == pytest.approx(TWO_LEVEL_SAFETY * change["finger_force"])


class _Snap:
    def __init__(self, label: str, phase: str, rho: float, force: float) -> None:
        self.label, self.phase, self.squeeze_depth, self._force = label, phase, rho, force

    def finger_normal_force(self, table) -> float:
        return self._force


def _squeezed(rhos, force_of, rho_star, lift_events=3):
    """A pickup's snapshots along the squeeze (forces force_of(ρ)), its lift start at ρ* and events of the lift."""
    from types import SimpleNamespace

    snaps = [_Snap("initial", "squeeze", 0.0, 0.0)] + [_Snap("event", "squeeze", r, force_of(r)) for r in rhos]
    snaps += [_Snap("lift start", "squeeze", rho_star, force_of(rho_star))]
    snaps += [_Snap("event", "lift", rho_star, 1.1 * force_of(rho_star)) for _ in range(lift_events)]
    return SimpleNamespace(squeeze_depth=rho_star, snapshots=snaps, rest=SimpleNamespace(table=None))


@pytest.mark.parametrize("power, offset", [(1.5, 0.0), (1.0, 0.0), (1.5, 2e-3), (2.0, 0.0)])
def test_the_force_exponent_is_the_slope_of_log_force_over_log_rho_along_the_squeeze(power, offset):
    from fem_grasp.grasp.answer import EXPONENT_WINDOW, force_exponent

    rho_star, step = 9e-3, 0.25e-3

    def force(r):
        return 3.0 * max(r - offset, 0.0) ** power

    res = _squeezed(np.arange(step, rho_star - step / 2, step), force, rho_star)
    r1 = rho_star - step * round((1 - EXPONENT_WINDOW) * rho_star / step)
    secant = math.log(force(rho_star) / force(r1)) / math.log(rho_star / r1)
    assert force_exponent(res) == pytest.approx(secant, rel=1e-12)
    # the local slope power·ρ/(ρ - offset) lies within the secant's range over the window
    local = [power * r / (r - offset) for r in (r1, rho_star)]
    assert min(local) - 1e-9 <= force_exponent(res) <= max(local) + 1e-9


def test_a_squeeze_without_earlier_pressing_states_hertz_exponent():
    from fem_grasp.grasp.answer import HERTZ_EXPONENT, force_exponent

    assert force_exponent(_squeezed([], lambda r: r, 1e-3)) == HERTZ_EXPONENT  # lifted at the first increment
    assert force_exponent(_squeezed([5e-4], lambda r: 0.0 * r, 1e-3)) == HERTZ_EXPONENT  # no force to compare


# ---------------------------------------------------------------- failures and the verdict
def _failure(held_steps: int, weight: float = 3.7753, steps: int = 20, success: bool = False):
    """A level that did not lift the object (the squeeze reached its maximum), having held ``held_steps`` steps
    h = weight / ``steps``; ``success``: one that lifted it."""
    from fem_grasp.grasp.answer import GraspAnswer

    f = {"resultant": 11.0, "along_squeeze": 11.0, "vertical": 0.1, "nodes": 40}
    h = weight / steps
    reason = "" if success else "the lift test did not pass by the maximum squeeze depth ρ = 34.97 mm"
    return GraspAnswer(success, reason, 0.03497, 22.35, (f, f), 90, held_steps * h, weight, (), 5000, 5e-4, h, 1.0, 4)


def _failure_change(before, after) -> dict:
    return {"squeeze_depth": relative_change(before.squeeze_depth, after.squeeze_depth),
            "finger_force": relative_change(before.finger_force, after.finger_force),
            "max_liftable": abs(after.max_liftable - before.max_liftable) / after.weight}


def test_two_failing_levels_state_three_times_the_change_of_the_weight_they_held():
    """The largest weight held by two failing levels is a converging quantity like ρ* and the force: two levels may
    agree on it by chance, and its estimate is three times their difference (relative to the weight)."""
    before, after = _failure(18), _failure(19)
    est = estimated_error(_failure_change(before, after), after)
    assert est["max_liftable"] == pytest.approx(TWO_LEVEL_SAFETY * 0.05)


def test_a_failed_lifts_depth_states_its_resolution_and_the_deepest_squeeze_none():
    """A pickup whose lift test passed and whose lift did not hold answers the depth of its last lift attempt, found
    as ρ* is, up to one resolution late; one that squeezed to the deepest squeeze without passing answers that
    setting, the same on every level (the loop keeps level 0's), which has no resolution."""
    slid = _Answer(20e-3)
    slid.success, slid.reason = False, ("every contact of finger 1 slides at lift height 12.3 mm: the object slides "
                                        "on the finger (after 3 lift attempts from ρ = 19.2 mm)")
    est = estimated_error({"squeeze_depth": 0.0, "finger_force": 0.0}, slid)
    q = slid.resolution / slid.squeeze_depth
    assert est["squeeze_depth"] == pytest.approx(2 * q) and est["finger_force"] == pytest.approx(q)
    deepest = _failure(18)
    assert estimated_error(_failure_change(deepest, deepest), deepest)["squeeze_depth"] == 0.0


def test_a_failure_within_its_error_of_the_weight_is_not_a_settled_verdict():
    """A random ellipsoid of the coverage study (seed 5): its last two levels failed, holding 18 and 19 steps h of
    the 20 of its weight, and a finer mesh lifted it; at 10 % the loop had called that failure converged.  The
    weight lies within the estimated error of the largest weight held: not settled.  Two failures four steps below
    the weight, one step apart (seed 8, whose finer reference failed too), are settled; a lift after a failure
    never is; two lifts are."""
    near = unsettled_verdict(_failure(19), _failure(18), estimated_error(_failure_change(_failure(18), _failure(19)),
                                                                        _failure(19)))
    assert "finer mesh may lift it" in near and "3.587 N" in near and "3.775 N" in near
    far = estimated_error(_failure_change(_failure(15), _failure(16)), _failure(16))
    assert unsettled_verdict(_failure(16), _failure(15), far) == ""
    # the same weight held twice, one step below: the levels agree, and nothing says a finer one would differ
    same = estimated_error(_failure_change(_failure(19), _failure(19)), _failure(19))
    assert unsettled_verdict(_failure(19), _failure(19), same) == ""
    lifted = _failure(20, success=True)
    lifts = {"squeeze_depth": 0.01, "finger_force": 0.01}
    assert "different verdicts" in unsettled_verdict(lifted, _failure(19), lifts)
    assert "different verdicts" in unsettled_verdict(_failure(19), lifted, far)
    assert unsettled_verdict(lifted, lifted, lifts) == ""


def test_a_lift_within_its_error_of_the_deepest_squeeze_is_not_a_settled_verdict():
    """A soft random capsule of the coverage study (seed 2): two levels lifted it at ρ* = 20.51 and 20.77 mm of a
    squeeze that goes no deeper than 21.50 mm, stating 4.9 %; the next level did not lift it.  ρ* plus its
    estimated error lies beyond the deepest squeeze: not settled.  The same lift with the squeeze going deeper than
    that is settled."""
    import dataclasses

    before, after = _answer(20.514, 5.4057, 0.1), _answer(20.77, 5.2811, 0.1)
    error = {"squeeze_depth": 0.049, "finger_force": 0.083}
    near = unsettled_verdict(dataclasses.replace(after, max_squeeze=0.021496), before, error)
    assert "deepest squeeze" in near and "20.77 mm" in near and "21.5 mm" in near
    assert unsettled_verdict(dataclasses.replace(after, max_squeeze=0.0219), before, error) == ""
    assert unsettled_verdict(after, before, error) == ""  # no deepest squeeze known (inf)


# ---------------------------------------------------------------- what the next level's resolution costs
def _answer(rho_mm: float, force: float, resolution_mm: float, force_exponent: float = 1.0):
    from fem_grasp.grasp.answer import GraspAnswer

    f = {"resultant": force / 2, "along_squeeze": force / 2, "vertical": 0.1, "nodes": 10}
    return GraspAnswer(True, "", 1e-3 * rho_mm, force, (f, f), 20, 1.0, 1.0, (), 1000, 4e-3 * resolution_mm, 0.05,
                       1.0, 4, force_exponent=force_exponent)


def _levels(first, second):
    from fem_grasp.grasp.accuracy import AccuracyLevel

    a, b = _answer(*first), _answer(*second)
    change = {"squeeze_depth": relative_change(a.squeeze_depth, b.squeeze_depth),
              "finger_force": relative_change(a.finger_force, b.finger_force)}
    return [AccuracyLevel(0, 4e-3, 6e-3, a), AccuracyLevel(1, 2e-3, 4e-3, b, change=change)]


def test_a_level_predicted_to_converge_resolves_rho_finer_and_others_do_not():
    from fem_grasp.grasp.accuracy import FINE_STEP_SHARE, STEP_SHARE, next_step, predicted_mesh_error

    target = 0.05
    # ρ* moved by less than the coarser level's resolution, the force by 3.6 %: about 1.8 % predicted
    quiet = _levels((2.27, 0.666, 0.25), (2.04, 0.642, 0.057))
    p = predicted_mesh_error(quiet)
    assert p == pytest.approx(max(0.0, relative_change(0.666, 0.642) - 0.25 / 2.04) / 2)
    assert p <= (1 - FINE_STEP_SHARE) * target
    rho = quiet[-1].answer.squeeze_depth
    assert next_step(1.0, quiet[-1].answer, target, p) == pytest.approx(FINE_STEP_SHARE * target * rho)
    # a change of 16 % beyond the resolution: the next level is not expected to converge, half the target for ρ*
    moving = _levels((12.40, 7.84, 0.59), (10.37, 6.05, 0.31))
    p = predicted_mesh_error(moving)
    assert p > (1 - FINE_STEP_SHARE) * target
    rho = moving[-1].answer.squeeze_depth
    assert next_step(1.0, moving[-1].answer, target, p) == pytest.approx(STEP_SHARE * target * rho)
    assert predicted_mesh_error(moving[:1]) is None  # level 1: no prediction, the fine share
    assert next_step(1.0, moving[0].answer, target, None) == pytest.approx(
        FINE_STEP_SHARE * target * moving[0].answer.squeeze_depth)
    # a force growing as ρ^1.6 takes 1.6 times ρ*'s error: ρ* is resolved 1.6 times finer; one growing more slowly
    # than ρ* not more coarsely
    for exponent, divided in ((1.6, 1.6), (0.8, 1.0)):
        steep = dataclasses.replace(quiet[-1].answer, force_exponent=exponent)
        assert next_step(1.0, steep, target, 0.0) == pytest.approx(FINE_STEP_SHARE * target * steep.squeeze_depth
                                                                   / divided)
        assert next_step(1.0, steep, target, 1.0) == pytest.approx(STEP_SHARE * target * steep.squeeze_depth / divided)
