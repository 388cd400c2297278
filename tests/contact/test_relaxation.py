"""The static stick/slide/release state of all contacts at once (fem_grasp.contact.relaxation).

Checked against a hand-computed single contact, and on a real body (a box
squeezed sideways on the table) against Coulomb's law at every contact.  Each
iteration bound (steady drift, stall, a contact with no local state,
``max_sweeps``) is driven on a load that friction cannot hold and must end in
a :class:`RelaxationFailure` that names it, never a loop.
"""

import numpy as np
import pytest

from fem_grasp import Body, ContactResponse, box_mesh
from fem_grasp.contact.relaxation import RELEASE, SLIDE, STICK, RelaxationFailure, relax_contacts
from fem_grasp.settings import DEFAULT_SETTINGS
from tests.helpers import box_on_the_table_pushed_sideways, squeezed_box_contacts

UP = np.array([0.0, 0.0, 1.0])
#: The settings with the growth bound out of reach, to see the bounds it would otherwise come before.
NO_GROWTH_BOUND = DEFAULT_SETTINGS.replace(growth_sweeps=10**9)


@pytest.mark.parametrize("force, status", [((0.2, 0.0, 1.0), STICK), ((0.8, 0.0, 1.0), SLIDE),
                                           ((0.3, 0.1, -0.5), RELEASE)])
def test_one_table_contact_by_hand(force, status):
    k, mu = 50.0, 0.5
    f0 = np.array([force])
    res = relax_contacts(k * np.eye(3), f0, np.zeros((1, 3)), [None], UP, np.array([mu]), force_scale=1.0)
    assert res.status[0] == status
    if status == STICK:
        assert np.all(res.displacements == 0) and np.allclose(res.forces, f0)
    elif status == SLIDE:
        # Isotropic stiffness: it slides straight back by (f_t − μ f_n)/k, its normal force unchanged.
        slide = (0.8 - mu * 1.0) / k
        assert res.displacements[0] == pytest.approx([-slide, 0.0, 0.0], abs=1e-13)
        assert res.forces[0] == pytest.approx([mu, 0.0, 1.0], abs=1e-11)
        assert res.slips[0] == pytest.approx(slide, rel=1e-10)
    else:
        assert np.allclose(res.forces, 0.0, atol=1e-14)
        assert res.displacements[0, 2] > 0  # it lifts off the table


def test_a_squeezed_box_reaches_a_state_that_obeys_coulombs_law_everywhere():
    c, f0, q0, centers, mu, radius = squeezed_box_contacts()
    fs = float(np.abs(f0).max())
    res = relax_contacts(c, f0, q0, centers, UP, mu, fs)
    assert set(res.status) >= {STICK, SLIDE}  # a real mix: some table nodes slide outward, some stick
    assert np.allclose(res.forces, f0 + (c @ res.displacements.reshape(-1)).reshape(-1, 3), atol=1e-14 * fs)
    fn = np.einsum("ki,ki->k", res.forces, res.normals)
    ft = res.forces - fn[:, None] * res.normals
    ftn = np.linalg.norm(ft, axis=1)
    for k, st in enumerate(res.status):
        q = q0[k] + res.displacements[k]
        gap = q[2] - q0[k][2] if centers[k] is None else np.linalg.norm(q - centers[k]) - radius
        if st == STICK:
            assert np.all(res.displacements[k] == 0)
            assert fn[k] >= 0 and ftn[k] <= mu[k] * fn[k] + 1e-10 * fs
        elif st == SLIDE:
            assert abs(gap) < 1e-15  # on its obstacle: the plane, or the fingertip sphere
            assert fn[k] > 0 and ftn[k] == pytest.approx(mu[k] * fn[k], abs=1e-10 * fs)
            # Friction opposes the motion (maximum dissipation): f_t ∥ −(tangential part of δ).
            move = res.displacements[k] - (res.displacements[k] @ res.normals[k]) * res.normals[k]
            assert ft[k] @ move / (ftn[k] * np.linalg.norm(move)) == pytest.approx(-1.0, abs=1e-6)
        else:
            assert np.allclose(res.forces[k], 0, atol=1e-10 * fs) and gap >= 0
    # The state is static: relaxing it again moves nothing.
    again = relax_contacts(c, res.forces, q0 + res.displacements, centers, UP, mu, fs)
    assert np.all(again.status != SLIDE) or np.abs(again.displacements).max() < 1e-12 * radius


