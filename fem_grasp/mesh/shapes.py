"""Tetrahedral meshes of simple solids with gmsh, and the four objects of the paper (Table I).

The paper (§IV) scanned a tomato, an orange, a steam bun and a toy football and
tetrahedralised the scans with CGAL.  The scans are not available, so this module
builds geometric stand-ins of plausible real size with gmsh's OpenCASCADE kernel:

============  ===================================  ==========================
object        shape                                size (semi-axes, metres)
============  ===================================  ==========================
tomato        slightly oblate spheroid             0.033 x 0.033 x 0.027
orange        sphere                               radius 0.037
steam bun     spheroid cut flat 1.2 cm below its   radius 0.048, semi-axis 0.023
              equator, base on z = 0               above the equator
football      prolate spheroid, long axis along x  0.085 x 0.045 x 0.045
============  ===================================  ==========================

With Table I's weights these give densities of about 1.0 (tomato), 0.9 (orange),
0.26 (steam bun) and 0.07 g/cm^3 (foam football).  The bun bulges out above
its base, as a steamed bun does: its side is vertical 1.2 cm up, 3.5 cm tall
in all.  (A half spheroid's side leans further than the friction angle at every
height where fingertips pushing slightly downward clear the table, so that
two fingers could not hold even a rigid bun there.)  Axes: x is the long axis, +z
points up; ellipsoids are centred on the origin and the bun's base lies on z = 0.

gmsh is an optional dependency (the ``mesh`` extra, or Debian's ``python3-gmsh``); it is imported
only inside the functions that need it, so ``import fem_grasp.mesh.shapes`` always works.
Every gmsh call runs in its own quiet, single-threaded, deterministic session:
the same arguments give bit-identical arrays.
"""

from __future__ import annotations

import functools
import logging
import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .gmsh_session import (
    AUTO_MESHADAPT_MAX_VERTICES,
    Refinement,
    apply_refinement,
    check_lengths,
    embed_surface_points,
    extract_tets,
    generate,
    gmsh_model,
    mesh_with_vertex_count,
    surface_algorithm,
)
from .tetmesh import TetMesh

__all__ = ["PAPER_SHAPES", "PaperShape", "Refinement", "dome", "dome_volume", "ellipsoid", "fused_spheres",
           "mesh_with_vertex_count", "paper_mesh", "paper_shape"]

log = logging.getLogger(__name__)


