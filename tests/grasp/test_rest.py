"""Resting pose and resting configuration on the table (paper §III-A)."""

import dataclasses
import functools

import numpy as np
import pytest

from fem_grasp import Body, TetMesh, box_mesh
from fem_grasp.errors import LockingWarning
from fem_grasp.grasp import objects
from fem_grasp.grasp.pose import (
    _polygon_margin,
    _triangle_margins,
    hull_facets,
    resting_pose,
    rotation_between,
    stable_facets,
    triangle_margin,
)
from fem_grasp.grasp.rest import RestCheckError, RestConvergenceError, rest
from fem_grasp.settings import EngineSettings

#: A soft modulus that makes the sag visible (millimetres); Table I's 1e9–6e9 Pa give micrometres.
SOFT_YOUNG = 3e4
DOWN = np.array([0.0, 0.0, -1.0])


@pytest.fixture(scope="module")
def box():
    """A 4×3×2 cm box of 1 N on a 4×3×3 grid (its bottom face has 20 nodes)."""
    return Body(box_mesh((0, 0, 0), (0.04, 0.03, 0.02), (4, 3, 3)), young=5e4, poisson=0.3, weight=1.0)


@functools.lru_cache(maxsize=None)
def paper_body(name: str) -> Body:
    """A paper object with Table I weight and ν at SOFT_YOUNG (committed mesh, else a fresh gmsh mesh)."""
    try:
        return objects.load(name, young=SOFT_YOUNG)
    except FileNotFoundError:
        shapes = pytest.importorskip("fem_grasp.mesh.shapes")
        pytest.importorskip("gmsh")
        row = objects.TABLE_I[name]
        return Body(shapes.paper_mesh(name), SOFT_YOUNG, row.poisson, weight=row.weight)


def _node(body, q):
    """Index of the node nearest to point q."""
    return int(np.argmin(np.linalg.norm(body.mesh.points - np.asarray(q), axis=1)))


def _sheared_box():
    """A parallelepiped leaning so far that its centre of mass overhangs its bottom face."""
    m = box_mesh((0, 0, 0), (0.02, 0.02, 0.02), (2, 2, 2))
    p = m.points.copy()
    p[:, 0] += 1.5 * p[:, 2]
    return Body(TetMesh(p, m.tets), 5e4, 0.3, weight=1.0)


# --------------------------------------------------------------------- pose
def test_rotation_between_is_the_smallest_proper_rotation(rng):
    for _ in range(5):
        a, b = rng.normal(size=3), rng.normal(size=3)
        r = rotation_between(a, b)
        np.testing.assert_allclose(r @ (a / np.linalg.norm(a)), b / np.linalg.norm(b), atol=1e-14)
        np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-14)
        assert np.linalg.det(r) == pytest.approx(1.0)
        np.testing.assert_allclose(r @ np.cross(a, b), np.cross(a, b), atol=1e-14)  # axis a × b is fixed
    np.testing.assert_allclose(rotation_between([0, 0, 1], [0, 0, -1]) @ [0, 0, 1], [0, 0, -1], atol=1e-15)


def test_margin_outside_is_the_distance_to_the_triangle():
    tri_points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]])
    normal = np.array([0, 0, -1.0])
    # Beyond vertex (1, 0): the distance is √2 though the nearest edge line is only 1 away.
    margin, _ = triangle_margin(tri_points, [0, 1, 2], np.array([2.0, -1.0, 5.0]), normal)
    assert margin == pytest.approx(-np.sqrt(2))
    margin, edge = triangle_margin(tri_points, [0, 1, 2], np.array([0.2, 0.1, -3.0]), normal)
    assert margin == pytest.approx(0.1) and edge == 0


def test_triangle_margins_at_once_agree_with_one_by_one():
    rng = np.random.default_rng(4)
    tri2 = rng.normal(size=(400, 3, 2))
    a, b = tri2[:, 1] - tri2[:, 0], tri2[:, 2] - tri2[:, 0]
    area2 = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    tri2[area2 < 0] = tri2[area2 < 0, ::-1]  # counter-clockwise, as hull_facets orders them
    points = rng.normal(size=(400, 2))  # inside some, outside most (beyond an edge or a vertex)
    expected = [_polygon_margin(t, p)[0] for t, p in zip(tri2, points)]
    got = _triangle_margins(tri2, points)
    assert (got > 0).sum() > 20 and (got < 0).sum() > 20
    np.testing.assert_allclose(got, expected, rtol=1e-13, atol=1e-15)


