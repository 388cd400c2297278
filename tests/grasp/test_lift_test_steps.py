"""The lift test's rule (paper §III-B) on a scripted holding capacity: w(ρ) follows the weight the fingers can
hold, to within one step h, never drops below a weight that is still held, and is reached by loading from zero in
steps of h (Coulomb friction is path dependent: a capacity only a gradual loading reaches is found)."""

import itertools
from dataclasses import dataclass
from types import SimpleNamespace

import pytest

from fem_grasp.grasp import lift_test
from fem_grasp.grasp.lift_test import HangResult, LiftTest
from fem_grasp.settings import DEFAULT_SETTINGS

_DEPTHS = itertools.count(1)


def _at(depth: float | None = None) -> SimpleNamespace:
    """A squeeze state at ``depth``, by default one increment deeper than the last (the test reads only ρ)."""
    return SimpleNamespace(squeeze_depth=next(_DEPTHS) * 1e-3 if depth is None else depth)


@dataclass
class _Capacity:
    """Stands in for the hanging return mapping: a weight is held iff it is at most ``limit``."""

    limit: float = 0.0
    calls: int = 0


@pytest.fixture
def scripted(monkeypatch):
    cap = _Capacity()

    def hanging_state(tracker, state):
        return HangResult(0.0, True, "", object())

    def hang(tracker, start, weight, *, max_depth=None):
        cap.calls += 1
        held = weight <= cap.limit * (1 + 1e-12)
        return HangResult(weight, held, "" if held else "slides", object())

    monkeypatch.setattr(lift_test, "hanging_state", hanging_state)
    monkeypatch.setattr(lift_test, "hang", hang)
    return cap


def test_a_weight_still_held_is_kept_when_the_next_step_is_not(scripted):
    """At a plateau of the holding capacity w(ρ_{l−1}) is still held but w(ρ_{l−1}) + h is not: w stays.

    (Before the fix the rule stepped down to w − h without testing w, and w(ρ) saw-toothed by h along
    every plateau: 1.59, 1.68, 1.59, 1.68 N on the 1,180-vertex orange.)
    """
    lt = LiftTest(tracker=None, weight=1.0, step=0.1)
    scripted.limit = 0.55
    assert lt.update(_at()) == pytest.approx(0.5)
    for _ in range(4):  # the capacity stays: so does w
        assert lt.update(_at()) == pytest.approx(0.5)


def test_w_follows_a_falling_and_rising_capacity_within_one_step(scripted):
    lt = LiftTest(tracker=None, weight=1.0, step=0.1)
    for limit, expected in ((0.35, 0.3), (0.72, 0.7), (0.41, 0.4), (0.05, 0.0), (1.3, 1.0)):
        scripted.limit = limit
        assert lt.update(_at()) == pytest.approx(expected)
        assert expected <= limit < expected + 0.1 or expected >= lt.weight
    assert lt.passed


@dataclass
class _Hanging:
    """A scripted hanging state: the weight it holds."""

    weight: float


def test_the_weight_is_raised_from_zero_in_steps_of_h_each_from_the_state_before(monkeypatch):
    """A grip that holds any weight reached in steps of at most h but slips under a larger jump (friction is
    path dependent: the 893-vertex football held mg when loaded gradually, not by one jump to w + h).  The test
    must find the whole capacity, at every squeeze increment, starting each time from zero weight."""
    h, limit = 0.1, 1.3
    calls = []

    def hanging_state(tracker, state):
        return HangResult(0.0, True, "", _Hanging(0.0))

    def hang(tracker, start, weight, *, max_depth=None):
        calls.append((start.weight, weight))
        held = weight <= limit and weight - start.weight <= h * (1 + 1e-9)
        return HangResult(weight, held, "" if held else "slides", _Hanging(weight) if held else None)

    monkeypatch.setattr(lift_test, "hanging_state", hanging_state)
    monkeypatch.setattr(lift_test, "hang", hang)
    lt = LiftTest(tracker=None, weight=1.0, step=h, stride=1)
    for _ in range(3):
        calls.clear()
        assert lt.update(_at()) == pytest.approx(1.0)
        assert lt.passed
        # h, 2h, …, mg, each from the weight held before it: no jump, and nothing beyond mg
        assert [round(b, 9) for _, b in calls] == [round(h * k, 9) for k in range(1, 11)]
        assert all(b - a == pytest.approx(h) for a, b in calls)


def _path_dependent_grip(monkeypatch, limit, h, max_jump):
    """A scripted grip that holds a weight up to ``limit`` reached by load steps of at most ``max_jump``."""
    calls = []

    def hanging_state(tracker, state):
        return HangResult(0.0, True, "", _Hanging(0.0))

    def hang(tracker, start, weight, *, max_depth=None):
        calls.append((start.weight, weight))
        held = weight <= limit[0] * (1 + 1e-12) and weight - start.weight <= max_jump * (1 + 1e-9)
        return HangResult(weight, held, "" if held else "slides", _Hanging(weight) if held else None)

    monkeypatch.setattr(lift_test, "hanging_state", hanging_state)
    monkeypatch.setattr(lift_test, "hang", hang)
    return calls


