"""Scan import: a closed triangle surface (STL, OBJ, PLY, OFF) → a tetrahedral mesh with gmsh.

:func:`read_surface` reads the triangles with meshio, merges the duplicate
vertices that STL repeats for every facet, and drops degenerate triangles.
:func:`check_surface` then refuses, with a message that says what is wrong
and where (a vertex position), a surface that

* is not closed (boundary edges: holes), or has an edge shared by more than
  two triangles, or a vertex where two sheets touch (non-manifold);
* cannot be oriented consistently, or consists of several separate pieces;
* intersects itself (two triangles that share no vertex cross; a broad
  phase on triangle bounding spheres, then exact edge–triangle tests).

Its triangles are oriented consistently and outward.  :func:`mesh_surface`
fills the volume with gmsh: keeping the scan's own triangles on the
boundary, or — with a target vertex count or mesh size — remeshing the
surface first (gmsh's ``classifySurfaces`` + ``createGeometry``, as in its
tutorial t13), which is how a dense scan is simplified to a size the FEM
needs.  gmsh is imported only here (the ``mesh`` extra, or Debian's ``python3-gmsh``).
"""

from __future__ import annotations

import functools
import logging
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import SurfaceError
from .units import length_scale

__all__ = ["SURFACE_SUFFIXES", "SurfaceError", "Surface", "read_surface", "check_surface", "self_intersections",
           "mesh_surface", "surface_report", "closest_points"]

log = logging.getLogger(__name__)

#: File suffixes read as triangle surfaces.
SURFACE_SUFFIXES = (".stl", ".obj", ".ply", ".off")
#: Vertices closer than this × the bounding-box diagonal are merged.
MERGE_TOL = 1e-9
#: Above this many surface vertices a surface kept as is makes a large mesh; the CLI suggests --vertices.
DENSE_SCAN_VERTICES = 5000
#: Feature angle for gmsh's surface classification when remeshing (degrees).
CLASSIFY_ANGLE = 40.0


@dataclass(frozen=True)
class Surface:
    """A triangle surface: points (n, 3) and faces (f, 3), with the name it came from."""

    points: np.ndarray
    faces: np.ndarray
    source: str = "<surface>"

    @property
    def diameter(self) -> float:
        return float(np.linalg.norm(self.points.max(axis=0) - self.points.min(axis=0))) if len(self.points) else 0.0

    @property
    def area(self) -> float:
        p = self.points[self.faces]
        return 0.5 * float(np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum())

    @property
    def volume(self) -> float:
        """Signed enclosed volume (positive for outward-oriented triangles)."""
        p = self.points[self.faces]
        return float(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0)


def _at(points: np.ndarray, k: int) -> str:
    x, y, z = points[k]
    return f"({x:.6g}, {y:.6g}, {z:.6g})"


# ------------------------------------------------------------------ reading
def read_surface(path: str | Path, units: str = "m") -> Surface:
    """Read a triangle surface with meshio (quads are split), merge duplicate vertices, drop degenerate triangles;
    the file's coordinates are in ``units`` ("m", "cm", "mm"), the surface returned is in metres.

    Raises
    ------
    SurfaceError
        The file is missing, unreadable, or holds no triangles.
    """
    import meshio

    p = Path(path)
    if not p.exists():
        raise SurfaceError(f"surface file {p} does not exist")
    try:
        m = meshio.read(p)
    except Exception as exc:  # meshio raises many types for unreadable files
        raise SurfaceError(f"cannot read {p} as a surface ({type(exc).__name__}: {exc})") from None
    blocks = []
    for c in m.cells:
        if c.type == "triangle":
            blocks.append(np.asarray(c.data, dtype=np.int64))
        elif c.type == "quad":
            q = np.asarray(c.data, dtype=np.int64)
            blocks += [q[:, [0, 1, 2]], q[:, [0, 2, 3]]]
        elif c.type in ("tetra", "hexahedron", "wedge", "pyramid"):
            raise SurfaceError(f"{p} holds volume cells ({c.type}); read it with TetMesh.from_file instead")
    if not blocks:
        raise SurfaceError(f"{p} holds no triangles (cell types: {sorted({c.type for c in m.cells}) or 'none'})")
    surface = clean_surface(np.asarray(m.points, dtype=float)[:, :3], np.concatenate(blocks), str(p))
    scale = length_scale(units)
    return surface if scale == 1.0 else Surface(surface.points * scale, surface.faces, surface.source)