def test_hull_facets_of_a_fine_mesh_match_the_triangles_one_by_one():
    """Triangular facets are measured all at once; each must have the polygon, area and margin that
    triangle_margin gives it alone."""
    orange = paper_body("orange")
    facets = [f for f in hull_facets(orange) if len(f.nodes) == 3]
    assert len(facets) > 100
    pts, com = orange.mesh.points, orange.center_of_mass
    for f in facets[::7]:
        margin, _ = triangle_margin(pts, f.polygon, com, f.normal)
        assert f.margin == pytest.approx(margin, rel=1e-12, abs=1e-15)
        a, b, c = pts[f.polygon]
        assert np.cross(b - a, c - a) @ f.normal > 0  # counter-clockwise about the outward normal
        assert f.area == pytest.approx(0.5 * np.linalg.norm(np.cross(b - a, c - a)), rel=1e-12)


def test_box_hull_has_six_merged_stable_facets(box):
    facets = hull_facets(box)
    assert len(facets) == 6  # coplanar hull triangles merged
    bottom = next(f for f in facets if f.normal @ DOWN > 0.999)
    assert len(bottom.nodes) == 20 and len(bottom.polygon) == 4
    assert bottom.area == pytest.approx(0.04 * 0.03)
    assert bottom.margin == pytest.approx(0.015)  # half the short side
    assert len(stable_facets(box)) == 6


def test_pose_of_an_upright_box_is_the_identity(box):
    pose = resting_pose(box, table_z=0.1)
    np.testing.assert_allclose(pose.rotation, np.eye(3), atol=1e-15)
    np.testing.assert_allclose(pose.body.mesh.points, box.mesh.points + [0, 0, 0.1], atol=1e-15)
    assert np.all(box.mesh.points[pose.triangle, 2] == 0)
    assert pose.margin > 0.005  # a well-spread triangle of bottom nodes around the centre


def test_the_support_triangle_of_a_flat_base_does_not_depend_on_round_off(box, rng):
    """A box's base holds many triangles with the same margin around the centre of mass; which one is the
    support (and so the centre the force-closure test uses) must not be decided by the last bits of the
    coordinates: ~1e-12 relative jitter picks the same triangle (it picked another, and the closure test
    then flipped, before ties were broken by node order)."""
    first = resting_pose(box).triangle
    for _ in range(4):
        moved = box.mesh.points + 1e-12 * box.mesh.diameter * rng.uniform(-1, 1, box.mesh.points.shape)
        jittered = Body(TetMesh(moved, box.mesh.tets), young=5e4, poisson=0.3, weight=1.0)
        np.testing.assert_array_equal(resting_pose(jittered).triangle, first)


def test_tilted_box_comes_back_to_its_bottom_face(box):
    tilt = rotation_between(DOWN, [0.3, 0.2, -1.0])
    state = rest(box.transformed(tilt), 0.3, table_z=-0.05)
    state.check()
    np.testing.assert_allclose(state.pose.rotation @ tilt, np.eye(3), atol=1e-12)
    assert np.all(box.mesh.points[state.contact_nodes, 2] == 0)  # all on the original bottom face
    assert state.body.mesh.points[:, 2].min() == pytest.approx(-0.05, abs=1e-15)


def test_down_direction_selects_the_facet(box):
    pose = resting_pose(box, down=[1.0, 0.0, 0.0])  # the face x = 0.04 goes down
    assert np.all(box.mesh.points[pose.triangle, 0] == pytest.approx(0.04))
    np.testing.assert_allclose(pose.rotation @ [1.0, 0, 0], DOWN, atol=1e-15)
    assert pose.body.mesh.points[:, 2].min() == pytest.approx(0.0, abs=1e-15)


def test_overhanging_body_rests_on_another_stable_facet():
    body = _sheared_box()
    bottom = next(f for f in hull_facets(body) if f.normal @ DOWN > 0.999)
    assert bottom.margin < 0  # it would tip over its bottom face
    state = rest(body, 0.3)
    state.check()
    n = state.pose.facet.normal
    assert n @ DOWN < 0.999 and state.pose.margin > 0
    posed = state.body
    margin, _ = triangle_margin(posed.mesh.points, state.support_triangle, posed.center_of_mass, DOWN)
    assert margin == pytest.approx(state.pose.margin, rel=1e-9)
    assert posed.mesh.points[:, 2].min() >= -1e-15


