"""Tetrahedral meshes of simple solids with gmsh, and the four objects of the paper (Table I).

The paper (§IV) scanned a tomato, an orange, a steam bun and a toy football and
tetrahedralised the scans with CGAL.  The scans are not available, so this module
builds geometric stand-ins of plausible real size with gmsh's OpenCASCADE kernel:

============  ===================================  ==========================
object        shape                                size (semi-axes, metres)
============  ===================================  ==========================
tomato        slightly oblate spheroid             0.033 x 0.033 x 0.027
orange        sphere                               radius 0.037
steam bun     spheroid cut flat 1.2 cm below its    radius 0.048, semi-axis 0.023
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

gmsh is an optional dependency (Debian package ``python3-gmsh``); it is imported
only inside the functions that need it, so ``import fem_grasp.shapes`` always works.
Every gmsh call runs in its own quiet, single-threaded, deterministic session:
the same arguments give bit-identical arrays.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Iterator, Sequence

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from .mesh import TetMesh

log = logging.getLogger(__name__)

#: A mesh builder: mesh size (metres) -> (points (n, 3) float64, tets (t, 4) int64).
Builder = Callable[[float], "tuple[np.ndarray, np.ndarray]"]


@dataclass(frozen=True)
class Refinement:
    """A finer mesh around some points: where the fingertips will touch.

    Within ``radius`` of a centre the target edge length is ``size``; it grows
    linearly to the outer mesh size over a further ``thickness`` (gmsh "Ball"
    fields, combined by "Min").  Lengths in metres.

    Why: a fingertip of radius R on a mesh of spacing h > R touches one to
    three nodes, and two or three point contacts hold a hanging body poorly
    (the lift test of §III-B).  Table II reports 8–15 contact nodes at lift;
    a spacing of R/2 under the fingertips gives such counts.
    """

    centers: tuple[tuple[float, float, float], ...]
    radius: float
    size: float
    thickness: float

    def __post_init__(self) -> None:
        _check_lengths(radius=self.radius, size=self.size, thickness=self.thickness)
        c = np.asarray(self.centers, dtype=float)
        if c.ndim != 2 or c.shape[1] != 3 or len(c) == 0 or not np.isfinite(c).all():
            raise ValueError(f"refinement centres must be finite 3-vectors, got {self.centers!r}")

    @classmethod
    def around(cls, centers: np.ndarray, finger_radius: float) -> "Refinement":
        """The default grading for fingertips of radius R: size R/2 within 2R, growing over R."""
        r = float(finger_radius)
        return cls(tuple(tuple(float(x) for x in row) for row in np.asarray(centers, float)), 2.0 * r, 0.5 * r, r)


def _apply_refinement(gmsh: Any, refine: "Refinement | Sequence[Refinement] | None", mesh_size: float) -> None:
    """Set the background size field of the current model (no-op without a refinement).

    ``refine`` may be one :class:`Refinement` or several (e.g. finer at the
    fingertips than at the table): the size is the smallest any of them asks.
    """
    if refine is None:
        return
    field = gmsh.model.mesh.field
    balls = []
    for ref in ((refine,) if isinstance(refine, Refinement) else tuple(refine)):
        for x, y, z in ref.centers:
            f = field.add("Ball")
            for key, value in (("Radius", ref.radius), ("Thickness", ref.thickness),
                               ("VIn", min(ref.size, mesh_size)), ("VOut", mesh_size),
                               ("XCenter", x), ("YCenter", y), ("ZCenter", z)):
                field.setNumber(f, key, float(value))
            balls.append(f)
    if not balls:
        return
    smallest = field.add("Min")
    field.setNumbers(smallest, "FieldsList", balls)
    field.setAsBackgroundMesh(smallest)

GMSH_MISSING = (
    "fem_grasp.shapes needs gmsh's Python module to generate meshes. On Debian/Ubuntu install "
    "the package python3-gmsh (`apt-get install python3-gmsh`) and run with /usr/bin/python3 or a "
    "venv created with `--system-site-packages`; elsewhere `pip install gmsh`. "
    "Ready-made meshes of the paper's objects are in meshes/*.vtu."
)

#: gmsh options fixed for every session: quiet, single-threaded and reproducible.
_GMSH_OPTIONS: dict[str, float] = {
    "General.Terminal": 0,
    "General.Verbosity": 2,
    "General.NumThreads": 1,
    "Mesh.MaxNumThreads1D": 1,
    "Mesh.MaxNumThreads2D": 1,
    "Mesh.MaxNumThreads3D": 1,
    "Mesh.RandomSeed": 1,
    "Mesh.Algorithm3D": 1,  # Delaunay volumes
    "Mesh.Optimize": 1,
    "Mesh.OptimizeNetgen": 0,
    "Mesh.ElementOrder": 1,
    "Mesh.MeshSizeFromPoints": 0,
    "Mesh.MeshSizeFromCurvature": 0,
    "Mesh.MeshSizeExtendFromBoundary": 1,
    "Mesh.MeshSizeMin": 0.0,
}

_GMSH_TET4 = 4  # gmsh element type of the 4-node tetrahedron

#: gmsh 2D algorithms for the surface mesh (``Mesh.Algorithm``).
SURFACE_ALGORITHMS: dict[str, int] = {"meshadapt": 1, "delaunay": 5, "frontal-delaunay": 6}

#: ``algorithm="auto"`` uses MeshAdapt up to this many (estimated) vertices and
#: Frontal-Delaunay above.  On coarse meshes of spheroids Frontal-Delaunay's
#: vertex count jumps by up to 15 % when the mesh size crosses the point where
#: a curve gains a segment, which leaves some vertex counts unreachable;
#: MeshAdapt's count varies smoothly.  On fine meshes the jumps are small and
#: MeshAdapt is 5x slower (60 s against 12 s at 70 000 vertices).
AUTO_MESHADAPT_MAX_VERTICES = 10_000


def _surface_algorithm(algorithm: str, volume: float, mesh_size: float) -> int:
    """gmsh's ``Mesh.Algorithm`` number for a name, resolving ``"auto"`` by estimated size."""
    if algorithm == "auto":
        # n ≈ V / h³ for these settings (within 0.7–1.3 from 200 to 70 000 vertices).
        estimate = volume / mesh_size**3
        algorithm = "meshadapt" if estimate <= AUTO_MESHADAPT_MAX_VERTICES else "frontal-delaunay"
    try:
        return SURFACE_ALGORITHMS[algorithm]
    except KeyError:
        raise ValueError(f"unknown algorithm {algorithm!r}; choose 'auto' or one of {sorted(SURFACE_ALGORITHMS)}") from None


