"""Friction cones and slip systems (paper §III, eqs. 6–8)."""

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from fem_grasp import Body, box_mesh
from fem_grasp.contact import friction
from fem_grasp.contact.obstacles import TablePlane, tangent_basis
from fem_grasp.grasp.pose import rotation_between

UP = np.array([0.0, 0.0, 1.0])
#: Entries of unit vectors computed two ways agree to a few ulps of 1.
UNIT_ROUNDOFF = 8 * np.finfo(float).eps


def _spd(rng, m, scale=1e3):
    a = rng.normal(size=(3 * m, 3 * m))
    return scale * (a @ a.T / (3 * m) + np.eye(3 * m))


def _fd_jacobian(fun, x, h):
    cols = []
    for j in range(len(x)):
        e = np.zeros_like(x)
        e[j] = h[j]
        cols.append((fun(x + e) - fun(x - e)) / (2 * h[j]))
    return np.stack(cols, axis=1)


# ---------------------------------------------------------------- cone tests
def test_cone_quantities_by_hand():
    f = np.array([[3.0, 4.0, 10.0], [0.0, 0.0, -1.0], [6.0, 8.0, 10.0]])
    np.testing.assert_allclose(friction.normal_component(f, UP), [10, -1, 10])
    np.testing.assert_allclose(friction.tangential_component(f, UP), [[3, 4, 0], [0, 0, 0], [6, 8, 0]])
    np.testing.assert_allclose(friction.cone_violation(f, UP, 0.5), [0, 0.5, 5])
    np.testing.assert_allclose(friction.cone_residual(f, UP, 0.5), [0, 0.25, 25 - 100])  # the double cone of eq. (6) holds f = (0, 0, −1) too
    np.testing.assert_array_equal(friction.is_compressive(f, UP), [True, False, True])
    np.testing.assert_array_equal(friction.in_cone(f, UP, 0.5), [True, False, False])
    np.testing.assert_allclose(friction.cone_ratio(f, UP), [0.5, np.inf, 1.0])
    np.testing.assert_allclose(friction.slip_directions(f[[0, 2]], UP), [[0.6, 0.8, 0], [0.6, 0.8, 0]])
    with pytest.raises(ValueError, match="no slip direction"):
        friction.slip_directions(f[1], UP)


@settings(max_examples=60, deadline=None)
@example([0.0, 0.0, 7.3], 2.7e-9, [0.0, 0.0, 1.0])  # once flaky: force on the normal, μ ~ 1e-9
@given(st.lists(st.floats(-10, 10), min_size=3, max_size=3), st.floats(0, 3),
       st.lists(st.floats(-1, 1), min_size=3, max_size=3).filter(lambda v: np.linalg.norm(v) > 0.1))
def test_cone_residual_and_violation_agree(force, mu, normal):
    f = np.array(force)
    n = np.array(normal) / np.linalg.norm(normal)
    fn = friction.normal_component(f, n)
    viol = friction.cone_violation(f, n, mu)
    res = friction.cone_residual(f, n, mu)
    # Eq. (6) rewritten: (1+μ²)(f·n)² − f·f = μ²(f·n)² − |f_t|².
    ft = np.linalg.norm(friction.tangential_component(f, n))
    assert res == pytest.approx(mu**2 * fn**2 - ft**2, abs=1e-9 * (1 + f @ f))
    # res = (1+μ²)(f·n)² − f·f cancels to round-off ~ε f·f; compare signs only above it.
    if fn > 0 and abs(viol) > 1e-9 * (1 + abs(fn)) and abs(res) > 1e-12 * (1 + f @ f):
        assert (viol < 0) == (res > 0)
        assert bool(friction.in_cone(f, n, mu)) == (viol < 0)


