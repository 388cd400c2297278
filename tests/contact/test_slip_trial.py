"""The compiled slip systems (fem_grasp.contact.kernels.slip_trial) against the numpy reference (MixedSlipSystem).

The tracker's trials assemble, solve and read out their slip systems with
:class:`~fem_grasp.contact.slip_system.CompiledSlipSystem` where numba is
installed; :class:`~fem_grasp.contact.slip_system.MixedSlipSystem` stays as the
reference path (``EngineSettings(compiled_trials=False)``).  The two do the same
arithmetic in another summation order, so they agree to round-off: the arrays
of the system to ``ASSEMBLY_AGREEMENT``, roots and rates to the slip solves'
own agreement (``SLIP_SOLVE_AGREEMENT``), and whole pickups with the same
events and answer.
"""

import numpy as np
import pytest

from fem_grasp.contact import tracking
from fem_grasp.contact.kernels import jit, slip_residual, slip_trial
from fem_grasp.contact.obstacles import FINGER1, FINGER2, TABLE
from fem_grasp.contact.slip_system import CompiledSlipSystem, MixedSlipSystem, SlipFailure
from fem_grasp.contact.tracking import Tracker
from fem_grasp.grasp.rest import rest
from fem_grasp.settings import EngineSettings
from tests.contact.test_jit import SLIP_SOLVE_AGREEMENT
from tests.helpers import box_squeezed_3mm, pick_up_box, pickup_box, spd_matrix

#: The system's arrays from the kernels against numpy's, relative to each array's largest entry: sums of three
#: products in another order (C times the slip directions), a few units of round-off.
ASSEMBLY_AGREEMENT = 1e-13
RADIUS = 0.01


def _random_system(rng, free):
    """A slip system of five sliding nodes (two on the table, three on the two fingertips) out of eight contacts."""
    m = 8
    c = spd_matrix(rng, m)
    fh = rng.normal(size=(m, 3))
    fh[:, 2] += 3.0
    dfh = rng.normal(size=(m, 3))
    sliding = np.array([0, 2, 3, 5, 7])
    kinds = np.array([TABLE, FINGER1, TABLE, FINGER2, FINGER1])
    mu = np.full(5, 0.4)
    up = np.array([0.0, 0.0, 1.0])
    r = rng.normal(size=(5, 3))
    r *= RADIUS / np.linalg.norm(r, axis=1, keepdims=True)
    n0 = np.where((kinds == TABLE)[:, None], up, r / RADIUS)
    t = rng.normal(size=(5, 3))
    t -= np.einsum("ki,ki->k", t, n0)[:, None] * n0
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    args = (c, fh, dfh, sliding, kinds, mu, t, r, up, RADIUS, free)
    return MixedSlipSystem(*args), CompiledSlipSystem(*args)


def _close(a, b, tol):
    np.testing.assert_allclose(a, b, rtol=0, atol=tol * max(float(np.abs(b).max(initial=0.0)), 1e-300))


@pytest.mark.parametrize("free", [False, True])
def test_the_compiled_assembly_is_the_reference_system(free):
    ref, comp = _random_system(np.random.default_rng(3), free)
    assert comp.n == ref.n
    _close(comp.g, ref.g, ASSEMBLY_AGREEMENT)
    _close(comp.dmap, ref.d_map.reshape(-1, ref.n), ASSEMBLY_AGREEMENT)
    _close(comp.n0, ref.n0, ASSEMBLY_AGREEMENT)
    _close(comp.kappa, ref.kappa, 0.0)
    np.testing.assert_array_equal(comp.sph, ref.sph_idx)
    for mine, theirs in ((comp.xscale, ref.xscale), (comp.row_scale, ref.row_scale), (comp.row_noise, ref.row_noise),
                         (comp.own, ref.own)):
        np.testing.assert_allclose(mine, theirs, rtol=ASSEMBLY_AGREEMENT, atol=0)


@pytest.mark.parametrize("free", [False, True])
def test_the_compiled_outcome_is_the_reference_outcome(free):
    """Forces, displacement changes, slip amounts and rates at one point x of the unknowns."""
    ref, comp = _random_system(np.random.default_rng(4), free)
    x = 1e-3 * np.random.default_rng(5).normal(size=ref.n) * ref.xscale
    for mine, theirs in zip(comp.outcome(x), ref.outcome(x)):
        assert np.isfinite(theirs).all()
        _close(mine, theirs, SLIP_SOLVE_AGREEMENT)


