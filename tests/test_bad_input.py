"""Bad input is refused with a specific exception that names the problem (issue #8).

Complements tests/mesh/test_mesh.py (shapes, dtypes, NaN, out-of-range, duplicate
and zero-volume tets), tests/elastic/test_fem.py (E and ν through ``Body``) and
tests/elastic/test_response.py (collinear and malformed contact sets), which are not
repeated here.  Every case is listed in docs/limits.md.
"""

import warnings

import numpy as np
import pytest

from fem_grasp import Body, MeshError, TetMesh, box_mesh
from fem_grasp.errors import ContactNodeError, DirectionError, LockingWarning, MaterialError, PlacementError, SceneError
from fem_grasp.grasp.placement import (
    PAPER_SQUEEZE_DIRECTIONS,
    check_contact_nodes,
    check_directions,
    check_finger_placement,
)
from fem_grasp.validation import check_friction, check_material

UNIT = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])


def cells(divisions, keep):
    """The tets of ``box_mesh`` cells listed in ``keep`` (integer cell coordinates), unused points dropped."""
    m = box_mesh((0, 0, 0), divisions, divisions)  # unit cells
    cell = np.floor(m.points[m.tets].mean(axis=1)).astype(int)
    sel = np.zeros(m.n_tets, dtype=bool)
    for c in keep:
        sel |= (cell == c).all(axis=1)
    tets = m.tets[sel]
    used, inv = np.unique(tets, return_inverse=True)
    return m.points[used], inv.reshape(-1, 4)


# ===================================================================== meshes
def test_unreferenced_point_named():
    p = np.vstack([UNIT, [[5.0, 5, 5]], UNIT[:1] + 0.1])
    with pytest.raises(MeshError, match=r"2 point\(s\) are not a vertex of any tet \(unreferenced.*first is point 4"):
        TetMesh(p, [[0, 1, 2, 3]])


def test_folded_element_is_refused_not_silently_reoriented():
    # Tet 1 = (1, 2, 3, 4) with point 4 on the same side of face (1, 2, 3) as point 0: it overlaps tet 0.
    p = np.vstack([UNIT, [[0.2, 0.2, 0.2]]])
    with pytest.raises(MeshError, match=r"1 pair\(s\) of tets overlap.*tets 0 and 1 share face \(1, 2, 3\).*tet 1 "
                                        r"was given with negative volume"):
        TetMesh(p, [[0, 1, 2, 3], [1, 2, 3, 4]])


def test_consistently_inverted_mesh_is_only_reoriented():
    m = box_mesh(divisions=(2, 2, 2))
    flipped = TetMesh(m.points, m.tets[:, [1, 0, 2, 3]])
    assert flipped.n_reoriented == m.n_tets
    np.testing.assert_allclose(flipped.volume, m.volume)


def test_disconnected_mesh_named():
    p = np.vstack([UNIT, UNIT + 3.0])
    with pytest.raises(MeshError, match=r"disconnected: 2 separate pieces \(tet 0 and tet 1"):
        TetMesh(p, [[0, 1, 2, 3], [4, 5, 6, 7]])


@pytest.mark.parametrize("extra, second", [
    (-UNIT[1:], [0, 4, 5, 6]),  # the second tet touches the first at vertex 0 only
    (-UNIT[2:], [0, 1, 4, 5]),  # ... along the edge (0, 1) only
])
def test_tets_touching_at_a_vertex_or_edge_named(extra, second):
    with pytest.raises(MeshError, match=r"2 pieces joined only at vertices or edges \(non-manifold.*first joint is "
                                        r"vertex 0, shared by tets \[0, 1\]"):
        TetMesh(np.vstack([UNIT, extra]), [[0, 1, 2, 3], second])


def test_triangle_in_three_tets_named():
    p = np.vstack([UNIT, [[0.6, 0.6, 0.6], [0.7, 0.7, 0.7]]])
    with pytest.raises(MeshError, match=r"shared by more than two tets.*face \(1, 2, 3\), shared by tets \[0, 1, 2\]"):
        TetMesh(p, [[0, 1, 2, 3], [1, 2, 3, 4], [1, 2, 3, 5]])


