"""Stable resting pose of a rigid body on a table (paper §III, the support triangle △p_q p_r p_s).

Before it deforms, an object put on a table rests on a facet of the convex
hull of its surface: the facet's plane supports it, and it stays put if the
vertical projection of its centre of mass falls *strictly inside* the facet
(otherwise it tips about an edge).  The paper starts the resting iteration
(§III-A) from a surface triangle △p_q p_r p_s with this property.

Rules used here
---------------
* Facets are those of ``scipy.spatial.ConvexHull`` of the surface nodes, with
  coplanar hull triangles merged into one polygonal facet (same outward
  normal and offset within ``coplanar_tol · diameter``).  A facet's nodes are
  all surface nodes within that distance of its plane.
* A facet is *stable* when the centre of mass, projected along the facet
  normal, lies inside the facet polygon by more than ``min_margin · diameter``
  (the margin is the distance to the nearest polygon edge).
* Among stable facets the one whose outward normal is closest to the given
  ``down`` direction is chosen (largest n̂·down): the pose needing the least
  rotation.  Ties go to the larger margin.
* Within the chosen facet the support triangle is the triple of facet nodes
  whose triangle contains the projected centre of mass with the largest
  margin.  (For a facet of more than ``MAX_TRIANGLE_CANDIDATES`` nodes, the
  candidates are the farthest node from the projected centre in each of that
  many equal angular sectors.)
* The body is rotated about its centre of mass by the smallest rotation
  taking the facet normal to ``down``, then by the smallest rotation taking
  ``down`` to −z, and translated vertically so the facet lies in
  ``z = table_z``: the centre of mass keeps its horizontal position when
  ``down`` is −z.
"""

from __future__ import annotations

import itertools
import logging
from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull

from ..contact.obstacles import tangent_bases
from ..elastic.body import Body

__all__ = ["Facet", "RestingPose", "hull_facets", "stable_facets", "resting_pose", "rotation_between",
           "triangle_margin"]

log = logging.getLogger(__name__)

#: Coplanarity tolerance, relative to the mesh diameter.
COPLANAR_TOL = 1e-9
#: A facet or triangle is stable when the projected centre of mass is inside it by more than this
#: fraction of the mesh diameter.
MIN_MARGIN = 1e-9
#: Facets with more nodes are thinned to this many candidates for the support triangle.
MAX_TRIANGLE_CANDIDATES = 40
#: Support triangles whose margins differ by less than this fraction of the facet's size are tied (the
#: first in node order is taken): far above round-off, far below any margin that matters.
TRIANGLE_TIE_TOL = 1e-9

_DOWN = np.array([0.0, 0.0, -1.0])


@dataclass(frozen=True)
class Facet:
    """A (merged) facet of the convex hull of the surface nodes.

    Attributes
    ----------
    normal : (3,) outward unit normal
    offset : float, the plane is ``normal · x = offset``
    nodes : (k,) surface nodes on the plane (mesh indices)
    polygon : (v,) mesh indices of the facet polygon's corners, counter-clockwise about ``normal``
    margin : float, distance of the projected centre of mass inside the polygon (negative outside), metres
    area : float, polygon area, m²
    """

    normal: np.ndarray
    offset: float
    nodes: np.ndarray
    polygon: np.ndarray
    margin: float
    area: float


@dataclass(frozen=True)
class RestingPose:
    """A body rigidly placed on the table ``z = table_z`` on a stable support triangle.

    Attributes
    ----------
    body : Body, the moved body (gravity −z, table below it)
    triangle : (3,) node indices of the support triangle △p_q p_r p_s
    rotation : (3, 3) applied rotation R (new point = R p + translation)
    translation : (3,)
    margin : float, distance (m) of the projected centre of mass inside the triangle
    facet : Facet or None, the hull facet (in the input frame) when chosen automatically
    """

    body: Body
    triangle: np.ndarray
    rotation: np.ndarray
    translation: np.ndarray
    margin: float
    facet: Facet | None = None


def _unit(v: np.ndarray, name: str) -> np.ndarray:
    v = np.asarray(v, dtype=float).reshape(-1)
    if v.shape != (3,) or not np.isfinite(v).all() or np.linalg.norm(v) == 0:
        raise ValueError(f"{name} must be a non-zero 3-vector, got {v!r}")
    return v / np.linalg.norm(v)


def rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest proper rotation R with R â = b̂ (Rodrigues; a half-turn if â = −b̂)."""
    a = _unit(a, "a")
    b = _unit(b, "b")
    v = np.cross(a, b)
    c = float(a @ b)
    s = float(np.linalg.norm(v))
    if s < 1e-14:
        if c > 0:
            return np.eye(3)
        axis = np.cross(a, np.eye(3)[int(np.argmin(np.abs(a)))])
        axis /= np.linalg.norm(axis)
        return 2.0 * np.outer(axis, axis) - np.eye(3)
    k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]]) / s
    angle = np.arctan2(s, c)
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)


def _plane_frame(normal: np.ndarray) -> np.ndarray:
    """(2, 3) orthonormal in-plane axes (e1, e2) with e1 × e2 = normal."""
    from ..contact.obstacles import tangent_basis

    return tangent_basis(normal)


def _polygon_margin(poly2: np.ndarray, point2: np.ndarray) -> tuple[float, int]:
    """Signed distance of ``point2`` inside a counter-clockwise convex polygon, and the nearest edge.

    Positive inside (distance to the nearest edge line), negative outside (minus the distance to the
    polygon).
    """
    a = poly2
    b = np.roll(poly2, -1, axis=0)
    e = b - a
    length = np.linalg.norm(e, axis=1)
    cross = e[:, 0] * (point2[1] - a[:, 1]) - e[:, 1] * (point2[0] - a[:, 0])
    dist = cross / np.where(length > 0, length, 1.0)
    j = int(np.argmin(dist))
    if dist[j] >= 0:
        return float(dist[j]), j
    # Outside: the Euclidean distance to the polygon is the distance to its nearest edge segment.
    t = np.clip(np.einsum("ij,ij->i", point2 - a, e) / np.where(length > 0, length**2, 1.0), 0.0, 1.0)
    seg = np.linalg.norm(a + t[:, None] * e - point2, axis=1)
    j = int(np.argmin(seg))
    return -float(seg[j]), j


def _triangle_margins(tri2: np.ndarray, point2: np.ndarray) -> np.ndarray:
    """:func:`_polygon_margin` of each point (t, 2) in its counter-clockwise triangle (t, 3, 2), all at once."""
    a = tri2
    e = np.roll(tri2, -1, axis=1) - a
    length = np.linalg.norm(e, axis=2)
    rel = point2[:, None, :] - a
    cross = e[..., 0] * rel[..., 1] - e[..., 1] * rel[..., 0]
    inside = (cross / np.where(length > 0, length, 1.0)).min(axis=1)
    t = np.clip(np.einsum("tij,tij->ti", rel, e) / np.where(length > 0, length**2, 1.0), 0.0, 1.0)
    outside = np.linalg.norm(t[..., None] * e - rel, axis=2).min(axis=1)
    return np.where(inside >= 0, inside, -outside)


def triangle_margin(points: np.ndarray, triangle: np.ndarray, point: np.ndarray,
                    normal: np.ndarray) -> tuple[float, int]:
    """Distance of ``point``, projected along ``normal``, inside the triangle (minus its distance outside).

    Returns the margin in metres and the index (0, 1, 2) of the nearest edge,
    edge j joining triangle corners j and j+1.
    """
    frame = _plane_frame(normal)
    tri2 = points[np.asarray(triangle)] @ frame.T
    p2 = np.asarray(point) @ frame.T
    a, b = tri2[1] - tri2[0], tri2[2] - tri2[0]
    area2 = a[0] * b[1] - a[1] * b[0]  # twice the signed area (NumPy 2 deprecates np.cross of 2-vectors)
    if area2 < 0:
        margin, j = _polygon_margin(tri2[::-1], p2)
        return margin, (1 - j) % 3  # map the reversed edge index back
    return _polygon_margin(tri2, p2)


def hull_facets(body: Body, coplanar_tol: float = COPLANAR_TOL) -> list[Facet]:
    """The facets of the convex hull of ``body``'s surface nodes, coplanar triangles merged.

    Each facet's margin is measured for the body's centre of mass.
    """
    mesh = body.mesh
    pts = mesh.points
    surf = mesh.surface_nodes
    diam = mesh.diameter
    tol = coplanar_tol * diam
    hull = ConvexHull(pts[surf])
    eq = hull.equations  # n·x + d <= 0 inside
    normals = eq[:, :3] / np.linalg.norm(eq[:, :3], axis=1, keepdims=True)
    offsets = -eq[:, 3] / np.linalg.norm(eq[:, :3], axis=1)
    com = body.center_of_mass
    assigned = np.full(len(eq), -1)
    planes: list[tuple[np.ndarray, float]] = []
    # Coplanar candidates of a triangle are among those of nearly its offset (sorted once): the test on
    # every pair was O(triangles²), seconds at 30k vertices.
    by_offset = np.argsort(offsets, kind="stable")
    sorted_offsets = offsets[by_offset]
    lows = np.searchsorted(sorted_offsets, offsets - 2.0 * tol, side="left")
    highs = np.searchsorted(sorted_offsets, offsets + 2.0 * tol, side="right")
    # A triangle alone in its offset window is a plane of its own (the window is symmetric, so no other
    # triangle's window holds it): nearly every triangle of a fine mesh, without the masks below.
    alone = (highs - lows == 1).tolist()
    for i in range(len(eq)):
        if assigned[i] >= 0:
            continue
        if alone[i]:
            assigned[i] = len(planes)
            n = normals[i]
            planes.append((n / np.linalg.norm(n), float(offsets[i])))
            continue
        cand = np.sort(by_offset[lows[i]:highs[i]])  # a superset of the triangles within tol; the exact test follows
        same = cand[(assigned[cand] < 0) & (normals[cand] @ normals[i] > 1.0 - coplanar_tol)
                    & (np.abs(offsets[cand] - offsets[i]) <= tol)]
        assigned[same] = len(planes)
        n = normals[same].mean(axis=0)
        planes.append((n / np.linalg.norm(n), float(offsets[same].mean())))
    # The surface nodes on each plane, found for many planes per matrix product (one scan per plane was
    # O(planes × surface) in Python: seconds at 30k vertices).
    surf_pts = pts[surf]
    on_plane: list[np.ndarray] = []
    chunk = max(1, 2 ** 22 // max(len(surf), 1))
    for start in range(0, len(planes), chunk):
        block = planes[start:start + chunk]
        dist = surf_pts @ np.array([n for n, _ in block]).T - np.array([off for _, off in block])
        rows, cols = np.nonzero(np.abs(dist) <= tol)
        order = np.argsort(cols, kind="stable")
        on_plane.extend(np.split(surf[rows[order]], np.searchsorted(cols[order], np.arange(1, len(block)))))
    frames = tangent_bases(np.array([n for n, _ in planes]).reshape(-1, 3))
    # Triangular facets (nearly all of them on a fine mesh) all at once: one by one they took 7 s at 100k vertices.
    tri = np.flatnonzero([len(on) == 3 for on in on_plane])
    tri_nodes = np.array([on_plane[i] for i in tri], dtype=np.int64).reshape(-1, 3)
    tri2 = np.einsum("tkd,tjd->tkj", pts[tri_nodes], frames[tri])  # (t, 3, 2) corners in each facet's frame
    e01, e02 = tri2[:, 1] - tri2[:, 0], tri2[:, 2] - tri2[:, 0]
    tri_area2 = e01[:, 0] * e02[:, 1] - e01[:, 1] * e02[:, 0]
    ccw = tri_area2 > 0
    tri_nodes[~ccw] = tri_nodes[~ccw, ::-1]
    tri2[~ccw] = tri2[~ccw, ::-1]
    tri_margin = _triangle_margins(tri2, np.einsum("d,tjd->tj", com, frames[tri]))
    triangles = dict(zip(tri.tolist(), zip(tri_nodes, 0.5 * np.abs(tri_area2), tri_margin)))
    facets: list[Facet] = []
    for i, ((n, off), on) in enumerate(zip(planes, on_plane)):
        if i in triangles:
            poly, area, margin = triangles[i]
            facets.append(Facet(n, off, on, poly, float(margin) if area > 0 else -np.inf, float(area)))
            continue
        frame = frames[i]
        p2 = pts[on] @ frame.T
        if len(on) > 3:
            try:
                h2 = ConvexHull(p2)
                poly = on[h2.vertices]  # counter-clockwise in (e1, e2)
                area = float(h2.volume)
            except Exception:  # degenerate (collinear) facet
                poly, area = on, 0.0
        else:
            poly, area = on, 0.0
        if area > 0:
            margin, _ = _polygon_margin(pts[poly] @ frame.T, com @ frame.T)
        else:
            margin = -np.inf
        facets.append(Facet(n, off, on, poly, margin, area))
    log.debug("%d hull triangles merged into %d facets", len(eq), len(facets))
    return facets


def stable_facets(body: Body, min_margin: float = MIN_MARGIN, coplanar_tol: float = COPLANAR_TOL) -> list[Facet]:
    """Hull facets on which the rigid body would rest without tipping (see module notes)."""
    tol = min_margin * body.mesh.diameter
    return [f for f in hull_facets(body, coplanar_tol) if f.margin > tol]


def _best_triangle(points: np.ndarray, nodes: np.ndarray, normal: np.ndarray, com: np.ndarray) -> tuple[np.ndarray, float]:
    """Triple of ``nodes`` whose triangle contains the projected ``com`` with the largest margin."""
    frame = _plane_frame(normal)
    p2 = points[nodes] @ frame.T
    c2 = com @ frame.T
    size = float(np.ptp(p2, axis=0).max()) if len(p2) else 0.0
    if len(nodes) > MAX_TRIANGLE_CANDIDATES:
        rel = p2 - c2
        ang = np.arctan2(rel[:, 1], rel[:, 0])
        sector = np.minimum(((ang + np.pi) / (2 * np.pi) * MAX_TRIANGLE_CANDIDATES).astype(int),
                            MAX_TRIANGLE_CANDIDATES - 1)
        r = np.hypot(rel[:, 0], rel[:, 1])
        keep = []
        for s in np.unique(sector):
            idx = np.flatnonzero(sector == s)
            # the farthest, ties (a circular rim) to the first: not decided by round-off
            keep.append(idx[np.flatnonzero(r[idx] >= r[idx].max() - TRIANGLE_TIE_TOL * size)[0]])
        keep = np.array(sorted(keep))
        nodes, p2 = nodes[keep], p2[keep]
    combos = np.array(list(itertools.combinations(range(len(nodes)), 3)))
    a, b, c = p2[combos[:, 0]], p2[combos[:, 1]], p2[combos[:, 2]]
    area2 = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    sign = np.sign(area2)

    def edge_dist(u: np.ndarray, v: np.ndarray) -> np.ndarray:
        e = v - u
        length = np.linalg.norm(e, axis=1)
        cr = e[:, 0] * (c2[1] - u[:, 1]) - e[:, 1] * (c2[0] - u[:, 0])
        return sign * cr / np.where(length > 0, length, 1.0)

    margin = np.minimum(np.minimum(edge_dist(a, b), edge_dist(b, c)), edge_dist(c, a))
    margin[sign == 0] = -np.inf
    # Symmetric facets (a box's base) have many triangles with the same margin: the first of those within
    # round-off of the best, so that the choice does not depend on the last bits of the coordinates.
    j = int(np.flatnonzero(margin >= margin.max() - TRIANGLE_TIE_TOL * size)[0])
    return nodes[combos[j]], float(margin[j])


def _outward_normal_of_triangle(points: np.ndarray, triangle: np.ndarray, surface: np.ndarray,
                                diam: float, coplanar_tol: float) -> tuple[np.ndarray, float]:
    """Unit normal of the triangle's plane pointing away from the body; checks the plane supports it."""
    p = points[triangle]
    n = np.cross(p[1] - p[0], p[2] - p[0])
    size = max(np.linalg.norm(p[1] - p[0]), np.linalg.norm(p[2] - p[0]), np.linalg.norm(p[2] - p[1]))
    if np.linalg.norm(n) <= 1e-12 * size**2:
        raise ValueError(f"support triangle {triangle.tolist()} is degenerate: its nodes are collinear")
    n /= np.linalg.norm(n)
    h = (points[surface] - p[0]) @ n
    if h.max() > -h.min():
        n, h = -n, -h
    beyond = float(h.max())
    if beyond > coplanar_tol * diam:
        worst = int(surface[np.argmax(h)])
        raise ValueError(
            f"support triangle {triangle.tolist()} does not lie on a supporting plane of the body: node {worst} is "
            f"{beyond:.3g} m beyond its plane, so the body would penetrate the table (name three nodes of a "
            "facet of the convex hull)")
    return n, beyond