def test_named_tipping_triangle_raises(box):
    corner = [_node(box, q) for q in ([0, 0, 0], [0.01, 0, 0], [0, 0.01, 0])]
    # The centre of mass projects to (0.02, 0.015): 0.025/√2 = 0.01768 m from this corner triangle.
    with pytest.raises(ValueError, match=r"would tip.*0\.01768 m outside"):
        rest(box, 0.3, support=corner)
    side = [_node(box, q) for q in ([0, 0, 0], [0.04, 0, 0], [0.02, 0.01, 0.02 / 3])]
    with pytest.raises(ValueError, match="supporting plane"):
        resting_pose(box, support=side)
    with pytest.raises(ValueError, match="collinear"):
        resting_pose(box, support=corner[:2] + [_node(box, [0.02, 0, 0])])
    with pytest.raises(ValueError, match="three distinct"):
        resting_pose(box, support=[0, 0, 1])


def test_named_stable_triangle_is_used(box):
    tri = [_node(box, q) for q in ([0, 0, 0], [0.04, 0, 0], [0.02, 0.03, 0])]
    state = rest(box, 0.3, support=tri)
    np.testing.assert_array_equal(state.support_triangle, tri)
    assert state.history[0].contacts == 3
    state.check()


# --------------------------------------------------------------------- rest
@pytest.mark.parametrize("mu", [0.0, 0.3, 10.0])
def test_box_rests_on_its_whole_bottom_face(box, mu):
    state = rest(box, mu)
    figures = state.check()
    assert figures["ok"] and figures["force_residual"] < 1e-10 and figures["torque_residual"] < 1e-10
    assert set(state.contact_nodes) == set(np.flatnonzero(box.mesh.points[:, 2] == 0))
    np.testing.assert_allclose(state.normal_forces.sum(), box.weight, rtol=1e-12)
    assert 1e-5 < state.max_sag < 1e-3
    assert state.iterations == len(state.history) and state.wall_time > 0
    assert state.history[-1].new_node is None
    if mu == 0.0:
        assert state.sliding.all() and figures["max_stick_cone_violation"] is None
        assert figures["max_slide_cone_error"] < 1e-10  # no friction at all
        mass = -box.gravity_loads.reshape(-1, 3)[:, 2]
        np.testing.assert_allclose(mass @ state.displacements[:, :2], 0, atol=1e-12 * state.max_sag * mass.sum())
    if mu == 10.0:
        assert not state.sliding.any() and sum(h.sliding for h in state.history) == 0
        assert figures["max_slide_cone_error"] is None and figures["max_stick_cone_violation"] < -5


def test_rest_backends_agree(box):
    small = Body(box_mesh((0, 0, 0), (0.03, 0.02, 0.02), (3, 2, 2)), 5e4, 0.3, weight=1.0)
    a = rest(small, 0.3)
    b = rest(small, 0.3, backend="spectral")
    # The same table forces node by node (a node in one contact set and not the other carries none within the
    # tolerance: which way a zero-force node goes is round-off's choice, not part of the answer).
    fa, fb = np.zeros((small.mesh.n_points, 3)), np.zeros((small.mesh.n_points, 3))
    fa[a.contact_nodes], fb[b.contact_nodes] = a.contact_forces, b.contact_forces
    np.testing.assert_allclose(fa, fb, rtol=0, atol=1e-9 * small.weight)
    assert len(a.contact_nodes) >= 3 and len(b.contact_nodes) >= 3
    np.testing.assert_allclose(a.positions, b.positions, atol=1e-9 * small.mesh.diameter)


def test_check_flags_violations(box):
    state = rest(box, 0.3)
    bad = state.contact_forces.copy()
    bad[0, 0] += 0.5  # breaks the cone and equilibrium
    broken = dataclasses.replace(state, contact_forces=bad)
    figures = broken.check(raise_on_failure=False)
    assert not figures["ok"] and len(figures["failures"]) == 2
    with pytest.raises(RestCheckError, match="equilibrium"):
        broken.check()
    sunk = dataclasses.replace(state, positions=state.positions - [0, 0, 1e-6])
    with pytest.raises(RestCheckError, match="1e-06 m off the table"):  # the contact nodes sank with the rest
        sunk.check()
    low = state.positions.copy()
    free = np.setdiff1d(box.mesh.surface_nodes, state.contact_nodes)
    low[free[np.argmin(low[free, 2])], 2] -= 1e-6 + low[free, 2].min()  # the lowest free node 1 µm into the table
    with pytest.raises(RestCheckError, match="1e-06 m below the table"):
        dataclasses.replace(state, positions=low).check()


def test_iteration_budget_and_arguments(box):
    with pytest.raises(RestConvergenceError, match="did not settle in 2 iterations"):
        rest(box, 0.3, max_iterations=2)
    with pytest.raises(ValueError, match="mu_table"):
        rest(box, -0.1)


