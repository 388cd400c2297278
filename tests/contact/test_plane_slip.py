"""The resting iteration's table slip (paper §III-A, eq. 6): slip systems against finite differences and by hand."""

import numpy as np
import pytest

from fem_grasp import Body, ContactResponse, box_mesh
from fem_grasp.contact import friction, plane_slip
from fem_grasp.grasp.pose import rotation_between
from tests.helpers import central_difference_jacobian, spd_matrix

UP = np.array([0.0, 0.0, 1.0])


def test_plane_slip_jacobian_matches_finite_differences(rng):
    m = 5
    c = spd_matrix(rng, m)
    f0 = rng.normal(size=(m, 3)) + [0, 0, 3]
    sliding = np.array([0, 2, 3])
    system = plane_slip.plane_slip_system(c, f0, sliding, UP, 0.4)
    x = 1e-3 * rng.normal(size=3)
    h = 1e-6 * np.ones(3)
    np.testing.assert_allclose(system.jacobian(x), central_difference_jacobian(system.residual, x, h), rtol=1e-6, atol=1e-6)
    # The residual is eq. (6) at the affine forces.
    f = system.forces(x)
    np.testing.assert_allclose(system.residual(x), (1 + 0.16) * f[sliding, 2] ** 2 - (f[sliding] ** 2).sum(1))
    np.testing.assert_allclose(system.forces(x).ravel(), f0.ravel() + c @ system.displacement_map @ x)


def test_free_direction_slip_jacobian_matches_finite_differences(rng):
    m = 4
    c = spd_matrix(rng, m)
    f0 = rng.normal(size=(m, 3)) + [0, 0, 3]
    n = np.array([0.2, -0.1, 1.0])
    n /= np.linalg.norm(n)
    system = plane_slip.plane_free_slip_system(c, f0, np.array([1, 3]), n, 0.3)
    assert system.n_unknowns == 4 and system.n_rows == (2, 0, 2)
    x = 1e-3 * rng.normal(size=4)
    np.testing.assert_allclose(system.jacobian(x), central_difference_jacobian(system.residual, x, 1e-6 * np.ones(4)),
                               rtol=1e-6, atol=1e-6)
    u = system.displacements(x)
    assert np.allclose(u @ n, 0)  # slips stay in the plane


def test_general_slip_system_with_constraint_matches_finite_differences(rng):
    """A fingertip-like system (eqs. 7–8): unknowns (c, s), displacement affine in them, c² + s² = 1."""
    m = 3
    c = spd_matrix(rng, m)
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
    circle = plane_slip.QuadraticConstraint(np.eye(2), np.zeros(2), -1.0)
    system = plane_slip.SlipSystem(c, f0, e, [k], (p - o) / np.linalg.norm(p - o), [0.5], displacement_offset=e0,
                                 constraints=[circle], unknown_scale=np.ones(2))
    x = np.array([np.cos(-0.1), np.sin(-0.1)]) * 1.01
    np.testing.assert_allclose(system.jacobian(x), central_difference_jacobian(system.residual, x, 1e-6 * np.ones(2)),
                               rtol=1e-6, atol=1e-6)
    # At c = 1, s = 0 the node has not moved.
    np.testing.assert_allclose(system.displacements([1.0, 0.0])[k], 0, atol=1e-15)
    with pytest.raises(ValueError, match="not square"):
        plane_slip.SlipSystem(c, f0, e, [k], UP, [0.5])


def test_spring_block_slides_exactly_to_the_cone():
    """One node on independent springs: f(d) = (F − k_t d, 0, N), so d = (F − μN)/k_t."""
    kt, kn, mu = 2.0e3, 5.0e3, 0.3
    c = np.diag([kt, kt, kn])
    f0 = np.array([[4.0, 0.0, 10.0]])
    out = plane_slip.solve_plane_slip(c, f0, [0], UP, mu)
    np.testing.assert_allclose(out.distances, [(4.0 - mu * 10.0) / kt], rtol=1e-12)
    np.testing.assert_allclose(out.directions, [[1, 0, 0]])
    np.testing.assert_allclose(out.forces, [[mu * 10.0, 0, 10.0]], rtol=1e-12)
    np.testing.assert_allclose(out.displacements, [[-(4.0 - mu * 10.0) / kt, 0, 0]], rtol=1e-12)
    # Free directions give the same answer here (the friction stays along x).
    free = plane_slip.solve_plane_slip(c, f0, [0], UP, mu, free=True)
    np.testing.assert_allclose(free.forces, out.forces, rtol=1e-10, atol=1e-12)


