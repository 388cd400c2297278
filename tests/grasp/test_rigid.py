"""Rigid-body comparison of Table III (least total normal force of two frictional point contacts)."""

import numpy as np
import pytest

from fem_grasp.grasp.rigid import rigid_grasp

UP = np.array([0.0, 0.0, 1.0])


def _check_cones(g, normals, mu):
    for f, n in zip(g.forces, normals):
        fn = f @ n
        assert fn >= -1e-12
        assert np.linalg.norm(f - fn * n) <= mu * fn * (1 + 1e-9) + 1e-12


def test_antipodal_horizontal_grasp_needs_weight_over_mu():
    # Contacts at ±y on the equator, pushing inward: each carries half the weight by friction,
    # so each normal force is mg / (2μ) and the total mg / μ.
    pts = np.array([[0, -0.03, 0.0], [0, 0.03, 0.0]])
    nrm = np.array([[0, 1.0, 0], [0, -1.0, 0]])
    g = rigid_grasp(pts, nrm, np.zeros(3), weight=1.2, mu=0.4)
    assert g.feasible
    assert g.total_normal_force == pytest.approx(1.2 / 0.4, rel=1e-12)
    np.testing.assert_allclose(g.forces.sum(axis=0), [0, 0, 1.2], atol=1e-12)
    _check_cones(g, nrm, 0.4)
    assert abs(g.axis_torque) < 1e-12


def test_contacts_below_the_equator_need_less_force():
    # Inward normals tilted up by α: each normal force lifts by N sin α plus friction μ N cos α.
    alpha = np.radians(20)
    pts = np.array([[0, -0.03, -0.01], [0, 0.03, -0.01]])
    nrm = np.array([[0, np.cos(alpha), np.sin(alpha)], [0, -np.cos(alpha), np.sin(alpha)]])
    mu, w = 0.3, 1.0
    g = rigid_grasp(pts, nrm, np.zeros(3), weight=w, mu=mu)
    assert g.feasible
    assert g.total_normal_force == pytest.approx(w / (np.sin(alpha) + mu * np.cos(alpha)), rel=1e-10)
    _check_cones(g, nrm, mu)


def test_contacts_above_the_equator_with_little_friction_cannot_hold():
    alpha = np.radians(30)  # normals pointing down more steeply than the friction angle (μ = 0.3 → 16.7°)
    pts = np.array([[0, -0.03, 0.01], [0, 0.03, 0.01]])
    nrm = np.array([[0, np.cos(alpha), -np.sin(alpha)], [0, -np.cos(alpha), -np.sin(alpha)]])
    g = rigid_grasp(pts, nrm, np.zeros(3), weight=1.0, mu=0.3)
    assert not g.feasible and np.isinf(g.total_normal_force) and "cannot hold" in g.reason
    # With enough friction it can, and the least force is the closed form.
    g = rigid_grasp(pts, nrm, np.zeros(3), weight=1.0, mu=0.8)
    assert g.feasible
    assert g.total_normal_force == pytest.approx(1.0 / (0.8 * np.cos(alpha) - np.sin(alpha)), rel=1e-10)


def test_off_centre_mass_is_balanced_by_unequal_forces(rng):
    pts = np.array([[0.002, -0.03, 0.0], [-0.001, 0.031, 0.001]])
    nrm = np.array([[0, 1.0, 0.05], [0.02, -1.0, 0.1]])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    com = np.array([0.0, 0.004, -0.002])
    g = rigid_grasp(pts, nrm, com, weight=0.8, mu=0.5)
    assert g.feasible
    np.testing.assert_allclose(g.forces.sum(axis=0), [0, 0, 0.8], atol=1e-12)
    r = pts - com
    torque = np.cross(r[0], g.forces[0]) + np.cross(r[1], g.forces[1])
    u = (pts[1] - pts[0]) / np.linalg.norm(pts[1] - pts[0])
    np.testing.assert_allclose(torque - (torque @ u) * u, 0, atol=1e-12)  # only the axis torque is left
    _check_cones(g, nrm, 0.5)
    # No other feasible squeeze gives less normal force: scan the one free parameter.
    best = g.total_normal_force
    for t in np.linspace(g.squeeze - 5, g.squeeze + 5, 2001):
        f = np.stack([g.forces[0] + (t - g.squeeze) * u, g.forces[1] - (t - g.squeeze) * u])
        fn = np.einsum("ki,ki->k", f, nrm)
        ft = np.linalg.norm(f - fn[:, None] * nrm, axis=1)
        if np.all(fn >= 0) and np.all(ft <= 0.5 * fn + 1e-12):
            assert fn.sum() >= best - 1e-9


@pytest.mark.parametrize("weight", [1.5e-9, 1e7, 1.5e13])
def test_the_grasp_scales_with_the_weight_at_any_magnitude(weight):
    # The grasp is linear in mg.  The cone intervals were once decided with tolerances mixing N, N² and
    # 1, which called every grasp above 1e7 N infeasible (found by the scaled pickups of issue #8).
    pts = np.array([[0.002, -0.03, 0.0], [-0.001, 0.031, 0.001]])
    nrm = np.array([[0, 1.0, 0.05], [0.02, -1.0, 0.1]])
    com = np.array([0.0, 0.004, -0.002])
    one = rigid_grasp(pts, nrm, com, weight=1.0, mu=0.5)
    g = rigid_grasp(pts, nrm, com, weight=weight, mu=0.5)
    assert g.feasible and one.feasible
    assert g.total_normal_force == pytest.approx(weight * one.total_normal_force, rel=1e-12)
    np.testing.assert_allclose(g.forces, weight * one.forces, rtol=1e-12, atol=1e-15 * weight)
    assert g.squeeze == pytest.approx(weight * one.squeeze, rel=1e-12)
    # Antipodal flat contacts: mg/μ in all, at every magnitude.
    flat = rigid_grasp(np.array([[0, -0.03, 0.0], [0, 0.03, 0.0]]), np.array([[0, 1.0, 0], [0, -1.0, 0]]),
                       np.zeros(3), weight=weight, mu=0.4)
    assert flat.feasible and flat.total_normal_force == pytest.approx(weight / 0.4, rel=1e-12)