@pytest.mark.parametrize("name", objects.NAMES)
def test_paper_objects_rest_with_table_one_friction(name):
    row = objects.TABLE_I[name]
    body = paper_body(name)
    for mu in (row.friction, 0.0, 10.0):
        state = rest(body, mu)
        figures = state.check()
        assert figures["ok"], figures
        assert state.n_contacts >= 3 and state.max_sag > 1e-5  # visible sag at SOFT_YOUNG
        np.testing.assert_allclose(state.normal_forces.sum(), row.weight, rtol=1e-10)
        if mu == 10.0:
            assert not state.sliding.any()


def test_tilted_tomato_comes_to_rest_on_a_stable_facet(rng):
    body = paper_body("tomato")
    q = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    tilt = q * np.sign(np.linalg.det(q))
    state = rest(body.transformed(tilt), objects.TABLE_I["tomato"].friction)
    state.check()
    posed = state.body
    margin, _ = triangle_margin(posed.mesh.points, state.support_triangle, posed.center_of_mass, DOWN)
    assert margin > 0
    np.testing.assert_allclose(posed.mesh.points[state.support_triangle, 2], 0, atol=1e-12)
    assert posed.mesh.points[:, 2].min() > -1e-9 * posed.mesh.diameter


def test_frictionless_rest_matches_a_direct_sliding_support_solve(box):
    """μ = 0: every bottom node sits on the table and slides freely, which is the classical roller support.

    Solve it independently: K Δ = G with the bottom nodes' z held at 0, x and y free, and the three
    horizontal rigid motions fixed by Lagrange multipliers on the same gauge as :func:`rest`
    (mass-weighted mean horizontal displacement and mean spin about the vertical through the
    centre of mass both zero).
    """
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    state = rest(box, 0.0)
    p = box.mesh.points
    n = box.n_nodes
    bottom = np.flatnonzero(p[:, 2] == 0)
    fixed = 3 * bottom + 2
    free = np.setdiff1d(np.arange(3 * n), fixed)
    mass = -box.gravity_loads.reshape(-1, 3)[:, 2]
    r = p - box.center_of_mass
    gauge = np.zeros((3, 3 * n))
    gauge[0, 0::3] = mass
    gauge[1, 1::3] = mass
    gauge[2, 0::3], gauge[2, 1::3] = -mass * r[:, 1], mass * r[:, 0]
    k = box.stiffness.tocsr()[free][:, free]
    a = sp.csr_matrix(gauge[:, free])
    mat = sp.bmat([[k, a.T], [a, None]]).tocsc()
    sol = spla.spsolve(mat, np.concatenate([box.gravity_loads[free], np.zeros(3)]))
    field = np.zeros(3 * n)
    field[free] = sol[:len(free)]
    np.testing.assert_allclose(state.displacements.ravel(), field, atol=1e-9 * np.abs(field).max())
    reactions = (box.stiffness @ field - box.gravity_loads).reshape(-1, 3)
    order = np.argsort(state.contact_nodes)
    np.testing.assert_allclose(state.contact_forces[order], reactions[np.sort(state.contact_nodes)],
                               atol=1e-9 * box.weight)


def test_a_frictionless_rest_with_derived_responses_is_the_rest_with_fresh_ones():
    """μ = 0 on an ellipsoid, whose contact set grows node by node: each set's response derived from the last
    one's (the default) or factorised afresh (EngineSettings.neighbour_updates=False) gives the same contact set
    and displacements to 1e-9 of the largest."""
    from fem_grasp.mesh import shapes
    from tests.helpers import count_derived_responses

    body = Body(TetMesh(*shapes.ellipsoid((0.02, 0.02, 0.015), 0.006)), 2e4, 0.4, weight=1.0)
    with pytest.MonkeyPatch.context() as mp:
        derived = count_derived_responses(mp)
        state = rest(body, 0.0)
        assert sum(derived) >= 10
        derived.clear()
        fresh = rest(body, 0.0, settings=EngineSettings(neighbour_updates=False))
        assert not any(derived)
    np.testing.assert_array_equal(np.sort(fresh.contact_nodes), np.sort(state.contact_nodes))
    np.testing.assert_allclose(fresh.displacements, state.displacements, rtol=0,
                               atol=1e-9 * np.abs(state.displacements).max())


def test_history_accounts_for_every_contact(box):
    state = rest(box, 0.3)
    added = [k for h in state.history for k in h.new_nodes]
    released = [k for h in state.history for k in h.released]
    assert state.history[0].contacts == 3
    assert len(state.contact_nodes) == 3 + len(added) - len(released)
    assert set(state.contact_nodes) <= set(state.support_triangle) | set(added)
    lam = [h.load_factor for h in state.history]
    assert lam == sorted(lam) and lam[-1] == 1.0  # gravity rises event by event
    assert all(h.max_penetration <= 1e-9 * box.mesh.diameter for h in state.history)  # the ramp never overshoots


