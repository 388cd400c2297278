"""The passing increment squeezed again in sub-increments (``PickupOptions.step_divisions``): ρ* and the forces of
the finer increment, for a few more lift tests; the events of the increment reported once."""

import pytest

from fem_grasp.grasp.options import PickupOptions
from fem_grasp.grasp.pickup import pickup
from fem_grasp.io.scene import load_scene, resolve_scene
from tests.helpers import force_along

DIVISIONS = 4


@pytest.fixture(scope="module")
def runs():
    """The tomato to the lift test's pass at its increment s, at s divided in the passing increment, and at s/4."""
    scene = load_scene(resolve_scene("tomato"))
    body = scene.body(None)
    opts = scene.pickup_options().replace(lift=False)
    coarse = pickup(body, opts)
    s = coarse.step
    divided = pickup(body, opts.replace(step=s, step_divisions=DIVISIONS))
    fine = pickup(body, opts.replace(step=s / DIVISIONS))
    return coarse, divided, fine


def test_the_divided_increment_finds_the_fine_increments_rho_and_follows_its_path(runs):
    coarse, divided, fine = runs
    s = coarse.step
    for r in runs:
        assert "lift test passed" in r.reason or "lift was not run" in r.reason
    # within the coarse increment that passed, and one sub-increment of the fine increment's answer (the two
    # test on different grids of depths, so where w(ρ) reaches mg between them they differ by up to one)
    assert coarse.squeeze_depth - s * (1 + 1e-9) <= divided.squeeze_depth <= coarse.squeeze_depth * (1 + 1e-12)
    assert abs(divided.squeeze_depth - fine.squeeze_depth) <= s / DIVISIONS * (1 + 1e-9)
    # the same squeeze path: the finger force of both at the shallower of the two answers within 1 % of mg
    mg = divided.body.weight
    rho = min(divided.squeeze_depth, fine.squeeze_depth)
    assert abs(force_along(divided, rho) - force_along(fine, rho)) <= 0.01 * mg
    assert divided.step_divisions == DIVISIONS and divided.to_dict()["step_divisions"] == DIVISIONS


def test_the_divided_run_tests_few_more_times_and_reports_each_event_once(runs):
    coarse, divided, fine = runs
    # the coarse tests up to the last failing one, then at most DIVISIONS sub-increment tests
    assert len(divided.liftable) <= len(coarse.liftable) - 1 + DIVISIONS
    assert len(divided.liftable) < len(fine.liftable)
    rho = [r for r, _ in divided.liftable]
    assert rho == sorted(rho) and rho[-1] == pytest.approx(divided.squeeze_depth)
    assert divided.liftable[-1][1] >= divided.body.weight * (1 - 1e-9) > max(w for _, w in divided.liftable[:-1])
    depths = [e.squeeze_depth for e in divided.events if e.phase == "squeeze"]
    assert depths == sorted(depths) and max(depths) <= divided.squeeze_depth * (1 + 1e-12)


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "4"])
def test_step_divisions_must_be_a_whole_number_of_at_least_one(bad):
    with pytest.raises(ValueError, match="step_divisions"):
        PickupOptions(step_divisions=bad)
