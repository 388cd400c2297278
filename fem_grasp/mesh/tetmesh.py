"""Tetrahedral meshes: validation, geometry and I/O (paper §II-B).

A :class:`TetMesh` is immutable.  It is validated on construction so that
every later stage (stiffness assembly, contact, rendering) can assume a sound
mesh: finite coordinates, in-range indices, no duplicate or degenerate
tetrahedra, and every tetrahedron positively oriented.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from functools import cached_property
from os import PathLike
from typing import Any

import numpy as np

from ..errors import MeshError

log = logging.getLogger(__name__)

#: A tetrahedron whose volume is below this fraction of (mean edge length)^3
#: is degenerate: its stiffness would be singular or meaningless.
DEGENERATE_VOLUME_RATIO = 1e-10

__all__ = ["DEGENERATE_VOLUME_RATIO", "MeshError", "TetMesh", "box_mesh", "check_rotation", "face_keys",
           "signed_volumes", "vertex_normals"]


def signed_volumes(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Signed volume of each tetrahedron, positive for right-handed vertex order."""
    p = points[tets]
    e = p[:, 1:] - p[:, :1]
    return np.einsum("ij,ij->i", e[:, 0], np.cross(e[:, 1], e[:, 2])) / 6.0


def _first(mask: np.ndarray) -> int:
    return int(np.flatnonzero(mask)[0])


def _as_array(value: Any, name: str) -> np.ndarray:
    try:
        return np.asarray(value)
    except (ValueError, TypeError) as exc:  # ragged nested lists and the like
        raise MeshError(f"{name} cannot be read as a rectangular array: {exc}") from None


def _validate(points: Any, tets: Any) -> tuple[np.ndarray, np.ndarray, int]:
    points = _as_array(points, "points")
    tets = _as_array(tets, "tets")
    if points.ndim != 2 or points.shape[1] != 3:
        raise MeshError(f"points must have shape (n, 3), got {points.shape}")
    if tets.ndim != 2 or tets.shape[1] != 4:
        raise MeshError(f"tets must have shape (t, 4), got {tets.shape}")
    if not np.issubdtype(points.dtype, np.number) or np.iscomplexobj(points):
        raise MeshError(f"points must be real numbers, got dtype {points.dtype}")
    if not np.issubdtype(tets.dtype, np.integer):
        if tets.size and np.issubdtype(tets.dtype, np.floating) and np.all(tets == np.round(tets)):
            tets = tets.astype(np.int64)
        else:
            raise MeshError(f"tets must be integer vertex indices, got dtype {tets.dtype}")
    if len(points) < 4 or len(tets) < 1:
        raise MeshError(f"a tetrahedral mesh needs >= 4 points and >= 1 tet, got {len(points)} and {len(tets)}")
    points = np.ascontiguousarray(points, dtype=np.float64)
    tets = np.ascontiguousarray(tets, dtype=np.int64)

    bad = ~np.isfinite(points).all(axis=1)
    if bad.any():
        raise MeshError(f"{bad.sum()} point(s) have NaN or infinite coordinates; first is point {_first(bad)}")
    bad = ((tets < 0) | (tets >= len(points))).any(axis=1)
    if bad.any():
        raise MeshError(
            f"{bad.sum()} tet(s) reference a point index outside [0, {len(points) - 1}]; first is tet {_first(bad)}"
        )
    srt = np.sort(tets, axis=1)
    bad = (np.diff(srt, axis=1) == 0).any(axis=1)
    if bad.any():
        raise MeshError(f"{bad.sum()} tet(s) repeat a vertex (degenerate); first is tet {_first(bad)}")
    # Duplicates by a lexicographic sort of the sorted vertex quadruples (np.unique(axis=0) sorts them as
    # opaque records, 1 s at 100k vertices).
    order = np.lexsort(srt.T[::-1])
    same = (srt[order[1:]] == srt[order[:-1]]).all(axis=1)
    if same.any():
        first = order[:-1][same & np.concatenate([[True], ~same[:-1]])]  # lexsort is stable: lowest index
        raise MeshError(f"{int(same.sum())} duplicate tet(s); first duplicated is tet {int(first.min())}")

    vol = signed_volumes(points, tets)
    edge = np.linalg.norm(points[tets[:, [1, 2, 3, 2, 3, 3]]] - points[tets[:, [0, 0, 0, 1, 1, 2]]], axis=2).mean(axis=1)
    bad = np.abs(vol) <= DEGENERATE_VOLUME_RATIO * edge**3
    if bad.any():
        raise MeshError(
            f"{bad.sum()} tet(s) have zero volume (flat or degenerate); first is tet {_first(bad)}"
        )
    neg = vol < 0
    n_neg = int(neg.sum())
    if n_neg:
        tets = tets.copy()
        tets[neg] = tets[neg][:, [0, 2, 1, 3]]
        log.info("reoriented %d inverted tetrahedra (first: tet %d)", n_neg, _first(neg))
    _check_topology(points, tets, neg)
    return points, tets, n_neg