def _import_gmsh() -> Any:
    """Import gmsh, or raise an ImportError that says how to install it."""
    try:
        import gmsh
    except (ImportError, OSError) as exc:  # OSError: module found but libgmsh missing
        raise ImportError(GMSH_MISSING) from exc
    return gmsh


@contextlib.contextmanager
def _gmsh_model(name: str, mesh_size: float, surface_algorithm: int) -> Iterator[Any]:
    """A fresh gmsh model with :data:`_GMSH_OPTIONS`, a uniform target size and a 2D algorithm.

    gmsh is initialised on entry and finalised on exit, even on error.  If the
    caller already runs a gmsh session (gmsh >= 4.9 can tell), that session is
    left alive: a separate model is added and removed, and the options changed
    here are restored.
    """
    if not (math.isfinite(mesh_size) and mesh_size > 0):
        raise ValueError(f"mesh_size must be a positive finite length, got {mesh_size!r}")
    gmsh = _import_gmsh()
    nested = bool(getattr(gmsh, "isInitialized", lambda: False)())
    saved: dict[str, float] = {}
    if not nested:
        gmsh.initialize([], False)  # no argv, do not read the user's gmshrc
    try:
        options = dict(_GMSH_OPTIONS)
        options["Mesh.MeshSizeMax"] = float(mesh_size)
        options["Mesh.Algorithm"] = surface_algorithm
        for key, value in options.items():
            if nested:
                saved[key] = gmsh.option.getNumber(key)
            gmsh.option.setNumber(key, value)
        gmsh.logger.start()
        gmsh.model.add(name)
        try:
            yield gmsh
        finally:
            for line in gmsh.logger.get():
                log.debug("gmsh: %s", line)
            gmsh.logger.stop()
            if nested:
                gmsh.model.remove()
    finally:
        if nested:
            for key, value in saved.items():
                gmsh.option.setNumber(key, value)
        else:
            gmsh.finalize()