def clean_surface(points: np.ndarray, faces: np.ndarray, source: str = "<surface>") -> Surface:
    """Merge duplicate vertices, drop degenerate and unused ones; check coordinates are finite."""
    points = np.asarray(points, dtype=float)
    faces = np.asarray(faces, dtype=np.int64)
    if points.ndim != 2 or points.shape[1] != 3 or faces.ndim != 2 or faces.shape[1] != 3:
        raise SurfaceError(f"{source}: expected points (n, 3) and triangles (f, 3), got {points.shape}, {faces.shape}")
    if len(faces) == 0:
        raise SurfaceError(f"{source}: the surface has no triangles")
    if faces.min() < 0 or faces.max() >= len(points):
        raise SurfaceError(f"{source}: a triangle refers to a vertex that does not exist")
    bad = ~np.isfinite(points).all(axis=1)
    if bad[faces].any():
        k = int(np.flatnonzero(bad)[0])
        raise SurfaceError(f"{source}: vertex {k} has a non-finite coordinate {points[k].tolist()}")
    used = np.unique(faces)
    diam = float(np.linalg.norm(points[used].max(axis=0) - points[used].min(axis=0)))
    if not diam > 0:
        raise SurfaceError(f"{source}: all vertices coincide")
    q = np.round(points / (MERGE_TOL * diam)).astype(np.int64)
    _, first, inverse = np.unique(q, axis=0, return_index=True, return_inverse=True)
    faces = inverse.reshape(-1)[faces]
    points = points[first]
    # Degenerate triangles: repeated vertex or zero area.
    rep = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 0] == faces[:, 2])
    pf = points[faces]
    area2 = np.linalg.norm(np.cross(pf[:, 1] - pf[:, 0], pf[:, 2] - pf[:, 0]), axis=1)
    degenerate = rep | (area2 <= 1e-14 * diam * diam)
    if degenerate.any():
        log.warning("%s: dropped %d degenerate triangle(s)", source, int(degenerate.sum()))
        faces = faces[~degenerate]
    used, compact = np.unique(faces, return_inverse=True)
    return Surface(points[used], compact.reshape(-1, 3), source)