def ellipsoid(
    semi_axes: tuple[float, float, float], mesh_size: float, *, algorithm: str = "auto",
    refine: "Refinement | Sequence[Refinement] | None" = None, embed: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Tetrahedral mesh of a solid ellipsoid centred on the origin.

    Parameters
    ----------
    semi_axes : (a, b, c)
        Semi-axes along x, y and z in metres.  ``a == b == c`` gives a sphere.
    mesh_size : float
        Target edge length in metres (gmsh's ``Mesh.MeshSizeMax``).
    algorithm : {"auto", "meshadapt", "frontal-delaunay", "delaunay"}
        gmsh's surface algorithm; see :data:`AUTO_MESHADAPT_MAX_VERTICES`.
    refine : Refinement or a sequence of them, optional
        A finer mesh around some points (``mesh_size`` elsewhere).
    embed : (k, 3) points on the surface to make nodes of the mesh, optional
        (:func:`~fem_grasp.mesh.gmsh_session.embed_surface_points`; the accuracy loop's grasp points)

    Returns
    -------
    points : (n, 3) float64 ndarray
        Vertex coordinates; only vertices of tetrahedra are kept.
    tets : (t, 4) int64 ndarray
        Positively oriented tetrahedra, indexing ``points``.

    Raises
    ------
    MissingExtraError
        If gmsh is not installed (the ``mesh`` extra, or Debian's ``python3-gmsh``): an ImportError.
    ValueError
        If a length is not positive and finite.
    """
    a, b, c = (float(s) for s in semi_axes)
    check_lengths(a=a, b=b, c=c, mesh_size=mesh_size)
    alg = surface_algorithm(algorithm, 4.0 / 3.0 * math.pi * a * b * c, mesh_size)
    with gmsh_model("ellipsoid", mesh_size, alg) as gmsh:
        occ = gmsh.model.occ
        tag = occ.addSphere(0.0, 0.0, 0.0, 1.0)
        occ.dilate([(3, tag)], 0.0, 0.0, 0.0, a, b, c)
        occ.synchronize()
        embed_surface_points(gmsh, tag, embed, mesh_size)
        apply_refinement(gmsh, refine, mesh_size)
        generate(gmsh, mesh_size)
        points, tets = extract_tets(gmsh)
    log.debug("ellipsoid %s h=%.4g: %d vertices, %d tets", (a, b, c), mesh_size, len(points), len(tets))
    return points, tets


def fused_spheres(radii: tuple[float, float], distance: float, mesh_size: float, *, algorithm: str = "auto",
                  refine: "Refinement | Sequence[Refinement] | None" = None) -> tuple[np.ndarray, np.ndarray]:
    """Tetrahedral mesh of two overlapping solid spheres fused into one body (a peanut or a snowman).

    The spheres of radii r₁, r₂ are centred on the x axis at −d/2 and +d/2 and joined by a boolean
    union, so the surface has a concave crease where they meet.

    Parameters
    ----------
    radii : (r₁, r₂), metres
    distance : d, the distance between the centres, metres, |r₁ − r₂| < d < r₁ + r₂ (they overlap
        and neither contains the other)
    mesh_size, algorithm, refine : as for :func:`ellipsoid`

    Returns
    -------
    points : (n, 3) float64 ndarray
    tets : (t, 4) int64 ndarray
    """
    r1, r2 = (float(r) for r in radii)
    d = float(distance)
    check_lengths(r1=r1, r2=r2, distance=d, mesh_size=mesh_size)
    if not abs(r1 - r2) < d < r1 + r2:
        raise ValueError(f"the spheres must overlap without one containing the other: |r1 - r2| < distance < "
                         f"r1 + r2, got r = ({r1:g}, {r2:g}), distance {d:g}")
    # the volume of the union, for the surface algorithm's choice: two spheres less their lens
    lens = math.pi * (r1 + r2 - d) ** 2 * (d * d + 2 * d * (r1 + r2) - 3 * (r1 - r2) ** 2) / (12 * d)
    alg = surface_algorithm(algorithm, 4.0 / 3.0 * math.pi * (r1**3 + r2**3) - lens, mesh_size)
    with gmsh_model("fused_spheres", mesh_size, alg) as gmsh:
        occ = gmsh.model.occ
        a = occ.addSphere(-0.5 * d, 0.0, 0.0, r1)
        b = occ.addSphere(0.5 * d, 0.0, 0.0, r2)
        occ.fuse([(3, a)], [(3, b)])
        occ.synchronize()
        apply_refinement(gmsh, refine, mesh_size)
        generate(gmsh, mesh_size)
        points, tets = extract_tets(gmsh)
    log.debug("fused spheres r=(%.4g, %.4g) d=%.4g h=%.4g: %d vertices, %d tets", r1, r2, d, mesh_size,
              len(points), len(tets))
    return points, tets


def dome(radius: float, height: float, mesh_size: float, *, algorithm: str = "auto",
         refine: "Refinement | Sequence[Refinement] | None" = None, equator: float = 0.0,
         embed: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Tetrahedral mesh of a steam-bun dome: a spheroid cut flat at its base.

    The solid is ``x² / r² + y² / r² + (z − e)² / h² <= 1, z >= 0`` with
    ``e = equator``: a spheroid whose equator lies at height e, cut by the
    plane z = 0.  With e = 0 it is a half spheroid whose flat base has radius
    ``radius``; with 0 < e < h its side bulges out above a smaller base of
    radius r √(1 − e²/h²), as a steamed bun's does, and rises to e + h.

    Parameters
    ----------
    radius : float
        Equatorial radius r, metres.
    height : float
        Semi-axis h along z: the height of the top above the equator, metres.
    equator : float
        Height e of the equator above the flat base, metres, 0 <= e < h.
    mesh_size : float
        Target edge length in metres.
    algorithm : {"auto", "meshadapt", "frontal-delaunay", "delaunay"}
        gmsh's surface algorithm, as for :func:`ellipsoid`.
    refine : Refinement or a sequence of them, optional
        A finer mesh around some points, as for :func:`ellipsoid`.
    embed : (k, 3) points on the surface to make nodes of the mesh, optional, as for :func:`ellipsoid`

    Returns
    -------
    points : (n, 3) float64 ndarray
    tets : (t, 4) int64 ndarray
        As for :func:`ellipsoid`.

    Raises
    ------
    MissingExtraError
        If gmsh is not installed (the ``mesh`` extra, or Debian's ``python3-gmsh``): an ImportError.
    ValueError
        If a length is not positive and finite.
    """
    check_lengths(radius=radius, height=height, mesh_size=mesh_size)
    if not (math.isfinite(equator) and 0.0 <= equator < height):
        raise ValueError(f"equator must be in [0, height) = [0, {height!r}), got {equator!r}")
    alg = surface_algorithm(algorithm, dome_volume(radius, height, equator), mesh_size)
    with gmsh_model("dome", mesh_size, alg) as gmsh:
        occ = gmsh.model.occ
        # the sphere from latitude −asin(e/h) up: after the dilation and the shift by e, the cut is z = 0
        tag = occ.addSphere(0.0, 0.0, 0.0, 1.0, angle1=-math.asin(equator / height))
        occ.dilate([(3, tag)], 0.0, 0.0, 0.0, float(radius), float(radius), float(height))
        if equator > 0.0:
            occ.translate([(3, tag)], 0.0, 0.0, float(equator))
        occ.synchronize()
        embed_surface_points(gmsh, tag, embed, mesh_size)
        apply_refinement(gmsh, refine, mesh_size)
        generate(gmsh, mesh_size)
        points, tets = extract_tets(gmsh)
    # The flat base must be exactly flat: snap round-off of the OCC plane to z = 0.
    points[np.abs(points[:, 2]) <= 1e-12 * max(radius, height), 2] = 0.0
    log.debug("dome r=%.4g h=%.4g e=%.4g size=%.4g: %d vertices, %d tets", radius, height, equator, mesh_size, len(points), len(tets))
    return points, tets


def dome_volume(radius: float, height: float, equator: float = 0.0) -> float:
    """Volume of :func:`dome`'s solid, m³: π r² [(h + e) − (h³ + e³) / (3 h²)]."""
    r, h, e = float(radius), float(height), float(equator)
    return math.pi * r * r * ((h + e) - (h**3 + e**3) / (3.0 * h * h))


@dataclass(frozen=True)
class PaperShape:
    """A geometric stand-in for one object of the paper's Table I.

    Attributes
    ----------
    name : str
        Key in :data:`PAPER_SHAPES`.
    kind : str
        ``"ellipsoid"`` (dimensions are semi-axes a, b, c) or ``"dome"``
        (dimensions are the equatorial radius r, the semi-axis h above the
        equator and the equator's height e above the flat base, :func:`dome`).
    dimensions : tuple of float
        Metres.
    vertices, surface_facets, tetrahedra : int
        Mesh sizes reported in Table I for the scanned object.
    weight : float
        Table I weight w in newtons (used only to choose plausible dimensions).
    """

    name: str
    kind: str
    dimensions: tuple[float, ...]
    vertices: int
    surface_facets: int
    tetrahedra: int
    weight: float

    def build(self, mesh_size: float, algorithm: str = "auto",
              refine: "Refinement | Sequence[Refinement] | None" = None,
              embed: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Mesh this shape with target edge length ``mesh_size`` (metres), finer where ``refine`` says, with the
        surface points ``embed`` as nodes."""
        if self.kind == "ellipsoid":
            a, b, c = self.dimensions
            return ellipsoid((a, b, c), mesh_size, algorithm=algorithm, refine=refine, embed=embed)
        if self.kind == "dome":
            r, h, e = self.dimensions
            return dome(r, h, mesh_size, algorithm=algorithm, refine=refine, equator=e, embed=embed)
        raise ValueError(f"unknown shape kind {self.kind!r}")

    @property
    def volume(self) -> float:
        """Exact volume of the smooth solid, m³."""
        if self.kind == "ellipsoid":
            a, b, c = self.dimensions
            return 4.0 / 3.0 * math.pi * a * b * c
        return dome_volume(*self.dimensions)

    @property
    def density(self) -> float:
        """Mass density implied by the weight and the smooth volume, kg/m³ (g = 9.8)."""
        return self.weight / 9.8 / self.volume


#: The four objects of Table I.  Dimensions in metres, weights in newtons.
PAPER_SHAPES: dict[str, PaperShape] = {
    "tomato": PaperShape("tomato", "ellipsoid", (0.033, 0.033, 0.027), 490, 498, 2129, 1.246),
    "orange": PaperShape("orange", "ellipsoid", (0.037, 0.037, 0.037), 600, 564, 2692, 1.868),
    "steam_bun": PaperShape("steam_bun", "dome", (0.048, 0.023, 0.012), 658, 646, 2941, 0.467),
    "football": PaperShape("football", "ellipsoid", (0.085, 0.045, 0.045), 875, 782, 4058, 0.489),
}


def _paper_shape_spec(name: str) -> PaperShape:
    try:
        return PAPER_SHAPES[name]
    except KeyError:
        raise ValueError(f"unknown paper shape {name!r}; choose from {sorted(PAPER_SHAPES)}") from None


def paper_shape(name: str, mesh_size: float, *, algorithm: str = "auto") -> tuple[np.ndarray, np.ndarray]:
    """Mesh one of the paper's objects at a given target edge length.

    Parameters
    ----------
    name : {"tomato", "orange", "steam_bun", "football"}
    mesh_size : float
        Target edge length in metres.
    algorithm : {"auto", "meshadapt", "frontal-delaunay", "delaunay"}
        gmsh's surface algorithm, as for :func:`ellipsoid`.

    Returns
    -------
    points : (n, 3) float64 ndarray
    tets : (t, 4) int64 ndarray

    See Also
    --------
    paper_mesh : the same object at a prescribed number of vertices.
    """
    return _paper_shape_spec(name).build(mesh_size, algorithm)


def paper_mesh(name: str, target_vertices: int | None = None, rel_tol: float = 0.05, *,
               refine: "Refinement | Sequence[Refinement] | None" = None) -> "TetMesh":
    """One of the paper's objects as a :class:`~fem_grasp.mesh.TetMesh` with a set vertex count.

    Parameters
    ----------
    name : {"tomato", "orange", "steam_bun", "football"}
    target_vertices : int, optional
        Wanted number of vertices; defaults to the Table I count.  Counts up to
        ~60 000 take a few seconds per gmsh call (use for refinement series).
    rel_tol : float
        Relative tolerance on the vertex count.
    refine : Refinement or a sequence of them, optional
        A finer mesh around given points; the search then sets the outer mesh
        size (see :func:`fem_grasp.grasp.objects.graded_paper_mesh`).

    Returns
    -------
    TetMesh
    """
    spec = _paper_shape_spec(name)
    target = spec.vertices if target_vertices is None else int(target_vertices)
    # One surface algorithm for the whole search, so that n(h) stays one function.
    algorithm = "meshadapt" if target <= AUTO_MESHADAPT_MAX_VERTICES else "frontal-delaunay"
    builder = functools.partial(spec.build, algorithm=algorithm, refine=refine)
    # n ≈ V / h³ for these gmsh settings (0.7–1.3 over 200–70 000 vertices).
    h0 = (spec.volume / target) ** (1.0 / 3.0)
    points, tets = mesh_with_vertex_count(builder, target, rel_tol, initial_size=float(f"{h0:.6g}"))
    log.info("%s: %d vertices, %d tets (target %d)", name, len(points), len(tets), target)
    return TetMesh(points, tets)