def test_surface_edge_in_four_triangles_named():
    # A ring of unit cubes that closes on itself along one edge: cells (1,1) and (2,2) touch only along the
    # vertical edge x = y = 2, yet the solid is one face-connected piece.
    p, t = cells((4, 4, 1), [(1, 1, 0), (1, 0, 0), (2, 0, 0), (3, 0, 0), (3, 1, 0), (3, 2, 0), (2, 2, 0)])
    edge = tuple(int(i) for i in np.sort(np.flatnonzero((np.abs(p[:, :2] - 2) < 1e-12).all(axis=1))))
    with pytest.raises(MeshError, match=rf"surface edge\(s\) are not shared by exactly two.*edge \({edge[0]}, "
                                        rf"{edge[1]}\), in 4 surface triangles"):
        TetMesh(p, t)


def test_pinched_vertex_named():
    # Cells (1,1,0) and (2,2,1) touch only at the point (2, 2, 1); a chain of cells joins them by faces.
    p, t = cells((4, 4, 2), [(1, 1, 0), (1, 0, 0), (2, 0, 0), (3, 0, 0), (3, 1, 0), (3, 2, 0), (3, 2, 1),
                             (2, 2, 1)])
    v = int(np.flatnonzero(np.linalg.norm(p - [2, 2, 1], axis=1) < 1e-12)[0])
    with pytest.raises(MeshError, match=rf"pinched.*first is vertex {v}, where 2 separate sheets"):
        TetMesh(p, t)


@pytest.mark.parametrize("points, tets, match", [
    ([[0.0, 0, 0], [1, 0, 0], [0, 1], [0, 0, 1]], [[0, 1, 2, 3]], "points cannot be read as a rectangular array"),
    (UNIT, [[0, 1, 2, 3], [0, 1]], "tets cannot be read as a rectangular array"),
    (UNIT, np.array([[True, True, False, True]]), "integer vertex indices"),
    (UNIT.astype(complex), [[0, 1, 2, 3]], "real numbers"),
    (np.vstack([UNIT, [[0, 0, np.inf]]]), [[0, 1, 2, 3], [1, 2, 3, 4]], r"NaN or infinite.*first is point 4"),
    (UNIT[None], [[0, 1, 2, 3]], r"points must have shape \(n, 3\), got \(1, 4, 3\)"),
    (np.zeros((0, 3)), np.zeros((0, 4), dtype=int), ">= 4 points and >= 1 tet"),
])
def test_malformed_arrays_named(points, tets, match):
    with pytest.raises(MeshError, match=match):
        TetMesh(points, tets)


def test_mesh_file_with_a_bad_mesh_is_refused(tmp_path):
    meshio = pytest.importorskip("meshio")
    p = np.vstack([UNIT, UNIT + 3.0])
    path = tmp_path / "two.vtu"
    meshio.Mesh(p, [("tetra", np.array([[0, 1, 2, 3], [4, 5, 6, 7]]))]).write(path)
    with pytest.raises(MeshError, match="disconnected"):
        TetMesh.from_file(path)


# ================================================================ materials
@pytest.mark.parametrize("kw, match", [
    (dict(young=np.inf), "Young's modulus E must be a positive"),
    (dict(young="stiff"), "Young's modulus E must be a real number, got 'stiff'"),
    (dict(young=[1e5, 2e5]), "Young's modulus E must be a real number"),
    (dict(young=True), "Young's modulus E must be a number, got the boolean"),
    (dict(poisson=0.4999999999999999 + 1e-16), "Poisson's ratio"),  # rounds to 0.5
    (dict(poisson=np.nan), "Poisson's ratio"),
    (dict(poisson=-1.5), "Poisson's ratio"),
    (dict(poisson=1j), "Poisson's ratio ν must be a real number"),
    (dict(weight=np.nan), "weight must be a positive number of newtons"),
    (dict(weight=0.0), "weight must be a positive"),
    (dict(weight=None, density=-1.0), "density must be a positive number of kg/m³"),
    (dict(weight=None, density=np.nan), "density must be a positive"),
    (dict(gravity=-9.8), "gravity must be a positive"),
    (dict(gravity=np.nan), "gravity must be a positive"),
])
def test_material_and_load_errors(kw, match):
    args = dict(young=1e5, poisson=0.3, weight=1.0)
    args.update(kw)
    with pytest.raises(MaterialError, match=match):
        Body(box_mesh(), args.pop("young"), args.pop("poisson"), **args)


