"""Tests of fem_grasp.mesh.bisection: nested refinement by conforming longest-edge bisection."""

from __future__ import annotations

import numpy as np
import pytest

from fem_grasp.mesh.bisection import _boundary_edge_keys, bisect_longest_edges, refine_to_size
from fem_grasp.mesh.gmsh_session import shape_quality
from fem_grasp.mesh.remesh import PaperGeometry
from fem_grasp.mesh.shapes import PAPER_SHAPES
from fem_grasp.mesh.tetmesh import TetMesh, box_mesh, signed_volumes


def _point_in_tet(points: np.ndarray, tet: np.ndarray, p: np.ndarray, tol: float = 1e-12) -> bool:
    a, b, c, d = points[tet]
    lam = np.linalg.solve(np.column_stack([b - a, c - a, d - a]), p - a)
    return bool(lam.min() >= -tol and lam.sum() <= 1 + tol)


def test_one_pass_is_conforming_and_nested():
    coarse = box_mesh((0.0, 0.0, 0.0), (1.0, 0.5, 0.25), (3, 2, 2))
    rng = np.random.default_rng(3)
    marked = rng.random(coarse.n_tets) < 0.3
    points, tets, parent, _ = bisect_longest_edges(coarse.points, coarse.tets, marked)
    fine = TetMesh(points, tets)  # validates: no overlap, manifold boundary, every point used
    assert fine.n_reoriented == 0 and (signed_volumes(points, tets) > 0).all()
    np.testing.assert_array_equal(points[:coarse.n_points], coarse.points)  # the coarse vertices keep their numbers
    # every child lies in its parent, and the children fill it
    assert np.allclose(np.bincount(parent, weights=fine.volumes, minlength=coarse.n_tets), coarse.volumes,
                       rtol=1e-12)
    for child, p in zip(tets[::7], parent[::7]):
        assert _point_in_tet(coarse.points, coarse.tets[p], points[child].mean(axis=0))
    # the boundary is the box's: the same area, and no new vertex off it or inside a face of the coarse mesh only
    assert fine.volume == pytest.approx(0.125, rel=1e-12)
    assert (fine.n_tets > coarse.n_tets) and marked.sum() <= fine.n_tets - coarse.n_tets


def test_boundary_edges_are_the_edges_of_the_surface_triangles():
    mesh = PaperGeometry("tomato").build(0.008)
    tri = mesh.surface_faces
    pairs = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    expected = np.unique(pairs[:, 0] * np.int64(mesh.n_points) + pairs[:, 1])
    got = _boundary_edge_keys(np.asarray(mesh.tets, np.int64), mesh.n_points)
    np.testing.assert_array_equal(got, expected)
    assert len(got) == 3 * len(tri) // 2  # a closed surface: each edge on two triangles


def test_a_marked_tetrahedron_has_its_longest_edge_halved():
    mesh = box_mesh((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), (2, 2, 2))
    marked = np.zeros(mesh.n_tets, dtype=bool)
    marked[5] = True
    a, b = max(((i, j) for i in range(4) for j in range(i + 1, 4)),
               key=lambda e: np.linalg.norm(mesh.points[mesh.tets[5, e[0]]] - mesh.points[mesh.tets[5, e[1]]]))
    mid = 0.5 * (mesh.points[mesh.tets[5, a]] + mesh.points[mesh.tets[5, b]])
    points, _, _, _ = bisect_longest_edges(mesh.points, mesh.tets, marked)
    assert np.isclose(np.linalg.norm(points[mesh.n_points:] - mid, axis=1), 0.0).any()


def test_refine_to_size_meets_the_size_field_and_keeps_shapes():
    coarse = box_mesh((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), (4, 4, 4))

    def size(x):
        return np.where(np.linalg.norm(x - 0.5, axis=1) < 0.3, 0.08, 1.0)

    fine = refine_to_size(coarse, size)
    e = fine.points[fine.tets[:, [0, 0, 0, 1, 1, 2]]] - fine.points[fine.tets[:, [1, 2, 3, 2, 3, 3]]]
    longest = np.linalg.norm(e, axis=2).max(axis=1)
    assert (longest <= size(fine.points[fine.tets].mean(axis=1)) * (1 + 1e-12)).all()
    assert fine.n_points > 10 * coarse.n_points and fine.volume == pytest.approx(1.0, rel=1e-12)
    # longest-edge bisection keeps the shapes within a bounded factor of the coarse mesh's
    assert shape_quality(fine.points, fine.tets).min() > 0.3 * shape_quality(coarse.points, coarse.tets).min()


