"""One gmsh session for every mesh fem_grasp makes: the solids of :mod:`~fem_grasp.mesh.shapes` and the scans
of :mod:`~fem_grasp.mesh.scan` share it.

Every gmsh call runs in its own quiet, single-threaded, deterministic session (:func:`gmsh_model`): the
same arguments give bit-identical arrays.  The points it is given (refinement centres, points to embed) and the
lengths of its size fields are rounded to about :data:`POINT_QUANTUM` of the mesh size first (:func:`snapped`,
:func:`rounded_length`), so that arguments that differ by round-off give the same mesh too.  The tetrahedra are
read back with boundary slivers removed and vertices renumbered (:func:`extract_tets`);
:func:`mesh_with_vertex_count` finds the mesh size that gives a wanted number of vertices; :class:`Refinement`
grades the mesh around given points (where the fingertips touch).  gmsh is an optional dependency (the ``mesh``
extra, or Debian's ``python3-gmsh``), imported only when a mesh is made (:func:`import_gmsh`).

gmsh keeps one global state per process, and sets the handler of SIGINT when it is imported and initialised,
which Python allows only on the main thread.  Sessions are therefore serialised within a process (a lock), and
on any other thread (a Dask worker's task, a thread pool) gmsh is imported and initialised with the signal
handlers left as they are.
"""

from __future__ import annotations

import contextlib
import logging
import math
import signal
import threading
from dataclasses import dataclass
from typing import Any, Callable, Iterator, Sequence

import numpy as np

from ..errors import require

__all__ = ["AUTO_MESHADAPT_MAX_VERTICES", "Builder", "GMSH_OPTIONS", "Refinement", "SLIVER_QUALITY",
           "SURFACE_ALGORITHMS", "POINT_QUANTUM", "apply_refinement", "rounded_length", "snapped",
           "embed_surface_points", "check_lengths", "extract_tets", "generate", "gmsh_model",
           "import_gmsh", "mesh_with_vertex_count", "orient_positive", "remove_boundary_slivers", "shape_quality",
           "surface_algorithm"]

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
        check_lengths(radius=self.radius, size=self.size, thickness=self.thickness)
        c = np.asarray(self.centers, dtype=float)
        if c.ndim != 2 or c.shape[1] != 3 or len(c) == 0 or not np.isfinite(c).all():
            raise ValueError(f"refinement centres must be finite 3-vectors, got {self.centers!r}")

    def size_at(self, points: np.ndarray, outer: float) -> np.ndarray:
        """(k,) the edge length this refinement asks at ``points`` (k, 3) in a mesh of size ``outer``: gmsh's Ball
        field, ``size`` within ``radius`` of the nearest centre, growing linearly to ``outer`` over ``thickness``."""
        from scipy.spatial import cKDTree

        d, _ = cKDTree(np.asarray(self.centers, float)).query(np.asarray(points, float).reshape(-1, 3))
        inner = min(self.size, outer)
        share = np.clip((d - self.radius) / self.thickness, 0.0, 1.0)
        return inner + share * (outer - inner)

    @classmethod
    def around(cls, centers: np.ndarray, finger_radius: float) -> "Refinement":
        """The default grading for fingertips of radius R: size R/2 within 2R, growing over R."""
        r = float(finger_radius)
        return cls(tuple(tuple(float(x) for x in row) for row in np.asarray(centers, float)), 2.0 * r, 0.5 * r, r)


#: Points handed to gmsh are rounded to about this share of the mesh size (:func:`snapped`), and the lengths of
#: its size fields to about this share of themselves (:func:`rounded_length`).  gmsh's mesh follows the last bits
#: of what it is given: the orange's level-1 mesh of the accuracy loop had 2,454, 2,456, 2,511 or 2,537 vertices
#: as its grasp and patch points were moved by 1e-15 of themselves, the size of the round-off another CPU's
#: arithmetic leaves in them (the loop built other meshes on two AMD EPYC machines).  Rounded, the mesh, and the
#: answer computed on it, are the same on every machine; a point moves by at most 1e-8 of a spacing.
POINT_QUANTUM = 1e-8


def _grid(length: float) -> float:
    """The power of two nearest below :data:`POINT_QUANTUM` × ``length``: a grid that round-off in ``length``
    does not move, on which rounding is exact."""
    return 2.0 ** math.floor(math.log2(POINT_QUANTUM * float(length)))


def snapped(points: Any, size: float) -> np.ndarray:
    """(k, 3) ``points`` rounded to a grid of about :data:`POINT_QUANTUM` × ``size`` (metres): round-off in them
    no longer changes the mesh, short of a coordinate within round-off of a half-step of the grid."""
    q = _grid(size)
    return np.round(np.asarray(points, float).reshape(-1, 3) / q) * q


def rounded_length(length: float) -> float:
    """``length`` rounded to a grid of about :data:`POINT_QUANTUM` of itself (see :func:`snapped`)."""
    q = _grid(length)
    return float(round(float(length) / q) * q)