def test_two_coupled_blocks_slide_symmetrically():
    """Two nodes with tangential coupling b: each slides d = (F − μN)/(a + b) (C[i,j] = b·I_t between them)."""
    a, b, kn, mu = 3.0e3, 1.0e3, 8.0e3, 0.25
    blk = np.diag([a, a, kn])
    off = np.diag([b, b, 0.0])
    c = np.block([[blk, off], [off, blk]])
    f0 = np.array([[2.0, 1.0, 4.0], [2.0, 1.0, 4.0]])
    out = plane_slip.solve_plane_slip(c, f0, [0, 1], UP, mu)
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
    out = plane_slip.solve_plane_slip(c, f0, [0, 1], UP, mu)
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
    resp = ContactResponse(body, base)
    return resp, resp.forces(np.zeros((len(base), 3))), n


def test_block_on_incline_holds_up_to_tan_theta_equal_mu():
    """Coulomb limit on a soft block: tanθ < μ settles with every node in its cone; tanθ > μ cannot."""
    mu = 0.4
    resp, f0, n = _inclined_block(0.99, mu)
    out = plane_slip.settle_plane_slip(resp.reduced_stiffness, f0, n, mu)
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
    out2 = plane_slip.settle_plane_slip(resp2.reduced_stiffness, f02, n2, mu)
    assert 0 < len(out2.slid) < len(f02)
    resp3, f03, n3 = _inclined_block(1.01, mu)
    with pytest.raises(plane_slip.FrictionError, match="gross sliding"):
        plane_slip.settle_plane_slip(resp3.reduced_stiffness, f03, n3, mu)


def test_frictionless_displacements_remove_all_friction():
    mesh = box_mesh((0, 0, 0), (0.03, 0.02, 0.02), (3, 2, 2))
    body = Body(mesh, 5e4, 0.3, weight=1.0)
    base = np.flatnonzero(mesh.points[:, 2] == 0)
    resp = ContactResponse(body, base)
    d0 = np.zeros((len(base), 3))
    dofs = (3 * base[:, None] + np.arange(3)).ravel()
    gauge = body.rigid_modes[dofs][:, [0, 1, 5]]
    u = plane_slip.frictionless_tangential_displacements(resp.reduced_stiffness, resp.forces(d0), UP, gauge)
    f = resp.forces(d0 + u)
    assert np.abs(u[:, 2]).max() == 0
    assert np.abs(f[:, :2]).max() < 1e-12 * np.abs(f).max()
    np.testing.assert_allclose(f[:, 2].sum(), body.weight, rtol=1e-12)
    assert np.abs(gauge.T @ u.ravel()).max() < 1e-12 * np.abs(u).max()


#: solve_slip's compiled homotopy against the numpy reference (homotopy.track): the same path to the same root,
#: to this fraction of the largest unknown (both polish the residual to 1e-13; the root's conditioning on these
#: random systems is ~1e2).
COMPILED_SLIP_AGREEMENT = 1e-10


@pytest.mark.parametrize("free", [False, True])
def test_the_compiled_plane_slip_homotopy_finds_the_reference_root(rng, monkeypatch, free):
    """Random coupled table slips (eq. 6 frozen, and the free form): compiled and numpy paths, the same roots; a
    system with an extra constraint stays on the numpy path."""
    solved = 0
    for _ in range(12):
        m = 6
        c = spd_matrix(rng, m)
        f0 = rng.normal(size=(m, 3)) * [1.0, 1.0, 0.3] + [0, 0, 3]
        sliding = np.flatnonzero(friction.cone_residual(f0, UP, 0.4) < 0)
        if not len(sliding):
            continue
        system = (plane_slip.plane_free_slip_system(c, f0, sliding, UP, 0.4) if free
                  else plane_slip.plane_slip_system(c, f0, sliding, UP, 0.4))
        assert plane_slip._kernel_arrays(system) is not None
        roots = {}
        for compiled in (False, True):
            monkeypatch.setattr(plane_slip, "COMPILED_HOMOTOPY", compiled)
            try:
                roots[compiled] = plane_slip.solve_slip(system)
            except plane_slip.FrictionError as exc:
                roots[compiled] = str(exc)
        ref, comp = roots[False], roots[True]
        assert type(ref) is type(comp)
        if isinstance(ref, str):
            continue
        solved += 1
        assert ref.method == comp.method
        np.testing.assert_allclose(comp.x, ref.x, rtol=0, atol=COMPILED_SLIP_AGREEMENT * np.abs(ref.x).max())
        assert comp.residual <= 1e-12
    assert solved >= 6
    con = plane_slip.QuadraticConstraint(np.eye(2), np.zeros(2), -1.0)
    with_constraint = plane_slip.SlipSystem(c, f0, np.eye(3 * m)[:, :2], [0], UP, 0.4, constraints=(con,))
    assert plane_slip._kernel_arrays(with_constraint) is None