def _orient_positive(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Swap two vertices of every tetrahedron with negative signed volume."""
    e = points[tets[:, 1:]] - points[tets[:, :1]]
    vol = np.einsum("ij,ij->i", e[:, 0], np.cross(e[:, 1], e[:, 2]))
    neg = vol < 0
    if neg.any():
        tets = tets.copy()
        tets[neg] = tets[neg][:, [0, 2, 1, 3]]
    return tets


#: Boundary tetrahedra whose shape quality 6√2·V/ℓ_rms³ is below this are removed.
SLIVER_QUALITY = 0.1

# The four faces of a tetrahedron (vertex positions).
_FACES = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])


def _shape_quality(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """6√2·|V| / ℓ_rms³: 1 for a regular tetrahedron, -> 0 for slivers (as ``TetMesh.quality``)."""
    p = points[tets]
    e = p[:, 1:] - p[:, :1]
    vol = np.abs(np.einsum("ij,ij->i", e[:, 0], np.cross(e[:, 1], e[:, 2]))) / 6.0
    pairs = np.array([(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)])
    l2 = np.sum((p[:, pairs[:, 0]] - p[:, pairs[:, 1]]) ** 2, axis=2).mean(axis=1)
    return 6.0 * math.sqrt(2.0) * vol / l2**1.5


def _remove_boundary_slivers(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Drop flat tetrahedra that lie on the boundary with two or more faces exposed.

    Delaunay tetrahedralisation of a curved surface mesh can leave a sliver
    spanned by four nearly coplanar surface vertices, with two faces on the
    boundary; gmsh's optimiser cannot swap it away.  Removing it exposes its
    other faces, changes the volume by a negligible amount and keeps the
    boundary a closed manifold; a stiffness matrix with it would be needlessly
    ill-conditioned.  Repeats until none is left.
    """
    removed = 0
    for _ in range(10):
        faces = np.sort(tets[:, _FACES].reshape(-1, 3), axis=1)
        n = int(tets.max()) + 1
        if n < 2_000_000:  # encode each face as one int64 key: much faster than unique(axis=0)
            faces = (faces[:, 0] * n + faces[:, 1]) * n + faces[:, 2]
        _, inverse, counts = np.unique(faces, axis=0, return_inverse=True, return_counts=True)
        exposed = (counts[inverse.reshape(-1)] == 1).reshape(-1, 4).sum(axis=1)
        drop = (exposed >= 2) & (_shape_quality(points, tets) < SLIVER_QUALITY)
        if not drop.any():
            break
        removed += int(drop.sum())
        tets = tets[~drop]
    if removed:
        log.debug("removed %d boundary sliver(s) with quality < %g", removed, SLIVER_QUALITY)
    return tets


def _extract_tets(gmsh: Any) -> tuple[np.ndarray, np.ndarray]:
    """The current model's linear tetrahedra, on compactly renumbered vertices.

    Boundary slivers are removed (:func:`_remove_boundary_slivers`), and nodes
    that belong to no tetrahedron (geometry points, seam or surface-only nodes)
    are dropped.
    """
    types, _, _ = gmsh.model.mesh.getElements(dim=3)
    other = sorted(int(t) for t in types if int(t) != _GMSH_TET4)
    if other:
        raise RuntimeError(f"gmsh produced non-tetrahedral 3D elements (types {other})")
    _, node_tags = gmsh.model.mesh.getElementsByType(_GMSH_TET4)
    if len(node_tags) == 0:
        raise RuntimeError("gmsh produced no tetrahedra; is the mesh size too large for the shape?")
    tags, coords, _ = gmsh.model.mesh.getNodes()
    tags = np.asarray(tags, dtype=np.int64)
    coords = np.asarray(coords, dtype=np.float64).reshape(-1, 3)
    lookup = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
    lookup[tags] = np.arange(len(tags))
    tets_by_row = lookup[np.asarray(node_tags, dtype=np.int64).reshape(-1, 4)]
    if (tets_by_row < 0).any():
        raise RuntimeError("gmsh tetrahedra reference nodes it did not return")
    tets_by_row = _remove_boundary_slivers(coords, tets_by_row)
    used, compact = np.unique(tets_by_row, return_inverse=True)
    points = np.ascontiguousarray(coords[used])
    tets = _orient_positive(points, compact.reshape(-1, 4).astype(np.int64))
    return points, np.ascontiguousarray(tets)


def _generate(gmsh: Any, mesh_size: float) -> None:
    """Mesh the current model in 3D; gmsh's bare ``Exception`` becomes a RuntimeError."""
    try:
        gmsh.model.mesh.generate(3)
    except Exception as exc:  # gmsh raises bare Exception with its last error message
        raise RuntimeError(f"gmsh failed to mesh {gmsh.model.getCurrent()!r} at mesh size {mesh_size:g}: {exc}") from exc


def _check_lengths(**lengths: float) -> None:
    for key, value in lengths.items():
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"{key} must be a positive finite length, got {value!r}")