def check_rotation(rotation: Any) -> np.ndarray:
    """``rotation`` as a (3, 3) float array; ValueError unless it is a proper rotation (orthogonal, det +1)."""
    rotation = np.asarray(rotation, dtype=float)
    if rotation.shape != (3, 3) or not np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-10):
        raise ValueError("rotation must be a 3x3 orthogonal matrix")
    if np.linalg.det(rotation) < 0:
        raise ValueError("rotation must be proper (det = +1), not a reflection")
    return rotation


def face_keys(tri: np.ndarray, n: int) -> np.ndarray:
    """One integer per unordered vertex triple (or pair, for (k, 2) input) of ``n`` vertices: equal keys, equal
    triangles (or edges), whichever order their vertices are given in."""
    s = np.sort(tri, axis=1)
    if n ** s.shape[1] < 2**62:
        key = s[:, 0]
        for j in range(1, s.shape[1]):
            key = key * n + s[:, j]
        return key
    return np.unique(s, axis=0, return_inverse=True)[1].reshape(-1)


def _check_topology(points: np.ndarray, tets: np.ndarray, inverted: np.ndarray) -> None:
    """Refuse meshes that are not one solid: see :class:`TetMesh` (Raises)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n, t = len(points), len(tets)
    used = np.zeros(n, dtype=bool)
    used[tets.ravel()] = True
    if not used.all():
        raise MeshError(f"{int((~used).sum())} point(s) are not a vertex of any tet (unreferenced; they would have no "
                        f"stiffness); first is point {_first(~used)} — drop them (TetMesh.from_meshio does)")

    faces = tets[:, _TET_FACES].reshape(-1, 3)  # outward for positively oriented tets
    owner = np.repeat(np.arange(t), 4)
    keys = face_keys(faces, n)
    order = np.argsort(keys, kind="stable")
    ks = keys[order]
    start = np.flatnonzero(np.r_[True, ks[1:] != ks[:-1]])
    counts = np.diff(np.r_[start, len(ks)])
    if (counts > 2).any():
        g = int(np.argmax(counts > 2))
        f = order[start[g]: start[g] + counts[g]]
        raise MeshError(f"{int((counts > 2).sum())} triangle(s) are shared by more than two tets (non-manifold); "
                        f"first is face {tuple(int(v) for v in np.sort(faces[f[0]]))}, shared by tets "
                        f"{sorted(int(k) for k in owner[f])}")
    # Interior faces: the two tets must lie on opposite sides, i.e. list the face with opposite orientations.
    pair = start[counts == 2]
    fa, fb = order[pair], order[pair + 1]

    def parity(tri: np.ndarray) -> np.ndarray:
        return ((tri[:, 0] > tri[:, 1]).astype(int) + (tri[:, 0] > tri[:, 2]) + (tri[:, 1] > tri[:, 2])) % 2

    same = parity(faces[fa]) == parity(faces[fb])
    if same.any():
        k = _first(same)
        a, b = sorted((int(owner[fa[k]]), int(owner[fb[k]])))
        given = [i for i in (a, b) if inverted[i]]
        note = (f"; tet {given[0]} was given with negative volume (inverted), and reorienting it does not undo the "
                "fold" if given else "")
        raise MeshError(f"{int(same.sum())} pair(s) of tets overlap (a folded or inverted element); first: tets {a} "
                        f"and {b} share face {tuple(int(v) for v in np.sort(faces[fa[k]]))} and lie on the same "
                        f"side of it{note}")
    # One solid: tets connected through shared faces.
    adj = coo_matrix((np.ones(len(fa)), (owner[fa], owner[fb])), shape=(t, t))
    n_pieces, label = connected_components(adj, directed=False)
    if n_pieces > 1:
        # Pieces that share vertices touch only at a vertex or an edge: a hinge with no stiffness.
        vert_label = np.full(n, -1)
        vert_label[tets.ravel()] = np.repeat(label, 4)
        shared = np.flatnonzero(vert_label[tets.ravel()] != np.repeat(label, 4))
        other = _first(label != label[0])
        if shared.size:
            v = int(tets.ravel()[shared[0]])
            touching = sorted({int(k) for k in np.flatnonzero((tets == v).any(axis=1))})
            raise MeshError(f"the tets form {n_pieces} pieces joined only at vertices or edges (non-manifold: the "
                            f"joint is a hinge with no stiffness); first joint is vertex {v}, shared by tets "
                            f"{touching}")
        raise MeshError(f"the mesh is disconnected: {n_pieces} separate pieces (tet 0 and tet {other} are in "
                        "different pieces); mesh one object at a time")
    # The boundary surface must be a 2-manifold: every surface edge in two surface faces ...
    surf = faces[np.sort(order[start[counts == 1]])]
    edges = surf[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    ekeys = face_keys(edges, n)
    uniq, e_inv, e_counts = np.unique(ekeys, return_inverse=True, return_counts=True)
    if (e_counts != 2).any():
        bad = e_counts[e_inv] != 2
        e = np.sort(edges[_first(bad)])
        raise MeshError(f"{int((e_counts != 2).sum())} surface edge(s) are not shared by exactly two surface "
                        f"triangles (non-manifold: the body touches itself along an edge); first is edge "
                        f"({int(e[0])}, {int(e[1])}), in {int(e_counts[e_inv[_first(bad)]])} surface triangles")
    # ... and the surface triangles around every surface vertex form a single fan (no pinched vertex).
    f_of = np.repeat(np.arange(len(surf)), 3)  # incidence (face, corner) numbered 3·face + corner
    order_e = np.argsort(e_inv, kind="stable")
    ea, eb = order_e[0::2], order_e[1::2]  # the two occurrences of each edge (edge index 3·face + k)
    rows, cols = [], []
    for end in (0, 1):  # connect (face_a, v) with (face_b, v) for both ends v of the edge
        va = edges[ea, end]
        ca = 3 * f_of[ea] + np.argmax(surf[f_of[ea]] == va[:, None], axis=1)
        cb = 3 * f_of[eb] + np.argmax(surf[f_of[eb]] == va[:, None], axis=1)
        rows.append(ca)
        cols.append(cb)
    m = 3 * len(surf)
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    n_fans, fan = connected_components(coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(m, m)), directed=False)
    n_surf = len(np.unique(surf))
    if n_fans != n_surf:
        corner_vertex = surf.ravel()
        fans_per_vertex = np.zeros(n, dtype=int)
        first_corner = np.unique(fan, return_index=True)[1]
        np.add.at(fans_per_vertex, corner_vertex[first_corner], 1)
        v = _first(fans_per_vertex > 1)
        raise MeshError(f"{int((fans_per_vertex > 1).sum())} surface vertex(es) are pinched (non-manifold: the body "
                        f"touches itself at a single point); first is vertex {v}, where "
                        f"{int(fans_per_vertex[v])} separate sheets of the surface meet")


def vertex_normals(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(n, 3) area-weighted unit normals at the vertices of triangles ``faces``; zero off the faces."""
    p = np.asarray(points, dtype=float)
    area_normals = 0.5 * np.cross(p[faces[:, 1]] - p[faces[:, 0]], p[faces[:, 2]] - p[faces[:, 0]])
    nodal = np.zeros_like(p)
    for k in range(3):
        np.add.at(nodal, faces[:, k], area_normals)
    norm = np.linalg.norm(nodal, axis=1, keepdims=True)
    return np.divide(nodal, norm, out=np.zeros_like(nodal), where=norm > 0)