# ------------------------------------------------------------------ topology
def _edges(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Directed edges (3f, 2), their undirected ids (3f,) and the count of each undirected edge."""
    directed = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key = np.sort(directed, axis=1)
    _, eid, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return directed, eid.reshape(-1), counts


def _components(n: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    g = sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(n, n))
    return connected_components(g, directed=False)[1]


def _face_pairs(eid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For every edge shared by exactly two faces: the two half-edge indices (into the 3f directed edges)."""
    order = np.argsort(eid, kind="stable")
    e_sorted = eid[order]
    same = e_sorted[1:] == e_sorted[:-1]
    h1, h2 = order[:-1][same], order[1:][same]
    return h1, h2, e_sorted[:-1][same]


def check_surface(surface: Surface, self_intersection: bool = True) -> Surface:
    """Check a surface can bound a solid; return it oriented consistently and outward.

    Raises
    ------
    SurfaceError
        Not closed, non-manifold edge or vertex, not orientable, several
        pieces, or self-intersecting; the message gives counts and a position.
    """
    pts, faces, src = surface.points, surface.faces, surface.source
    nf = len(faces)
    if nf < 4:
        raise SurfaceError(f"{src}: a closed surface needs at least 4 triangles, got {nf}")
    directed, eid, counts = _edges(faces)
    c = counts[eid]
    if (c == 1).any():
        open_edges = directed[c == 1]
        n_holes = len(np.unique(_components(len(pts), open_edges[:, 0], open_edges[:, 1])[np.unique(open_edges)]))
        i, j = (int(x) for x in open_edges[0])
        raise SurfaceError(
            f"{src}: the surface is not closed: {len(open_edges)} boundary edge(s) forming {n_holes} hole(s); "
            f"e.g. the edge between vertices {i} and {j} at {_at(pts, i)} has only one triangle. Close the holes "
            "(e.g. MeshLab's 'Close Holes') before meshing")
    if (c > 2).any():
        i, j = (int(x) for x in directed[c > 2][0])
        raise SurfaceError(
            f"{src}: the surface is not manifold: {int((counts > 2).sum())} edge(s) are shared by more than two "
            f"triangles; e.g. the edge between vertices {i} and {j} at {_at(pts, i)} has {int(c[c > 2][0])}")
    h1, h2, _ = _face_pairs(eid)
    f1, f2 = h1 // 3, h2 // 3
    # Non-manifold vertices: the triangles around a vertex must form a single fan.
    corner_of = lambda f, v: 3 * f + np.argmax(faces[f] == v[:, None], axis=1)  # noqa: E731
    a_v, b_v = directed[h1, 0], directed[h1, 1]
    ca = np.concatenate([corner_of(f1, a_v), corner_of(f1, b_v)])
    cb = np.concatenate([corner_of(f2, a_v), corner_of(f2, b_v)])
    labels = _components(3 * nf, ca, cb)
    fans = np.unique(np.stack([faces.reshape(-1), labels], axis=1), axis=0)
    fan_count = np.bincount(fans[:, 0], minlength=len(pts))
    if (fan_count > 1).any():
        k = int(np.flatnonzero(fan_count > 1)[0])
        raise SurfaceError(f"{src}: the surface is not manifold at {int((fan_count > 1).sum())} vertex(es) where "
                           f"separate sheets touch; e.g. vertex {k} at {_at(pts, k)}")
    # Pieces.
    comp = _components(nf, f1, f2)
    n_comp = int(comp.max()) + 1
    if n_comp > 1:
        sizes = np.bincount(comp)
        small = int(np.argmin(sizes))
        k = int(faces[np.flatnonzero(comp == small)[0], 0])
        raise SurfaceError(f"{src}: the surface has {n_comp} separate pieces (triangles per piece: "
                           f"{sorted(sizes.tolist(), reverse=True)}); e.g. a piece of {int(sizes[small])} triangles "
                           f"at {_at(pts, k)}. Mesh one closed object per file")
    # Consistent orientation: neighbours traverse their shared edge in opposite directions.
    flip = _orientation(nf, f1, f2, directed[h1, 0] == directed[h2, 0], src, pts, faces)
    faces = np.where(flip[:, None], faces[:, ::-1], faces)
    out = Surface(pts, faces, src)
    if out.volume < 0:
        out = Surface(pts, faces[:, ::-1].copy(), src)
    if self_intersection:
        pairs = self_intersections(out.points, out.faces)
        if len(pairs):
            a, b = (int(x) for x in pairs[0])
            where = out.points[out.faces[[a, b]]].reshape(-1, 3).mean(axis=0)
            raise SurfaceError(f"{src}: the surface intersects itself: {len(pairs)} pair(s) of triangles cross; "
                               f"e.g. triangles {a} and {b} near ({where[0]:.6g}, {where[1]:.6g}, {where[2]:.6g})")
    return out


def _orientation(nf: int, f1: np.ndarray, f2: np.ndarray, same_direction: np.ndarray, src: str,
                 pts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Which faces to flip so that the surface is consistently oriented (breadth-first over neighbours)."""
    from collections import deque

    if not same_direction.any():
        return np.zeros(nf, dtype=bool)
    nbr: list[list[tuple[int, bool]]] = [[] for _ in range(nf)]
    for a, b, s in zip(f1.tolist(), f2.tolist(), same_direction.tolist()):
        nbr[a].append((b, s))
        nbr[b].append((a, s))
    flip = np.zeros(nf, dtype=bool)
    seen = np.zeros(nf, dtype=bool)
    seen[0] = True
    queue = deque([0])
    while queue:
        a = queue.popleft()
        for b, s in nbr[a]:
            want = flip[a] ^ s
            if not seen[b]:
                seen[b] = True
                flip[b] = want
                queue.append(b)
            elif flip[b] != want:
                k = int(faces[b, 0])
                raise SurfaceError(f"{src}: the surface cannot be oriented (it is one-sided, like a Möbius strip or a "
                                   f"Klein bottle); the conflict is at triangle {b} near {_at(pts, k)}")
    log.info("%s: reoriented %d triangle(s) consistently", src, int(flip.sum()))
    return flip


# ------------------------------------------------------------------ self-intersection
def _orient(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Signed volume ×6 of (a, b, c, d), row-wise."""
    return np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a))