def test_a_singular_rate_jacobian_reads_as_a_friction_limit():
    """The kernels' LU: numpy's solution for a regular matrix, 'no rates' when a pivot falls below
    SINGULAR_PIVOT of the largest (as MixedSlipSystem.rates reads scipy's factors) or for non-finite entries."""
    rng = np.random.default_rng(6)
    a = rng.normal(size=(12, 12))
    b = rng.normal(size=12)
    ok, x = slip_trial._solve_checked(a, b)
    assert ok
    _close(x, np.linalg.solve(a, b), 1e-12)
    singular = a.copy()
    singular[:, 5] = singular[:, 2] - singular[:, 7]
    assert not slip_trial._solve_checked(singular, b)[0]
    a[3, 3] = np.inf
    assert not slip_trial._solve_checked(a, b)[0]


def _trials(compiled, method):
    rs, tracker, state, vel = box_squeezed_3mm()
    tracker.compiled = compiled
    out = []
    for free in (False, True):
        tracker.forms = (free,)
        for dt in (1e-6, 1e-4, 1e-3, 3.4e-3, 6e-3):
            try:
                t = tracker.trial(state, dt, vel, methods=(method,))
                out.append((t.state.disp, t.state.forces, t.amounts, t.rates))
            except SlipFailure as exc:
                out.append(str(exc))
    return out


@pytest.mark.parametrize("method", ["newton", "homotopy"])
def test_compiled_trials_are_the_reference_trials(method):
    """The squeezed box's trial states, both slip forms, increments up to 60 % of the fingertip radius, by Newton's
    method or by the Newton homotopy alone: the same roots (or the same failure, with the same message), slip
    amounts and rates."""
    compiled, reference = _trials(True, method), _trials(False, method)
    assert sum(not isinstance(r, str) for r in reference) >= 6
    for a, b in zip(compiled, reference):
        if isinstance(a, str) or isinstance(b, str):
            assert a == b
            continue
        for u, v in zip(a, b):
            _close(u, v, SLIP_SOLVE_AGREEMENT)


def test_a_pickup_with_compiled_trials_is_the_reference_pickup():
    """The box picked up at μ = 0.5 with either path: the same verdict and events, ρ* to 1e-9 and the final contact
    forces to 1e-9 of the weight (issue #27's "same answer")."""
    results = {}
    for compiled in (False, True):
        results[compiled] = pick_up_box(0.5, settings=EngineSettings(compiled_trials=compiled))
    ref, comp = results[False], results[True]
    assert ref.success == comp.success
    assert [(e.kind, e.node, e.contact, e.phase) for e in comp.events] == \
        [(e.kind, e.node, e.contact, e.phase) for e in ref.events]
    assert len(ref.events) > 10
    assert abs(comp.squeeze_depth - ref.squeeze_depth) <= 1e-9 * ref.squeeze_depth
    weight = ref.body.weight
    for key, forces in ref.final.contact_forces.items():
        np.testing.assert_allclose(comp.final.contact_forces[key], forces, rtol=0, atol=1e-9 * weight)


def test_trackers_compile_their_trials_where_numba_is_installed():
    assert tracking.COMPILED_TRIALS == jit.ENABLED
    rs = rest(pickup_box(), 0.5)
    assert Tracker(rs.body, radius=RADIUS, mu_finger=0.5, mu_table=0.5, table=rs.table).compiled == jit.ENABLED


@pytest.mark.parametrize("free", [False, True])
def test_the_fused_residual_jacobian_and_newton_are_the_slip_newton_kernels(free):
    """fused_newton's residual and Jacobian (loops over the affine maps into preallocated arrays) against
    slip_newton's at a point x, and the two Newton iterations from the held state: the same verdict and root."""
    from fem_grasp.contact.kernels import slip_newton

    ref, comp = _random_system(np.random.default_rng(7), free)
    args = (comp.base_sl, comp.g_sl, comp.dmap, comp.n0, comp.kappa, comp.mu, comp.sph, comp.free)
    x = 1e-3 * np.random.default_rng(8).normal(size=comp.n) * comp.xscale
    p = len(comp.sliding)
    out, f, d, n = np.empty(comp.n), np.empty((p, 3)), np.empty((p, 3)), np.empty((p, 3))
    slip_residual.fused_residual(x, *args, out, f, d, n)
    _close(out, slip_newton.residual(x, *args), ASSEMBLY_AGREEMENT)
    jac = np.empty((comp.n, comp.n))
    slip_residual.fused_jacobian(x, comp.g_sl, comp.dmap, comp.kappa, comp.mu, comp.sph, comp.free, f, d, n, jac)
    _close(jac, slip_newton.jacobian(x, *args), ASSEMBLY_AGREEMENT)
    lim = np.maximum(1e-12, comp.row_noise)
    old = slip_newton.newton(np.zeros(comp.n), lim, 40, comp.xscale, comp.row_scale, *args)
    new = slip_residual.fused_newton(np.zeros(comp.n), lim, 40, comp.xscale, comp.row_scale, *args)
    assert old[0] == new[0]
    if old[0]:
        _close(new[1], old[1], SLIP_SOLVE_AGREEMENT)
