"""The first lift test at a given depth (``PickupOptions.first_lift_test``, what the accuracy loop's finer levels
use, at the coarser level's ρ*): the same answer as testing every increment, with fewer tests; two at a good guess
of ρ*; should the first test pass, the ends below it tested after all, from the deepest down, so that ρ* is still
the first that passes where w(ρ) crosses mg once."""

import threading

import pytest

from fem_grasp.grasp.options import PickupOptions
from fem_grasp.grasp.pickup import pickup
from fem_grasp.io.scene import load_scene, resolve_scene
from fem_grasp.settings import EngineSettings
from tests.helpers import force_along


@pytest.fixture(scope="module", params=[1, 4], ids=["undivided", "divided"])
def tomato(request):
    scene = load_scene(resolve_scene("tomato"))
    body = scene.body(None)
    opts = scene.pickup_options().replace(lift=False, step_divisions=request.param)
    return body, opts, pickup(body, opts)


def _same_answer(a, b):
    mg = a.body.weight
    assert "lift test passed" in a.reason and "lift test passed" in b.reason
    assert abs(a.squeeze_depth - b.squeeze_depth) <= a.step / a.step_divisions * (1 + 1e-9)
    # the same squeeze path: the finger force at the shallower answer within 1 % of mg (the two test at different
    # depths where events shift the increments)
    rho = min(a.squeeze_depth, b.squeeze_depth)
    assert abs(force_along(a, rho) - force_along(b, rho)) <= 0.01 * mg
    # each squeeze event reported once, in order, none beyond ρ* (the events of a pass through an increment that is
    # squeezed again, were they kept, would come before the second pass's, deeper than its first)
    depths = [e.squeeze_depth for e in b.events if e.phase == "squeeze"]
    assert depths == sorted(depths) and max(depths) <= b.squeeze_depth * (1 + 1e-12)
    assert 0.8 * len([e for e in a.events if e.phase == "squeeze"]) <= len(depths)


def test_tests_from_below_rho_star_give_the_same_answer_with_fewer_tests(tomato):
    body, opts, every = tomato
    first = 0.8 * every.squeeze_depth
    later = pickup(body, opts.replace(first_lift_test=first))
    _same_answer(every, later)
    rho = [r for r, _ in later.liftable]
    assert rho == sorted(rho) and min(rho) >= first * (1 - 1e-9)
    assert len(later.liftable) < len(every.liftable)
    # where both tested, w(ρ) is the same test (h apart at most: round-off may decide a step near a finger's limit)
    w_every = dict(every.liftable)
    for r, w in later.liftable:
        if r in w_every:
            assert abs(w - w_every[r]) <= later.lift_test_step * (1 + 1e-9)


def test_a_first_test_that_passes_tests_the_increments_below_it_from_the_deepest_down(tomato):
    """The increments below a first test that passes are tested from the deepest down to the first that fails
    (the last failing increment of a run that tests every one): the same ρ*, and no test further down."""
    body, opts, every = tomato
    late = pickup(body, opts.replace(first_lift_test=1.3 * every.squeeze_depth))
    _same_answer(every, late)
    mg = late.body.weight
    lowest, w = min(late.liftable)
    # the lowest test fails, at an increment where testing every one also failed, and it is the one just below
    # the passing increment: every test above it passed, but those of a passing increment squeezed again
    assert w < mg and any(abs(r - lowest) <= 1e-9 * lowest and we < mg for r, we in every.liftable)
    divided = late.step_divisions > 1
    whole = [wl for r, wl in late.liftable if r > lowest and not (divided and r < late.squeeze_depth)]
    assert all(wl >= mg * (1 - 1e-12) for wl in whole)
    assert len(late.liftable) < len(every.liftable)


