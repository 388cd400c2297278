"""The event tracker's own machinery (paper §III-C): the slip systems of eqs. (6)–(8) against finite differences,
slip rates, warm starts, the order of slip forms, event location and the response caches, on the test box of
tests/helpers.py (3×4×3 cm, 64 nodes, 2 cm fingertips).
"""


import numpy as np
import pytest

from fem_grasp import Body
from fem_grasp.contact.kernels import slip_trial
from fem_grasp.contact.obstacles import Fingertip
from fem_grasp.contact.slip_system import CompiledSlipSystem
from fem_grasp.contact.tracking import FINGER1, TABLE, MixedSlipSystem, Tracker
from fem_grasp.grasp.rest import rest
from fem_grasp.settings import EngineSettings
from tests.helpers import RADIUS, WEIGHT, box_squeezed_3mm, central_difference_jacobian, face_centres, pickup_box


@pytest.mark.parametrize("free", [False, True])
def test_slip_system_jacobian_matches_finite_differences(rng, free):
    m = 4
    a = rng.normal(size=(3 * m, 3 * m))
    c = 100.0 * (a @ a.T / (3 * m) + np.eye(3 * m))
    fh = rng.normal(size=(m, 3)) + [0, 0, 3.0]
    df = rng.normal(size=(m, 3))
    radius = 0.01
    tip = Fingertip(np.zeros(3), radius)
    r = tip.project(rng.normal(size=(1, 3)))[0]
    n = r / radius
    ft = fh[1] - (fh[1] @ n) * n
    t_hat = np.array([[1.0, 0.0, 0.0], ft / np.linalg.norm(ft)])
    system = MixedSlipSystem(c, fh, df, np.array([0, 1]), np.array([TABLE, FINGER1]), np.array([0.4, 0.3]),
                             t_hat, np.stack([np.zeros(3), r]), np.array([0.0, 0.0, 1.0]), radius, free)
    x = system.x0 + 1e-3 * rng.normal(size=system.n)
    np.testing.assert_allclose(system.jacobian(x), central_difference_jacobian(system.residual, x, 1e-8), rtol=1e-5, atol=1e-6)
    # The rate of the residual at fixed x: the held forces move at ``df``.
    shifted = MixedSlipSystem(c, fh + 1e-6 * df, df, np.array([0, 1]), np.array([TABLE, FINGER1]),
                              np.array([0.4, 0.3]), t_hat, np.stack([np.zeros(3), r]), np.array([0.0, 0.0, 1.0]),
                              radius, free)
    np.testing.assert_allclose((shifted.residual(x) - system.residual(x)) / 1e-6, system.residual_rate(x),
                               rtol=1e-5, atol=1e-6)


def test_fingertip_slip_lands_on_the_cone_and_the_sphere(rng):
    m = 3
    a = rng.normal(size=(3 * m, 3 * m))
    c = 100.0 * (a @ a.T / (3 * m) + np.eye(3 * m))
    radius = 0.01
    r = np.array([0.0, -radius, 0.0])  # node on the sphere, inward normal −y... pointing from O to the node
    n = r / radius
    fh = np.zeros((m, 3))
    fh[0] = 1.0 * n + 0.6 * np.array([0.0, 0.0, 1.0])  # outside a μ = 0.3 cone
    fh[1:] = [0, 0, 1.0]
    df = np.zeros((m, 3))
    t = np.array([0.0, 0.0, 1.0])
    system = MixedSlipSystem(c, fh, df, np.array([0]), np.array([FINGER1]), np.array([0.3]), t[None, :],
                             r[None, :], np.array([0.0, 0.0, 1.0]), radius)
    x = system.solve()
    q_rel = r + system.slips(x)[0]
    assert np.linalg.norm(q_rel) == pytest.approx(radius, rel=1e-12)  # eq. (8): on the sphere
    f = system.forces(x)[0]
    nq = q_rel / radius
    fn = f @ nq
    assert np.linalg.norm(f - fn * nq) == pytest.approx(0.3 * fn, rel=1e-9)  # eq. (7): on the cone
    assert system.amounts(x)[0] > 0  # it slid against its friction (θ < 0)
    assert (q_rel - r) @ t < 0  # opposite to the tangential force