@pytest.mark.parametrize("mu", [0.0, 0.3])
def test_paper_literal_iteration_without_load_ramp(box, mu):
    """Gravity applied at once (the paper's procedure): the contacts land one by one, deepest first."""
    state = rest(box, mu, load_ramp=False)
    state.check()
    assert set(state.contact_nodes) == set(np.flatnonzero(box.mesh.points[:, 2] == 0))
    depths = [h.max_penetration for h in state.history]
    assert depths[0] > 1e-4 and depths[-1] <= 1e-9 * box.mesh.diameter
    assert all(len(h.new_nodes) <= 1 for h in state.history)
    if mu == 0.0:  # frictionless: the resting state is unique, whatever the path
        np.testing.assert_allclose(state.displacements, rest(box, mu).displacements, atol=1e-12)


def test_soft_objects_in_random_orientations_rock_onto_a_new_support(rng):
    """Small hull facets of a soft tomato: the support rocks (contacts released, event B) as it settles, in some
    of the orientations."""
    body = paper_body("tomato").with_material(young=1e4)
    released = 0
    for _ in range(6):
        q = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        for mu in (0.32, 0.05):
            state = rest(body.transformed(q * np.sign(np.linalg.det(q))), mu)
            assert state.check()["ok"]
            released += sum(len(h.released) for h in state.history)
    assert released > 0


def test_rest_table_script_reports_the_tomato():
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "scripts" / "rest_table.py"
    if not path.exists():
        pytest.skip("scripts/ is in the source tree, not in the installed package")
    spec = importlib.util.spec_from_file_location("rest_table", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    try:
        rows = module.rows(1e4, ["tomato"])
    except FileNotFoundError:
        pytest.skip("paper meshes not generated")
    assert rows[0]["contacts"] >= 3 and rows[0]["sag_mm"] > 1 and rows[0]["residual"] < 1e-10
    table = module.format_table(rows)
    assert table.splitlines()[2].startswith(f"| tomato | {rows[0]['nodes']} |")
    # the guide's table is the script's: `make rest-table` rewrites it between its markers
    readme = (path.parents[1] / "docs" / "physics.md").read_text(encoding="utf-8")
    block = readme.split(module.BEGIN, 1)[1].split(module.END, 1)[0]
    assert table.splitlines()[0] in block
    tomato = next(line for line in block.splitlines() if line.startswith("| tomato |")).split(" | ")
    assert (int(tomato[5]), int(tomato[6])) == (rows[0]["contacts"], rows[0]["sliding"])
    assert float(tomato[7]) == pytest.approx(rows[0]["sag_mm"], rel=2e-3)
    replaced = module.replace_block(f"a\n{module.BEGIN}\nold\n{module.END}\nb", "new")
    assert replaced == f"a\n{module.BEGIN}\nnew\n{module.END}\nb"


def test_a_nearly_incompressible_box_comes_to_rest_on_a_table_of_friction_one_half():
    """ν = 0.4999: each table contact's slip pushes its neighbours' forces out of their cones again; the rest
    still settles, most of its base sliding on the cone boundary, and obeys every contact law."""
    with pytest.warns(LockingWarning, match="lock"):
        body = Body(box_mesh((-0.015, -0.02, 0.0), (0.015, 0.02, 0.03), (3, 3, 3)), 2e4, 0.4999, weight=0.3)
        state = rest(body, 0.5)
    figures = state.check()
    assert figures["ok"] and figures["force_residual"] < 1e-10
    np.testing.assert_allclose(state.normal_forces.sum(), body.weight, rtol=1e-10)
    assert state.n_contacts >= 3 and state.sliding.sum() > state.n_contacts / 2


def test_a_rest_the_tracker_cannot_settle_is_a_rest_convergence_error(box, monkeypatch):
    """Where the event engine finds no quasi-static state on the table the object does not come to rest: a named
    RestConvergenceError carrying the engine's reason, not a tracking error from inside the engine."""
    from fem_grasp.contact.tracking import Tracker
    from fem_grasp.errors import TrackingError

    def fail(*args, **kwargs):
        raise TrackingError("no quasi-static equilibrium at gravity load λ = 0.5: gross slip")

    monkeypatch.setattr(Tracker, "settle", fail)
    with pytest.raises(RestConvergenceError, match="does not come to rest on the table: no quasi-static"):
        rest(box, 0.3)