def ellipsoid(
    semi_axes: tuple[float, float, float], mesh_size: float, *, algorithm: str = "auto",
    refine: "Refinement | Sequence[Refinement] | None" = None,
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

    Returns
    -------
    points : (n, 3) float64 ndarray
        Vertex coordinates; only vertices of tetrahedra are kept.
    tets : (t, 4) int64 ndarray
        Positively oriented tetrahedra, indexing ``points``.

    Raises
    ------
    ImportError
        If gmsh is not installed (Debian package ``python3-gmsh``).
    ValueError
        If a length is not positive and finite.
    """
    a, b, c = (float(s) for s in semi_axes)
    _check_lengths(a=a, b=b, c=c, mesh_size=mesh_size)
    alg = _surface_algorithm(algorithm, 4.0 / 3.0 * math.pi * a * b * c, mesh_size)
    with _gmsh_model("ellipsoid", mesh_size, alg) as gmsh:
        occ = gmsh.model.occ
        tag = occ.addSphere(0.0, 0.0, 0.0, 1.0)
        occ.dilate([(3, tag)], 0.0, 0.0, 0.0, a, b, c)
        occ.synchronize()
        _apply_refinement(gmsh, refine, mesh_size)
        _generate(gmsh, mesh_size)
        points, tets = _extract_tets(gmsh)
    log.debug("ellipsoid %s h=%.4g: %d vertices, %d tets", (a, b, c), mesh_size, len(points), len(tets))
    return points, tets


def dome(radius: float, height: float, mesh_size: float, *, algorithm: str = "auto",
         refine: "Refinement | Sequence[Refinement] | None" = None, equator: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
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

    Returns
    -------
    points : (n, 3) float64 ndarray
    tets : (t, 4) int64 ndarray
        As for :func:`ellipsoid`.

    Raises
    ------
    ImportError
        If gmsh is not installed (Debian package ``python3-gmsh``).
    ValueError
        If a length is not positive and finite.
    """
    _check_lengths(radius=radius, height=height, mesh_size=mesh_size)
    if not (math.isfinite(equator) and 0.0 <= equator < height):
        raise ValueError(f"equator must be in [0, height) = [0, {height!r}), got {equator!r}")
    alg = _surface_algorithm(algorithm, dome_volume(radius, height, equator), mesh_size)
    with _gmsh_model("dome", mesh_size, alg) as gmsh:
        occ = gmsh.model.occ
        # the sphere from latitude −asin(e/h) up: after the dilation and the shift by e, the cut is z = 0
        tag = occ.addSphere(0.0, 0.0, 0.0, 1.0, angle1=-math.asin(equator / height))
        occ.dilate([(3, tag)], 0.0, 0.0, 0.0, float(radius), float(radius), float(height))
        if equator > 0.0:
            occ.translate([(3, tag)], 0.0, 0.0, float(equator))
        occ.synchronize()
        _apply_refinement(gmsh, refine, mesh_size)
        _generate(gmsh, mesh_size)
        points, tets = _extract_tets(gmsh)
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
              refine: "Refinement | Sequence[Refinement] | None" = None) -> tuple[np.ndarray, np.ndarray]:
        """Mesh this shape with target edge length ``mesh_size`` (metres), finer where ``refine`` says."""
        if self.kind == "ellipsoid":
            a, b, c = self.dimensions
            return ellipsoid((a, b, c), mesh_size, algorithm=algorithm, refine=refine)
        if self.kind == "dome":
            r, h, e = self.dimensions
            return dome(r, h, mesh_size, algorithm=algorithm, refine=refine, equator=e)
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