def test_a_first_test_a_few_sub_increments_above_rho_star_walks_down_on_its_grid(tomato, monkeypatch):
    """A finer level's ρ* a few sub-increments below the coarser's: the walk down from the passing first test goes
    one end at a time to the first that fails, and no depth is tested twice (the increment below the first test's
    is squeezed in sub-increments on the way, not again after a failing increment's end).  Beside each test the end
    below it is tested (two at a time): beyond the first that fails, at most that one more, and not recorded."""
    from fem_grasp.grasp.lift_test import LiftTest

    body, opts, every = tomato
    update = LiftTest.update
    tested = []

    def recording(self, state, **kw):
        w = update(self, state, **kw)
        tested.append((state.squeeze_depth, w))
        return w

    monkeypatch.setattr(LiftTest, "update", recording)
    sub = every.step / every.step_divisions
    late = pickup(body, opts.replace(first_lift_test=every.squeeze_depth + 3.5 * sub))
    _same_answer(every, late)
    depths = sorted(r for r, _ in tested)
    assert all(b - a > 0.5 * sub for a, b in zip(depths, depths[1:]))  # none twice
    mg = body.weight
    lowest = min(r for r, _ in late.liftable)  # the failing end the walk ended at (the answer's record)
    assert len([r for r in depths if r < lowest * (1 - 1e-9)]) <= 1  # the end below it, tested beside it
    held = [w >= mg * (1 - 1e-12) for r, w in sorted(tested) if r >= lowest * (1 - 1e-9)]
    assert held == [False] + [True] * (len(held) - 1)  # from the first test down to the first that fails
    assert len(held) <= 6


def test_a_lift_that_fails_resumes_at_the_walks_next_passing_end_without_testing_it_again(tomato, monkeypatch):
    """A lift from ρ* that slides off resumes at the next end of a sub-increment (Algorithm 1 step 6).  Where the
    walk down from a passing first test tested that end and it passed, the lift starts from the walk's state there:
    no depth tested twice, and the answer of squeezing to it again from the lift's start (the same increments from
    the same state) — the same depth, the verdict, the force within 1 % of mg and the squeeze's events between."""
    import sys

    from fem_grasp.grasp.lift import LiftOutcome
    from fem_grasp.grasp.lift_test import LiftTest

    pickup_module = sys.modules["fem_grasp.grasp.pickup"]  # the module; fem_grasp.grasp.pickup is the function
    body, opts, every = tomato
    real_lift, update = pickup_module.run_lift, LiftTest.update
    lifts, tested = [], []

    def first_slides_off(tracker, state, **kw):
        lifts.append(state.squeeze_depth)
        if len(lifts) % 2 == 1:  # the first lift of each pickup below
            return LiftOutcome(state, [], False, "made to slide off by the test")
        return real_lift(tracker, state, **kw)

    def recording(self, state, **kw):
        w = update(self, state, **kw)
        tested.append((state.squeeze_depth, w))
        return w

    monkeypatch.setattr(pickup_module, "run_lift", first_slides_off)
    monkeypatch.setattr(LiftTest, "update", recording)
    sub = every.step / every.step_divisions
    at = opts.replace(lift=True, first_lift_test=every.squeeze_depth + 3.5 * sub)
    walked = pickup(body, at)
    walk_tests, walk_lifts = list(tested), list(lifts)
    monkeypatch.setattr(pickup_module, "next_passed", lambda *a, **k: None)  # squeezed to and tested again
    again = pickup(body, at)

    mg = body.weight
    rho1, rho2 = walk_lifts
    assert walked.success and again.success and len(walked.lift_attempts) == len(again.lift_attempts) == 2
    # the first end at or past ρ* + a sub-increment (events can move it further), the same both ways
    assert rho1 + sub * (1 - 1e-9) <= rho2 < rho1 + 2 * sub and lifts[3] == pytest.approx(rho2, rel=1e-9)
    assert walked.squeeze_depth == pytest.approx(rho2, rel=1e-9)
    walk_tested_it = [w >= mg * (1 - 1e-12) for r, w in walk_tests if abs(r - rho2) <= 1e-9 * rho2]  # and passed
    depths = sorted(r for r, _ in walk_tests)
    assert all(b - a > 0.5 * sub for a, b in zip(depths, depths[1:]))  # none twice
    # counted down to the failing end the walk ended at (the answer's record): the end below it is tested beside
    # it and abandoned, and whether that test got as far as recording depends on the timing of the two threads
    lowest = min(r for r, _ in walked.liftable) * (1 - 1e-9)
    walk_count = len([r for r, _ in walk_tests if r >= lowest])
    assert walk_tested_it == [True] and len([r for r, _ in tested if r >= lowest]) == 2 * walk_count + 1  # once more
    assert [r for r, _ in walked.liftable] == sorted({r for r, _ in walked.liftable})
    assert max(walked.liftable)[0] == pytest.approx(rho2, rel=1e-9)
    assert abs(walked.finger_normal_force - again.finger_normal_force) <= 0.01 * mg

    def squeezed_between(result):
        return [e for e in result.events if e.phase == "squeeze" and rho1 * (1 + 1e-12) < e.squeeze_depth]

    n1, n2 = len(squeezed_between(walked)), len(squeezed_between(again))
    assert n2 > 0 and abs(n1 - n2) <= max(2, 0.2 * n2)
    assert all(e.squeeze_depth <= rho2 * (1 + 1e-12) for e in squeezed_between(walked))