def apply_refinement(gmsh: Any, refine: "Refinement | Sequence[Refinement] | None", mesh_size: float) -> None:
    """Set the background size field of the current model (no-op without a refinement).

    ``refine`` may be one :class:`Refinement` or several (e.g. finer at the
    fingertips than at the table): the size is the smallest any of them asks.
    """
    if refine is None:
        return
    field = gmsh.model.mesh.field
    balls = []
    for ref in ((refine,) if isinstance(refine, Refinement) else tuple(refine)):
        lengths = {"Radius": ref.radius, "Thickness": ref.thickness, "VIn": min(ref.size, mesh_size),
                   "VOut": mesh_size}
        lengths = {key: rounded_length(value) for key, value in lengths.items()}
        for x, y, z in snapped(ref.centers, lengths["VIn"]):
            f = field.add("Ball")
            for key, value in (*lengths.items(), ("XCenter", x), ("YCenter", y), ("ZCenter", z)):
                field.setNumber(f, key, float(value))
            balls.append(f)
    if not balls:
        return
    smallest = field.add("Min")
    field.setNumbers(smallest, "FieldsList", balls)
    field.setAsBackgroundMesh(smallest)

#: A point to embed may lie this share of the mesh size off the solid's surface (the surface's own round-off);
#: farther, it is not embedded and the caller's nearest surface node stands in for it.
EMBED_TOLERANCE = 1e-6


def embed_surface_points(gmsh: Any, volume: int, points: np.ndarray | None, mesh_size: float) -> int:
    """Make ``points`` (on the boundary of the OCC ``volume``) nodes of the mesh to come: each is added as an OCC
    point and embedded in the boundary surface nearest it (gmsh puts a node there, curved surfaces included).
    Call before :func:`apply_refinement` and :func:`generate`, with the OCC model not yet synchronised after the
    volume was made.  Returns the number embedded (points off the surface by more than
    :data:`EMBED_TOLERANCE` × ``mesh_size`` are not)."""
    pts = np.zeros((0, 3)) if points is None else snapped(points, mesh_size)
    occ = gmsh.model.occ
    tags = [occ.addPoint(*map(float, p)) for p in pts]
    occ.synchronize()
    if not tags:
        return 0
    surfaces = [t for d, t in gmsh.model.getBoundary([(3, volume)], oriented=False) if d == 2]
    done = 0
    for tag, p in zip(tags, pts):
        gap, best = min((float(np.linalg.norm(np.asarray(gmsh.model.getClosestPoint(2, s, list(p))[0]) - p)), s)
                        for s in surfaces)
        if gap <= EMBED_TOLERANCE * mesh_size:
            gmsh.model.mesh.embed(0, [tag], 2, best)
            done += 1
        else:
            log.debug("point %s lies %.3g m off the surface: not embedded", p.tolist(), gap)
    return done


