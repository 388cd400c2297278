"""A body's geometry, remeshed finer where its contacts are.

The pickup answer of *Picking up Soft 3D Objects with Two Fingers* (the
squeeze depth ρ* at which the lift test of §III-B passes, the finger forces,
the liftable weight w(ρ)) is governed by how finely the contact patches are
resolved: a hemispherical fingertip pressing on the nodes of a P1 mesh
stiffens in steps, one node carrying the load until the next ring of nodes
touches.  Refining where the fingertips and the table touch is the cheap way
to a converged answer (:mod:`fem_grasp.grasp.accuracy`); this module supplies the
meshes.

A :class:`Geometry` builds tetrahedral meshes of one solid at any mesh size,
optionally graded (finer inside gmsh "Ball" fields, :class:`fem_grasp.mesh.shapes.Refinement`)
and with given points embedded as nodes:

* :class:`PaperGeometry`: the gmsh stand-ins of the paper's four objects (Table I);
* :class:`BoxGeometry`: a box, also as a structured grid (:func:`fem_grasp.mesh.box_mesh`);
* :class:`SurfaceGeometry`: the solid inside a closed triangle surface — a scan
  (:mod:`fem_grasp.scan`), or the boundary of an arbitrary :class:`~fem_grasp.mesh.TetMesh`
  (:func:`geometry_of_mesh`).  A mesh that came with no geometry is remeshed from its
  own boundary triangles: the converged answer is then that of the *faceted*
  solid, which is all the mesh says about the shape.

:func:`patch_refinement` turns contact-patch points (node positions in the
mesh frame) into a size field: spacing ``size`` within ``radius`` of any
patch point, growing at ``grading`` metres of spacing per metre of distance
to the outer size.

gmsh is needed to build meshes (the ``mesh`` extra, or Debian's ``python3-gmsh``); it is imported
only inside the functions that mesh.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from .gmsh_session import AUTO_MESHADAPT_MAX_VERTICES, SURFACE_ALGORITHMS, Refinement
from .shapes import PAPER_SHAPES
from .tetmesh import TetMesh, box_mesh

__all__ = ["Geometry", "PaperGeometry", "BoxGeometry", "SurfaceGeometry", "NoGeometryError", "geometry_of_mesh",
           "geometry_of_scene",
           "patch_refinement", "nearest_surface_nodes", "spacing", "DEFAULT_GRADING"]

log = logging.getLogger(__name__)

#: Growth of the mesh spacing per unit distance away from a refined patch.  0.5 keeps neighbouring
#: tetrahedra within a factor ~1.5 in size (gmsh's Delaunay mesher keeps quality at that rate) while the
#: refined layer costs few vertices: the transition from R/16 to 7 mm takes about 13 mm.
DEFAULT_GRADING = 0.5


class NoGeometryError(ValueError):
    """A body cannot be remeshed: it has no geometry and its boundary is not a closed manifold surface."""


def spacing(mesh: TetMesh, nodes: np.ndarray | None = None) -> float:
    """Median length of the edges of the surface triangles (touching ``nodes`` if given), metres.

    The nodal spacing a fingertip sees: the size the contact patch is resolved with.
    """
    faces = mesh.surface_faces
    if nodes is not None:
        mark = np.zeros(mesh.n_points, dtype=bool)
        mark[np.asarray(nodes, dtype=np.int64)] = True
        faces = faces[mark[faces].any(axis=1)]
        if not len(faces):
            faces = mesh.surface_faces
    p = mesh.points
    e = np.concatenate([p[faces[:, 1]] - p[faces[:, 0]], p[faces[:, 2]] - p[faces[:, 1]],
                        p[faces[:, 0]] - p[faces[:, 2]]])
    return float(np.median(np.linalg.norm(e, axis=1)))


def nearest_surface_nodes(mesh: TetMesh, points: np.ndarray) -> np.ndarray:
    """(k,) the surface node of ``mesh`` nearest to each of ``points`` (k, 3)."""
    from scipy.spatial import cKDTree

    surf = mesh.surface_nodes
    _, idx = cKDTree(mesh.points[surf]).query(np.asarray(points, float).reshape(-1, 3))
    return surf[np.asarray(idx, dtype=np.int64)]


def _dedupe(points: np.ndarray, cell: float) -> np.ndarray:
    """One point per grid cell of side ``cell`` (the first), so that a patch of thousands of nodes makes
    a few hundred Ball fields."""
    p = np.asarray(points, float).reshape(-1, 3)
    if not len(p) or not cell > 0:
        return p
    keys = np.floor(p / cell).astype(np.int64)
    _, first = np.unique(keys, axis=0, return_index=True)
    return p[np.sort(first)]


def patch_refinement(points: np.ndarray, size: float, radius: float, outer: float,
                     grading: float = DEFAULT_GRADING) -> Refinement | None:
    """A size field refined around contact-patch points (module notes); None for no points.

    Parameters
    ----------
    points : (k, 3) patch points in the mesh frame (contact node positions)
    size : spacing within ``radius`` of a patch point, metres
    radius : metres; at least the spacing of the mesh the points came from, so the balls overlap
    outer : the mesh size elsewhere, metres
    grading : growth of the spacing per unit distance beyond ``radius`` (:data:`DEFAULT_GRADING`)
    """
    pts = _dedupe(points, 0.5 * radius)
    if not len(pts):
        return None
    thickness = max(outer - size, 0.0) / grading + 1e-12
    return Refinement(tuple(tuple(float(x) for x in q) for q in pts), float(radius), float(size), float(thickness))


def _refinements(refine: Refinement | Sequence[Refinement] | None) -> tuple[Refinement, ...]:
    if refine is None:
        return ()
    return (refine,) if isinstance(refine, Refinement) else tuple(r for r in refine if r is not None)


def _estimated_vertices(volume: float, size: float, refine: Sequence[Refinement]) -> float:
    """n ≈ V / h³ (shapes' measured rule) with each refinement's balls counted at their own spacing
    (an overestimate: the balls overlap and stick out of the solid)."""
    n = volume / size**3
    for r in refine:
        ball = min(len(r.centers) * 4.0 / 3.0 * math.pi * r.radius**3, volume)
        n += ball / min(r.size, size) ** 3 * 0.5
    return n


def _algorithm(volume: float, size: float, refine: Sequence[Refinement]) -> int:
    """MeshAdapt for small meshes, Frontal-Delaunay for large (:data:`fem_grasp.mesh.shapes.AUTO_MESHADAPT_MAX_VERTICES`)."""
    est = _estimated_vertices(volume, size, refine)
    return SURFACE_ALGORITHMS["meshadapt" if est <= AUTO_MESHADAPT_MAX_VERTICES else "frontal-delaunay"]


@dataclass(frozen=True)
class Geometry:
    """A solid that can be meshed at any size (subclasses say how); lengths in metres."""

    def build(self, size: float, refine: Refinement | Sequence[Refinement] | None = None,
              embed: np.ndarray | None = None) -> TetMesh:
        """A tetrahedral mesh at outer size ``size``, graded by ``refine``, with ``embed`` points as nodes.

        Points that are not embedded (curved surfaces unless asked, a scan's or a mesh's discrete surface,
        points off the surface) are mapped by callers to the nearest surface node
        (:func:`nearest_surface_nodes`).
        """
        raise NotImplementedError

    @property
    def volume(self) -> float:
        raise NotImplementedError

    @property
    def embeds_points(self) -> bool:
        """True when :meth:`build` makes points of the surface it is given nodes of the mesh (else callers map them
        to the nearest surface nodes)."""
        return False

    def describe(self) -> str:
        return type(self).__name__

    def project(self, points: np.ndarray) -> np.ndarray:
        """(k, 3) ``points`` near the solid's surface moved onto it, for a curved surface that a refined mesh should
        follow (:func:`fem_grasp.mesh.bisection.refine_to_size`); a flat or faceted one returns them unchanged."""
        return np.asarray(points, float)

    def surface_points(self, spacing: float) -> np.ndarray:
        """(n, 3) points on the solid's surface about ``spacing`` apart or closer: where a rule that picks surface
        nodes (the fingers' placement) finds the point a fine enough mesh would have as a node."""
        raise NotImplementedError

    def size_for_vertices(self, vertices: int) -> float:
        """The uniform mesh size that gives about ``vertices`` vertices (n ≈ V / h³)."""
        return (self.volume / vertices) ** (1.0 / 3.0)


@dataclass(frozen=True)
class PaperGeometry(Geometry):
    """One of the paper's objects (:data:`fem_grasp.mesh.shapes.PAPER_SHAPES`), in the frame of the committed paper meshes (``fem_grasp/scenes/meshes``).

    ``embed_points``: :meth:`build` makes the points it is given nodes of the curved surface, so that the
    accuracy loop's levels all grasp at the placement rule's points themselves (on by default).  Off, they grasp
    at their nearest surface nodes, up to half a spacing away, and the answer moves with the grasp (the steam bun's
    ρ* from 3.3 to 15 mm over 4.5 mm of its side; ``scripts/grasp_height.py``, ``scripts/pinned_reference.py``).
    """

    name: str
    embed_points: bool = True

    @property
    def embeds_points(self) -> bool:
        return self.embed_points

    def __post_init__(self) -> None:
        if self.name not in PAPER_SHAPES:
            raise ValueError(f"unknown paper shape {self.name!r}; choose from {sorted(PAPER_SHAPES)}")

    @property
    def volume(self) -> float:
        return PAPER_SHAPES[self.name].volume

    def describe(self) -> str:
        return f"paper shape {self.name}"

    def _spheroid(self) -> tuple[np.ndarray, np.ndarray, float]:
        """The curved surface's semi-axes and centre, and the lowest cos(polar angle) on it (the dome's base cut)."""
        shape = PAPER_SHAPES[self.name]
        if shape.kind == "ellipsoid":
            return np.asarray(shape.dimensions, float), np.zeros(3), -1.0
        r, h, e = shape.dimensions  # the spheroid (r, r, h) about (0, 0, e), above its flat base z = 0
        return np.array([r, r, h], float), np.array([0.0, 0.0, e]), -e / h

    def project(self, points: np.ndarray) -> np.ndarray:
        """Along the ray from the spheroid's centre (the dome's flat base, z = 0, stays where it is)."""
        axes, centre, lowest = self._spheroid()
        p = np.array(points, float).reshape(-1, 3)
        curved = p[:, 2] > 1e-9 * axes[2] if lowest > -1.0 else np.ones(len(p), dtype=bool)
        q = p[curved] - centre
        p[curved] = centre + q / np.linalg.norm(q / axes, axis=1)[:, None]
        return p

    def surface_points(self, spacing: float) -> np.ndarray:
        axes, centre, lowest = self._spheroid()
        n = max(16, int(math.ceil(math.pi * float(axes.max()) / spacing)))
        polar = np.linspace(0.0, math.pi, n + 1)
        polar = polar[np.cos(polar) >= lowest]
        azimuth = np.linspace(0.0, 2.0 * math.pi, 2 * n, endpoint=False)
        t, a = np.meshgrid(polar, azimuth, indexing="ij")
        unit = np.stack([np.sin(t) * np.cos(a), np.sin(t) * np.sin(a), np.cos(t)], axis=-1).reshape(-1, 3)
        return centre + unit * axes

    def build(self, size: float, refine: Refinement | Sequence[Refinement] | None = None,
              embed: np.ndarray | None = None) -> TetMesh:
        refs = _refinements(refine)
        alg = "meshadapt" if _algorithm(self.volume, size, refs) == SURFACE_ALGORITHMS["meshadapt"] \
            else "frontal-delaunay"
        if not self.embed_points or embed is None or not len(embed):
            embed = None
        else:
            # MeshAdapt refines about an embedded vertex (twice the surface nodes of the football graded to 2 mm)
            alg = "frontal-delaunay"
        points, tets = PAPER_SHAPES[self.name].build(size, alg, refine=refs or None, embed=embed)
        return TetMesh(points, tets)


@dataclass(frozen=True)
class BoxGeometry(Geometry):
    """The box ``lower`` ≤ x ≤ ``upper``; uniform meshes are structured grids, graded ones gmsh's."""

    lower: tuple[float, float, float]
    upper: tuple[float, float, float]

    @property
    def embeds_points(self) -> bool:
        return True

    @property
    def volume(self) -> float:
        return float(np.prod(np.subtract(self.upper, self.lower)))

    def describe(self) -> str:
        return f"box {np.subtract(self.upper, self.lower).round(6).tolist()} m"

    def surface_points(self, spacing: float) -> np.ndarray:
        lo, hi = np.asarray(self.lower, float), np.asarray(self.upper, float)
        ticks = [np.linspace(lo[k], hi[k], max(2, int(math.ceil((hi[k] - lo[k]) / spacing)) + 1)) for k in range(3)]
        out = []
        for k in range(3):  # the two faces normal to axis k
            i, j = [m for m in range(3) if m != k]
            u, v = np.meshgrid(ticks[i], ticks[j], indexing="ij")
            for w in (lo[k], hi[k]):
                p = np.empty((u.size, 3))
                p[:, i], p[:, j], p[:, k] = u.ravel(), v.ravel(), w
                out.append(p)
        return np.vstack(out)

    def grid(self, divisions: Sequence[int]) -> TetMesh:
        """The structured Kuhn-split grid of :func:`fem_grasp.mesh.box_mesh`."""
        return box_mesh(tuple(self.lower), tuple(self.upper), tuple(int(d) for d in divisions))

    def build(self, size: float, refine: Refinement | Sequence[Refinement] | None = None,
              embed: np.ndarray | None = None) -> TetMesh:
        from .gmsh_session import apply_refinement, extract_tets, generate, gmsh_model

        refs = _refinements(refine)
        lo, hi = np.asarray(self.lower, float), np.asarray(self.upper, float)
        ext = hi - lo
        tol = 1e-9 * float(np.linalg.norm(ext))
        pts = np.zeros((0, 3)) if embed is None else np.asarray(embed, float).reshape(-1, 3)
        # A point on a face is embedded in it; a point on an edge splits the edge (embedding it in a face makes gmsh
        # abort the process); a corner is a node of every mesh already.
        on_bounds = (np.abs(pts - lo) <= tol) | (np.abs(pts - hi) <= tol)
        dims = 3 - on_bounds.sum(axis=1)
        inside = pts[(dims == 3) | (pts < lo - tol).any(axis=1) | (pts > hi + tol).any(axis=1)]
        if len(inside):
            raise ValueError(f"point {inside[0].tolist()} to embed is not on the box's surface")
        with gmsh_model("box", size, _algorithm(self.volume, size, refs)) as gmsh:
            occ = gmsh.model.occ
            box = occ.addBox(*lo, *ext)
            edge_points = [occ.addPoint(*map(float, p)) for p in pts[dims == 1]]
            if edge_points:
                occ.fragment([(3, box)], [(0, t) for t in edge_points])
            tags = [occ.addPoint(*map(float, p)) for p in pts[dims == 2]]
            occ.synchronize()
            faces = gmsh.model.getEntities(2)
            for tag, p in zip(tags, pts[dims == 2]):
                for _, s in faces:
                    closest = np.asarray(gmsh.model.getClosestPoint(2, s, p.tolist())[0], float)
                    if np.linalg.norm(closest - p) <= tol:
                        gmsh.model.mesh.embed(0, [tag], 2, s)
                        break
                else:
                    raise ValueError(f"point {p.tolist()} to embed is not on the box's surface")
            apply_refinement(gmsh, refs or None, size)
            generate(gmsh, size)
            points, tets = extract_tets(gmsh)
        return TetMesh(points, tets)


@dataclass(frozen=True)
class SurfaceGeometry(Geometry):
    """The solid inside a closed, manifold triangle surface (a scan, or a mesh's boundary)."""

    surface: Any = field(repr=False)  # fem_grasp.scan.Surface

    @property
    def volume(self) -> float:
        return abs(float(self.surface.volume))

    def describe(self) -> str:
        return f"surface {self.surface.source} ({len(self.surface.faces)} triangles)"

    def project(self, points: np.ndarray) -> np.ndarray:
        """The nearest points of the triangle surface (:func:`fem_grasp.mesh.scan.closest_points`)."""
        from .scan import closest_points

        return closest_points(self.surface, points)

    def surface_points(self, spacing: float) -> np.ndarray:
        """The surface's vertices: a faceted surface has its extremes there."""
        return np.asarray(self.surface.points, float)

    def build(self, size: float, refine: Refinement | Sequence[Refinement] | None = None,
              embed: np.ndarray | None = None) -> TetMesh:
        from .gmsh_session import apply_refinement, extract_tets, generate, gmsh_model
        from .scan import CLASSIFY_ANGLE

        refs = _refinements(refine)
        surf = self.surface
        with gmsh_model("surface", size, SURFACE_ALGORITHMS["frontal-delaunay"]) as gmsh:
            tag = gmsh.model.addDiscreteEntity(2)
            n = len(surf.points)
            gmsh.model.mesh.addNodes(2, tag, list(range(1, n + 1)), np.asarray(surf.points, float).reshape(-1).tolist())
            gmsh.model.mesh.addElementsByType(tag, 2, [], (np.asarray(surf.faces) + 1).reshape(-1).tolist())
            gmsh.model.mesh.classifySurfaces(math.radians(CLASSIFY_ANGLE), True, True, math.pi)
            gmsh.model.mesh.createGeometry()
            gmsh.model.geo.synchronize()
            loop = gmsh.model.geo.addSurfaceLoop([e[1] for e in gmsh.model.getEntities(2)])
            gmsh.model.geo.addVolume([loop])
            gmsh.model.geo.synchronize()
            apply_refinement(gmsh, refs or None, size)
            generate(gmsh, size)
            points, tets = extract_tets(gmsh)
        return TetMesh(points, tets)


def geometry_of_mesh(mesh: TetMesh, source: str = "the body's mesh") -> SurfaceGeometry:
    """The solid bounded by ``mesh``'s boundary triangles, to remesh a body that came with no geometry.

    Raises
    ------
    NoGeometryError
        The boundary is not a closed, manifold, non-self-intersecting surface
        (:func:`fem_grasp.scan.check_surface` says where).
    """
    from .scan import SurfaceError, check_surface, clean_surface

    try:
        surf = check_surface(clean_surface(mesh.points, mesh.surface_faces, source))
    except SurfaceError as exc:
        raise NoGeometryError(f"cannot remesh {source} from its boundary: {exc}") from None
    return SurfaceGeometry(surf)


def geometry_of_scene(scene: Any) -> Geometry | None:
    """The geometry of a :class:`~fem_grasp.io.scene.Scene`'s object: its paper shape, its box, its scan's surface
    (in metres: the file's ``units`` applied, as to the scene's mesh); None for a volume mesh file (remeshed from
    its boundary by :func:`geometry_of_mesh` when needed)."""
    spec = scene.object
    if spec.kind == "paper":
        return PaperGeometry(spec.paper)
    if spec.kind == "box":
        lx, ly, lz = spec.box
        return BoxGeometry((-lx / 2, -ly / 2, 0.0), (lx / 2, ly / 2, lz))
    from .scan import SURFACE_SUFFIXES, check_surface, read_surface

    if spec.mesh is not None and spec.mesh.suffix.lower() in SURFACE_SUFFIXES:
        return SurfaceGeometry(check_surface(read_surface(spec.mesh, spec.units)))
    return None
