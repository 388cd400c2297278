"""The VTU writer (fem_grasp.io.vtu): what it writes is read back bit for bit by meshio and by VTK."""

import meshio
import numpy as np
import pytest

from fem_grasp.io.vtu import BLOCK_BYTES, cells_xml, data_array, write_grid


def _grid(n=2000, cells=9000, seed=0):
    rng = np.random.default_rng(seed)
    points = rng.normal(size=(n, 3))
    tets = np.stack([rng.choice(n, 4, replace=False) for _ in range(cells)])
    point_data = {"displacement": rng.normal(size=(n, 3)), "contact_state": rng.integers(0, 3, n).astype(np.int32),
                  "flag": rng.random(n) < 0.5}
    cell_data = {"von_mises": rng.random(cells)}
    return points, tets, point_data, cell_data


def test_a_grid_is_read_back_bit_for_bit_by_meshio_and_vtk(tmp_path):
    """Arrays over several 32 KiB blocks (and a last, shorter one), vectors, int32, booleans, field data."""
    points, tets, pd, cd = _grid()
    assert tets.nbytes > 3 * BLOCK_BYTES and tets.nbytes % BLOCK_BYTES
    field = {"phase": np.array([2], np.int32), "squeeze_depth": np.array([0.0123456789012345])}
    path = write_grid(tmp_path / "g.vtu", points, cells_xml("tetra", tets), pd, cd, field)
    m = meshio.read(path)
    np.testing.assert_array_equal(m.points, points)
    assert m.cells[0].type == "tetra"
    np.testing.assert_array_equal(m.cells[0].data, tets)
    np.testing.assert_array_equal(m.point_data["displacement"], pd["displacement"])
    np.testing.assert_array_equal(m.point_data["contact_state"], pd["contact_state"])
    np.testing.assert_array_equal(m.point_data["flag"], pd["flag"].astype(np.uint8))
    np.testing.assert_array_equal(m.cell_data["von_mises"][0], cd["von_mises"])
    assert m.field_data["squeeze_depth"][0] == field["squeeze_depth"][0] and m.field_data["phase"][0] == 2
    vtk = pytest.importorskip("vtk")
    from vtk.util.numpy_support import vtk_to_numpy

    reader = vtk.vtkXMLUnstructuredGridReader()
    reader.SetFileName(str(path))
    reader.Update()
    grid = reader.GetOutput()
    assert grid.GetNumberOfCells() == len(tets) and grid.GetCellType(0) == 10  # VTK_TETRA
    np.testing.assert_array_equal(vtk_to_numpy(grid.GetPoints().GetData()), points)
    np.testing.assert_array_equal(vtk_to_numpy(grid.GetPointData().GetArray("displacement")), pd["displacement"])
    np.testing.assert_array_equal(vtk_to_numpy(grid.GetCellData().GetArray("von_mises")), cd["von_mises"])
    assert grid.GetFieldData().GetArray("squeeze_depth").GetTuple1(0) == field["squeeze_depth"][0]


def test_triangles_and_empty_data(tmp_path):
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    tris = np.array([[0, 1, 2], [0, 2, 3]])
    m = meshio.read(write_grid(tmp_path / "t.vtu", pts, cells_xml("triangle", tris)))
    assert m.cells[0].type == "triangle"
    np.testing.assert_array_equal(m.cells[0].data, tris)
    np.testing.assert_array_equal(m.points, pts)


def test_the_connectivity_is_compressed(tmp_path):
    """Node indices compress (zlib at level 1); the file is well under the raw connectivity's size."""
    points, tets, _, _ = _grid(n=500, cells=20000, seed=1)
    path = write_grid(tmp_path / "c.vtu", points, cells_xml("tetra", tets))
    assert path.stat().st_size < 0.6 * (tets.nbytes + points.nbytes)


def test_what_is_not_written_is_refused():
    with pytest.raises(TypeError, match="complex128"):
        data_array("z", np.zeros(3, complex))
    with pytest.raises(ValueError, match="'hexahedron'"):
        cells_xml("hexahedron", np.zeros((2, 8), int))
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        write_grid("/nonexistent/never.vtu", np.zeros((4, 2)), cells_xml("triangle", [[0, 1, 2]]))


def test_a_meshio_mesh_is_written_with_its_field_data(tmp_path):
    """``fem_grasp.io.output.write_vtu``: a meshio.Mesh of one cell block, with VTK field data beside it."""
    from fem_grasp.io.output import write_vtu

    points, tets, pd, cd = _grid(n=300, cells=800, seed=3)
    mesh = meshio.Mesh(points, [("tetra", tets)], point_data={"displacement": pd["displacement"]},
                       cell_data={"von_mises": [cd["von_mises"]]})
    m = meshio.read(write_vtu(tmp_path / "m.vtu", mesh, {"lift_height": np.array([0.004])}))
    np.testing.assert_array_equal(m.cells[0].data, tets)
    np.testing.assert_array_equal(m.cell_data["von_mises"][0], cd["von_mises"])
    assert m.field_data["lift_height"][0] == 0.004