@pytest.mark.parametrize("max_jump", [0.1, 0.4, 10.0])
def test_strides_find_the_capacity_that_steps_of_h_find(monkeypatch, max_jump):
    """Strides of four steps h below the weight held at the previous increment: w(ρ) is the capacity on the grid of
    h at every increment, as with steps of h throughout, whether the grip holds a stride's jump (``max_jump`` 0.4,
    10) or only steps of h (0.1: each stride fails and is taken again in steps of h)."""
    h, limit = 0.1, [0.0]
    calls = _path_dependent_grip(monkeypatch, limit, h, max_jump)
    lt = LiftTest(tracker=None, weight=1.0, step=h, stride=4)
    previous = 0.0
    for cap in (0.35, 0.62, 0.91, 0.47, 0.86, 1.3):
        calls.clear()
        limit[0] = cap
        w = lt.update(_at())
        assert w == pytest.approx(min(1.0, h * int(cap / h + 1e-9)))
        # a jump larger than h only from a held weight, and never beyond the previous increment's w
        for a, b in calls:
            assert b - a <= h * (1 + 1e-9) or b <= previous * (1 + 1e-12)
        strides = [(a, b) for a, b in calls if b - a > h * (1 + 1e-9)]
        if max_jump >= 4 * h and previous >= 4 * h:
            assert strides and all(b - a == pytest.approx(4 * h) for a, b in strides)
        previous = w
    assert lt.passed


def test_strides_cut_the_hangs_of_a_ramp_to_mg(monkeypatch):
    """Near ρ* (w(ρ_{l−1}) close to mg) a test that passes takes about mg/(4h) strides instead of mg/h steps."""
    calls = _path_dependent_grip(monkeypatch, [2.0], 0.05, 10.0)
    counts = {}
    for stride in (1, 4):
        lt = LiftTest(tracker=None, weight=1.0, step=0.05, stride=stride)
        lt.update(_at())
        calls.clear()
        lt.update(_at())
        counts[stride] = len(calls)
    assert counts[1] == 20 and counts[4] == 5


def test_strides_go_up_to_the_weight_held_at_the_deepest_squeeze_tested_below(monkeypatch):
    """A passing increment squeezed again in sub-increments is tested at depths between the last failing test and
    the pass: each strides up to what the test just below it held, not up to the pass's mg."""
    h, limit = 0.1, [0.0]
    calls = _path_dependent_grip(monkeypatch, limit, h, 10.0)
    lt = LiftTest(tracker=None, weight=1.0, step=h, stride=4)
    for depth, cap in ((1e-3, 0.85), (2e-3, 1.2)):
        limit[0] = cap
        lt.update(_at(depth))
    assert lt.passed and lt.guide(1.5e-3) == pytest.approx(0.8) and lt.guide(1e-3) == 0.0
    calls.clear()
    limit[0] = 0.93
    assert lt.update(_at(1.5e-3)) == pytest.approx(0.9)
    assert max(b for a, b in calls if b - a > h * (1 + 1e-9)) == pytest.approx(0.8)


def test_the_stride_must_be_a_whole_number_of_steps():
    with pytest.raises(ValueError, match="stride"):
        LiftTest(tracker=None, weight=1.0, step=0.1, stride=0)


@pytest.mark.parametrize("halvings", [0, 1, 3])
def test_a_weight_with_no_static_state_is_tried_at_each_halving_of_the_tracker_setting(halvings):
    """hang halves a load step that finds no static state load_halvings times — the setting of the tracker it is
    given — each halving one more settle of a smaller jump, every one from the configuration held before."""
    from fem_grasp.errors import TrackingError

    settles = []

    class NeverSettles:
        body = SimpleNamespace(weight=2.0)
        settings = DEFAULT_SETTINGS.replace(load_halvings=halvings)

        def make_state(self, *, load, **_):
            return load

        def implicit_step(self, begin, *_args, **_kw):
            settles.append(begin)
            raise TrackingError("no static state")

    start = SimpleNamespace(load=0.25, squeeze_depth=0.0, lift_height=0.0, centers=None, nodes=None, owner=None,
                            disp=None, sliding=None, slip=None)
    res = lift_test.hang(NeverSettles(), start, 1.5)  # from 0.5 N held to 1.5 N
    assert not res.held and "no static state" in res.reason
    # the full jump, then ever smaller ones from the same start: loads 0.75, 0.5, 0.375, ... of mg
    assert settles == [0.75] + [0.25 + 0.5 / 2 ** k for k in range(1, halvings + 1)]