def test_a_first_test_at_rho_star_costs_two_or_three_tests(tomato):
    """At the answer itself: the test there and the sub-increment below it (three where the two paths' w(ρ) differ
    at a knife edge), against a test at every increment below ρ* and at every sub-increment of the passing one."""
    body, opts, every = tomato
    guess = pickup(body, opts.replace(first_lift_test=every.squeeze_depth))
    _same_answer(every, guess)
    assert len(guess.liftable) <= 3 < len(every.liftable)
    assert min(r for r, _ in guess.liftable) >= every.squeeze_depth - 2.5 * every.step / every.step_divisions


def test_the_end_below_a_first_test_is_tested_beside_it_with_the_same_numbers(tomato):
    """A passing first test walks down to the end below it first; that end is tested beside the first test (a
    helper thread, EngineSettings.parallel_lift_tests) or after it in the same thread, on a branch of the
    tracker either way: the same w(ρ) at every depth and the same ρ*.  No thread outlives the pickup, also
    where the first test fails and the test beside it is abandoned."""
    body, opts, every = tomato
    before = threading.active_count()
    at = opts.replace(first_lift_test=every.squeeze_depth)
    side = pickup(body, at, settings=EngineSettings(parallel_lift_tests=True))
    after = pickup(body, at, settings=EngineSettings(parallel_lift_tests=False))
    _same_answer(every, side)
    assert side.squeeze_depth == pytest.approx(after.squeeze_depth, rel=1e-12)
    assert len(side.liftable) == len(after.liftable) >= 2
    mg = body.weight
    for (r1, w1), (r2, w2) in zip(side.liftable, after.liftable):
        assert r1 == pytest.approx(r2, rel=1e-12) and abs(w1 - w2) <= 1e-9 * mg
    # a walk of several ends, two at a time beside each other or one after another: the same numbers
    sub = every.step / every.step_divisions
    far = opts.replace(first_lift_test=every.squeeze_depth + 3.5 * sub)
    side = pickup(body, far, settings=EngineSettings(parallel_lift_tests=True))
    after = pickup(body, far, settings=EngineSettings(parallel_lift_tests=False))
    _same_answer(every, side)
    assert side.squeeze_depth == pytest.approx(after.squeeze_depth, rel=1e-12)
    assert len(side.liftable) == len(after.liftable) >= 2  # the answer's record: ρ* and the end below it
    for (r1, w1), (r2, w2) in zip(side.liftable, after.liftable):
        assert r1 == pytest.approx(r2, rel=1e-12) and abs(w1 - w2) <= 1e-9 * mg
    early = pickup(body, opts.replace(first_lift_test=0.8 * every.squeeze_depth))
    _same_answer(every, early)
    assert threading.active_count() == before
    from fem_grasp import threads

    assert threads._SECTIONS == 0  # every side-by-side section closed: the BLAS threads switch again


def test_a_first_test_beyond_the_maximum_squeeze_is_made_there(tomato):
    """The squeeze reaches its maximum below the first test: tested there, and, passing, down from it."""
    body, opts, every = tomato
    capped = pickup(body, opts.replace(first_lift_test=3.0 * every.squeeze_depth,
                                       max_squeeze=every.squeeze_depth + 1.5 * every.step))
    _same_answer(every, capped)
    assert max(r for r, _ in capped.liftable) <= capped.max_squeeze * (1 + 1e-9)


@pytest.mark.parametrize("bad", [0.0, -1e-3, float("nan")])
def test_first_lift_test_must_be_a_positive_depth(bad):
    with pytest.raises(ValueError, match="first lift test"):
        PickupOptions(first_lift_test=bad)
