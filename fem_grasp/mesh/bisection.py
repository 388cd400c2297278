"""Nested refinement of a tetrahedral mesh by conforming longest-edge bisection.

A level of the accuracy loop (:mod:`fem_grasp.grasp.accuracy`) refined this way
*contains* the level before: every vertex and every face of the coarse mesh is
kept, and each coarse tetrahedron is cut into finer ones.  Two such levels differ
only in resolution, where two meshes generated afresh at two spacings differ also
in where their nodes fall (the scatter of gmsh's draws, as large as a halving of
the spacing at the contact patches).

One pass (:func:`bisect_longest_edges`) cuts the longest edge of each marked
tetrahedron, then, so that the mesh stays conforming and its shapes do not
degrade, the longest edge of every tetrahedron one of whose edges is cut
(Rivara's longest-edge closure), and splits each tetrahedron at its cut edges,
longest first (ties: the lower vertex numbers), so that a face shared by two
tetrahedra is split the same way from both sides.  :func:`refine_to_size`
repeats passes until every tetrahedron's longest edge is within a size field.

New vertices on boundary edges are moved onto the solid's surface when a
projection is given (a curved geometry or a scan; :meth:`fem_grasp.mesh.remesh.Geometry.project`),
so that the refined mesh converges to the solid rather than to the coarse mesh's facets.
"""

from __future__ import annotations

import logging
from typing import Callable

import numpy as np

from .tetmesh import TetMesh, face_keys, signed_volumes

__all__ = ["bisect_longest_edges", "refine_to_size", "MAX_PASSES"]

log = logging.getLogger(__name__)

#: Bisection passes :func:`refine_to_size` makes at most (each halves a marked tetrahedron's longest edge; three
#: passes halve all its edges).
MAX_PASSES = 40

# the six edges of a tetrahedron (local vertex pairs)
_EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])


def _edge_keys(tets: np.ndarray, n_points: int) -> np.ndarray:
    """(t, 6) one integer per vertex pair of each tetrahedron's edges."""
    a, b = tets[:, _EDGES[:, 0]], tets[:, _EDGES[:, 1]]
    return np.minimum(a, b) * np.int64(n_points) + np.maximum(a, b)


def _lengths_squared(points: np.ndarray, keys: np.ndarray, n_points: int) -> np.ndarray:
    d = points[keys // n_points] - points[keys % n_points]
    return d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2]  # the same bits on every CPU


def _ranks(points: np.ndarray, edges: np.ndarray, n_points: int) -> np.ndarray:
    """Rank of each of ``edges`` (unique keys) by length, ties by key: one order both sides of a face agree on."""
    order = np.lexsort((edges, _lengths_squared(points, edges, n_points)))
    rank = np.empty(len(edges), dtype=np.int64)
    rank[order] = np.arange(len(edges))
    return rank


