"""Tests of fem_grasp.mesh.shapes (gmsh generators) and of the committed paper meshes (fem_grasp/scenes/meshes)."""

from __future__ import annotations

import functools
import math
import sys

import numpy as np
import pytest

from fem_grasp.grasp import objects
from fem_grasp.mesh import shapes

MESH_DIR = objects.MESH_DIR
TABLE_I_VERTICES = {"tomato": 490, "orange": 600, "steam_bun": 658, "football": 875}


@pytest.fixture
def gmsh():
    return pytest.importorskip("gmsh", reason="gmsh's Python module is not installed (Debian package python3-gmsh)")


def signed_volumes(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    e = points[tets[:, 1:]] - points[tets[:, :1]]
    return np.einsum("ij,ij->i", e[:, 0], np.cross(e[:, 1], e[:, 2])) / 6.0


def check_arrays(points: np.ndarray, tets: np.ndarray) -> None:
    assert points.dtype == np.float64 and points.ndim == 2 and points.shape[1] == 3
    assert tets.dtype == np.int64 and tets.ndim == 2 and tets.shape[1] == 4
    # compact numbering: every vertex belongs to a tetrahedron
    assert np.array_equal(np.unique(tets), np.arange(len(points)))
    assert (signed_volumes(points, tets) > 0).all()


# ---------------------------------------------------------------- without gmsh
def test_missing_gmsh_gives_install_hint(monkeypatch):
    monkeypatch.setitem(sys.modules, "gmsh", None)  # makes `import gmsh` raise ImportError
    with pytest.raises(ImportError, match="python3-gmsh"):
        shapes.ellipsoid((0.01, 0.01, 0.01), 0.005)


def test_bad_arguments_rejected_before_meshing():
    with pytest.raises(ValueError, match="mesh_size"):
        shapes.ellipsoid((0.01, 0.01, 0.01), 0.0)
    with pytest.raises(ValueError, match="height"):
        shapes.dome(0.05, -1.0, 0.01)
    with pytest.raises(ValueError, match="unknown paper shape"):
        shapes.paper_shape("banana", 0.01)


def test_paper_shapes_table():
    assert {k: s.vertices for k, s in shapes.PAPER_SHAPES.items()} == TABLE_I_VERTICES
    for spec in shapes.PAPER_SHAPES.values():
        assert 50.0 < spec.density < 1200.0  # foam to water-rich fruit, kg/m³
    a, b, c = shapes.PAPER_SHAPES["football"].dimensions
    assert a > b == c  # long axis along x


def _fake_builder(counts: dict[float, int] | None = None):
    """A gmsh-free builder with n(h) = round(1e-4 / h³), or a step function."""

    def build(h: float) -> tuple[np.ndarray, np.ndarray]:
        n = round(1e-4 / h**3) if counts is None else next(v for k, v in sorted(counts.items()) if h <= k)
        return np.zeros((n, 3)), np.zeros((1, 4), dtype=np.int64)

    return build


def test_vertex_count_search_logic():
    calls = []
    builder = _fake_builder()
    points, _ = shapes.mesh_with_vertex_count(lambda h: calls.append(h) or builder(h), 5000, initial_size=0.01)
    assert abs(len(points) - 5000) <= 250
    assert len(calls) <= 4


def test_vertex_count_search_reports_an_unreachable_count():
    step = _fake_builder({0.0048: 1000, math.inf: 800})  # no size gives 900 ± 5 %
    with pytest.raises(RuntimeError, match="closest: (800|1000) vertices"):
        shapes.mesh_with_vertex_count(step, 900, initial_size=0.005, max_calls=8)


# ------------------------------------------------------------------- with gmsh
@pytest.mark.gmsh
def test_ellipsoid_volume_and_shape(gmsh):
    a, b, c = 0.03, 0.02, 0.015
    points, tets = shapes.ellipsoid((a, b, c), 0.003)
    check_arrays(points, tets)
    exact = 4.0 / 3.0 * math.pi * a * b * c
    volume = signed_volumes(points, tets).sum()
    assert 0.97 * exact < volume < exact  # inscribed polyhedron of a convex body
    r = (points[:, 0] / a) ** 2 + (points[:, 1] / b) ** 2 + (points[:, 2] / c) ** 2
    assert r.max() <= 1.0 + 1e-6
    np.testing.assert_allclose(points.max(axis=0), [a, b, c], rtol=0.05)


@pytest.mark.gmsh
def test_dome_has_flat_base(gmsh):
    radius, height = 0.05, 0.035
    points, tets = shapes.dome(radius, height, 0.008)
    check_arrays(points, tets)
    assert points[:, 2].min() == 0.0
    assert points[:, 2].max() == pytest.approx(height, rel=1e-6)
    base = points[points[:, 2] == 0.0]
    assert len(base) > 10 and np.hypot(base[:, 0], base[:, 1]).max() == pytest.approx(radius, rel=1e-6)
    exact = 2.0 / 3.0 * math.pi * radius**2 * height
    assert 0.95 * exact < signed_volumes(points, tets).sum() < exact


@pytest.mark.gmsh
@pytest.mark.parametrize("initial_size", [None, 0.004])
def test_vertex_count_targeting(gmsh, initial_size):
    builder = functools.partial(shapes.ellipsoid, (0.03, 0.02, 0.015))
    points, tets = shapes.mesh_with_vertex_count(builder, 700, initial_size=initial_size)
    check_arrays(points, tets)
    assert abs(len(points) - 700) <= 0.05 * 700


@pytest.mark.gmsh
def test_meshing_is_deterministic(gmsh):
    for algorithm in ("meshadapt", "frontal-delaunay"):
        p1, t1 = shapes.paper_shape("steam_bun", 0.009, algorithm=algorithm)
        p2, t2 = shapes.paper_shape("steam_bun", 0.009, algorithm=algorithm)
        assert np.array_equal(p1, p2) and np.array_equal(t1, t2)
    m1 = shapes.paper_mesh("tomato")
    m2 = shapes.paper_mesh("tomato")
    assert np.array_equal(m1.points, m2.points) and np.array_equal(m1.tets, m2.tets)


@pytest.mark.gmsh
def test_paper_mesh_orientation(gmsh):
    mesh = shapes.paper_mesh("football", 400)
    lo, hi = mesh.bounds
    extent = hi - lo
    assert extent[0] > 1.5 * extent[1] and extent[0] > 1.5 * extent[2]  # long axis along x
    assert abs(mesh.n_points - 400) <= 20


# ------------------------------------------------------------ committed meshes
@pytest.mark.parametrize("name", sorted(TABLE_I_VERTICES))
def test_committed_mesh(name):
    meshio = pytest.importorskip("meshio")
    path = MESH_DIR / f"{name}.vtu"
    assert path.exists(), f"{path} is missing; regenerate with `make meshes`"
    m = meshio.read(path)
    assert [c.type for c in m.cells] == ["tetra"]
    points = np.asarray(m.points, dtype=float)
    tets = np.asarray(m.cells[0].data, dtype=np.int64)
    assert abs(len(points) - TABLE_I_VERTICES[name]) <= 0.05 * TABLE_I_VERTICES[name]
    assert np.array_equal(np.unique(tets), np.arange(len(points)))
    assert (signed_volumes(points, tets) > 0).all()
    spec = shapes.PAPER_SHAPES[name]
    assert signed_volumes(points, tets).sum() == pytest.approx(spec.volume, rel=0.05)
    if spec.kind == "dome":
        assert points[:, 2].min() == 0.0


def _edge_lengths_near(points: np.ndarray, tets: np.ndarray, centre: np.ndarray, radius: float) -> np.ndarray:
    pairs = np.array([(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)])
    a, b = points[tets[:, pairs[:, 0]]].reshape(-1, 3), points[tets[:, pairs[:, 1]]].reshape(-1, 3)
    near = np.linalg.norm(0.5 * (a + b) - centre, axis=1) <= radius
    return np.linalg.norm(a - b, axis=1)[near]


@pytest.mark.gmsh
def test_refinement_makes_the_mesh_finer_only_around_its_centres(gmsh):
    centre = np.array([0.0, 0.03, 0.0])
    refine = shapes.Refinement.around(np.array([centre]), 0.01)  # size 5 mm within 2 cm
    assert (refine.radius, refine.size, refine.thickness) == (0.02, 0.005, 0.01)
    p0, t0 = shapes.ellipsoid((0.03, 0.03, 0.025), 0.012)
    p1, t1 = shapes.ellipsoid((0.03, 0.03, 0.025), 0.012, refine=refine)
    check_arrays(p1, t1)
    inside = np.median(_edge_lengths_near(p1, t1, centre, 0.015))
    assert inside < 0.75 * np.median(_edge_lengths_near(p0, t0, centre, 0.015))
    assert 0.003 < inside < 0.0075  # about the requested 5 mm
    far = -centre  # the opposite side keeps the outer size
    np.testing.assert_allclose(np.median(_edge_lengths_near(p1, t1, far, 0.015)),
                               np.median(_edge_lengths_near(p0, t0, far, 0.015)), rtol=0.2)
    with pytest.raises(ValueError, match="3-vectors"):
        shapes.Refinement(((0.0, 1.0),), 0.02, 0.005, 0.01)
    with pytest.raises(ValueError, match="size must be a positive"):
        shapes.Refinement(((0.0, 0.0, 0.0),), 0.02, 0.0, 0.01)


@pytest.mark.gmsh
def test_graded_paper_mesh_keeps_the_vertex_count(gmsh):
    refine = shapes.Refinement.around(np.array([[0.0, 0.033, 0.0], [0.0, -0.033, 0.0]]), 0.01)
    mesh = shapes.paper_mesh("tomato", 490, refine=refine)
    assert abs(mesh.n_points - 490) <= 0.05 * 490
    uniform = shapes.paper_mesh("tomato", 490)
    for c in refine.centers:
        # more surface nodes within a fingertip radius of the refined points than on the uniform mesh
        near = lambda m: int((np.linalg.norm(m.points[m.surface_nodes] - np.array(c), axis=1) <= 0.01).sum())
        assert near(mesh) >= 1.5 * near(uniform)


@pytest.mark.gmsh
def test_bulging_dome_has_its_widest_point_at_the_equator(gmsh):
    r, h, e = 0.048, 0.025, 0.010
    points, tets = shapes.dome(r, h, 0.006, equator=e)
    check_arrays(points, tets)
    assert points[:, 2].min() == 0.0 and points[:, 2].max() == pytest.approx(e + h, rel=1e-6)
    base = points[points[:, 2] == 0.0]
    np.testing.assert_allclose(np.hypot(base[:, 0], base[:, 1]).max(), r * math.sqrt(1 - (e / h) ** 2), rtol=1e-6)
    rho = np.hypot(points[:, 0], points[:, 1])
    assert abs(points[rho.argmax(), 2] - e) < 0.006 and rho.max() == pytest.approx(r, rel=1e-3)
    assert 0.95 * shapes.dome_volume(r, h, e) < signed_volumes(points, tets).sum() < shapes.dome_volume(r, h, e)
    assert shapes.dome_volume(r, h) == pytest.approx(2.0 / 3.0 * math.pi * r * r * h)
    with pytest.raises(ValueError, match="equator"):
        shapes.dome(r, h, 0.006, equator=h)


@pytest.mark.parametrize("name", ["tomato", "steam_bun"])
def test_points_on_a_paper_shapes_curved_surface_become_nodes_and_the_mesh_stays_as_fine(name, gmsh):
    """Asked to (``embed_points``), a paper shape makes points of its curved surface nodes, on the ellipsoid and
    on the dome's side (the solid's volume kept), with about as many vertices as without them; a point off the
    surface is left to the nearest node, and unless asked not to (``embed_points=False``) the points are embedded."""
    from fem_grasp.mesh.remesh import PaperGeometry, nearest_surface_nodes, patch_refinement

    geo = PaperGeometry(name, embed_points=True)
    samples = geo.surface_points(0.5e-3)
    points = samples[[int(np.argmin(samples[:, 1])), int(np.argmax(samples[:, 1]))]]
    refine = patch_refinement(points, 2e-3, 6e-3, 8e-3)
    plain, embedded = geo.build(8e-3, [refine]), geo.build(8e-3, [refine], embed=points)
    at = embedded.points[nearest_surface_nodes(embedded, points)]
    assert np.allclose(at, points, rtol=0, atol=1e-9)  # within the grid gmsh's points are rounded to
    assert embedded.volume == pytest.approx(geo.volume, rel=0.03)
    assert 0.8 < len(embedded.points) / len(plain.points) < 1.25
    off = points + [[0.0, -1e-3, 0.0], [0.0, 1e-3, 0.0]]  # a millimetre outside
    mesh = geo.build(8e-3, [refine], embed=off)
    assert np.linalg.norm(mesh.points[nearest_surface_nodes(mesh, off)] - off, axis=1).min() > 0.5e-3
    assert PaperGeometry(name).embeds_points and not PaperGeometry(name, embed_points=False).embeds_points
    plain = PaperGeometry(name, embed_points=False).build(8e-3, [refine], embed=points)
    assert np.linalg.norm(plain.points[nearest_surface_nodes(plain, points)] - points, axis=1).max() > 1e-6


@pytest.mark.gmsh
def test_round_off_in_what_gmsh_is_given_does_not_change_the_mesh(gmsh):
    """gmsh's mesh follows the last bits of its points and lengths, and another CPU's round-off moves them (the
    accuracy loop's grasp and patch points, its level's spacings): they are rounded to a grid of about 1e-8 of the
    spacing first (``POINT_QUANTUM``), so a mesh moved by 1e-15 of itself is the same mesh, and each point given to
    embed is a node within that grid of where it was asked."""
    from fem_grasp.mesh.gmsh_session import POINT_QUANTUM
    from fem_grasp.mesh.remesh import PaperGeometry, nearest_surface_nodes, patch_refinement

    geo = PaperGeometry("orange", embed_points=True)
    samples = geo.surface_points(0.3e-3)
    grasp = samples[[int(np.argmin(samples[:, 1])), int(np.argmax(samples[:, 1]))]]
    fingers = samples[np.linalg.norm(samples[:, None, :] - grasp[None], axis=2).min(axis=1) < 4e-3]
    table = samples[samples[:, 2] < samples[:, 2].min() + 2e-3]
    inner, outer = 2.45e-3, 6.9e-3

    def mesh(points, fingers, table, inner, outer):
        refs = [patch_refinement(fingers, inner, 2 * inner, outer),
                patch_refinement(table, 2 * inner, 4 * inner, outer)]
        return geo.build(outer, refs, embed=points)

    first = mesh(grasp, fingers, table, inner, outer)
    at = first.points[nearest_surface_nodes(first, grasp)]
    np.testing.assert_allclose(at, grasp, rtol=0, atol=2 * POINT_QUANTUM * outer)
    rng = np.random.default_rng(7)
    for k in range(4):
        jitter = lambda a: a * (1.0 + 1e-15 * rng.standard_normal(np.shape(a)))
        again = mesh(jitter(grasp), jitter(fingers), jitter(table), jitter(inner), jitter(outer))
        assert again.n_points == first.n_points and np.array_equal(again.points, first.points), k