def test_material_error_is_a_value_error_and_valid_values_pass():
    assert issubclass(MaterialError, ValueError)
    assert check_material(np.float32(1e5), 0) == (1e5, 0.0)
    Body(box_mesh(), 1e5, -0.999, weight=1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Body(box_mesh(), 1e5, 0.45, weight=1.0)  # no warning up to LOCKING_POISSON


def test_near_incompressible_material_is_accepted_with_a_locking_warning():
    with pytest.warns(LockingWarning, match=r"ν = 0.4999 > 0.45: P1 tetrahedra lock"):
        body = Body(box_mesh(), 1e5, 0.4999, weight=1.0)
    assert body.poisson == 0.4999


def test_strain_energy_of_a_nan_field_is_refused_not_nan():
    body = Body(box_mesh(), 1e5, 0.3, weight=1.0)
    u = np.zeros((body.n_nodes, 3))
    u[5, 1] = np.nan
    with pytest.raises(ValueError, match="NaN or infinite components; first is node 5, component y"):
        body.strain_energy(u)
    with pytest.raises(ValueError, match="expected 81 displacement components, got 3"):
        body.strain_energy(np.zeros(3))


def test_body_refuses_a_non_mesh():
    with pytest.raises(TypeError, match="mesh must be a TetMesh, got ndarray"):
        Body(UNIT, 1e5, 0.3, weight=1.0)


# ================================================================= friction
@pytest.mark.parametrize("mu", [-0.1, np.nan, np.inf, "rough", None])
def test_friction_coefficient_refused(mu):
    with pytest.raises(SceneError, match="mu_finger must be a"):
        check_friction(mu, "mu_finger")


def test_friction_zero_and_large_pass():
    assert check_friction(0) == 0.0 and check_friction(10) == 10.0


@pytest.mark.parametrize("mu", [-0.5, np.nan])
def test_rest_and_pickup_refuse_bad_friction(mu):
    from fem_grasp import pickup, rest

    body = Body(box_mesh((0, 0, 0), (0.03, 0.03, 0.03)), 1e4, 0.3, weight=0.3)
    with pytest.raises(ValueError, match="mu_table must be a finite friction coefficient"):
        rest(body, mu)
    with pytest.raises(ValueError, match="mu_finger must be a finite friction coefficient"):
        pickup(body, mu_finger=mu)


# =============================================================== directions
D1, D2 = PAPER_SQUEEZE_DIRECTIONS


def test_paper_directions_pass_and_are_normalised():
    d1, d2 = check_directions(2 * D1, D2)
    np.testing.assert_allclose(np.linalg.norm([d1, d2], axis=1), 1.0, rtol=1e-15)
    np.testing.assert_allclose(d1, D1 / np.linalg.norm(D1))
    check_directions([0, 1, 0], [0, -1, 0])  # horizontal is not upward
    check_directions(D1, [0, 0, -1], ratio=0.0)  # finger 2 held still: d2 need not point towards finger 1
    # a component of round-off size is not "upward"
    check_directions([0, 1, 1e-17], [0, -1, 0])


@pytest.mark.parametrize("d1, d2, kw, match", [
    ([0, 0, 0], D2, {}, r"d1 = \[0.0, 0.0, 0.0\] has zero length"),
    (D1, [0, 0, 0], {}, "d2 .* has zero length"),
    ([0, np.nan, 0], D2, {}, "d1 has NaN or infinite"),
    ([0, 1, 0, 0], D2, {}, r"d1 must be a 3-vector, got shape \(4,\)"),
    ("up", D2, {}, "d1 must be a 3-vector of real numbers"),
    ([0, 0.974, 0.227], D2, {}, r"d1 = .* points upward \(d·up = 0.227 > 0\)"),
    (D1, [0, -0.974, 0.01], {}, r"d2 = .* points upward"),
    ([0, 0, -1], D2, {}, "d1 = .* is vertical"),
    (D1, [0, 0.974, -0.227], {}, r"d2 = .* does not move finger 2 towards finger 1 \(d2·h = 0.974"),
    (D1, [1, 0, 0], {}, r"does not move finger 2 towards finger 1 \(d2·h = 0 >= 0"),
    (D1, D2, dict(ratio=-1), "squeeze ratio s must be a finite number >= 0"),
    (D1, D2, dict(ratio=np.nan), "squeeze ratio s"),
])
def test_bad_directions_named(d1, d2, kw, match):
    with pytest.raises(DirectionError, match=match):
        check_directions(d1, d2, **kw)


def test_upward_is_relative_to_the_given_vertical():
    # With "up" = +y, the paper's d1 (y-component 0.974) is upward.
    with pytest.raises(DirectionError, match="points upward"):
        check_directions(D1, D2, up=[0, 1, 0])


# ============================================================ contact nodes
@pytest.fixture(scope="module")
def box():
    return box_mesh((0, 0, 0), (0.03, 0.04, 0.03), (3, 3, 3))


def test_surface_nodes_pass(box):
    nodes = box.surface_nodes[[0, 5, 17]]
    np.testing.assert_array_equal(check_contact_nodes(box, None, list(nodes)), nodes)
    assert check_contact_nodes(box, box.points, np.int32(nodes[0])).tolist() == [nodes[0]]


def test_bad_contact_nodes_named(box):
    interior = int(np.setdiff1d(np.arange(box.n_points), box.surface_nodes)[0])
    s = box.surface_nodes
    cases = [
        ([s[0], box.n_points], rf"contact node {box.n_points} \(entry 1\) is not a node of the mesh \(0 … 63\)"),
        ([-1], r"contact node -1 \(entry 0\) is not a node"),
        ([s[0], s[3], s[0]], rf"contact node {s[0]} is listed twice \(entries \[0, 2\]\)"),
        ([s[0], interior], rf"contact node {interior} \(entry 1\) is an interior node"),
        ([1.0, 2.0], "must be integer node indices, got dtype float64"),
        ([True, False], "must be integer node indices, got dtype bool"),
        ([[s[0], s[1]]], r"must be a 1-D list of node indices, got shape \(1, 2\)"),
    ]
    for nodes, match in cases:
        with pytest.raises(ContactNodeError, match=match):
            check_contact_nodes(box, None, nodes)


def test_contact_node_on_a_knife_edge_is_refused():
    # Node 4's surface triangles (1,2,4), (2,3,4), (3,1,4) have a summed area vector equal to the vector area of
    # the loop 1-2-3 whatever the position of 4; in a resting shape with 1, 2, 3 in line it vanishes.
    p = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]])
    m = TetMesh(p, [[0, 1, 2, 3], [1, 2, 3, 4]])
    check_contact_nodes(m, None, [4])
    pos = p.copy()
    pos[3] = 0.5 * (pos[1] + pos[2])
    with pytest.raises(ContactNodeError, match=r"contact node 4 \(entry 0\) has no outward direction"):
        check_contact_nodes(m, pos, [4])