def test_nothing_to_refine_leaves_the_mesh():
    coarse = box_mesh((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), (2, 2, 2))
    fine = refine_to_size(coarse, lambda x: np.full(len(x), 10.0))
    np.testing.assert_array_equal(fine.points, coarse.points)
    np.testing.assert_array_equal(fine.tets, coarse.tets)


@pytest.mark.parametrize("name", ["tomato", "steam_bun"])
def test_refined_boundary_follows_the_curved_surface(name):
    pytest.importorskip("gmsh", reason="gmsh's Python module is not installed (Debian package python3-gmsh)")
    geo = PaperGeometry(name)
    coarse = geo.build(0.012)
    top = coarse.points[:, 2].max()
    fine = refine_to_size(coarse, lambda x: np.where(x[:, 2] > 0.5 * top, 0.003, 1.0), geo.project)
    np.testing.assert_allclose(geo.project(fine.points[fine.surface_nodes]), fine.points[fine.surface_nodes],
                               atol=1e-12)
    # the refined solid is closer to the smooth one than the coarse mesh's facets were
    exact = PAPER_SHAPES[name].volume
    assert abs(fine.volume - exact) < 0.8 * abs(coarse.volume - exact)


def test_projection_onto_the_paper_shapes():
    rng = np.random.default_rng(0)
    q = rng.normal(size=(50, 3))
    for name, shape in PAPER_SHAPES.items():
        p = PaperGeometry(name).project(q * 0.05 + np.array([0.0, 0.0, 0.02]))
        if shape.kind == "ellipsoid":
            np.testing.assert_allclose(np.linalg.norm(p / np.asarray(shape.dimensions), axis=1), 1.0, rtol=1e-12)
        else:
            r, h, e = shape.dimensions
            curved = p[:, 2] > 0
            np.testing.assert_allclose(np.linalg.norm((p[curved] - [0, 0, e]) / [r, r, h], axis=1), 1.0, rtol=1e-12)


def test_closest_points_of_a_triangle_surface_against_sampling():
    from fem_grasp.mesh.scan import Surface, closest_points

    # a tetrahedron's surface: every query's nearest surface point, against 40,000 samples of each face
    pts = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    surface = Surface(pts, faces, "tetrahedron")
    rng = np.random.default_rng(2)
    q = rng.normal(size=(40, 3)) * 0.8 + 0.25
    u = rng.random((40000, 2))
    u[u.sum(axis=1) > 1] = 1 - u[u.sum(axis=1) > 1]
    tri = pts[faces]
    samples = (tri[:, None, 0] + (tri[:, None, 1] - tri[:, None, 0]) * u[:, :1]
               + (tri[:, None, 2] - tri[:, None, 0]) * u[:, 1:]).reshape(-1, 3)
    c = closest_points(surface, q)
    d_sampled = np.linalg.norm(samples[None] - q[:, None], axis=2).min(axis=1)
    d = np.linalg.norm(c - q, axis=1)
    assert (d <= d_sampled + 1e-12).all() and (d >= d_sampled - 0.02).all()


def test_a_projection_that_would_fold_the_mesh_leaves_the_vertices_on_their_chords():
    coarse = box_mesh((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), (2, 2, 2))

    def size(x):
        return np.full(len(x), 0.4)

    def into_the_centre(p):  # a "surface" through the middle of the box: every move folds a tetrahedron
        return np.full_like(p, 0.5)

    plain = refine_to_size(coarse, size)
    folded = refine_to_size(coarse, size, into_the_centre)
    assert (signed_volumes(folded.points, folded.tets) > 0).all() and folded.volume == pytest.approx(1.0, rel=1e-12)
    np.testing.assert_allclose(folded.points, plain.points, atol=1e-15)
