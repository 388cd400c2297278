"""The rigid obstacles (paper §III): the table plane, the hemispherical fingertips, tangent bases."""

import numpy as np
import pytest

from fem_grasp.contact.obstacles import DEFAULT_RADIUS, Fingertip, TablePlane, tangent_basis


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
    axis = tip.slip_axis(p, f)
    n = tip.inward_normals(p)[0]
    f_t = f - (f @ n) * n
    # N̂ is orthogonal to n̂ and to f⊥.
    np.testing.assert_allclose([axis @ n, axis @ f_t], [0, 0], atol=1e-15)
    for theta in (-0.3, -0.05, 0.0):
        q = tip.great_circle_point(p, axis, np.cos(theta), np.sin(theta))
        np.testing.assert_allclose(tip.signed_distance(q), [0.0], atol=1e-15)
        np.testing.assert_allclose((q - tip.center) @ axis, 0.0, atol=1e-15)  # in the great circle's plane
    # A small negative angle moves the node opposite to f⊥ (the paper's θ_k < 0).
    q = tip.great_circle_point(p, axis, np.cos(-1e-4), np.sin(-1e-4))
    step = q - p
    np.testing.assert_allclose(step / np.linalg.norm(step), -f_t / np.linalg.norm(f_t), atol=1e-4)


def test_slip_axis_undefined_for_purely_normal_force():
    tip = Fingertip(np.zeros(3), radius=0.01)
    p = np.array([0.01, 0.0, 0.0])
    with pytest.raises(ValueError, match="no tangential component"):
        tip.slip_axis(p, np.array([-3.0, 0.0, 0.0]))


#: Entries of unit vectors computed two ways agree to a few ulps of 1.
UNIT_ROUNDOFF = 8 * np.finfo(float).eps


def test_table_plane_geometry():
    table = TablePlane(0.5)
    p = np.array([[0, 0, 1.0], [1, 2, 0.25]])
    np.testing.assert_allclose(table.signed_distance(p), [0.5, -0.25])
    np.testing.assert_allclose(table.penetration(p), [0, 0.25])
    np.testing.assert_allclose(table.project(p), [[0, 0, 0.5], [1, 2, 0.5]])
    np.testing.assert_allclose(table.inward_normals(p), [[0, 0, 1], [0, 0, 1]])
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


def test_the_sphere_gap_and_normal_are_the_fingertip_geometry(rng):
    """sphere_gaps and sphere_normals (the one numpy copy the tracker, the checks and the results use): points
    placed at known distances along known directions from the centre give those distances minus R and those
    directions; they are the Fingertip's own signed distance and inward normal."""
    from fem_grasp.contact.obstacles import sphere_gaps, sphere_normals

    centre, radius = np.array([0.01, -0.02, 0.03]), 0.008
    directions = rng.normal(size=(9, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    distances = radius * rng.uniform(0.5, 1.5, size=9)
    points = centre + distances[:, None] * directions
    np.testing.assert_allclose(sphere_gaps(points, centre, radius), distances - radius, atol=1e-15)
    np.testing.assert_allclose(sphere_normals(points, centre), directions, atol=1e-15)
    tip = Fingertip(centre, radius)
    np.testing.assert_array_equal(tip.signed_distance(points), sphere_gaps(points, centre, radius))
    np.testing.assert_array_equal(tip.inward_normals(points), sphere_normals(points, centre))