def test_a_sideways_load_no_friction_can_hold_is_refused():
    body = Body(box_mesh((-0.015, -0.02, 0.0), (0.015, 0.02, 0.03), (3, 3, 3)), 2e4, 0.3, weight=0.3)
    p = body.mesh.points
    table = np.flatnonzero(np.isclose(p[:, 2], 0.0))
    c = ContactResponse(body, table).reduced_stiffness
    # Only the table holds, and the load's tangential total is twice what μ times its normal total allows.
    # C annihilates rigid translations, so the force sum is the same whatever the contacts do: no static
    # state exists, and the contacts slide on until the slip bound.
    f = np.tile([1.0, 0.0, 1.0], (len(table), 1))
    with pytest.raises(RelaxationFailure, match="cannot hold|no longer hold"):
        relax_contacts(c, f, p[table], [None] * len(table), UP, np.full(len(table), 0.5), 1.0, max_slip=1e-3,
                       max_sweeps=2000)


def test_a_release_beyond_the_slip_bound_is_refused_not_returned():
    # A nearly free contact pulled off the table would fly a kilometre to carry no force: refused by name
    # (never an overflow or a NaN in the result).
    with pytest.raises(RelaxationFailure, match="no longer hold") as failure:
        relax_contacts(1e-3 * np.eye(3), np.array([[0.0, 0.0, -1.0]]), np.zeros((1, 3)), [None], UP,
                       np.array([0.5]), force_scale=1.0, max_slip=1e-2)
    assert (failure.value.kind, failure.value.contact) == ("lost support", 0)


def test_a_failure_says_its_kind_and_keeps_it_across_processes():
    """The verdict of a return mapping with no static state is its kind (what the callers and the cross-path
    tests compare), not its message; it survives pickling (Dask workers, subprocesses)."""
    import pickle

    c, f, q, centers, mu = box_on_the_table_pushed_sideways(1.0)
    with pytest.raises(RelaxationFailure) as failure:
        relax_contacts(c, f, q, centers, UP, mu, 1.0, max_slip=1.0)
    assert failure.value.kind == "gross slip" and 0 <= failure.value.contact < len(f)
    again = pickle.loads(pickle.dumps(failure.value))
    assert (again.kind, again.contact, str(again)) == (failure.value.kind, failure.value.contact, str(failure.value))
    with pytest.raises(RelaxationFailure, match="singular") as singular:
        relax_contacts(np.zeros((3, 3)), np.array([[0.0, 0.0, 1.0]]), np.zeros((1, 3)), [None], UP, np.array([0.5]),
                       1.0)
    assert singular.value.kind == "singular"
    with pytest.raises(ValueError, match="unknown relaxation failure kind"):
        RelaxationFailure("x", "slipped")


# ------------------------------------------------------------ every iteration bound ends in a named failure


def test_a_load_friction_can_hold_sticks_at_once():
    c, f, q, centers, mu = box_on_the_table_pushed_sideways(0.49)
    res = relax_contacts(c, f, q, centers, UP, mu, 1.0, max_slip=1.0)
    assert res.sweeps == 1 and np.all(res.status == STICK) and np.all(res.displacements == 0)


def test_motion_that_does_not_decay_ends_at_the_growth_bound(monkeypatch):
    """0.8 N sideways per newton down, μ = 0.5: the contacts slide ever faster from sweep to sweep.  Once a
    contact has moved DRIFT_SLIP × max_slip, a motion per sweep no smaller than GROWTH_SWEEPS sweeps before ends
    the sweeps — before the drift bound (which needs DRIFT_SWEEPS sweeps of unchanged statuses) or the slip
    bound — and names the contact that has moved furthest.  (At 0.6 N the motion decays, if slowly: the drift
    bound, below, ends that one.)"""
    import re

    c, f, q, centers, mu = box_on_the_table_pushed_sideways(0.8)
    match = r"move no slower after (\d+) Gauss–Seidel sweeps than 20 sweeps before \(contact (\d+) has moved"
    with pytest.raises(RelaxationFailure, match=match) as failure:
        relax_contacts(c, f, q, centers, UP, mu, 1.0, max_slip=1.0)
    assert failure.value.kind == "gross slip"
    sweeps, k = (int(g) for g in re.search(match, str(failure.value)).groups())
    assert DEFAULT_SETTINGS.growth_sweeps < sweeps < DEFAULT_SETTINGS.drift_sweeps
    assert failure.value.contact == k and 0 <= k < len(f)
    # Without the growth bound the same slide runs on until another bound ends it.
    with pytest.raises(RelaxationFailure, match=r"(?:after|sweep) (\d+)") as later:
        relax_contacts(c, f, q, centers, UP, mu, 1.0, max_slip=1.0, settings=NO_GROWTH_BOUND)
    assert later.value.kind == "gross slip"
    assert int(re.search(r"(?:after|sweep) (\d+)", str(later.value)).group(1)) > sweeps


