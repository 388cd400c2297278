"""Force closure of the initial placement (paper Algorithm 1, step 1)."""

import numpy as np
import pytest

from fem_grasp import box_mesh
from fem_grasp.grasp.closure import cone_generators, contact_wrenches, force_closure, placement_closure

#: A 4×3×2 cm box: fingers at the centres of the y-faces at mid-height, table under the centre.
CENTER = np.array([0.02, 0.015, 0.01])
FINGERS = np.array([[0.02, 0.0, 0.01], [0.02, 0.03, 0.01]])
TABLE = np.array([0.02, 0.015, 0.0])
UP = np.array([0.0, 0.0, 1.0])


def _box_grasp(mu_finger, mu_table, fingers=FINGERS, normals=None):
    if normals is None:
        normals = np.array([[0, 1.0, 0], [0, -1.0, 0]])
    return force_closure(np.vstack([fingers, TABLE]), np.vstack([normals, UP]),
                         [mu_finger, mu_finger, mu_table], CENTER)


def test_cone_generators_lie_on_the_cone():
    n = np.array([0.3, -0.2, 0.9])
    g = cone_generators(n, 0.4, edges=12)
    nh = n / np.linalg.norm(n)
    fn = g @ nh
    ft = np.linalg.norm(g - np.outer(fn, nh), axis=1)
    np.testing.assert_allclose(fn, 1.0)
    np.testing.assert_allclose(ft, 0.4)
    assert len(cone_generators(n, 0.0)) == 1


def test_wrenches_have_the_moment_of_their_force():
    w = contact_wrenches(FINGERS, [[0, 1.0, 0], [0, -1.0, 0]], 0.5, CENTER, length=1.0, edges=4)
    assert w.shape == (8, 6)
    for row, p in zip(w, np.repeat(FINGERS, 4, axis=0)):
        np.testing.assert_allclose(row[3:], np.cross(p - CENTER, row[:3]), atol=1e-15)


def test_opposed_fingers_and_a_frictional_table_are_force_closure():
    res = _box_grasp(0.3, 0.3)
    assert res.closed and res.rank == 6 and res.margin > 0 and res.quality > 0 and not res.reason
    # More friction, a better grasp.
    assert _box_grasp(0.6, 0.6).quality > res.quality


def test_frictionless_table_leaves_torque_about_the_finger_axis_free():
    # The finger forces pass through the finger axis; only table friction twists the body about it.
    res = _box_grasp(0.5, 0.0)
    assert not res.closed and "wrench" in res.reason


def test_frictionless_fingers_are_not_force_closure():
    res = _box_grasp(0.0, 0.5)
    assert not res.closed and res.rank < 6


def test_fingers_on_the_same_side_are_not_force_closure():
    # Both fingers push along +y: pulling the body along +y needs table friction N μ > F + finger push,
    # and the table's normal force N can only come from finger friction ≤ μ × finger push (μ < 1).
    same = np.array([[0.01, 0.0, 0.01], [0.03, 0.0, 0.01]])
    res = _box_grasp(0.5, 0.5, fingers=same, normals=np.array([[0, 1.0, 0], [0, 1.0, 0]]))
    assert not res.closed and res.quality == 0


def test_placement_closure_on_a_mesh():
    from fem_grasp import Body

    mesh = box_mesh((0, 0, 0), (0.04, 0.03, 0.02), (4, 4, 2))
    body = Body(mesh, 5e4, 0.3, weight=1.0)
    p = mesh.points
    np.testing.assert_allclose(mesh.outward_normals(p), mesh.surface_normals, atol=1e-15)
    node = lambda q: int(np.argmin(np.linalg.norm(p - q, axis=1)))  # noqa: E731
    i, j = node([0.02, 0.0, 0.01]), node([0.02, 0.03, 0.01])
    tri = np.array([node([0.01, 0.0075, 0]), node([0.03, 0.0075, 0]), node([0.02, 0.0225, 0])])
    assert placement_closure(body, p, (i, j), tri, 0.4, 0.4).closed
    assert not placement_closure(body, p, (i, j), tri, 0.4, 0.0).closed
    assert not placement_closure(body, p, (i, i), tri, 0.4, 0.4).closed
    with pytest.raises(ValueError, match="surface nodes"):
        interior = np.setdiff1d(np.arange(mesh.n_points), mesh.surface_nodes)[0]
        placement_closure(body, p, (i, int(interior)), tri, 0.4, 0.4)