def test_a_new_contact_brings_the_columns_of_the_surface_nodes_nearest_an_obstacle():
    """A new contact's compliance columns are solved together with those of the likely next contacts
    (compliance.PREFETCH_NODES in all): the uncached surface nodes nearest a fingertip or the table."""
    from fem_grasp.elastic.compliance import PREFETCH_NODES

    rs = rest(pickup_box(), 0.5)
    posed = Body(rs.body.mesh, 2e4, 0.3, weight=WEIGHT)  # the rest cached columns of the resting body's
    tracker = Tracker(posed, radius=RADIUS, mu_finger=0.5, mu_table=0.5, table=rs.table)
    comp = posed.compliance
    surf = posed.mesh.surface_nodes
    pos = posed.mesh.points[surf]
    i, j = face_centres(rs)
    centers = posed.mesh.points[[i, j]] + np.array([[0, -RADIUS, 0], [0, RADIUS, 0]])
    before = {int(k) for k in surf if comp.is_cached(k)}
    assert i not in before and len(surf) - len(before) > PREFETCH_NODES
    gap = tracker.obstacle_gaps(pos, centers).min(axis=1)
    expected = [int(k) for k in surf[np.argsort(gap, kind="stable")] if k not in before and k != i]
    tracker.prefetch_columns([i], pos, centers)
    now = {int(k) for k in surf if comp.is_cached(k)}
    assert now - before == {i, *expected[:PREFETCH_NODES - 1]}
    assert j in now  # the other fingertip's node touches it too
    tracker.prefetch_columns([i, j], pos, centers)  # cached already: nothing more
    assert {int(k) for k in surf if comp.is_cached(k)} == now


def test_the_tracker_keeps_its_latest_contact_responses_within_a_byte_budget():
    rs = rest(pickup_box(), 0.5)
    tracker = Tracker(rs.body, radius=RADIUS, mu_finger=0.5, mu_table=0.5, table=rs.table)
    others = np.setdiff1d(rs.body.mesh.surface_nodes, rs.contact_nodes)
    sets = [np.concatenate([rs.contact_nodes, others[:i]]) for i in range(6)]
    size = [tracker.response(k).nbytes for k in sets]  # under the default budget: all kept
    assert len(tracker._responses) == 6 and size[5] > size[0] > 0
    budget = size[4] + size[5] + size[0] // 2
    tracker.settings = tracker.settings.replace(response_cache_bytes=budget)
    latest = tracker.response(others[:7])  # a seventh set: the oldest go until the rest fit
    assert sum(r.nbytes for r in tracker._responses.values()) <= budget
    assert list(tracker._responses)[-1] == tuple(others[:7]) and tracker.response(others[:7]) is latest
    assert tuple(sets[0]) not in tracker._responses
    tracker.settings = tracker.settings.replace(response_cache_bytes=1)  # smaller than any: the latest alone is kept
    again = tracker.response(sets[0])
    assert list(tracker._responses) == [tuple(sets[0])] and tracker.response(sets[0]) is again
    # Recomputed (derived from the cached neighbour, ContactResponse.neighbour): a fresh tracker's to round-off.
    fresh = Tracker(rs.body, radius=RADIUS, mu_finger=0.5, mu_table=0.5, table=rs.table).response(sets[0])
    np.testing.assert_allclose(again.reduced_stiffness, fresh.reduced_stiffness, rtol=0,
                               atol=1e-11 * np.abs(fresh.reduced_stiffness).max())


@pytest.mark.parametrize("free", [False, True])
def test_slip_rates_of_event_d_match_finite_differences(free):
    # Event D watches d(slip)/dρ from the implicit-function theorem; compare with the slips themselves.
    _, tracker, state, vel = box_squeezed_3mm()
    tracker.forms = (free,)
    t0 = tracker.trial(state, 0.0, vel)
    t1 = tracker.trial(state, 1e-8, vel)
    sl = state.sliding
    np.testing.assert_allclose((t1.amounts - t0.amounts)[sl] / 1e-8, t0.rates[sl], rtol=0,
                               atol=1e-4 * np.abs(t0.rates[sl]).max())