def test_a_slowly_converging_relaxation_is_not_ended_by_the_growth_bound():
    """A load friction can hold, on contacts that slide before they stick (the squeezed box): the sweeps' motion
    decays, so the growth bound never fires and the static state is found."""
    c, f0, q0, centers, mu, _ = squeezed_box_contacts()
    res = relax_contacts(c, f0, q0, centers, UP, mu, float(np.abs(f0).max()))
    assert res.sweeps >= 2 and np.all(np.isfinite(res.forces))


@pytest.mark.parametrize("bound, value, match", [
    ("drift_sweeps", 20, r"keep sliding at a steady rate after (\d+) Gauss–Seidel sweeps"),
    ("drift_sweeps", 300, r"keep sliding at a steady rate after (\d+) Gauss–Seidel sweeps"),  # the default
    ("stall_sweeps", 5, r"stops settling after (\d+) Gauss–Seidel sweeps \(no progress in the last 5\)"),
])
def test_gross_slip_ends_at_the_drift_or_stall_bound(monkeypatch, bound, value, match):
    """0.6 N sideways per newton down, μ = 0.5: the contacts slide at a steady rate forever.  With unchanged
    statuses a steady drift is recognised after drift_sweeps sweeps (the motion does not decay: at its rate the
    contacts would slide past the slip bound); with no halving of the largest force
    change in stall_sweeps sweeps the sweeps stop too (here the stall bound is set below the drift one)."""
    import re

    settings = NO_GROWTH_BOUND.replace(**{bound: value})
    c, f, q, centers, mu = box_on_the_table_pushed_sideways(0.6)
    with pytest.raises(RelaxationFailure, match=match) as failure:
        relax_contacts(c, f, q, centers, UP, mu, 1.0, max_slip=1.0, settings=settings)
    sweeps = int(re.search(match, str(failure.value)).group(1))
    # The statuses settle within the first sweeps, then the bound counts; the drift bound extrapolates the motion
    # still to come from its decay over the last drift_sweeps sweeps, so a steady drift ends within two windows.
    assert value < sweeps <= (2 * value if bound == "drift_sweeps" else value) + 5


def test_max_sweeps_ends_a_slow_slide():
    c, f, q, centers, mu = box_on_the_table_pushed_sideways(0.6)
    with pytest.raises(RelaxationFailure, match=r"did not settle in 100 Gauss–Seidel sweeps"):
        relax_contacts(c, f, q, centers, UP, mu, 1.0, max_slip=1.0, max_sweeps=100)
    # A solvable problem that needs two sweeps (the squeezed box) fails on one and passes on two.
    c, f0, q0, centers, mu, _ = squeezed_box_contacts()
    fs = float(np.abs(f0).max())
    with pytest.raises(RelaxationFailure, match=r"did not settle in 1 Gauss–Seidel sweeps"):
        relax_contacts(c, f0, q0, centers, UP, mu, fs, max_sweeps=1)
    assert relax_contacts(c, f0, q0, centers, UP, mu, fs, max_sweeps=2).sweeps == 2


def test_a_contact_with_no_local_state_ends_at_the_stuck_bound(monkeypatch):
    """1 N sideways per newton down: once the neighbours have slid far, some contact has no stick, slide or
    release state with them frozen; after stuck_sweeps such sweeps in a row the relaxation gives up
    (50, the default, is reached before the drift bound).  A larger bound can only end it later: a run of
    stuck sweeps long enough for a larger bound is long enough for a smaller one."""
    import re

    c, f, q, centers, mu = box_on_the_table_pushed_sideways(1.0)
    ends = []
    for stuck in (2, 5, DEFAULT_SETTINGS.stuck_sweeps):
        settings = NO_GROWTH_BOUND.replace(stuck_sweeps=stuck)
        with pytest.raises(RelaxationFailure, match=r"contact \d+ can neither stick, slide nor lift off with its "
                                                    r"neighbours held .* μ = 0.5; sweep (\d+)\): friction cannot "
                                                    r"hold it") as failure:
            relax_contacts(c, f, q, centers, UP, mu, 1.0, max_slip=1.0, settings=settings)
        sweep = int(re.search(r"sweep (\d+)\)", str(failure.value)).group(1))
        assert sweep > stuck
        ends.append(sweep)
    assert ends == sorted(ends)