# ------------------------------------------------- Jacobians vs finite differences
def test_plane_slip_jacobian_matches_finite_differences(rng):
    m = 5
    c = _spd(rng, m)
    f0 = rng.normal(size=(m, 3)) + [0, 0, 3]
    sliding = np.array([0, 2, 3])
    system = friction.plane_slip_system(c, f0, sliding, UP, 0.4)
    x = 1e-3 * rng.normal(size=3)
    h = 1e-6 * np.ones(3)
    np.testing.assert_allclose(system.jacobian(x), _fd_jacobian(system.residual, x, h), rtol=1e-6, atol=1e-6)
    # The residual is eq. (6) at the affine forces.
    f = system.forces(x)
    np.testing.assert_allclose(system.residual(x), (1 + 0.16) * f[sliding, 2] ** 2 - (f[sliding] ** 2).sum(1))
    np.testing.assert_allclose(system.forces(x).ravel(), f0.ravel() + c @ system.displacement_map @ x)


def test_free_direction_slip_jacobian_matches_finite_differences(rng):
    m = 4
    c = _spd(rng, m)
    f0 = rng.normal(size=(m, 3)) + [0, 0, 3]
    n = np.array([0.2, -0.1, 1.0])
    n /= np.linalg.norm(n)
    system = friction.plane_free_slip_system(c, f0, np.array([1, 3]), n, 0.3)
    assert system.n_unknowns == 4 and system.n_rows == (2, 0, 2)
    x = 1e-3 * rng.normal(size=4)
    np.testing.assert_allclose(system.jacobian(x), _fd_jacobian(system.residual, x, 1e-6 * np.ones(4)),
                               rtol=1e-6, atol=1e-6)
    u = system.displacements(x)
    assert np.allclose(u @ n, 0)  # slips stay in the plane


def test_general_slip_system_with_constraint_matches_finite_differences(rng):
    """A fingertip-like system (eqs. 7–8): unknowns (c, s), displacement affine in them, c² + s² = 1."""
    m = 3
    c = _spd(rng, m)
    f0 = rng.normal(size=(m, 3)) + [0, 0, 2]
    k = 1  # the sliding node, on a sphere of centre o
    o, p = np.array([0.0, 0.0, -0.02]), np.array([0.003, 0.001, 0.0])
    axis = np.array([0.3, 1.0, 0.0])
    axis /= np.linalg.norm(axis)
    e = np.zeros((3 * m, 2))
    e[3 * k:3 * k + 3, 0] = p - o
    e[3 * k:3 * k + 3, 1] = np.cross(axis, p - o)
    e0 = np.zeros(3 * m)
    e0[3 * k:3 * k + 3] = o - p  # q − p = o + c(p−o) + s N×(p−o) − p
    circle = friction.QuadraticConstraint(np.eye(2), np.zeros(2), -1.0)
    system = friction.SlipSystem(c, f0, e, [k], (p - o) / np.linalg.norm(p - o), [0.5], displacement_offset=e0,
                                 constraints=[circle], unknown_scale=np.ones(2))
    x = np.array([np.cos(-0.1), np.sin(-0.1)]) * 1.01
    np.testing.assert_allclose(system.jacobian(x), _fd_jacobian(system.residual, x, 1e-6 * np.ones(2)),
                               rtol=1e-6, atol=1e-6)
    # At c = 1, s = 0 the node has not moved.
    np.testing.assert_allclose(system.displacements([1.0, 0.0])[k], 0, atol=1e-15)
    with pytest.raises(ValueError, match="not square"):
        friction.SlipSystem(c, f0, e, [k], UP, [0.5])