#: gmsh options fixed for every session: quiet, single-threaded and reproducible.
GMSH_OPTIONS: dict[str, float] = {
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

GMSH_TET4 = 4  # gmsh element type of the 4-node tetrahedron

#: gmsh 2D algorithms for the surface mesh (``Mesh.Algorithm``).
SURFACE_ALGORITHMS: dict[str, int] = {"meshadapt": 1, "delaunay": 5, "frontal-delaunay": 6}

#: ``algorithm="auto"`` uses MeshAdapt up to this many (estimated) vertices and
#: Frontal-Delaunay above.  On coarse meshes of spheroids Frontal-Delaunay's
#: vertex count jumps by up to 15 % when the mesh size crosses the point where
#: a curve gains a segment, which leaves some vertex counts unreachable;
#: MeshAdapt's count varies smoothly.  On fine meshes the jumps are small and
#: MeshAdapt is 5x slower (60 s against 12 s at 70 000 vertices).
AUTO_MESHADAPT_MAX_VERTICES = 10_000


def surface_algorithm(algorithm: str, volume: float, mesh_size: float) -> int:
    """gmsh's ``Mesh.Algorithm`` number for a name, resolving ``"auto"`` by estimated size."""
    if algorithm == "auto":
        # n ≈ V / h³ for these settings (within 0.7–1.3 from 200 to 70 000 vertices).
        estimate = volume / mesh_size**3
        algorithm = "meshadapt" if estimate <= AUTO_MESHADAPT_MAX_VERTICES else "frontal-delaunay"
    try:
        return SURFACE_ALGORITHMS[algorithm]
    except KeyError:
        raise ValueError(f"unknown algorithm {algorithm!r}; choose 'auto' or one of {sorted(SURFACE_ALGORITHMS)}") from None


#: One gmsh session at a time in a process (gmsh's state is global); re-entrant for a caller's own session.
_SESSION = threading.RLock()
_SIGNALS = threading.Lock()


@contextlib.contextmanager
def _signal_handlers_kept() -> Iterator[None]:
    """On a thread other than the main one, make ``signal.signal`` leave the handlers as they are for the duration
    (gmsh sets SIGINT's when imported and initialised, which Python refuses there); on the main thread, nothing."""
    if threading.current_thread() is threading.main_thread():
        yield
        return
    with _SIGNALS:
        real = signal.signal
        signal.signal = lambda signum, handler: signal.getsignal(signum)  # type: ignore[assignment]
        try:
            yield
        finally:
            signal.signal = real


def import_gmsh() -> Any:
    """Import gmsh, or raise :class:`~fem_grasp.errors.MissingExtraError` (an ImportError) that says how to
    install it: the ``mesh`` extra, or Debian's python3-gmsh.  (The shipped paper scenes load their committed
    meshes without gmsh.)  Works on any thread (module notes)."""
    with _signal_handlers_kept():
        return require("gmsh", "mesh", "Making a tetrahedral mesh (gmsh)")


@contextlib.contextmanager
def gmsh_model(name: str, mesh_size: float, surface_algorithm: int) -> Iterator[Any]:
    """A fresh gmsh model with :data:`GMSH_OPTIONS`, a uniform target size and a 2D algorithm.

    gmsh is initialised on entry and finalised on exit, even on error.  If the
    caller already runs a gmsh session (gmsh >= 4.9 can tell), that session is
    left alive: a separate model is added and removed, and the options changed
    here are restored.  One session at a time per process, on any thread (module notes).
    """
    if not (math.isfinite(mesh_size) and mesh_size > 0):
        raise ValueError(f"mesh_size must be a positive finite length, got {mesh_size!r}")
    with _SESSION:
        with _gmsh_model(name, mesh_size, surface_algorithm) as gmsh:
            yield gmsh


@contextlib.contextmanager
def _gmsh_model(name: str, mesh_size: float, surface_algorithm: int) -> Iterator[Any]:
    gmsh = import_gmsh()
    nested = bool(getattr(gmsh, "isInitialized", lambda: False)())
    saved: dict[str, float] = {}
    if not nested:
        with _signal_handlers_kept():
            gmsh.initialize([], False)  # no argv, do not read the user's gmshrc
    try:
        options = dict(GMSH_OPTIONS)
        options["Mesh.MeshSizeMax"] = rounded_length(mesh_size)
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
            with _signal_handlers_kept():
                gmsh.finalize()


def orient_positive(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
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


def shape_quality(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """6√2·|V| / ℓ_rms³: 1 for a regular tetrahedron, -> 0 for slivers (as ``TetMesh.quality``)."""
    p = points[tets]
    e = p[:, 1:] - p[:, :1]
    vol = np.abs(np.einsum("ij,ij->i", e[:, 0], np.cross(e[:, 1], e[:, 2]))) / 6.0
    pairs = np.array([(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)])
    l2 = np.sum((p[:, pairs[:, 0]] - p[:, pairs[:, 1]]) ** 2, axis=2).mean(axis=1)
    return 6.0 * math.sqrt(2.0) * vol / l2**1.5


def remove_boundary_slivers(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
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
        drop = (exposed >= 2) & (shape_quality(points, tets) < SLIVER_QUALITY)
        if not drop.any():
            break
        removed += int(drop.sum())
        tets = tets[~drop]
    if removed:
        log.debug("removed %d boundary sliver(s) with quality < %g", removed, SLIVER_QUALITY)
    return tets


def extract_tets(gmsh: Any) -> tuple[np.ndarray, np.ndarray]:
    """The current model's linear tetrahedra, on compactly renumbered vertices.

    Boundary slivers are removed (:func:`remove_boundary_slivers`), and nodes
    that belong to no tetrahedron (geometry points, seam or surface-only nodes)
    are dropped.
    """
    types, _, _ = gmsh.model.mesh.getElements(dim=3)
    other = sorted(int(t) for t in types if int(t) != GMSH_TET4)
    if other:
        raise RuntimeError(f"gmsh produced non-tetrahedral 3D elements (types {other})")
    _, node_tags = gmsh.model.mesh.getElementsByType(GMSH_TET4)
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
    tets_by_row = remove_boundary_slivers(coords, tets_by_row)
    used, compact = np.unique(tets_by_row, return_inverse=True)
    points = np.ascontiguousarray(coords[used])
    tets = orient_positive(points, compact.reshape(-1, 4).astype(np.int64))
    return points, np.ascontiguousarray(tets)


def generate(gmsh: Any, mesh_size: float) -> None:
    """Mesh the current model in 3D; gmsh's bare ``Exception`` becomes a RuntimeError."""
    try:
        gmsh.model.mesh.generate(3)
    except Exception as exc:  # gmsh raises bare Exception with its last error message
        raise RuntimeError(f"gmsh failed to mesh {gmsh.model.getCurrent()!r} at mesh size {mesh_size:g}: {exc}") from exc


def check_lengths(**lengths: float) -> None:
    for key, value in lengths.items():
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"{key} must be a positive finite length, got {value!r}")


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