def test_the_polish_projection_is_the_slide_residual_of_the_sweeps(rng):
    """The polish maps each sliding contact's force to its slide residual (slide_projection, all contacts
    at once in gauss_seidel.SlideGeometry); the sweeps evaluate the residual of one contact (slide_residual).  The two
    must agree, on a table and on a fingertip, with and without motion."""
    from fem_grasp.contact.kernels import gauss_seidel as gs

    up = np.array([0.0, 0.0, 1.0])
    m = 6
    a = rng.normal(size=(m, 3, 3))
    ckk = a @ a.transpose(0, 2, 1) + 3 * np.eye(3)
    centres = [None if k % 2 else rng.normal(size=3) for k in range(m)]
    q0 = np.array([rng.normal(size=3) if ctr is None else
                   ctr + 0.01 * (lambda v: v / np.linalg.norm(v))(rng.normal(size=3)) for ctr in centres])
    rec = gs.contact_records(q0, centres, up, ckk)
    mu = rng.uniform(0.2, 0.8, size=m)
    us = 3e-3 * rng.normal(size=(m, 2))
    us[1] = 0.0  # no motion at all
    proj, delta = gs.SlideGeometry(rec, mu).projections(us)
    for k in range(m):
        d0, d1, d2, n0, n1, n2, *_ = gs.motion(rec[k], *us[k])
        # all contacts at once against one contact's kernel call: equal to round-off
        np.testing.assert_allclose(delta[k], [d0, d1, d2], rtol=0, atol=1e-15 * 3e-3)
        if centres[k] is not None:  # on the sphere, and moved along it by the arc length |u|
            assert np.linalg.norm(q0[k] + delta[k] - centres[k]) == pytest.approx(0.01, rel=1e-12)
            np.testing.assert_allclose([n0, n1, n2], (q0[k] + delta[k] - centres[k]) / 0.01, atol=1e-12)
        f = rng.normal(size=3)
        fs = f - ckk[k] @ delta[k]
        g0, g1, _ = gs.slide_residual(rec[k], *fs, float(mu[k]), *us[k])
        np.testing.assert_allclose(proj[k] @ f, [g0, g1], atol=1e-12 * np.abs(f).max())


def test_a_sideways_loaded_fingertip_contact_lifts_off_the_curved_tip():
    """A fingertip node carrying mostly tangential force with a tensile normal part (taken from a 10k-vertex
    orange's lift) has no slide state: no tangential motion brings its force into the cone.  Its force-free
    position lies inside the tangent plane (δ·n̂⁰ < 0) yet outside the sphere (|r⁰ + δ| > R), so by the
    exact Signorini condition it lifts off; the linearised test alone left it with no state at all."""
    radius = 0.01
    r0 = np.array([0.007290439, -0.00614403, -0.003016686])
    r0 *= radius / np.linalg.norm(r0)
    ckk = np.array([[95.542592, 5.754139, -1.083938], [5.754139, 62.401059, 9.654799],
                    [-1.083938, 9.654799, 89.765847]])
    f0 = np.array([[0.001207033731, -0.000896926887, 0.008640064297]])
    n0 = r0 / radius
    assert f0[0] @ n0 < 0 < np.linalg.norm(f0[0] - (f0[0] @ n0) * n0)
    res = relax_contacts(ckk, f0, r0[None, :], [np.zeros(3)], UP, np.array([0.5]), force_scale=0.01)
    assert res.status[0] == RELEASE
    assert np.abs(res.forces).max() <= 1e-15
    delta = res.displacements[0]
    assert delta @ n0 < 0  # into the tangent plane ...
    assert np.linalg.norm(r0 + delta) > radius  # ... but clear of the sphere


