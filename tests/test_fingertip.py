import numpy as np
import pytest

from fem_grasp.contact.obstacles import DEFAULT_RADIUS, Fingertip, great_circle_point, slip_axis


def test_tangent_placement_touches_without_penetrating():
    p = np.array([0.01, 0.03, 0.02])
    n = np.array([0.0, 1.0, 0.2])
    tip = Fingertip.tangent_at(p, n, radius=0.008)
    np.testing.assert_allclose(tip.signed_distance(p), [0.0], atol=1e-17)
    # The normal pointing into the object is the object's outward normal reversed.
    np.testing.assert_allclose(tip.inward_normals(p)[0], -n / np.linalg.norm(n), rtol=1e-14)
    # A point just inside the object (along −n) is outside the sphere; one beyond the contact penetrates.
    assert tip.signed_distance(p - 1e-3 * n)[0] > 0
    assert tip.signed_distance(p + 1e-3 * n)[0] < 0
    assert Fingertip(np.zeros(3)).radius == DEFAULT_RADIUS


def test_bad_fingertips_are_refused():
    with pytest.raises(ValueError, match="radius must be a positive length"):
        Fingertip(np.zeros(3), radius=0.0)
    with pytest.raises(ValueError, match="3 finite coordinates"):
        Fingertip(np.array([0.0, np.nan, 0.0]))
    with pytest.raises(ValueError, match="normal at the contact node is zero"):
        Fingertip.tangent_at(np.zeros(3), np.zeros(3))


def test_great_circle_slip_stays_on_sphere_and_opposes_tangential_force():
    tip = Fingertip(np.array([0.0, 0.0, 0.0]), radius=0.01)
    p = tip.project(np.array([[1.0, 0.3, 0.2]]))[0]
    f = np.array([-2.0, 0.5, 1.0])  # compressive part along −n̂ plus a tangential part
    axis = slip_axis(p, tip, f)
    n = tip.inward_normals(p)[0]
    f_t = f - (f @ n) * n
    # N̂ is orthogonal to n̂ and to f⊥.
    np.testing.assert_allclose([axis @ n, axis @ f_t], [0, 0], atol=1e-15)
    for theta in (-0.3, -0.05, 0.0):
        q = great_circle_point(p, tip, axis, np.cos(theta), np.sin(theta))
        np.testing.assert_allclose(tip.signed_distance(q), [0.0], atol=1e-15)
        np.testing.assert_allclose((q - tip.center) @ axis, 0.0, atol=1e-15)  # in the great circle's plane
    # A small negative angle moves the node opposite to f⊥ (the paper's θ_k < 0).
    q = great_circle_point(p, tip, axis, np.cos(-1e-4), np.sin(-1e-4))
    step = q - p
    np.testing.assert_allclose(step / np.linalg.norm(step), -f_t / np.linalg.norm(f_t), atol=1e-4)


def test_slip_axis_undefined_for_purely_normal_force():
    tip = Fingertip(np.zeros(3), radius=0.01)
    p = np.array([0.01, 0.0, 0.0])
    with pytest.raises(ValueError, match="no tangential component"):
        slip_axis(p, tip, np.array([-3.0, 0.0, 0.0]))
