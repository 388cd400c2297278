"""The lift test's rule (paper §III-B) on a scripted holding capacity: w(ρ) follows the weight the fingers can
hold, to within one step h, never drops below a weight that is still held, and is reached by loading from zero in
steps of h (Coulomb friction is path dependent: a capacity only a gradual loading reaches is found)."""

from dataclasses import dataclass

import pytest

from fem_grasp.grasp import lift_test
from fem_grasp.grasp.lift_test import HangResult, LiftTest
from fem_grasp.settings import DEFAULT_SETTINGS


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
    assert lt.update(None) == pytest.approx(0.5)
    for _ in range(4):  # the capacity stays: so does w
        assert lt.update(None) == pytest.approx(0.5)


def test_a_stopped_test_is_abandoned_before_its_next_weight(scripted):
    """``stop`` (how a speculative test beside the squeeze's is cancelled) is asked before every weight: the ramp
    ends there, with no verdict, and the last verdict stands."""
    lt = LiftTest(tracker=None, weight=1.0, step=0.1)
    scripted.limit = 0.35
    assert lt.update(None) == pytest.approx(0.3)
    scripted.limit, scripted.calls = 0.95, 0
    with pytest.raises(lift_test.LiftTestCancelled, match="abandoned"):
        lt.update(None, stop=lambda: scripted.calls >= 2)
    assert scripted.calls == 2 and lt.liftable == pytest.approx(0.3)


def test_w_follows_a_falling_and_rising_capacity_within_one_step(scripted):
    lt = LiftTest(tracker=None, weight=1.0, step=0.1)
    for limit, expected in ((0.35, 0.3), (0.72, 0.7), (0.41, 0.4), (0.05, 0.0), (1.3, 1.0)):
        scripted.limit = limit
        assert lt.update(None) == pytest.approx(expected)
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
    lt = LiftTest(tracker=None, weight=1.0, step=h)
    for _ in range(3):
        calls.clear()
        assert lt.update(None) == pytest.approx(1.0)
        assert lt.passed
        # h, 2h, …, mg, each from the weight held before it: no jump, and nothing beyond mg
        assert [round(b, 9) for _, b in calls] == [round(h * k, 9) for k in range(1, 11)]
        assert all(b - a == pytest.approx(h) for a, b in calls)


@pytest.mark.parametrize("halvings", [0, 1, 3])
def test_a_weight_with_no_static_state_is_tried_at_each_halving_of_the_tracker_setting(halvings):
    """hang halves a load step that finds no static state load_halvings times — the setting of the tracker it is
    given — each halving one more settle of a smaller jump, every one from the configuration held before."""
    from types import SimpleNamespace

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
