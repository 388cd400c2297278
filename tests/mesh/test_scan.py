"""Scan import (fem_grasp.mesh.scan): closed-surface checks with messages that say where, gmsh volume meshes."""

import meshio
import numpy as np
import pytest

from fem_grasp.mesh.scan import (
    Surface,
    SurfaceError,
    check_surface,
    clean_surface,
    mesh_surface,
    read_surface,
    self_intersections,
)
from tests.helpers import icosphere, write_stl

gmsh = pytest.importorskip("gmsh")
R = 0.03


@pytest.fixture(scope="module")
def sphere():
    return icosphere(R, 2)


def test_stl_vertices_are_merged_and_the_sphere_passes(tmp_path, sphere):
    p, f = sphere
    surf = read_surface(write_stl(tmp_path / "s.stl", p, f))
    assert (len(surf.points), len(surf.faces)) == (len(p), len(f))  # 3 × 320 STL vertices merged to 162
    good = check_surface(surf)
    # Inscribed polyhedron: its volume is below the sphere's, by the known ratio for this subdivision.
    assert 0.95 < good.volume / (4 / 3 * np.pi * R**3) < 1.0
    assert len(self_intersections(good.points, good.faces)) == 0


def test_orientation_is_made_consistent_and_outward(sphere):
    p, f = sphere
    flipped = f.copy()
    flipped[::3] = flipped[::3, ::-1]  # a third of the triangles inside out
    a = check_surface(clean_surface(p, flipped))
    b = check_surface(clean_surface(p, f[:, ::-1]))  # all inside out
    ref = check_surface(clean_surface(p, f)).volume
    assert a.volume == pytest.approx(ref, rel=1e-12) and b.volume == pytest.approx(ref, rel=1e-12) and ref > 0


def test_hole_is_reported_with_its_position(sphere):
    p, f = sphere
    with pytest.raises(SurfaceError) as exc:
        check_surface(clean_surface(p, f[1:], "holey.stl"))
    msg = str(exc.value)
    assert "holey.stl" in msg and "not closed: 3 boundary edge(s) forming 1 hole(s)" in msg
    # The position named is a vertex of the removed triangle.
    xyz = np.array([float(x) for x in msg.split(" at (")[1].split(")")[0].split(",")])
    assert np.min(np.linalg.norm(p[f[0]] - xyz, axis=1)) < 1e-6


def test_non_manifold_edge_two_pieces_and_self_intersection(sphere):
    p, f = sphere
    # A fin: a triangle hanging off an existing edge makes that edge carry three triangles.
    fin_p = np.vstack([p, p[f[0, 0]] * 1.5])
    fin = np.vstack([f, [[f[0, 0], f[0, 1], len(p)], [f[0, 1], f[0, 0], len(p)]]])
    with pytest.raises(SurfaceError, match="not manifold: 1 edge"):
        check_surface(clean_surface(fin_p, fin))
    with pytest.raises(SurfaceError, match=r"2 separate pieces \(triangles per piece: \[320, 320\]\)"):
        check_surface(clean_surface(np.vstack([p, p + 0.1]), np.vstack([f, f + len(p)])))
    # Pull the top vertex through the bottom of the sphere: its fan crosses the lower half.
    q = p.copy()
    q[np.argmax(q[:, 2])] = [0.0, 0.0, -2 * R]
    with pytest.raises(SurfaceError) as exc:
        check_surface(clean_surface(q, f, "dented.stl"))
    assert "dented.stl: the surface intersects itself" in str(exc.value) and "triangles" in str(exc.value)
    # Two overlapping spheres are refused as two pieces first; the crossing test alone finds their intersection.
    both = clean_surface(np.vstack([p, p + [R, 0, 0]]), np.vstack([f, f + len(p)]))
    assert len(self_intersections(both.points, both.faces)) > 0


def test_mesh_keeping_the_scan_triangles_encloses_the_same_volume(tmp_path, sphere):
    p, f = sphere
    path = write_stl(tmp_path / "s.stl", p, f)
    mesh = mesh_surface(path)
    surf = check_surface(read_surface(path))
    assert mesh.volume == pytest.approx(surf.volume, rel=1e-9)
    assert len(mesh.surface_faces) == len(f)  # the boundary is the scan's own triangles


@pytest.mark.parametrize("suffix", [".obj", ".ply"])
def test_remesh_at_a_vertex_count_from_obj_and_ply(tmp_path, sphere, suffix):
    p, f = icosphere(R, 4)  # a "dense scan": 2562 vertices
    path = tmp_path / f"dense{suffix}"
    meshio.write(path, meshio.Mesh(p, [("triangle", f)]))
    mesh = mesh_surface(path, target_vertices=300)
    assert abs(mesh.n_points - 300) <= 30
    assert mesh.volume == pytest.approx(4 / 3 * np.pi * R**3, rel=0.05)


def test_non_surface_inputs_are_refused(tmp_path):
    with pytest.raises(SurfaceError, match="does not exist"):
        read_surface(tmp_path / "none.stl")
    vol = tmp_path / "v.vtu"
    meshio.write(vol, meshio.Mesh(np.eye(4, 3), [("tetra", np.array([[0, 1, 2, 3]]))]))
    with pytest.raises(SurfaceError, match="volume cells"):
        read_surface(vol)
    with pytest.raises(SurfaceError, match="at least 4 triangles"):
        check_surface(Surface(np.eye(3), np.array([[0, 1, 2]])))
    with pytest.raises(SurfaceError, match="target_vertices or size, not both"):
        mesh_surface(Surface(np.eye(3), np.array([[0, 1, 2]])), target_vertices=100, size=0.01)


def test_a_scan_scenes_geometry_is_in_metres_as_its_mesh_is(tmp_path):
    """A scene's scan in millimetres (object.units = "mm"): the geometry the accuracy loop remeshes is the scene's
    object in metres, as its mesh is; remeshed at a size in metres it has the mesh's extent and volume (read in
    the file's millimetres, a size of 5 mm asked gmsh for tens of thousands of elements per edge)."""
    from fem_grasp.io.scene import parse_scene
    from fem_grasp.mesh.remesh import geometry_of_scene

    p, f = icosphere(1e3 * R, 3)  # millimetres
    write_stl(tmp_path / "ball_mm.stl", p, f)
    scene = parse_scene({"object": {"mesh": "ball_mm.stl", "units": "mm", "vertices": 300},
                         "material": {"young": 2e4, "poisson": 0.4, "weight": 1.0}, "friction": {"finger": 0.5}},
                        base_dir=tmp_path)
    geo = geometry_of_scene(scene)
    mesh = scene.load_mesh(None)
    extent = np.ptp(1e-3 * p, axis=0)  # the scan's box, in metres
    assert np.ptp(geo.surface.points, axis=0) == pytest.approx(extent, rel=1e-9)
    assert np.ptp(mesh.points, axis=0) == pytest.approx(extent, rel=0.03)
    again = geo.build(0.01)
    assert np.ptp(again.points, axis=0) == pytest.approx(extent, rel=0.03)
    assert again.volume == pytest.approx(mesh.volume, rel=0.05) and again.n_points < 2000