def mesh_with_vertex_count(
    builder: Builder,
    target: int,
    rel_tol: float = 0.05,
    *,
    initial_size: float | None = None,
    max_calls: int = 16,
) -> tuple[np.ndarray, np.ndarray]:
    """Find the mesh size at which ``builder`` gives about ``target`` vertices.

    The vertex count n(h) behaves like a power of the mesh size h (n ∝ h⁻³ for
    fine meshes, nearer h⁻² for coarse ones), so the search runs a secant
    iteration on ``log n`` against ``log h``, safeguarded by bisection once the
    target is bracketed.  It usually needs 3–5 builder calls.  Each call is
    deterministic, so the search (and its result) is too.

    Parameters
    ----------
    builder : callable
        ``builder(mesh_size) -> (points, tets)``, e.g.
        ``functools.partial(ellipsoid, (a, b, c))``.
    target : int
        Wanted number of vertices (>= 10).
    rel_tol : float
        Accept a mesh whose vertex count is within ``rel_tol * target`` of target.
    initial_size : float, optional
        First mesh size to try.  If omitted, a coarse probe mesh (size 1 m,
        shrunk tenfold while gmsh fails, grown tenfold while too fine) measures
        the volume V and the search starts from ``(V / target) ** (1/3)``.
    max_calls : int
        Give up after this many builder calls.

    Returns
    -------
    points : (n, 3) float64 ndarray
    tets : (t, 4) int64 ndarray
        The accepted mesh.

    Raises
    ------
    RuntimeError
        If no mesh within tolerance was found in ``max_calls`` calls; the
        message names the closest count and its size.
    """
    if target < 10:
        raise ValueError(f"target must be at least 10 vertices, got {target}")
    if not 0 < rel_tol < 1:
        raise ValueError(f"rel_tol must be in (0, 1), got {rel_tol}")
    log_target = math.log(target)
    tried: dict[float, tuple[np.ndarray, np.ndarray]] = {}

    def count(h: float) -> int:
        if h not in tried:
            if len(tried) >= max_calls:
                raise _GiveUp
            tried[h] = builder(h)
            log.debug("mesh size %.6g -> %d vertices (target %d)", h, len(tried[h][0]), target)
        return len(tried[h][0])

    def ok(h: float) -> bool:
        return abs(count(h) - target) <= rel_tol * target

    def best() -> float:
        return min(tried, key=lambda h: abs(len(tried[h][0]) - target))

    try:
        if initial_size is None:
            h = _probe_size(count, target)
            if ok(h):
                return tried[h]
            p, t = tried[h]
            e = p[t[:, 1:]] - p[t[:, :1]]
            volume = abs(np.einsum("ij,ij->i", e[:, 0], np.cross(e[:, 1], e[:, 2]))).sum() / 6.0
            h = float((volume / target) ** (1.0 / 3.0))
        else:
            if not (math.isfinite(initial_size) and initial_size > 0):
                raise ValueError(f"initial_size must be positive, got {initial_size!r}")
            h = float(initial_size)

        # Secant in (x, y) = (log h, log n), bracketed by bisection.
        x_prev: float | None = None
        y_prev: float | None = None
        lo = -math.inf  # largest log h known to give too many vertices
        hi = math.inf  # smallest log h known to give too few
        x = math.log(h)
        while True:
            h = math.exp(x)
            y = math.log(count(h))
            if ok(h):
                return tried[h]
            if y > log_target:
                lo = max(lo, x)
            else:
                hi = min(hi, x)
            if hi - lo < _SCAN_WIDTH:  # bracket narrow (or inverted by noise)
                break
            slope = -2.5
            if x_prev is not None and x != x_prev:
                s = (y - y_prev) / (x - x_prev)
                if -5.0 <= s <= -1.0:
                    slope = s
            x_new = x + (log_target - y) / slope
            x_new = min(max(x_new, x - math.log(4.0)), x + math.log(4.0))
            if math.isfinite(lo) and math.isfinite(hi) and not lo < x_new < hi:
                x_new = 0.5 * (lo + hi)
            x_prev, y_prev, x = x, y, _round_log(x_new)

        # n(h) is not monotone at the scale of a few per cent: the surface
        # mesh jumps as curve subdivisions change.  Near the target, sample
        # sizes at small fixed steps around the best one until a count lands.
        centre = math.log(best())
        for k in range(1, 4 * max_calls):
            x = _round_log(centre + _SCAN_STEP * ((k + 1) // 2) * (1 if k % 2 else -1))
            if ok(math.exp(x)):
                return tried[math.exp(x)]
        raise _GiveUp
    except _GiveUp:
        h = best()
        raise RuntimeError(
            f"no mesh with {target} ± {100 * rel_tol:g} % vertices after {len(tried)} builder calls; "
            f"closest: {len(tried[h][0])} vertices at mesh size {h:.6g}"
        ) from None


#: Log-width of a bracket below which the vertex-count search stops bisecting.
_SCAN_WIDTH = 0.02
#: Step in log mesh size of the final local scan (0.4 %).
_SCAN_STEP = 0.004


def _round_log(x: float) -> float:
    """Round exp(x) to 10 significant digits, so equal sizes reached by different paths hit the cache."""
    return math.log(float(f"{math.exp(x):.10g}"))


class _GiveUp(Exception):
    """Internal: the vertex-count search ran out of calls or of bracket."""


def _probe_size(count: Callable[[float], int], target: int) -> float:
    """A mesh size (a power of ten) that meshes without error and gives <= 4 * target vertices.

    Starts at 1 m; gmsh fails outright ("No elements in volume") when the size
    dwarfs the solid, so failures shrink the size and overly fine meshes grow it.
    """
    h = 1.0
    for _ in range(12):
        try:
            n = count(h)
        except RuntimeError as exc:  # gmsh could not mesh at this size
            log.debug("probe mesh size %.3g failed (%s); trying a finer one", h, exc)
            h /= 10.0
            continue
        if n <= 4 * target:
            return h
        h *= 10.0
    raise RuntimeError("could not find a probe mesh size; pass initial_size")


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
        size (see :func:`fem_grasp.objects.graded_paper_mesh`).

    Returns
    -------
    TetMesh
    """
    from .mesh import TetMesh

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