def bisect_longest_edges(points: np.ndarray, tets: np.ndarray, marked: np.ndarray,
                         boundary_edges: np.ndarray | None = None,
                         project: Callable[[np.ndarray], np.ndarray] | None = None
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One conforming pass of longest-edge bisection (module notes).

    Parameters
    ----------
    points : (n, 3) vertices
    tets : (t, 4) positively oriented tetrahedra
    marked : (t,) bool, the tetrahedra whose longest edge is cut
    boundary_edges : sorted keys (``min · n + max``) of the edges on the boundary surface; their midpoints are
        projected by ``project``
    project : (k, 3) → (k, 3) points moved onto the solid's surface, or None (the midpoints stay on the facets)

    Returns
    -------
    points, tets, parent : the refined mesh (the first n vertices are the given ones) and, per new tetrahedron, the
        index of the tetrahedron it came from
    chords : (m, 3) the new vertices where they were cut, before ``project`` moved them
    """
    n = len(points)
    keys = _edge_keys(tets, n)
    edges, inverse = np.unique(keys, return_inverse=True)
    tet_edges = inverse.reshape(keys.shape)
    rank = _ranks(points, edges, n)
    longest = tet_edges[np.arange(len(tets)), np.argmax(rank[tet_edges], axis=1)]
    cut = np.zeros(len(edges), dtype=bool)
    cut[longest[np.asarray(marked, bool)]] = True
    while True:  # closure: a tetrahedron that is cut anywhere is cut at its longest edge
        touched = cut[tet_edges].any(axis=1)
        more = longest[touched]
        if cut[more].all():
            break
        cut[more] = True
    cut_keys = edges[cut]
    chords = 0.5 * (points[cut_keys // n] + points[cut_keys % n])
    mid = chords.copy()
    if project is not None and boundary_edges is not None and len(boundary_edges):
        on = np.isin(cut_keys, boundary_edges)
        if on.any():
            mid[on] = project(mid[on])
    new_index = n + np.arange(len(cut_keys), dtype=np.int64)
    all_points = np.vstack([points, mid])
    cut_rank = rank[cut]
    n_all = len(all_points)
    cut_keys = (cut_keys // n) * n_all + cut_keys % n  # the same order, in the numbering that includes the midpoints
    current, parent = np.asarray(tets, np.int64), np.arange(len(tets), dtype=np.int64)
    done_t, done_p = [], []
    for _ in range(7):  # a tetrahedron has six edges: at most six splits deep
        k = _edge_keys(current, n_all)
        pos = np.searchsorted(cut_keys, k).clip(0, max(len(cut_keys) - 1, 0))
        is_cut = (cut_keys[pos] == k) if len(cut_keys) else np.zeros(k.shape, bool)
        has = is_cut.any(axis=1)
        done_t.append(current[~has])
        done_p.append(parent[~has])
        if not has.any():
            break
        c, cp, ck, cpos = current[has], parent[has], is_cut[has], pos[has]
        score = np.where(ck, cut_rank[cpos], -1)
        j = np.argmax(score, axis=1)
        rows = np.arange(len(c))
        m = new_index[cpos[rows, j]]
        a, b = _EDGES[j, 0], _EDGES[j, 1]
        first, second = c.copy(), c.copy()
        first[rows, a] = m  # (m, b, ·, ·): replacing a vertex of the edge by its midpoint keeps the orientation
        second[rows, b] = m
        current = np.vstack([first, second])
        parent = np.concatenate([cp, cp])
    else:  # not reached: each split leaves the children fewer cut edges than the parent had
        raise RuntimeError("bisection left a tetrahedron with cut edges")
    return all_points, np.vstack(done_t), np.concatenate(done_p), chords


def _boundary_edge_keys(tets: np.ndarray, n_points: int) -> np.ndarray:
    """Sorted keys of the edges of the triangles that belong to one tetrahedron only."""
    faces = tets[:, [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]].reshape(-1, 3)
    # one integer per face (face_keys orders each face's vertices): a 1-D sort, six times faster than np.unique's
    # rows (0.08 against 0.53 s at 26k vertices); only the boundary faces are then put in order here
    _, first, counts = np.unique(face_keys(faces, n_points), return_index=True, return_counts=True)
    f = np.sort(faces[first[counts == 1]], axis=1)
    pairs = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [0, 2]]])
    return np.unique(pairs[:, 0] * np.int64(n_points) + pairs[:, 1])


def refine_to_size(mesh: TetMesh, size: Callable[[np.ndarray], np.ndarray],
                   project: Callable[[np.ndarray], np.ndarray] | None = None,
                   max_passes: int = MAX_PASSES) -> TetMesh:
    """``mesh`` bisected until every tetrahedron's longest edge is at most ``size`` at its centroid.

    Parameters
    ----------
    mesh : the mesh to refine (its vertices keep their numbers)
    size : (k, 3) points → (k,) the largest edge length wanted there, metres
    project : boundary midpoints onto the solid's surface (module notes), or None
    max_passes : bisection passes at most

    A new boundary vertex whose move onto the surface would invert a tetrahedron stays where it was cut.
    """
    points, tets = np.asarray(mesh.points, float), np.asarray(mesh.tets, np.int64)
    for _ in range(max_passes):
        n = len(points)
        keys = _edge_keys(tets, n)
        longest2 = _lengths_squared(points, keys, n).max(axis=1)
        want = np.asarray(size(points[tets].mean(axis=1)), float)
        marked = longest2 > want * want
        if not marked.any():
            break
        boundary = _boundary_edge_keys(tets, n) if project is not None else None
        points, tets, _, chords = bisect_longest_edges(points, tets, marked, boundary, project)
        inverted = signed_volumes(points, tets) <= 0
        while inverted.any():  # a vertex moved onto the surface through a thin tetrahedron stays on its chord
            new = np.unique(tets[inverted])
            new = new[new >= n]
            if not len(new) or np.array_equal(points[new], chords[new - n]):
                raise ValueError("bisection inverted a tetrahedron")  # not reached: the chords keep orientation
            log.debug("refine_to_size: %d new boundary vertices left on their chords", len(new))
            points[new] = chords[new - n]
            inverted = signed_volumes(points, tets) <= 0
    else:
        log.warning("refine_to_size stopped after %d passes with tetrahedra larger than asked", max_passes)
    return TetMesh(points, tets)