def test_positions_of_the_wrong_shape_or_nan(box):
    with pytest.raises(SceneError, match=r"positions must have the mesh's shape \(64, 3\), got \(3, 3\)"):
        check_contact_nodes(box, np.zeros((3, 3)), [box.surface_nodes[0]])
    pos = box.points.copy()
    pos[7, 2] = np.nan
    with pytest.raises(SceneError, match="first is node 7"):
        check_contact_nodes(box, pos, [box.surface_nodes[0]])


# =============================================================== fingertips
R = 0.01


def tangent(mesh, nodes, radius=R):
    out = mesh.outward_normals(mesh.points)
    return mesh.points[nodes] + radius * out[nodes], out


def side_nodes(mesh):
    """Centre nodes of the y = min and y = max faces of the box fixture."""
    p = mesh.points
    a = int(np.argmin(np.linalg.norm(p - [0.01, 0.0, 0.01], axis=1)))
    b = int(np.argmin(np.linalg.norm(p - [0.01, 0.04, 0.01], axis=1)))
    return [a, b]


def test_tangent_placement_passes(box):
    nodes = side_nodes(box)
    c, out = tangent(box, nodes)
    fig = check_finger_placement(box.points, box.surface_nodes, c, R, contact_nodes=nodes, normals=out,
                                 directions=PAPER_SQUEEZE_DIRECTIONS, table_z=0.0)
    assert np.all(np.abs(fig["gap"]) <= 1e-15) and np.all(fig["penetration"] == 0)
    assert fig["tol"] == pytest.approx(1e-6 * box.diameter)


def test_fingertip_that_misses_is_refused(box):
    nodes = side_nodes(box)
    c, out = tangent(box, nodes)
    c[0, 1] -= 0.005  # 5 mm away from the object
    with pytest.raises(PlacementError, match=rf"fingertip 1 misses the object.*is 0.005 m from the nearest surface "
                                             rf"node {nodes[0]}"):
        check_finger_placement(box.points, box.surface_nodes, c, R)


