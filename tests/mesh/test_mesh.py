import numpy as np
import pytest

from fem_grasp import MeshError, TetMesh, box_mesh

UNIT_TET = (np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]), np.array([[0, 1, 2, 3]]))


def two_tets():
    p = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]])
    t = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
    return p, t


@pytest.mark.parametrize(
    "points, tets, match",
    [
        (np.zeros((4, 2)), UNIT_TET[1], r"points must have shape \(n, 3\)"),
        (UNIT_TET[0], np.array([[0, 1, 2]]), r"tets must have shape \(t, 4\)"),
        (UNIT_TET[0], np.array([[0.5, 1, 2, 3]]), "integer vertex indices"),
        (UNIT_TET[0].astype(str), UNIT_TET[1], "real numbers"),
    ],
)
def test_shape_and_dtype_errors(points, tets, match):
    with pytest.raises(MeshError, match=match):
        TetMesh(points, tets)


def test_nan_point_named():
    p, t = two_tets()
    p[3, 1] = np.nan
    with pytest.raises(MeshError, match=r"1 point\(s\) have NaN.*first is point 3"):
        TetMesh(p, t)


def test_out_of_range_index_named():
    p, t = two_tets()
    t[1, 2] = 7
    with pytest.raises(MeshError, match=r"1 tet\(s\) reference .*first is tet 1"):
        TetMesh(p, t)


def test_duplicate_and_repeated_vertex_named():
    p, t = two_tets()
    with pytest.raises(MeshError, match=r"1 duplicate tet\(s\); first duplicated is tet 0"):
        TetMesh(p, np.vstack([t, t[[0]][:, [1, 0, 2, 3]]]))
    with pytest.raises(MeshError, match=r"repeat a vertex.*first is tet 1"):
        TetMesh(p, np.array([[0, 1, 2, 3], [1, 2, 2, 4]]))


def test_zero_volume_named():
    p, t = two_tets()
    p[4] = p[1] * 0.3 + p[2] * 0.3 + p[3] * 0.4  # inside face (1,2,3): zero volume
    with pytest.raises(MeshError, match=r"1 tet\(s\) have zero volume.*first is tet 1"):
        TetMesh(p, t)


def test_inverted_tets_are_reoriented_and_counted():
    p, t = two_tets()
    t_bad = t.copy()
    t_bad[1] = t_bad[1, [1, 0, 2, 3]]
    m = TetMesh(p, t_bad)
    assert m.n_reoriented == 1
    assert np.all(m.volumes > 0)
    np.testing.assert_allclose(m.volumes, TetMesh(p, t).volumes)


def test_box_geometry_and_closed_outward_surface():
    lo, hi = np.array([0.1, -0.2, 0.0]), np.array([0.5, 0.1, 0.2])
    m = box_mesh(lo, hi, (4, 3, 2))
    assert m.n_points == 5 * 4 * 3 and m.n_tets == 6 * 24
    assert m.n_reoriented == 0  # every tet listed with positive orientation
    np.testing.assert_allclose(m.volume, np.prod(hi - lo), rtol=1e-13)
    np.testing.assert_allclose(m.bounds[0], lo)
    np.testing.assert_allclose(m.bounds[1], hi)
    # Boundary nodes of a 5×4×3 grid: all but the 3×2×1 interior.
    assert len(m.surface_nodes) == 60 - 6
    f = m.surface_faces
    assert len(f) == 2 * 2 * (4 * 3 + 4 * 2 + 3 * 2)
    # Divergence theorem with outward normals: ∮ x·n dA / 3 = V.
    p = m.points
    an = 0.5 * np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]])
    np.testing.assert_allclose(np.einsum("ij,ij->", p[f].mean(axis=1), an) / 3.0, m.volume, rtol=1e-12)
    # Closed: every surface edge is shared by exactly two faces.
    edges = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert np.all(counts == 2)
    # Vertex normals on the bottom face interior point down.
    bottom = np.flatnonzero((np.abs(p[:, 2]) < 1e-12) & (p[:, 0] > 0.15) & (p[:, 0] < 0.45)
                            & (p[:, 1] > -0.15) & (p[:, 1] < 0.05))
    np.testing.assert_allclose(m.surface_normals[bottom], [[0, 0, -1]] * len(bottom), atol=1e-12)


def test_quality_regular_tet_is_one():
    s = np.array([[1.0, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]])
    m = TetMesh(s, np.array([[0, 1, 2, 3]]))
    np.testing.assert_allclose(m.quality, [1.0], rtol=1e-12)
    assert 0.3 < box_mesh().quality.min() < 1.0


def test_meshio_round_trip(tmp_path):
    m = box_mesh(divisions=(2, 3, 2))
    path = tmp_path / "box.vtu"
    m.write(path, point_data={"u": np.ones((m.n_points, 3))})
    back = TetMesh.from_file(path)
    np.testing.assert_array_equal(back.points, m.points)
    np.testing.assert_array_equal(back.tets, m.tets)


def test_from_meshio_without_tets_says_so():
    meshio = pytest.importorskip("meshio", reason="meshio is a declared dependency")
    surf = meshio.Mesh(UNIT_TET[0], [("triangle", np.array([[0, 1, 2]]))])
    with pytest.raises(MeshError, match="no tetra cells"):
        TetMesh.from_meshio(surf)


def test_transformed_is_rigid_and_rejects_reflection():
    m = box_mesh(divisions=(2, 2, 2))
    c, s = np.cos(0.3), np.sin(0.3)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    moved = m.transformed(rot, [1.0, 2.0, 3.0])
    np.testing.assert_allclose(moved.volumes, m.volumes, rtol=1e-12)
    assert moved.n_reoriented == 0
    with pytest.raises(ValueError, match="reflection"):
        m.transformed(np.diag([1.0, 1.0, -1.0]))


def test_surface_index_maps_surface_nodes_to_their_positions_and_interior_to_minus_one():
    mesh = box_mesh((0, 0, 0), (1, 1, 1), (3, 3, 3))
    surf = mesh.surface_nodes
    idx = mesh.surface_index
    assert np.array_equal(idx[surf], np.arange(len(surf)))
    interior = np.setdiff1d(np.arange(mesh.n_points), surf)
    assert len(interior) == 8 and np.all(idx[interior] == -1)


def test_surface_points_are_the_surface_nodes_positions_and_read_only():
    mesh = box_mesh((0, 0, 0), (1, 1, 1), (3, 3, 3))
    p = mesh.surface_points
    assert p.shape == (len(mesh.surface_nodes), 3)
    # on the unit box every surface node has a coordinate at 0 or 1
    assert np.all(np.any(np.isclose(p, 0.0) | np.isclose(p, 1.0), axis=1))
    assert np.array_equal(p, mesh.points[mesh.surface_nodes])  # a gather, no arithmetic
    with pytest.raises(ValueError):
        p[0, 0] = 5.0  # shared by every tracker of the body: not to be written