# ------------------------------------------------------ hand-computable slips
def test_spring_block_slides_exactly_to_the_cone():
    """One node on independent springs: f(d) = (F − k_t d, 0, N), so d = (F − μN)/k_t."""
    kt, kn, mu = 2.0e3, 5.0e3, 0.3
    c = np.diag([kt, kt, kn])
    f0 = np.array([[4.0, 0.0, 10.0]])
    out = friction.solve_plane_slip(c, f0, [0], UP, mu)
    np.testing.assert_allclose(out.distances, [(4.0 - mu * 10.0) / kt], rtol=1e-12)
    np.testing.assert_allclose(out.directions, [[1, 0, 0]])
    np.testing.assert_allclose(out.forces, [[mu * 10.0, 0, 10.0]], rtol=1e-12)
    np.testing.assert_allclose(out.displacements, [[-(4.0 - mu * 10.0) / kt, 0, 0]], rtol=1e-12)
    # Free directions give the same answer here (the friction stays along x).
    free = friction.solve_plane_slip(c, f0, [0], UP, mu, free=True)
    np.testing.assert_allclose(free.forces, out.forces, rtol=1e-10, atol=1e-12)


def test_two_coupled_blocks_slide_symmetrically():
    """Two nodes with tangential coupling b: each slides d = (F − μN)/(a + b) (C[i,j] = b·I_t between them)."""
    a, b, kn, mu = 3.0e3, 1.0e3, 8.0e3, 0.25
    blk = np.diag([a, a, kn])
    off = np.diag([b, b, 0.0])
    c = np.block([[blk, off], [off, blk]])
    f0 = np.array([[2.0, 1.0, 4.0], [2.0, 1.0, 4.0]])
    out = friction.solve_plane_slip(c, f0, [0, 1], UP, mu)
    ft0 = np.hypot(2.0, 1.0)
    np.testing.assert_allclose(out.distances, 2 * [(ft0 - mu * 4.0) / (a + b)], rtol=1e-12)
    np.testing.assert_allclose(friction.cone_violation(out.forces, UP, mu), 0, atol=1e-12)


def test_node_pulled_back_into_its_cone_sticks():
    """Node A's slip relieves node B, so B's eq. (6) root is a negative slip: B sticks instead."""
    kt, kn, cpl, mu = 1.0e3, 1.0e3, 0.6e3, 0.5
    c = np.zeros((6, 6))
    c[:3, :3] = c[3:, 3:] = np.diag([kt, kt, kn])
    c[0, 3] = c[3, 0] = -cpl  # A's x-slip pushes B's x-force up
    f0 = np.array([[3.0, 0.0, 2.0], [-1.05, 0.0, 2.0]])  # A far outside (1.5), B barely (|f_t| 1.05 > 1.0)
    out = friction.solve_plane_slip(c, f0, [0, 1], UP, mu)
    np.testing.assert_array_equal(out.sliding, [0])
    np.testing.assert_array_equal(out.stuck, [1])
    assert friction.cone_violation(out.forces, UP, mu)[0] == pytest.approx(0, abs=1e-12)
    assert friction.in_cone(out.forces[1], UP, mu)


def _inclined_block(ratio, mu):
    """A soft block held at its base nodes on a plane inclined by θ = atan(ratio·μ); gravity −z."""
    theta = np.arctan(ratio * mu)
    n = np.array([np.sin(theta), 0.0, np.cos(theta)])
    mesh = box_mesh((0, 0, 0), (0.03, 0.02, 0.01), (3, 2, 2))
    base = np.flatnonzero(mesh.points[:, 2] == 0)
    body = Body(mesh.transformed(rotation_between(UP, n)), 1e5, 0.3, weight=1.0)
    resp = body.contact_response(base)
    return resp, resp.forces(np.zeros((len(base), 3))), n