def test_fingertip_not_at_its_contact_node_is_refused(box):
    nodes = side_nodes(box)
    c, _ = tangent(box, nodes)
    other = int(np.argmin(np.linalg.norm(box.points - [0.0, 0.0, 0.02], axis=1)))
    with pytest.raises(PlacementError, match=rf"fingertip 2 does not touch its contact node {other}"):
        check_finger_placement(box.points, box.surface_nodes, c, R, contact_nodes=[nodes[0], other])


def test_fingertip_on_the_wrong_side_does_not_face_the_object():
    # A thin plate: the fingertip is tangent at the bottom-face node but its centre is inside the plate's
    # inner side; with the normals it is refused as not facing the object.
    m = box_mesh((0, 0, 0), (0.04, 0.04, 0.002), (2, 2, 1))
    k = int(np.argmin(np.linalg.norm(m.points - [0.02, 0.02, 0.002], axis=1)))  # top centre node
    out = m.outward_normals(m.points)
    c = m.points[[k]] - R * out[[k]]  # tangent from the inside (below the top face)
    with pytest.raises(PlacementError, match=rf"fingertip 1 does not face the object.*node {k}"):
        check_finger_placement(m.points, m.surface_nodes, c, R, contact_nodes=[k], normals=out)


def test_fingertip_that_starts_inside_is_refused(box):
    nodes = side_nodes(box)
    c, out = tangent(box, nodes)
    c[1, 1] -= 0.003  # finger 2 pushed 3 mm into the object
    with pytest.raises(PlacementError, match=r"fingertip 2 starts inside the object: surface node \d+ lies "
                                             r"0.003 m inside its sphere"):
        check_finger_placement(box.points, box.surface_nodes, c, R)


def test_fingertip_at_a_concave_node_starts_inside():
    # An L-shaped solid: at the inner corner edge, a tangent sphere along the vertex normal cuts the other leg.
    p, t = cells((2, 2, 1), [(0, 0, 0), (1, 0, 0), (0, 1, 0)])
    m = TetMesh(p * 0.01, t)
    k = int(np.flatnonzero(np.linalg.norm(m.points - [0.01, 0.01, 0.0], axis=1) < 1e-12)[0])
    c, out = tangent(m, [k], radius=0.05)
    assert out[k, 0] > 0 and out[k, 1] > 0  # the normal points out of the re-entrant corner
    with pytest.raises(PlacementError, match="fingertip 1 starts inside the object"):
        check_finger_placement(m.points, m.surface_nodes, c, 0.05, contact_nodes=[k], normals=out)


def test_direction_out_of_the_object_is_refused(box):
    nodes = side_nodes(box)
    c, out = tangent(box, nodes)
    with pytest.raises(PlacementError, match=rf"finger 1's squeeze direction .* points out of the object at its "
                                             rf"contact node {nodes[0]}"):
        check_finger_placement(box.points, box.surface_nodes, c, R, contact_nodes=nodes, normals=out,
                               directions=PAPER_SQUEEZE_DIRECTIONS[::-1])


def test_standing_finger_is_not_checked_for_direction(box):
    nodes = side_nodes(box)
    c, out = tangent(box, nodes)
    velocities = np.stack([PAPER_SQUEEZE_DIRECTIONS[0], 0.0 * PAPER_SQUEEZE_DIRECTIONS[0]])  # s = 0
    check_finger_placement(box.points, box.surface_nodes, c, R, contact_nodes=nodes, normals=out,
                           directions=velocities)


def test_overlapping_fingertips_and_table_are_refused(box):
    nodes = side_nodes(box)
    c, out = tangent(box, nodes)
    with pytest.raises(PlacementError, match="fingertips 1 and 2 overlap: their centres are 0 m apart"):
        check_finger_placement(box.points, box.surface_nodes, c[[0, 0]], R)
    with pytest.raises(PlacementError, match=r"fingertip 1 reaches 0.0005 m below the table"):
        check_finger_placement(box.points, box.surface_nodes, c, R, table_z=c[0, 2] - R + 5e-4)


@pytest.mark.parametrize("centers, radius, match", [
    (np.zeros((2, 2)), R, r"centres must have shape \(k, 3\)"),
    ([[0, 0, np.nan]], R, "NaN or infinite"),
    ([[0, 0, 0]], 0.0, "radius R must be a positive"),
    ([[0, 0, 0]], -R, "radius R must be a positive"),
    ([[0, 0, 0]], np.inf, "radius R must be a positive"),
])
def test_fingertip_array_errors(box, centers, radius, match):
    with pytest.raises(SceneError, match=match):
        check_finger_placement(box.points, box.surface_nodes, centers, radius)
