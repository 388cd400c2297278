"""The lift test's incremental rule (paper §III-B) on a scripted holding capacity: w(ρ) follows the weight the
fingers can hold, to within one step h, and never drops below a weight that is still held."""

from dataclasses import dataclass

import pytest

from fem_grasp.grasp import lift_test
from fem_grasp.grasp.lift_test import HangResult, LiftTest


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

    def hang(tracker, start, weight, *, max_depth=lift_test.LOAD_HALVINGS):
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


def test_w_follows_a_falling_and_rising_capacity_within_one_step(scripted):
    lt = LiftTest(tracker=None, weight=1.0, step=0.1)
    for limit, expected in ((0.35, 0.3), (0.72, 0.7), (0.41, 0.4), (0.05, 0.0), (1.3, 1.0)):
        scripted.limit = limit
        assert lt.update(None) == pytest.approx(expected)
        assert expected <= limit < expected + 0.1 or expected >= lt.weight
    assert lt.passed