def test_the_polish_jacobian_matches_finite_differences(rng):
    """The polish's Newton Jacobian (coupling blocks ∂R/∂f C ∂δ/∂x assembled contact by contact, plus each
    sliding contact's own geometric block) against central differences of its residual, on the squeezed box
    with table and fingertip contacts sliding, one table contact released and the rest sticking."""
    from fem_grasp.contact.kernels import gauss_seidel as gs
    from fem_grasp.contact.relaxation import _polish_system

    c, f0, q0, centers, mu, radius = squeezed_box_contacts()
    m = len(f0)
    ckk = np.array([c[3 * k:3 * k + 3, 3 * k:3 * k + 3] for k in range(m)])
    rec = gs.contact_records(q0, centers, UP, ckk)
    status = np.full(m, STICK)
    status[[0, 2, m - 2, m - 1]] = SLIDE  # two table contacts and both fingertip contacts
    status[1] = RELEASE
    u = np.zeros((m, 2))
    u[status == SLIDE] = 1e-4 * rng.normal(size=(4, 2))
    d = np.zeros((m, 3))
    d[1] = 1e-4 * rng.normal(size=3)
    act, offs, x, evaluate = _polish_system(rec, c, f0, mu, status, d, u)
    assert act == [0, 1, 2, m - 2, m - 1] and len(x) == 2 + 3 + 2 + 2 + 2
    x = x + 1e-5 * rng.normal(size=len(x))
    jac = evaluate(x, True)[3]
    h = 1e-8
    fd = np.stack([(evaluate(x + h * e, False)[0] - evaluate(x - h * e, False)[0]) / (2 * h)
                   for e in np.eye(len(x))], axis=1)
    np.testing.assert_allclose(jac, fd, rtol=0, atol=1e-5 * np.abs(fd).max())
    assert np.abs(jac).max() > 0 and np.count_nonzero(np.abs(jac) > 1e-6 * np.abs(jac).max()) > len(x)


def test_the_static_state_does_not_depend_on_where_the_sweeps_start():
    """A start (statuses, displacements, motions) is only where the sweeps begin: from the solution they stop at
    once, from another problem's solution they reach this problem's static state, the same as from held."""
    from tests.helpers import assert_same_relaxation

    def outcome(r, scale):
        return r.status, r.forces, r.displacements, scale

    for mu, depth, other in ((0.5, 2e-3, 4e-3), (0.3, 2e-3, 1e-3), (0.5, 4e-3, 2e-3)):
        c, f0, q0, centers, mu_k, _ = squeezed_box_contacts(mu, depth)
        fs = float(np.abs(f0).max())
        held = relax_contacts(c, f0, q0, centers, UP, mu_k, fs)
        assert (held.status == SLIDE).any()
        again = relax_contacts(c, f0, q0, centers, UP, mu_k, fs, start=(held.status, held.displacements, held.motions))
        assert again.sweeps <= 2
        assert_same_relaxation(outcome(again, fs), outcome(held, fs))
        # another depth's solution, on this problem's start positions: a wrong start, the same answer
        c2, f2, q2, centers2, _, _ = squeezed_box_contacts(mu, other)
        wrong = relax_contacts(c2, f2, q2, centers2, UP, mu_k, float(np.abs(f2).max()))
        moved = relax_contacts(c, f0, q0, centers, UP, mu_k, fs, start=(wrong.status, wrong.displacements,
                                                                        wrong.motions))
        assert_same_relaxation(outcome(moved, fs), outcome(held, fs))


def test_a_contact_whose_own_block_is_singular_still_slides_onto_its_cone():
    """With exactly three contacts each one's own stiffness block C_kk is singular (a rigid turn about the line
    through the other two moves that contact alone), so its smallest eigenvalue, which bounds the slide's ray
    search, is zero up to round-off and may be exactly zero: the sweep must not divide by it.  A table contact
    pressed with 10 N and pushed sideways with 30 N (μ = 0.5), its record's smallest eigenvalue set to 0, slides
    until its tangential force is μ times its normal force."""
    from fem_grasp.contact.kernels import gauss_seidel as gs

    stiffness = 1e4 * np.eye(3)
    rec = gs.contact_records(np.zeros((1, 3)), [None], np.array([0.0, 0.0, 1.0]), stiffness[None])
    rec[0, gs.REC_KMIN] = 0.0
    f = np.array([[30.0, 0.0, 10.0]])
    d, u = np.zeros((1, 3)), np.zeros((1, 2))
    has_u, status = np.zeros(1, np.int64), np.full(1, gs.STICK, np.int64)
    code, _, _, _, unsolved = gs.sweep(rec, stiffness.T.copy(), f, d, u, has_u, status, np.array([0.5]), 1e-12,
                                       1e-12, 0.1, np.zeros((1, 10)), np.zeros(3))
    assert code == gs.OK and unsolved == -1 and status[0] == gs.SLIDE
    assert f[0, 2] == pytest.approx(10.0, rel=1e-12)
    assert np.hypot(f[0, 0], f[0, 1]) == pytest.approx(0.5 * f[0, 2], rel=1e-9)