def _segment_crosses(p0: np.ndarray, p1: np.ndarray, v0: np.ndarray, v1: np.ndarray, v2: np.ndarray,
                     eps: float) -> np.ndarray:
    """Whether segment p0p1 crosses triangle v0v1v2 (row-wise; an end point on its plane does not count)."""
    d0 = _orient(v0, v1, v2, p0)
    d1 = _orient(v0, v1, v2, p1)
    straddle = ((d0 > eps) & (d1 < -eps)) | ((d0 < -eps) & (d1 > eps))
    s0 = _orient(p0, p1, v0, v1)
    s1 = _orient(p0, p1, v1, v2)
    s2 = _orient(p0, p1, v2, v0)
    # The line may pass through an edge or a vertex of the triangle (then one or two s_i vanish).
    inside = ((s0 >= -eps) & (s1 >= -eps) & (s2 >= -eps)) | ((s0 <= eps) & (s1 <= eps) & (s2 <= eps))
    return straddle & inside


def self_intersections(points: np.ndarray, faces: np.ndarray, max_report: int | None = None) -> np.ndarray:
    """Pairs (k, 2) of triangles that share no vertex and cross each other.

    Broad phase: pairs whose bounding spheres (about the centroids) overlap,
    found with a k-d tree; narrow phase: an edge of one triangle properly
    crosses the other (exact orientation tests with a round-off margin).
    Coplanar overlaps and crossings between triangles that share a vertex are
    not detected.
    """
    from scipy.spatial import cKDTree

    p = points[faces]
    cen = p.mean(axis=1)
    rad = np.linalg.norm(p - cen[:, None], axis=2).max(axis=1)
    tree = cKDTree(cen)
    pairs = tree.query_pairs(2.0 * float(rad.max()), output_type="ndarray")
    if not len(pairs):
        return np.zeros((0, 2), dtype=np.int64)
    a, b = pairs[:, 0], pairs[:, 1]
    keep = np.linalg.norm(cen[a] - cen[b], axis=1) <= rad[a] + rad[b]
    fa, fb = faces[a], faces[b]
    shares = (fa[:, :, None] == fb[:, None, :]).any(axis=(1, 2))
    keep &= ~shares
    a, b = a[keep], b[keep]
    if not len(a):
        return np.zeros((0, 2), dtype=np.int64)
    diam = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    eps = 1e-12 * diam ** 3
    hit = np.zeros(len(a), dtype=bool)
    for s, t in ((a, b), (b, a)):
        ps, pt = p[s], p[t]
        for i, j in ((0, 1), (1, 2), (2, 0)):
            hit |= _segment_crosses(ps[:, i], ps[:, j], pt[:, 0], pt[:, 1], pt[:, 2], eps)
    out = np.stack([a[hit], b[hit]], axis=1)
    return out if max_report is None else out[:max_report]