def test_block_on_incline_holds_up_to_tan_theta_equal_mu():
    """Coulomb limit on a soft block: tanθ < μ settles with every node in its cone; tanθ > μ cannot."""
    mu = 0.4
    resp, f0, n = _inclined_block(0.99, mu)
    out = friction.settle_plane_slip(resp.reduced_stiffness, f0, n, mu)
    f = out.forces
    fn = friction.normal_component(f, n)
    ft = np.linalg.norm(friction.tangential_component(f, n), axis=1)
    assert (fn > 0).all() and (ft <= (mu + 1e-9) * fn).all()
    assert len(out.slid) == len(f)  # near the limit every node slides ...
    assert ft.sum() == pytest.approx(mu * fn.sum(), rel=1e-9)  # ... so Σ|f_t| = μ Σ f_n
    # The resultant balances the weight: its tangential/normal ratio is tanθ.
    total = f.sum(axis=0)
    tn = total @ n
    assert np.linalg.norm(total - tn * n) / tn == pytest.approx(0.99 * mu, rel=1e-9)
    # The forces are those of eq. (5) at the slid contact displacements.
    np.testing.assert_allclose(resp.forces(out.displacements), f, atol=1e-12)
    # Far from the limit only the most loaded nodes slip.
    resp2, f02, n2 = _inclined_block(0.5, mu)
    out2 = friction.settle_plane_slip(resp2.reduced_stiffness, f02, n2, mu)
    assert 0 < len(out2.slid) < len(f02)
    resp3, f03, n3 = _inclined_block(1.01, mu)
    with pytest.raises(friction.FrictionError, match="gross sliding"):
        friction.settle_plane_slip(resp3.reduced_stiffness, f03, n3, mu)


def test_frictionless_displacements_remove_all_friction():
    mesh = box_mesh((0, 0, 0), (0.03, 0.02, 0.02), (3, 2, 2))
    body = Body(mesh, 5e4, 0.3, weight=1.0)
    base = np.flatnonzero(mesh.points[:, 2] == 0)
    resp = body.contact_response(base)
    d0 = np.zeros((len(base), 3))
    dofs = (3 * base[:, None] + np.arange(3)).ravel()
    gauge = body.rigid_modes[dofs][:, [0, 1, 5]]
    u = friction.frictionless_tangential_displacements(resp.reduced_stiffness, resp.forces(d0), UP, gauge)
    f = resp.forces(d0 + u)
    assert np.abs(u[:, 2]).max() == 0
    assert np.abs(f[:, :2]).max() < 1e-12 * np.abs(f).max()
    np.testing.assert_allclose(f[:, 2].sum(), body.weight, rtol=1e-12)
    assert np.abs(gauge.T @ u.ravel()).max() < 1e-12 * np.abs(u).max()


def test_table_plane_geometry():
    table = TablePlane(0.5)
    p = np.array([[0, 0, 1.0], [1, 2, 0.25]])
    np.testing.assert_allclose(table.signed_distance(p), [0.5, -0.25])
    np.testing.assert_allclose(table.penetration(p), [0, 0.25])
    np.testing.assert_allclose(table.project(p), [[0, 0, 0.5], [1, 2, 0.5]])
    np.testing.assert_allclose(table.inward_normal(p), [[0, 0, 1], [0, 0, 1]])
    tilted = TablePlane(0.0, up=[0, 1, 1])
    np.testing.assert_allclose(tilted.up, np.array([0, 1, 1]) / np.sqrt(2))
    e = tangent_basis(tilted.up)
    np.testing.assert_allclose(e @ e.T, np.eye(2), atol=1e-15)
    np.testing.assert_allclose(np.cross(e[0], e[1]), tilted.up, atol=1e-15)
    with pytest.raises(ValueError):
        TablePlane(0.0, up=[0, 0, 0])


def test_tangent_bases_are_the_tangent_basis_of_each_normal(rng):
    from fem_grasp.contact.obstacles import tangent_bases

    normals = np.vstack([rng.normal(size=(20, 3)), np.eye(3), -np.eye(3)])
    bases = tangent_bases(normals)
    for n, b in zip(normals, bases):
        # Two code paths (vectorised and per row): the same basis to round-off, not bit for bit (the
        # vectorised norms and cross products round differently on some CPUs).
        np.testing.assert_allclose(b, tangent_basis(n), rtol=0, atol=UNIT_ROUNDOFF)
        np.testing.assert_allclose(np.cross(b[0], b[1]), n / np.linalg.norm(n), atol=1e-15)