# Faces of a tetrahedron (v0,v1,v2,v3) ordered so their normals point outward
# for a positively oriented tetrahedron.
_TET_FACES = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


@dataclass(frozen=True, eq=False)
class TetMesh:
    """A validated, positively oriented tetrahedral mesh.

    Parameters
    ----------
    points : (n, 3) array_like of float
        Vertex coordinates in metres.
    tets : (t, 4) array_like of int
        Vertex indices of each tetrahedron.  Negatively oriented tetrahedra
        are reoriented; their count is kept in :attr:`n_reoriented`.

    Raises
    ------
    MeshError
        (a ``ValueError``) for wrong shapes or dtypes, NaN/inf coordinates,
        out-of-range indices, duplicate or zero-volume tetrahedra, points used
        by no tetrahedron, tetrahedra that overlap a neighbour (a fold: an
        inverted element that reorientation cannot mend), a mesh in several
        pieces (disconnected, or joined only at vertices or edges: hinges
        with no stiffness), and a non-manifold boundary (a triangle in three
        tets, a surface edge not in exactly two surface triangles, a pinched
        surface vertex); the message gives the count and the first offending
        index.
    """

    points: np.ndarray
    tets: np.ndarray
    n_reoriented: int = field(init=False, default=0)

    def __post_init__(self) -> None:
        points, tets, n_neg = _validate(self.points, self.tets)
        points.setflags(write=False)
        tets.setflags(write=False)
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "tets", tets)
        object.__setattr__(self, "n_reoriented", n_neg)

    def __repr__(self) -> str:
        return f"TetMesh(n_points={self.n_points}, n_tets={self.n_tets})"

    @property
    def n_points(self) -> int:
        return len(self.points)

    @property
    def n_tets(self) -> int:
        return len(self.tets)

    @cached_property
    def volumes(self) -> np.ndarray:
        """(t,) positive volume of each tetrahedron."""
        return signed_volumes(self.points, self.tets)

    @property
    def volume(self) -> float:
        return float(self.volumes.sum())

    @cached_property
    def surface_faces(self) -> np.ndarray:
        """(f, 3) boundary triangles, ordered so their normals point out of the body."""
        faces = self.tets[:, _TET_FACES].reshape(-1, 3)
        _, inv, counts = np.unique(face_keys(faces, self.n_points), return_inverse=True, return_counts=True)
        inv = inv.reshape(-1)
        if (counts > 2).any():
            raise MeshError(f"{int((counts > 2).sum())} triangle(s) are shared by more than two tets (non-manifold)")
        return np.ascontiguousarray(faces[counts[inv] == 1])

    @cached_property
    def surface_nodes(self) -> np.ndarray:
        """Sorted indices of the vertices on the boundary surface."""
        return np.unique(self.surface_faces)

    @cached_property
    def surface_index(self) -> np.ndarray:
        """(n,) each vertex's position in :attr:`surface_nodes`, −1 for interior vertices."""
        index = np.full(self.n_points, -1, dtype=np.int64)
        index[self.surface_nodes] = np.arange(len(self.surface_nodes))
        return index

    @cached_property
    def surface_points(self) -> np.ndarray:
        """(s, 3) reference positions of :attr:`surface_nodes` (read-only; the tracking adds a field to them at
        every trial state)."""
        points = self.points[self.surface_nodes]
        points.setflags(write=False)
        return points

    @cached_property
    def surface_normals(self) -> np.ndarray:
        """(n, 3) outward unit normal at each vertex (area-weighted; zero off the surface)."""
        return vertex_normals(self.points, self.surface_faces)

    def outward_normals(self, positions: np.ndarray) -> np.ndarray:
        """(n, 3) :attr:`surface_normals` of the surface deformed to ``positions`` (n, 3)."""
        return vertex_normals(positions, self.surface_faces)

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) corners of the axis-aligned bounding box."""
        return self.points.min(axis=0), self.points.max(axis=0)

    @property
    def diameter(self) -> float:
        lo, hi = self.bounds
        return float(np.linalg.norm(hi - lo))

    @cached_property
    def quality(self) -> np.ndarray:
        """(t,) normalised shape quality in (0, 1]: 1 for a regular tetrahedron.

        The ratio 6√2·V / ℓ_rms³, which tends to zero for slivers and needles.
        """
        p = self.points[self.tets]
        pairs = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
        l2 = np.stack([np.sum((p[:, i] - p[:, j]) ** 2, axis=1) for i, j in pairs], axis=1)
        l_rms = np.sqrt(l2.mean(axis=1))
        return 6.0 * np.sqrt(2.0) * self.volumes / l_rms**3

    def transformed(self, rotation: np.ndarray | None = None, translation: np.ndarray | None = None) -> "TetMesh":
        """A new mesh with points mapped to ``rotation @ p + translation``."""
        p = self.points
        if rotation is not None:
            p = p @ check_rotation(rotation).T
        if translation is not None:
            p = p + np.asarray(translation, dtype=float)
        return TetMesh(p, self.tets)

    # ------------------------------------------------------------------ I/O
    @classmethod
    def from_meshio(cls, mesh: Any) -> "TetMesh":
        """Build from a ``meshio.Mesh``, keeping only its tetra cells and the points they use."""
        blocks = [c.data for c in mesh.cells if c.type == "tetra"]
        if not blocks:
            types = sorted({c.type for c in mesh.cells})
            raise MeshError(f"the mesh has no tetra cells (cell types: {types}); mesh a surface with fem_grasp.mesh.mesh_surface")
        tets = np.concatenate(blocks).astype(np.int64)
        used, tets_c = np.unique(tets, return_inverse=True)
        return cls(np.asarray(mesh.points, dtype=float)[used, :3], tets_c.reshape(-1, 4))

    @classmethod
    def from_file(cls, path: str | PathLike) -> "TetMesh":
        """Read any volume format meshio reads (VTU, MSH, XDMF, MEDIT, …)."""
        import meshio

        return cls.from_meshio(meshio.read(path))

    def to_meshio(self, point_data: dict | None = None, cell_data: dict | None = None) -> Any:
        import meshio

        cd = {k: [np.asarray(v)] for k, v in (cell_data or {}).items()}
        return meshio.Mesh(self.points, [("tetra", self.tets)], point_data=point_data or {}, cell_data=cd)

    def write(self, path: str | PathLike, point_data: dict | None = None) -> None:
        """Write in the format meshio infers from the file extension."""
        self.to_meshio(point_data).write(path)


def box_mesh(lower: tuple[float, float, float] = (0.0, 0.0, 0.0), upper: tuple[float, float, float] = (1.0, 1.0, 1.0),
             divisions: tuple[int, int, int] = (2, 2, 2)) -> TetMesh:
    """A structured mesh of a box, each hexahedral cell split into six tetrahedra (Kuhn split).

    Needs no mesher; used by tests, examples and convergence studies.
    """
    nx, ny, nz = (int(d) for d in divisions)
    if min(nx, ny, nz) < 1:
        raise ValueError(f"divisions must be positive integers, got {divisions}")
    axes = [np.linspace(lo, hi, d + 1) for lo, hi, d in zip(lower, upper, (nx, ny, nz))]
    gx, gy, gz = np.meshgrid(*axes, indexing="ij")
    points = np.stack([gx.ravel(), gy.ravel(), gz.ravel()], axis=1)
    idx = np.arange(len(points)).reshape(nx + 1, ny + 1, nz + 1)
    i, j, k = (a.ravel() for a in np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"))
    corner = np.stack([idx[i + dx, j + dy, k + dz] for dz in (0, 1) for dy in (0, 1) for dx in (0, 1)], axis=1)
    # The six tets of the cube around its main diagonal 0-7 (corner bits x=1, y=2, z=4), each listed with
    # positive orientation (half of them would otherwise be reoriented, and logged, by TetMesh).
    kuhn = np.array([[0, 1, 3, 7], [0, 5, 1, 7], [0, 3, 2, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 6, 4, 7]])
    tets = corner[:, kuhn].reshape(-1, 4)
    return TetMesh(points, tets)