def resting_pose(body: Body, down: np.ndarray | None = None, table_z: float = 0.0,
                 support: np.ndarray | None = None, *, min_margin: float = MIN_MARGIN,
                 coplanar_tol: float = COPLANAR_TOL) -> RestingPose:
    """Place ``body`` rigidly on the table ``z = table_z`` on a stable support triangle.

    Parameters
    ----------
    body : Body
        In any orientation.
    down : (3,) array_like, optional
        The direction, in the body's current frame, that should become
        downward (default −z).  It selects among the stable facets (see the
        module notes); the posed body always has gravity along −z.
    table_z : float
        Height of the table plane in the output frame.
    support : (3,) int, optional
        A user-named support triangle (three node indices).  Its plane must
        support the body and the centre of mass must project strictly inside
        it.
    min_margin, coplanar_tol : float
        Tolerances relative to the mesh diameter (module notes).

    Returns
    -------
    RestingPose
        ``.body`` (the moved body) and ``.triangle`` (the three node indices),
        plus the rigid motion applied and the stability margin.

    Raises
    ------
    ValueError
        If the named triangle is degenerate, does not lie on a supporting
        plane, or the centre of mass projects outside it (the object would
        tip; the message says by how much), or if no hull facet is stable.
    """
    down_u = _DOWN.copy() if down is None else _unit(down, "down")
    mesh = body.mesh
    pts = mesh.points
    com = body.center_of_mass
    diam = mesh.diameter
    facet = None
    if support is not None:
        tri = np.asarray(support)
        if tri.shape != (3,) or not np.issubdtype(tri.dtype, np.integer):
            raise ValueError(f"support must be three integer node indices, got {support!r}")
        tri = tri.astype(np.int64)
        if np.any((tri < 0) | (tri >= mesh.n_points)) or len(set(tri.tolist())) != 3:
            raise ValueError(f"support {tri.tolist()} must be three distinct node indices in [0, {mesh.n_points - 1}]")
        normal, _ = _outward_normal_of_triangle(pts, tri, mesh.surface_nodes, diam, coplanar_tol)
        margin, edge = triangle_margin(pts, tri, com, normal)
        if margin <= min_margin * diam:
            a, b = int(tri[edge]), int(tri[(edge + 1) % 3])
            where = "on" if abs(margin) <= min_margin * diam else f"{-margin:.4g} m outside"
            raise ValueError(
                f"the object would tip on support triangle {tri.tolist()}: its centre of mass projects {where} the "
                f"triangle (beyond the edge between nodes {a} and {b}), so the triangle is not a stable support "
                f"(paper §III: the projection must lie strictly inside)")
    else:
        cands = stable_facets(body, min_margin, coplanar_tol)
        if not cands:
            raise ValueError("no facet of the convex hull supports the body stably (the centre of mass projects "
                             "outside every facet); check the mesh")
        score = np.array([[f.normal @ down_u, f.margin] for f in cands])
        best = max(range(len(cands)), key=lambda i: (round(score[i, 0], 12), score[i, 1]))
        facet = cands[best]
        normal = facet.normal
        tri, margin = _best_triangle(pts, facet.nodes, normal, com)
        if margin <= min_margin * diam:
            raise ValueError(f"the stable facet with nodes {facet.polygon.tolist()} has no triangle of its nodes that "
                             "contains the projected centre of mass strictly inside; name a support triangle")
        log.info("resting on hull facet with %d nodes (normal %s, tilt %.3g deg from down), triangle %s, margin %.3g m",
                 len(facet.nodes), np.round(normal, 4), np.degrees(np.arccos(np.clip(normal @ down_u, -1, 1))),
                 tri.tolist(), margin)
    rot = rotation_between(down_u, _DOWN) @ rotation_between(normal, down_u)
    moved = (pts[tri] - com) @ rot.T + com
    dz = table_z - float(moved[:, 2].mean())
    translation = com - rot @ com + np.array([0.0, 0.0, dz])
    posed = body.transformed(rot, translation)
    return RestingPose(posed, tri, rot, translation, float(margin), facet)