@pytest.mark.parametrize("free", [False, True])
def test_warm_started_slip_roots_are_the_homotopy_roots(free, monkeypatch):
    """Newton from the root at a nearby parameter (continuation in t) finds the root the paper's homotopy finds."""
    rs, t0, state, vel = box_squeezed_3mm()
    if not t0.compiled:  # the test steers the whole-trial kernel, which only the compiled path calls
        pytest.skip("numba is not installed: trials run on the reference path only")

    def tracker():
        t = Tracker(rs.body, radius=RADIUS, mu_finger=0.5, mu_table=0.5, table=rs.table)
        t.forms = (free,)
        return t

    big = 3.4e-3  # a third of the fingertip radius in one increment, ten nodes sliding
    by_homotopy = tracker().trial(state, big, vel, methods=("homotopy",))
    warm = tracker()
    seen = []
    for system in (MixedSlipSystem, CompiledSlipSystem):  # the reference path and the compiled one
        def solve(self, *a, start=None, _orig=system.solve, **k):
            seen.append(start is not None)
            return _orig(self, *a, start=start, **k)

        monkeypatch.setattr(system, "solve", solve)
    # Newton from zero slip (the whole-trial kernel's first try) is made to miss after the first trial, so that
    # every later trial solves from the previous root.
    real, calls = slip_trial.newton_trial, []

    def zero_misses(*args):
        out = list(real(*args))
        calls.append(out[0])
        if len(calls) > 1 and out[0] == slip_trial.TRIAL_ROOT:
            out[0], out[6] = slip_trial.TRIAL_NO_ROOT, False
        return tuple(out)

    monkeypatch.setattr(slip_trial, "newton_trial", zero_misses)
    for k in range(1, 9):
        stepped = warm.trial(state, big * k / 8, vel, methods=("newton",))
    assert calls == [slip_trial.TRIAL_ROOT] * 8  # Newton from zero would have found every root ...
    assert seen == [True] * 7  # ... but every later trial solved from the previous root
    scale = np.abs(by_homotopy.state.forces).max()
    np.testing.assert_allclose(stepped.state.forces, by_homotopy.state.forces, rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(stepped.state.disp, by_homotopy.state.disp, rtol=0, atol=1e-12)


def test_a_lightly_loaded_fingertip_contact_on_a_stiff_body_slides_onto_its_cone():
    # Figures of the tomato at Table I's E = 1 GPa just after ρ = 0: a contact of 5 µN, 25 % outside its
    # cone, with an own stiffness of 5e6 N/m and R = 1 cm.  Carried as c_k (≈ 1), the fingertip unknowns
    # put C·r_k ≈ 5e4 N into every force and buried this one in round-off (Newton failed).
    c = np.array([[123569.8, -31895.7, -220655.4], [-31895.7, 5290413.3, 1039374.6],
                  [-220655.4, 1039374.6, 2255505.1]])
    n = np.array([0.05818, -0.96774, 0.24512])
    n /= np.linalg.norm(n)
    radius = 0.01
    fh = np.array([[3.2622e-09, -5.33995e-06, -6.75193e-07]])
    fn = fh[0] @ n
    ft = fh[0] - fn * n
    assert np.linalg.norm(ft) > 1.2 * 0.32 * fn  # starts well outside
    system = MixedSlipSystem(c, fh, np.zeros((1, 3)), np.array([0]), np.array([FINGER1]), np.array([0.32]),
                             (ft / np.linalg.norm(ft))[None, :], (radius * n)[None, :],
                             np.array([0.0, 0.0, 1.0]), radius)
    x = system.solve()
    f = system.forces(x)[0]
    nq = system.normals(x)[0]
    fn_new = f @ nq
    assert np.linalg.norm(f - fn_new * nq) == pytest.approx(0.32 * fn_new, rel=1e-9)
    assert np.linalg.norm(system.normals(x)[0]) == pytest.approx(1.0, abs=1e-15)  # still on the sphere
    assert 0 < system.amounts(x)[0] < 1e-12  # a slip of a few 1e-14 m


def test_the_event_predicted_to_fire_first_leads_the_location():
    """Regula falsi follows the event function whose linear interpolation crosses zero first; functions that
    do not fire, or are not defined (−inf), are ignored; without a no-event side there is no prediction."""
    lo = np.array([-1.0, -0.1, -np.inf, -2.0, -0.5])
    hi = np.array([1.0, 0.01, 5.0, -1.0, 2.0])
    # crossing fractions: 0.5, 0.909, -, -, 0.2 -> index 4 first
    assert Tracker._first_to_fire(lo, hi) == 4
    assert Tracker._first_to_fire(lo, np.array([-1.0, 0.01, 5.0, -1.0, -0.1])) == 1
    assert Tracker._first_to_fire(lo, np.full(5, -1.0)) is None
    assert Tracker._first_to_fire(None, hi) is None and Tracker._first_to_fire(lo, None) is None


@pytest.mark.parametrize("compiled", [False, True])
def test_a_slip_form_whose_newton_failed_at_a_smaller_step_is_tried_last(monkeypatch, compiled):
    """After the great-circle Newton finds no root at dt, later trials of the same motion at dt' ≥ dt start
    with the free-direction form; a trial at a smaller step still tries the great circle first.  Compiled, the
    first form is tried by the whole-trial kernel, the others by the slip system."""
    from fem_grasp.contact.tracking import SlipFailure

    _, t, state, vel = box_squeezed_3mm()
    if compiled and not t.compiled:
        pytest.skip("numba is not installed: trials run on the reference path only")
    t.compiled = compiled
    order = []
    system = CompiledSlipSystem if compiled else MixedSlipSystem
    orig, kernel = system.solve, slip_trial.newton_trial

    def solve(self, *a, methods=("newton", "homotopy"), zero_start=None, **k):
        if zero_start is None:  # (else the kernel tried this form and recorded it)
            order.append(self.free)
        if not self.free and methods == ("newton",):
            raise SlipFailure("great circle made to fail")
        return orig(self, *a, methods=methods, **k, **({} if zero_start is None else {"zero_start": zero_start}))

    def newton_trial(*args):
        free = args[18]
        order.append(free)
        out = list(kernel(*args))
        if not free:
            out[0] = slip_trial.TRIAL_NO_ROOT
        return tuple(out)

    monkeypatch.setattr(system, "solve", solve)
    monkeypatch.setattr(slip_trial, "newton_trial", newton_trial)
    t.trial(state, 2e-4, vel, methods=("newton",))
    assert order == [False, True]
    order.clear()
    t.trial(state, 3e-4, vel, methods=("newton",))
    assert order == [True]  # the free form found a root at once
    order.clear()
    t.trial(state, 1e-4, vel, methods=("newton",))  # smaller than the failing step: great circle first
    assert order == [False, True]


def test_a_node_crawling_through_stick_slip_toggles_is_crossed_by_an_implicit_increment():
    """On the quick tomato (152 vertices, 20 kPa) node 118 of finger 1 sticks and slides again every 40 nm of
    squeeze: too far apart for the chatter window (1e-6 × diameter), so the run once spent 5,000 events crawling
    0.04 mm and gave up.  Counted over the increment, the toggles send it into one implicit increment; every
    snapshot still obeys the contact laws and equilibrium."""
    import fem_grasp
    from fem_grasp.contact.tracking import CRAWL_TOGGLES

    result = fem_grasp.run_scene("tomato", quick=True, cache_dir=None)
    assert "events: the tracking is not progressing" not in result.reason
    toggles = [e for e in result.events if e.kind in "CD" and e.node == 118]
    assert len(result.events) < 500 and len(toggles) <= CRAWL_TOGGLES + 2
    result.check()


def test_a_pickup_with_derived_contact_responses_is_the_pickup_with_fresh_ones(monkeypatch):
    """The box picked up at μ = 0.5 with each new contact set's response derived from a cached neighbour's
    (ContactResponse.neighbour, the default) or factorised afresh (EngineSettings.neighbour_updates): the same
    verdict, ρ* to 1e-9 and the final contact forces to 1e-9 of the weight."""
    from tests.helpers import count_derived_responses, pick_up_box

    derived = count_derived_responses(monkeypatch)
    results = {}
    for updates in (False, True):
        results[updates] = pick_up_box(0.5, settings=EngineSettings(neighbour_updates=updates))
    fresh, new = results[False], results[True]
    assert sum(derived) >= 10  # the default path did derive responses
    assert new.success == fresh.success and len(fresh.events) > 10
    assert abs(new.squeeze_depth - fresh.squeeze_depth) <= 1e-9 * fresh.squeeze_depth
    for key, forces in fresh.final.contact_forces.items():
        np.testing.assert_allclose(new.final.contact_forces[key], forces, rtol=0, atol=1e-9 * fresh.body.weight)