# ------------------------------------------------------------------ meshing
def _closest_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """(k, 3) the point of each triangle (a, b, c) closest to p (Ericson, Real-Time Collision Detection, 5.1.5):
    its barycentric coordinates projected onto the triangle, region by region."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(-1), (ac * ap).sum(-1)
    bp, cp = p - b, p - c
    d3, d4 = (ab * bp).sum(-1), (ac * bp).sum(-1)
    d5, d6 = (ab * cp).sum(-1), (ac * cp).sum(-1)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        v, w = vb / denom, vc / denom
        out = a + ab * v[..., None] + ac * w[..., None]  # inside the face
        t_ab, t_ac = d1 / (d1 - d3), d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    regions = [  # Ericson's tests in reverse: a region applied later takes precedence
        ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), b + (c - b) * t_bc[..., None]),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + ac * t_ac[..., None]),
        ((d6 >= 0) & (d5 <= d6), c),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + ab * t_ab[..., None]),
        ((d3 >= 0) & (d4 <= d3), b),
        ((d1 <= 0) & (d2 <= 0), a),
    ]
    for mask, q in regions:
        out = np.where(mask[..., None], q, out)
    return out


def closest_points(surface: Surface, points: np.ndarray, candidates: int = 8) -> np.ndarray:
    """(k, 3) the point of ``surface`` nearest to each of ``points`` (k, 3), among the ``candidates``
    triangles whose centroids are nearest to it (the points lie near the surface, within a triangle or two)."""
    from scipy.spatial import cKDTree

    p = np.asarray(points, float).reshape(-1, 3)
    tri = np.asarray(surface.points, float)[np.asarray(surface.faces)]
    m = min(int(candidates), len(tri))
    _, idx = cKDTree(tri.mean(axis=1)).query(p, k=m)
    idx = np.asarray(idx).reshape(len(p), m)
    t = tri[idx]  # (k, m, 3, 3)
    q = _closest_on_triangles(p[:, None, :], t[..., 0, :], t[..., 1, :], t[..., 2, :])
    best = np.argmin(((q - p[:, None, :]) ** 2).sum(-1), axis=1)
    return q[np.arange(len(p)), best]


def _gmsh_fill(surface: Surface, mesh_size: float | None) -> tuple[np.ndarray, np.ndarray]:
    """Tetrahedralise the volume bounded by ``surface``; remesh the surface first when ``mesh_size`` is given."""
    from .gmsh_session import SURFACE_ALGORITHMS, extract_tets, generate, gmsh_model

    size = mesh_size if mesh_size is not None else surface.diameter  # size only matters when remeshing
    with gmsh_model("scan", size, SURFACE_ALGORITHMS["frontal-delaunay"]) as gmsh:
        tag = gmsh.model.addDiscreteEntity(2)
        n = len(surface.points)
        gmsh.model.mesh.addNodes(2, tag, list(range(1, n + 1)), surface.points.reshape(-1).tolist())
        gmsh.model.mesh.addElementsByType(tag, 2, [], (surface.faces + 1).reshape(-1).tolist())
        if mesh_size is not None:
            gmsh.model.mesh.classifySurfaces(math.radians(CLASSIFY_ANGLE), True, True, math.pi)
            gmsh.model.mesh.createGeometry()
        else:
            gmsh.model.mesh.createTopology()
        gmsh.model.geo.synchronize()
        surfaces = [e[1] for e in gmsh.model.getEntities(2)]
        loop = gmsh.model.geo.addSurfaceLoop(surfaces)
        gmsh.model.geo.addVolume([loop])
        gmsh.model.geo.synchronize()
        generate(gmsh, size)
        return extract_tets(gmsh)


def mesh_surface(source: str | Path | Surface, target_vertices: int | None = None, size: float | None = None,
                 rel_tol: float = 0.1, check: bool = True) -> Any:
    """A :class:`~fem_grasp.mesh.TetMesh` filling a closed triangle surface.

    Parameters
    ----------
    source : path of an STL/OBJ/PLY/OFF file, or a :class:`Surface`
    target_vertices : int, optional
        Remesh the surface so that the tetrahedral mesh has about this many
        vertices (within ``rel_tol``); simplifies a dense scan.
    size : float, optional
        Remesh at this target edge length (metres) instead.
    check : bool
        Run :func:`check_surface` first (always, unless the surface is known good).

    Without ``target_vertices`` and ``size`` the scan's own triangles form
    the boundary.

    Raises
    ------
    SurfaceError
        A bad surface (see :func:`check_surface`) or bad arguments.
    RuntimeError
        gmsh could not mesh it.
    """
    from .gmsh_session import mesh_with_vertex_count
    from .tetmesh import TetMesh

    if target_vertices is not None and size is not None:
        raise SurfaceError("give target_vertices or size, not both")
    if target_vertices is not None and (int(target_vertices) != target_vertices or target_vertices < 20):
        raise SurfaceError(f"target_vertices must be an integer ≥ 20, got {target_vertices!r}")
    if size is not None and not (math.isfinite(size) and size > 0):
        raise SurfaceError(f"size must be a positive length in metres, got {size!r}")
    surf = source if isinstance(source, Surface) else read_surface(source)
    if check:
        surf = check_surface(surf)
    if target_vertices is not None:
        h0 = (abs(surf.volume) / target_vertices) ** (1.0 / 3.0)
        builder = functools.partial(lambda s, h: _gmsh_fill(s, h), surf)
        points, tets = mesh_with_vertex_count(builder, int(target_vertices), rel_tol, initial_size=float(f"{h0:.6g}"))
    else:
        points, tets = _gmsh_fill(surf, size)
    mesh = TetMesh(points, tets)
    log.info("%s: %d vertices, %d tets (surface %d vertices)", surf.source, mesh.n_points, mesh.n_tets,
             len(surf.points))
    return mesh


def surface_report(path: str | Path) -> dict[str, Any]:
    """Figures of a surface file and the verdict of :func:`check_surface` (``ok``, ``problem``)."""
    surf = read_surface(path)
    out: dict[str, Any] = {"vertices": len(surf.points), "triangles": len(surf.faces), "diameter": surf.diameter,
                           "area": surf.area}
    try:
        good = check_surface(surf)
        out.update(ok=True, problem="", volume=good.volume)
    except SurfaceError as exc:
        out.update(ok=False, problem=str(exc), volume=None)
    return out
