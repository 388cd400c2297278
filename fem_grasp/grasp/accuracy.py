"""The pickup answer, converged: accuracy as a setting (``pickup(..., accuracy=0.05)``).

What a user of *Picking up Soft 3D Objects with Two Fingers* wants from
Algorithm 1 is its **answer**: the verdict, the squeeze depth ρ* at which the
lift test of §III-B passes and the lift starts, the finger forces at lift-off
and the liftable weight w(ρ).  On P1 meshes with node-on-sphere contact that
answer depends on the discretisation:

* a hemispherical fingertip pressing on mesh nodes stiffens in steps (one node
  carries the load until the next ring touches), so w(ρ) and ρ* are set by how
  finely the contact patches are resolved;
* ρ* is found to within one squeeze increment (the lift test runs once per
  increment) and w(ρ) to within the lift-test step h;
* where w(ρ) flattens near the weight mg, a small error in w moves ρ* far
  (δρ* ≈ δw / w'(ρ*)), and where the peak of w(ρ) is within the error of mg the
  verdict itself depends on the mesh.

:func:`converged_pickup` (what ``pickup(..., accuracy=...)`` calls) therefore
runs Algorithm 1 on a sequence of levels: level 0 on the body as given finds
the contact patches (fingertips and table) and the grasp points (the given
contacts, or those the placement rule gives on the geometry's surface,
:func:`placement_target`); where the body's own finger nodes lie away from the
points and the geometry can make them nodes, level 0 is the body remeshed at
its spacing with them as nodes (:data:`GRASP_TOLERANCE`: the answer moves with
the grasp); each next level asks for half the spacing at those patches
(:data:`LEVEL_RATIO`), the table patch at four times that (:data:`TABLE_LAG`) and the
bulk √2 finer (:data:`OUTER_EXPONENT`), and by default (``PickupOptions.refinement = "nested"``) gets them
by bisecting the level before (:mod:`fem_grasp.mesh.bisection`, :data:`NESTED_EDGE_RATIO`), so that the
levels differ only in resolution and gmsh's draw of tetrahedra enters at level 0 alone — or, with
``refinement = "remesh"``, by remeshing the geometry (:mod:`fem_grasp.mesh.remesh`); it grasps at the same
points (as nodes where the geometry can embed them, else at each level's nearest surface nodes), and takes
a squeeze increment small enough that the lift
test's quantisation of ρ* (at most one increment) uses at most a quarter of the
target, half where the last two levels predict that this one will not meet it
(:func:`next_step`), with level 0's lift-test step h (below); it stops when two successive levels
agree on the verdict and their estimated error is within the target.  The
answer is the last level's.  The estimated error (:func:`estimated_error`) is
:data:`TWO_LEVEL_SAFETY` (3) times the difference of ρ* and of the finger force
Σ f·n̂ between the last two levels, relative to the last — for a sequence
converging at least linearly in the spacing with ratio 2, the last level's
error against the converged value is at most the difference, and two levels
may agree by chance (Roache's grid convergence index of a two-grid study) —
or, from the third level on, the larger of that and the
uncertainty of the last three levels (:func:`~fem_grasp.grasp.level_error.three_level_errors`, after Eça and
Hoekstra, :mod:`fem_grasp.grasp.estimates`: 1.25 × the extrapolated error
where they converge monotonically, at least 1.25 × their spread where faster
than order 2, three times their spread where they swing; the levels are
not in an asymptotic range, so three levels never state less than two
would), plus the resolution
of ρ* (one increment); for ρ* the part before the resolution is at least one
resolution too (two levels that find the same ρ* agree only to within it).  Where three levels are
monotone with an observed order, the Richardson estimate is reported too
(:func:`estimate`).

Every level squeezes at most as deep as the body as given does: where the grasp sets no deepest squeeze
(``PickupOptions.max_squeeze`` None, Algorithm 1 step 6: 40 % of the object's width along ĥ), the loop takes the
one level 0 found on the body as given for every level.  It is a setting of the grasp, not a quantity to
converge, and a failure's answer — ρ where the squeeze stopped — is then that setting on every level.  Each
level's own 40 % differs with its mesh (a remesh of the surface's facets cuts inside their extreme vertices, and
the resting tilt moves with the hull): a random capsule's levels and finer meshes gave 22.57–22.61 mm, which
nested levels (the same extreme vertices) did not show, so that their failure stated 0.036 % for 0.07 % off.

Every level tests the weights with level 0's lift-test step h (mg/20 unless
set).  The lift test passes when the ramp h, 2h, … reaches mg, so h does not
quantise ρ* as the squeeze increment does; it only sets how finely the load
path is followed (a failing step is halved three times before the weight is
not held), and a ramp's cost is in proportion to 1/h.  The convergence study
halved and quartered h at a fixed mesh and increment on all five objects:
ρ* and the finger force did not change (``make converge``, series ``h``).

The answer a level gives is a :class:`~fem_grasp.grasp.answer.GraspAnswer` (the quantities and their definitions:
:mod:`fem_grasp.grasp.answer`).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from .answer import GraspAnswer, answer_of, failure_kind, finger_nodes, passed, patch_points
from .estimates import estimate, relative_change
from .level_error import estimated_error, force_factor, three_level_errors, unsettled_verdict
from .options import MAX_FINGER_CONTACTS as _MAX_FINGER_CONTACTS
from .options import PickupOptions

__all__ = ["AccuracyLevel", "AccuracyReport", "single_run_report", "next_step", "predicted_mesh_error",
           "predicted_level_seconds", "first_lift_test", "placement_target", "converged_pickup", "GRASP_TOLERANCE",
           "ANNOUNCE_VERTICES", "LEVEL_COST_GROWTH", "LEVEL_RATIO", "STEP_SHARE", "FINE_STEP_SHARE", "STEP_DIVISIONS",
           "DEFAULT_ACCURACY", "MAX_LEVELS", "MAX_FINGER_CONTACTS", "SPECTRAL_MAX_VERTICES", "NESTED_EDGE_RATIO",
           "OUTER_EXPONENT", "outer_spacing", "levels_label", "percent_error"]

log = logging.getLogger(__name__)

#: Spacing ratio between successive levels (halving, as in the study's grading series R/2 … R/16).
LEVEL_RATIO = 2.0
#: The accuracy a scene is run to unless it says otherwise (relative error of ρ* and of the finger force).
DEFAULT_ACCURACY = 0.05
#: Levels tried after level 0 before the loop gives up and reports an unconverged answer.
MAX_LEVELS = 4
#: A level that would put more contacts than this on one fingertip is not run (``PickupOptions.max_finger_contacts``,
#: whose default this is): each halving of the patch spacing quadruples the patch's contacts, and the contact
#: algebra is dense in them (the (3m)² reduced stiffness, its factorisations, the hanging patch's return mappings).
#: The loop then stops with the last level's answer and its estimated error.
MAX_FINGER_CONTACTS = _MAX_FINGER_CONTACTS
#: The spectral backend's eigendecomposition is dense, O(n³) in time and O(n²) in memory (the football's 869
#: vertices take 5.6 s, its 2,744-vertex level would take minutes and its 7,521-vertex one an hour): the loop does
#: not run a level with more vertices on it, and stops with the last level's answer.  The sparse backend gives the
#: same answers to round-off (``python -m bench.bench --only spectral``).
SPECTRAL_MAX_VERTICES = 1500


# ============================================================ the loop
@dataclass(frozen=True)
class AccuracyLevel:
    """One level of :func:`converged_pickup`.

    Attributes
    ----------
    level : 0 for the body as given
    inner_size : spacing at the contact patches, metres (the body's own at level 0)
    outer_size : spacing elsewhere, metres
    answer : the level's :class:`GraspAnswer`
    mesh_seconds : time to build the mesh
    change : relative change of ρ* and of the finger force from the previous level (None at level 0)
    """

    level: int
    inner_size: float
    outer_size: float
    answer: GraspAnswer
    mesh_seconds: float = 0.0
    change: dict[str, float] | None = None

    def to_dict(self) -> dict[str, Any]:
        a = self.answer
        return {"level": self.level, "vertices": a.n_vertices, "inner_size": self.inner_size,
                "outer_size": self.outer_size, "step": a.step, "step_divisions": a.step_divisions,
                "resolution": a.resolution, "lift_test_step": a.lift_test_step,
                "success": a.success, "squeeze_depth": a.squeeze_depth, "finger_force": a.finger_force,
                "finger_nodes": [f["nodes"] for f in a.fingers], "table_nodes": a.table_nodes,
                "max_liftable": a.max_liftable, "max_squeeze": a.max_squeeze, "liftable": [list(p) for p in a.liftable],
                "force_exponent": a.force_exponent, "seconds": a.seconds,
                "mesh_seconds": self.mesh_seconds, "change": self.change, "reason": a.reason}


@dataclass
class AccuracyReport:
    """What :func:`converged_pickup` found (``result.accuracy``; ``"accuracy"`` in result.json).

    Attributes
    ----------
    target : the requested relative accuracy
    estimated_error : {"squeeze_depth", "finger_force"}: relative error estimates of the answer
    converged : two successive levels agree within ``target`` with the same verdict
    levels : every level run
    note : how the estimate was made, or why the loop stopped unconverged
    richardson : per quantity, :func:`estimate` over the levels (when three or more were run)
    geometry : what the levels remeshed
    refinement : how each level was made finer (``PickupOptions.refinement``: "nested" or "remesh")
    three_levels : per quantity, how the last three levels behaved (:func:`three_level_errors`: ``method``,
        observed ``order``, ``contraction``, ``relative`` uncertainty), when they all lifted the object
    contact_points : (2, 3) the initial finger contact points every level grasps at, in the frame of the body as
        given (the given contacts, or those the placement rule chose on level 0), or None before a placement
    verdict : why the last level's verdict is not settled at its resolution
        (:func:`~fem_grasp.grasp.level_error.unsettled_verdict`; the estimated errors are then inf), or empty
    given_mesh : where the body as given grasps away from ``contact_points`` and the geometry can make them nodes,
        its run (``grasp_offset``, m, its ``vertices``, ``success``, ``squeeze_depth``, ``finger_force`` and
        ``seconds``), which then is not level 0: level 0 is the body remeshed at its own spacing with the points
        as nodes (:data:`GRASP_TOLERANCE`); else None
    """

    target: float
    estimated_error: dict[str, float]
    converged: bool
    levels: list[AccuracyLevel] = field(default_factory=list)
    note: str = ""
    richardson: dict[str, Any] = field(default_factory=dict)
    geometry: str = ""
    three_levels: dict[str, Any] = field(default_factory=dict)
    contact_points: list[list[float]] | None = None
    given_mesh: dict[str, Any] | None = None
    verdict: str = ""
    refinement: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {"target": self.target, "estimated_error": dict(self.estimated_error), "converged": self.converged,
                "note": self.note, "verdict": self.verdict, "geometry": self.geometry,
                "refinement": self.refinement, "richardson": self.richardson,
                "three_levels": self.three_levels, "contact_points": self.contact_points,
                "given_mesh": self.given_mesh, "levels": [lv.to_dict() for lv in self.levels]}

    def summary_line(self) -> str:
        e = self.estimated_error
        return (f"target {100 * self.target:g} %: estimated error rho* {percent_error(e.get('squeeze_depth'))}, "
                f"finger force {percent_error(e.get('finger_force'))} "
                f"({levels_label(len(self.levels), self.refinement)}, "
                f"{'converged' if self.converged else 'error estimate above the target'})")


def levels_label(count: int, refinement: str | None) -> str:
    """"3 levels", or "3 nested levels" where each bisected the one before."""
    return f"{count} {'nested levels' if refinement == 'nested' else 'levels'}"


def percent_error(x: float | None) -> str:
    """A relative error as the summaries print it: "3.3 %", "12 %", "unknown" (None or infinite)."""
    if x is None or not math.isfinite(x):
        return "unknown"
    return f"{100 * x:.0f} %" if x >= 0.1 else f"{100 * x:.2g} %"


#: Radius of the refined region about each patch point, × the spacing the patch was found with: the patch of
#: a finer mesh reaches about one coarse spacing beyond the coarse one (more nodes touch at its rim), and balls
#: of this radius about points one spacing apart overlap.
PATCH_RADIUS = 1.5
#: The table patch is refined two levels behind the fingertips (four times their spacing): it carries the weight
#: as a wide, smooth pressure, and its many contacts make every return mapping of the squeeze dearer (the steam
#: bun's flat base at R/4 took more than 900 s against 37 s with only the fingertips graded; `make converge`).
TABLE_LAG = 4.0
#: Each level divides the spacing away from the patches (the bulk) by ``LEVEL_RATIO ** OUTER_EXPONENT``, √2,
#: where it halves the patches': P1's error in the bulk's stiffness falls as the square of its spacing and the
#: patches' about as their spacing, so both fall by about half from level to level and the levels' change sees
#: both.  A bulk kept at level 0's spacing (0) or refined more slowly (0.25) is faster and its levels do not see
#: the bulk's error, so their estimate understated it (docs/accuracy.md, "The bulk's spacing").
OUTER_EXPONENT = 0.5


def outer_spacing(outer: float, level: int, inner: float) -> float:
    """Level ``level``'s spacing away from the patches: level 0's, ``outer``, divided by
    ``LEVEL_RATIO ** (OUTER_EXPONENT × level)``, and never finer than the level's patch spacing ``inner``."""
    return max(outer / LEVEL_RATIO ** (OUTER_EXPONENT * level), inner)


def placement_target(geometry: Any, result: Any, direction: Any, spacing: float) -> np.ndarray:
    """(2, 3) the points every finer level grasps at when the placement rule chose level 0's contacts, in the
    frame of the body as given.

    The rule (:func:`~fem_grasp.grasp.placement.finger_contact_nodes`, the nodes extreme along ∓d̂ near a height)
    applied to points of the geometry's surface an eighth of level 0's patch spacing apart, at the height it
    chose on level 0 (the centre of mass's, when both of level 0's nodes lie within its band), in level 0's
    resting pose: where a mesh fine enough would put its nodes, rather than where level 0's coarse mesh had one.
    Level 0's own nodes are kept for a finger whose point lies more than two spacings from it, and for both
    where the geometry offers no surface points.
    """
    from .placement import HEIGHT_BAND, extreme_points

    mesh = result.body.mesh  # posed: the numbering of the body as given
    pose = result.rest.pose
    rot, trans = np.asarray(pose.rotation, float), np.asarray(pose.translation, float)
    nodes = [int(k) for k in result.finger_nodes]
    chosen = (mesh.points[nodes] - trans) @ rot  # level 0's nodes in the given frame
    try:
        samples = np.asarray(geometry.surface_points(spacing / 8.0), float)
    except NotImplementedError:
        return chosen
    posed = samples @ rot.T + trans
    z = posed[:, 2]
    band = HEIGHT_BAND * float(z.max() - z.min())
    com = float(result.body.center_of_mass[2])
    on = mesh.points[nodes, 2]
    height = com if bool(np.all(np.abs(on - com) <= band)) else float(on.mean())
    try:
        i, j = extreme_points(posed, height, direction)
    except ValueError:
        return chosen
    target = samples[[i, j]]
    far = np.linalg.norm(target - chosen, axis=1) > 2.0 * spacing
    target[far] = chosen[far]
    return target


#: Level 0 is the body remeshed with the grasp points as nodes (where the geometry can embed them) when the given
#: mesh's finger nodes lie farther than this × its patch spacing from them: every level then answers the same
#: grasp, and the levels differ only in resolution.  The shipped paper meshes' nodes lie 1.5-5 mm from the rule's
#: points, and the answer moves with the grasp: the steam bun's 659-vertex mesh grasps 2 mm above its equator,
#: where ρ* is 13.6 mm against 4.8 mm at it (``scripts/pinned_reference.py``); the tomato's remeshed level 0
#: answers 8.68 mm against the shipped mesh's 9.42, and the finer levels settle at 9.0 (the reference: 9.01).
GRASP_TOLERANCE = 1e-3

#: A level is not run when it would put more than this many times ``max_finger_contacts`` on the table (its count
#: grown as from the level before): the rest and the squeeze track every table contact.  The steam bun's flat
#: base, grasped at its equator on every level (``scripts/grasp_height.py``), had 300 table contacts at level 1
#: at 5 %, 572 at level 2 (25 s) and 1,115 at level 3, whose rest took 26 s and whose pickup 7 minutes, for a
#: rho* within 3.5 % of level 2's.
TABLE_CONTACT_SHARE = 2.5

#: A level costs at least this many times the one before (its patches hold about four times the contacts).
LEVEL_COST_GROWTH = 4.0
#: A level with more vertices than this is announced before it runs: it takes seconds (the shipped scenes' levels
#: of 7,500-9,700 vertices 4-9 s, the football's of 26,000 about 30 s), those before it about one.
ANNOUNCE_VERTICES = 5000


def first_lift_test(levels: Sequence[AccuracyLevel]) -> float | None:
    """The depth of the next level's first lift test (``PickupOptions.first_lift_test``): the last level's ρ*, so
    that a level that agrees with it to a sub-increment costs two lift tests (the first, and the sub-increment
    below or above it); None (every increment) when the last level was not picked up."""
    last = levels[-1]
    if not passed(last.answer) or not last.answer.squeeze_depth > 0:
        return None
    return last.answer.squeeze_depth


def predicted_level_seconds(levels: Sequence[AccuracyLevel]) -> float:
    """The time the next level will take: the last level's (meshing included), times the growth from the level
    before it, at least :data:`LEVEL_COST_GROWTH` (the orange: 1, 8 and 50 s for levels 0, 1 and 2)."""
    t = [lv.answer.seconds + lv.mesh_seconds for lv in levels]
    growth = max(LEVEL_COST_GROWTH, t[-1] / t[-2]) if len(t) >= 2 and t[-2] > 0 else LEVEL_COST_GROWTH
    return t[-1] * growth


def _level_refinements(fingers: np.ndarray, table: np.ndarray, inner: float, radius: float, outer: float) -> list:
    """A level's size field: ``inner`` at the fingertip patches, :data:`TABLE_LAG` × that at the table's."""
    from ..mesh.remesh import patch_refinement

    refs = [patch_refinement(fingers, inner, radius, outer),
            patch_refinement(table, min(TABLE_LAG * inner, outer), max(radius, TABLE_LAG * inner), outer)]
    return [r for r in refs if r is not None]


def _level_meshes(geometry: Any, fingers: np.ndarray, table: np.ndarray, inner: float, radius: float,
                  outer: float, embed: np.ndarray | None) -> Any:
    return geometry.build(outer, _level_refinements(fingers, table, inner, radius, outer), embed=embed)


#: A nested level (``PickupOptions.refinement = "nested"``) bisects every tetrahedron whose longest edge is more than
#: this × the size the level asks there (gmsh's size is a typical edge, bisection's bound the longest): at 2 the
#: tomato's nested levels 1 and 2 have 2,669 and 7,932 vertices where gmsh's have 2,166 and 6,105; at 1.6 level 1
#: had 4,816, at 1 20,441.
NESTED_EDGE_RATIO = 2.0


def _nested_level_mesh(geometry: Any, coarse: Any, fingers: np.ndarray, table: np.ndarray, inner: float,
                       radius: float, outer: float) -> Any:
    """The level before (``coarse``) bisected until it is as fine as :func:`_level_meshes` asks of gmsh."""
    from ..mesh.bisection import refine_to_size

    refs = _level_refinements(fingers, table, inner, radius, outer)

    def size(points: np.ndarray) -> np.ndarray:
        s = np.full(len(points), outer)
        for r in refs:
            s = np.minimum(s, r.size_at(points, outer))
        return NESTED_EDGE_RATIO * s

    return refine_to_size(coarse, size, geometry.project)


def converged_pickup(body: Any, *, solve: Callable[..., Any], accuracy: float = DEFAULT_ACCURACY, geometry: Any = None,
                     max_levels: int = MAX_LEVELS, max_seconds: float | None = None,
                     max_finger_contacts: int | None = None, options: PickupOptions | None = None,
                     rest_state: Any = None, settings: Any = None, on_level: Any = None, **overrides: Any) -> Any:
    """Algorithm 1 to a target accuracy of its answer (module notes); what ``pickup(..., accuracy=...)`` runs.

    Parameters
    ----------
    body : Body
        Level 0 runs on it as given; its mesh's frame is the geometry's.
    solve : one run of Algorithm 1, :func:`fem_grasp.grasp.pickup.pickup` (which passes itself when called
        with ``accuracy=``; taken as an argument so that this module sits above the pickup, not beside it)
    accuracy : relative accuracy wanted of ρ* and of the finger force Σ f·n̂ (0 < accuracy < 1)
    geometry : :class:`fem_grasp.mesh.remesh.Geometry` of the levels: level 0 and remeshed levels are meshed from
        it, nested levels' new boundary vertices moved onto it (default: ``body``'s boundary surface,
        :func:`fem_grasp.mesh.remesh.geometry_of_mesh`, which raises
        :class:`~fem_grasp.mesh.remesh.NoGeometryError` when that surface is not closed and manifold)
    max_levels : refinements tried after level 0
    max_finger_contacts : a level whose fingertip patches would hold more contacts than this (predicted from the
        level before: times the square of ``LEVEL_RATIO`` per halving of the spacing) is not run (default: the
        options' ``max_finger_contacts``, :data:`MAX_FINGER_CONTACTS` unless set)
    max_seconds : a time budget, seconds: no level is started once the levels so far took this long, nor when
        :func:`predicted_level_seconds` would carry the loop past it (the answer is then reported unconverged,
        with its estimated error); default the options' ``max_seconds``, None: no budget
    options : the grasp's :class:`~fem_grasp.grasp.options.PickupOptions` (default: the defaults), of which
        ``contacts`` are finger contact nodes of ``body`` (on finer levels the surface nodes at their positions,
        embedded as nodes where the geometry allows, :meth:`~fem_grasp.mesh.remesh.Geometry.build`) and ``step``,
        ``lift_test_step`` level 0's squeeze increment (m) and lift-test step h (N), default pickup's (each next
        level takes :func:`next_step` and the same h) and ``max_squeeze``, where None, level 0's on every level
        (module notes); its ``accuracy`` and ``geometry`` are not read (the arguments above are)
    rest_state : a resting state of ``body`` (level 0 only)
    settings : the engine's :class:`~fem_grasp.settings.EngineSettings`, the same at every level
    on_level : called with the :class:`AccuracyReport` after every level (progress, partial records)
    **overrides : fields of ``options`` changed by name (:meth:`PickupOptions.from_overrides`)

    Returns
    -------
    PickupResult
        The last level's result; ``result.accuracy`` holds :meth:`AccuracyReport.to_dict`.
    """
    from ..elastic.body import Body
    from ..errors import FrictionError, RestConvergenceError
    from ..mesh.remesh import geometry_of_mesh, nearest_surface_nodes, patch_refinement, spacing
    pickup = solve
    if not (isinstance(accuracy, (int, float)) and 0.0 < float(accuracy) < 1.0):
        raise ValueError(f"accuracy must be a relative error in (0, 1), e.g. 0.05; got {accuracy!r}")
    accuracy = float(accuracy)
    opts = PickupOptions.from_overrides(overrides, base=options).replace(accuracy=None, geometry=None)
    if max_finger_contacts is None:
        max_finger_contacts = opts.max_finger_contacts
    if max_seconds is None:
        max_seconds = opts.max_seconds
    contacts = opts.contacts
    t_start = time.perf_counter()
    geo = geometry if geometry is not None else geometry_of_mesh(body.mesh)
    points0 = body.mesh.points
    contact_points = None if contacts is None else points0[list(contacts)]
    report = AccuracyReport(accuracy, {"squeeze_depth": math.inf, "finger_force": math.inf}, False,
                            geometry=geo.describe(), refinement=opts.refinement)

    t0 = time.perf_counter()
    result = pickup(body, opts, rest_state=rest_state, settings=settings)
    ans = answer_of(result, time.perf_counter() - t0)
    fin_nodes = finger_nodes(result)
    inner = spacing(body.mesh, fin_nodes)
    outer = spacing(body.mesh)
    log.info("accuracy level 0: %d vertices, %s, rho* = %.4g mm, finger force %.4g N (%.1f s)", ans.n_vertices,
             "picked up" if ans.success else "not picked up", 1e3 * ans.squeeze_depth, ans.finger_force, ans.seconds)
    placed = len(result.finger_nodes) == 2 and min(result.finger_nodes) >= 0
    if opts.max_squeeze is None and math.isfinite(ans.max_squeeze) and ans.max_squeeze > 0:
        # The deepest squeeze is a setting of the grasp, not a quantity to converge (module notes).
        opts = opts.replace(max_squeeze=ans.max_squeeze)
    if contact_points is None and placed:
        # One grasp on every level: not a choice made again on each finer mesh, where a tie along a flat or
        # cylindrical side, or the next facet, moves the fingers by up to centimetres (a capsule's ρ* followed
        # its contacts' offset along the axis from the centre of mass).
        # The centre-of-mass-height rule is a rule on the surface, so it is taken on the geometry; another
        # rule's choice (the least force over heights) is kept as level 0 made it.
        contact_points = (placement_target(geo, result, opts.directions[0], inner)
                          if opts.placement_rule == "centre-of-mass-height"
                          else points0[[int(k) for k in result.finger_nodes]])
    if contact_points is not None:
        report.contact_points = np.asarray(contact_points, float).tolist()
    offset = (float(np.linalg.norm(points0[[int(k) for k in result.finger_nodes]] - contact_points, axis=1).max())
              if contact_points is not None and placed else 0.0)
    mesh_s0 = 0.0
    level_mesh = body.mesh  # the last level's, in the given frame (what a nested level bisects)
    if geo.embeds_points and offset > GRASP_TOLERANCE * inner:
        # Level 0 grasps at its mesh's nodes, `offset` from the points every finer level grasps at: another grasp,
        # whose answer may differ from theirs by more than any mesh error.  Level 0 is the body remeshed at its own
        # spacing with the points as nodes.
        t0 = time.perf_counter()
        refs = [r for r in (patch_refinement(contact_points, inner, PATCH_RADIUS * inner, outer),) if r is not None]
        mesh0 = geo.build(outer, refs, embed=contact_points)
        t_mesh = time.perf_counter() - t0
        body0 = Body(mesh0, body.young, body.poisson, weight=body.weight, gravity=body.gravity)
        given = ans
        t0 = time.perf_counter()
        try:
            result = pickup(body0, opts.replace(contacts=tuple(int(k) for k in
                                                               nearest_surface_nodes(mesh0, contact_points))),
                            settings=settings)
        except (RestConvergenceError, FrictionError) as exc:
            log.info("accuracy level 0 with the grasp points as nodes found no resting state (%s): level 0 is the "
                     "body as given", exc)
        else:
            ans, mesh_s0, level_mesh = answer_of(result, time.perf_counter() - t0), t_mesh, mesh0
            report.given_mesh = {"grasp_offset": offset, "vertices": given.n_vertices, "success": given.success,
                                 "squeeze_depth": given.squeeze_depth, "finger_force": given.finger_force,
                                 "seconds": given.seconds}
            log.info("accuracy level 0 remeshed with the grasp points as nodes (the given mesh's lie up to %.2g mm "
                     "from them): %d vertices, %s, rho* = %.4g mm, finger force %.4g N (%.1f s)", 1e3 * offset,
                     ans.n_vertices, "picked up" if ans.success else "not picked up", 1e3 * ans.squeeze_depth,
                     ans.finger_force, ans.seconds + t_mesh)
    report.levels.append(AccuracyLevel(0, inner, outer, ans, mesh_s0))
    if on_level is not None:
        on_level(report)
    fingers, table = patch_points(result)
    s0, h0 = ans.resolution, result.lift_test_step
    step_l = s0
    prev_inner = inner
    if not s0 > 0:  # stopped before the squeeze (no placement, no force closure): no increment to refine from
        report.note = f"level 0 stopped before the squeeze ({ans.reason}): there is no squeeze to refine"
        max_levels = 0
    for level in range(1, max_levels + 1):
        if max_seconds is not None:
            spent = time.perf_counter() - t_start
            ahead = predicted_level_seconds(report.levels)
            if spent >= max_seconds or spent + ahead > max_seconds:
                report.note = (f"stopped after {spent:.0f} s before level {level}"
                               + (f", predicted to take about {ahead:.0f} s" if spent < max_seconds else "")
                               + f" (max_seconds = {max_seconds:g}; to go on, raise it: fem-grasp run --max-seconds "
                               "S, the scene's [solver] max_seconds, or PickupOptions.max_seconds)")
                break
        inner_l = inner / LEVEL_RATIO**level
        predicted = max(f["nodes"] for f in report.levels[-1].answer.fingers) * LEVEL_RATIO**2
        if predicted > max_finger_contacts:
            report.note = (f"stopped before level {level}: it would put about {predicted:.0f} contacts on a fingertip, "
                           f"more than max_finger_contacts = {max_finger_contacts} (each level costs several times "
                           "the last; to go on: --max-finger-contacts N, the scene's [solver] max_finger_contacts "
                           "or PickupOptions.max_finger_contacts)")
            break
        table_now = report.levels[-1].answer.table_nodes
        table_before = report.levels[-2].answer.table_nodes if len(report.levels) > 1 else 0
        # the table patch is refined more coarsely than the fingertips' (TABLE_LAG): its count grows by 2 to 4
        growth = min(max(table_now / table_before, LEVEL_RATIO), LEVEL_RATIO**2) if table_before > 0 \
            else LEVEL_RATIO**2
        table_predicted = table_now * growth
        if table_predicted > TABLE_CONTACT_SHARE * max_finger_contacts:
            report.note = (f"stopped before level {level}: it would put about {table_predicted:.0f} contacts on the "
                           f"table, more than {TABLE_CONTACT_SHARE:g} × max_finger_contacts = "
                           f"{TABLE_CONTACT_SHARE * max_finger_contacts:g} (each level costs several times the last; "
                           "to go on: --max-finger-contacts N, the scene's [solver] max_finger_contacts or "
                           "PickupOptions.max_finger_contacts)")
            break
        outer_l = outer_spacing(outer, level, inner_l)
        t0 = time.perf_counter()
        if opts.refinement == "nested":
            mesh = _nested_level_mesh(geo, level_mesh, fingers, table, inner_l, PATCH_RADIUS * prev_inner, outer_l)
        else:
            mesh = _level_meshes(geo, fingers, table, inner_l, PATCH_RADIUS * prev_inner, outer_l, contact_points)
        t_mesh = time.perf_counter() - t0
        if opts.backend == "spectral" and mesh.n_points > SPECTRAL_MAX_VERTICES:
            report.note = (f"stopped before level {level}: its {mesh.n_points:,} vertices are more than the spectral "
                           f"backend's dense eigendecomposition runs in the loop (SPECTRAL_MAX_VERTICES = "
                           f"{SPECTRAL_MAX_VERTICES}; its time grows as the cube of the vertices); the sparse backend "
                           "gives the same answers to round-off and refines further")
            break
        if mesh.n_points > ANNOUNCE_VERTICES:  # a wait worth a word before it starts
            last = report.levels[-1]
            log.info("accuracy level %d: %d vertices (spacing %.3g mm at the patches) running; level %d took %.1f s, "
                     "and a level takes several times the one before", level, mesh.n_points, 1e3 * inner_l,
                     last.level, last.answer.seconds + last.mesh_seconds)
        lv_body = Body(mesh, body.young, body.poisson, weight=body.weight, gravity=body.gravity)
        lv_contacts = None if contact_points is None else tuple(int(k) for k in
                                                                nearest_surface_nodes(mesh, contact_points))
        before = report.levels[-1].answer
        # the resolution of ρ*; the lift-test step stays level 0's (LIFT_TEST_STEP_NOTE)
        step_l = next_step(step_l, before, accuracy, predicted_mesh_error(report.levels))
        t0 = time.perf_counter()
        try:
            level_result = pickup(lv_body, opts.replace(contacts=lv_contacts, step=STEP_DIVISIONS * step_l,
                                                        step_divisions=STEP_DIVISIONS,
                                                        lift_test_step=h0,
                                                        first_lift_test=first_lift_test(report.levels)),
                              settings=settings)
        except (RestConvergenceError, FrictionError) as exc:
            # The finer body does not come to rest as the coarser one did: no answer to compare at this level.
            report.note = (f"level {level} ({lv_body.n_nodes} vertices) found no resting state ({exc}): the answer "
                           f"is level {level - 1}'s, its error not estimated by this level")
            break
        result, level_mesh = level_result, mesh
        ans = answer_of(result, time.perf_counter() - t0)
        change = {"squeeze_depth": relative_change(before.squeeze_depth, ans.squeeze_depth),
                  "finger_force": relative_change(before.finger_force, ans.finger_force)}
        if not (passed(ans) or passed(before)):
            # Two failures agree only when they fail the same way and the fingers could hold as much:
            # where a squeeze stops says little (both at the maximum depth agree trivially).
            change["max_liftable"] = abs(ans.max_liftable - before.max_liftable) / ans.weight
            if failure_kind(ans.reason) != failure_kind(before.reason):
                change["max_liftable"] = math.inf
        report.levels.append(AccuracyLevel(level, inner_l, outer_l, ans, t_mesh, change))
        log.info("accuracy level %d: %d vertices (spacing %.3g mm at the patches), %s, rho* = %.4g mm (change %.2g), "
                 "finger force %.4g N (change %.2g) (%.1f s)", level, ans.n_vertices, 1e3 * inner_l,
                 "picked up" if ans.success else "not picked up", 1e3 * ans.squeeze_depth, change["squeeze_depth"],
                 ans.finger_force, change["finger_force"], ans.seconds + t_mesh)
        if on_level is not None:
            on_level(report)
        three = three_level_errors([lv.to_dict() for lv in report.levels])
        report.estimated_error = estimated_error(change, ans, three)
        report.three_levels = {k: {"method": u["method"], "order": u["order"], "contraction": u["contraction"],
                                   "spread": u["spread"], "relative": u["relative"]} for k, u in three.items()}
        report.verdict = unsettled_verdict(ans, before, report.estimated_error)
        if report.verdict:
            report.estimated_error.update(squeeze_depth=math.inf, finger_force=math.inf)
            report.note = (f"the verdict changed between levels {level - 1} and {level}"
                           if passed(ans) != passed(before) else f"the verdict of level {level} is not settled")
        elif max(report.estimated_error.values()) <= accuracy:
            report.converged = True
            report.note = (f"levels {level - 1} and {level} agree within {100 * accuracy:g} %: the estimated error is "
                           + ("the larger of three times their difference and the uncertainty of the last three "
                              "levels" if three else "three times their difference") + " plus the resolution of rho* "
                           "(for rho*, at least twice the resolution)")
            break
        f2, t2 = patch_points(result)
        fingers, table = np.vstack([fingers, f2]), np.vstack([table, t2])
        prev_inner = inner_l
    else:
        report.note = report.note or f"not converged to {100 * accuracy:g} % in {max_levels} refinements"
    if len(report.levels) >= 3:
        ok = [lv for lv in report.levels if passed(lv.answer) == passed(report.levels[-1].answer)]
        if len(ok) >= 3:
            h = [lv.inner_size for lv in ok]
            est = {"squeeze_depth": estimate([lv.answer.squeeze_depth for lv in ok], h),
                   "finger_force": estimate([lv.answer.finger_force for lv in ok], h)}
            report.richardson = {k: v for k, v in est.items() if v["method"] == "richardson"}
    result.accuracy = report.to_dict()
    result.accuracy["seconds"] = time.perf_counter() - t_start
    log.info("accuracy: %s", report.summary_line())
    return result


#: Share of the target the resolution of ρ* may take: the lift test runs once per increment (or sub-increment),
#: so ρ* is found up to one late (0 to 1 increment: the answer of 4,586-vertex orange moved by 2.3 % from
#: increment ρ*/22 to ρ*/176, all but 0.6 % of it within the first increment's bracket).
STEP_SHARE = 0.5
#: The share at level 1 and wherever the next level is predicted to meet the target (:func:`predicted_mesh_error`):
#: a finer ρ* costs more lift tests at that level, a further level several times the level before, so a level
#: that may converge leaves three quarters of the target to the mesh (the foam block at 5 %: converged at level
#: 2, where half the target for ρ* took it on to level 3, 205 s).  The prediction only chooses what a level
#: costs; the estimated error is measured as ever.
FINE_STEP_SHARE = 0.25
#: Levels after the first squeeze in increments of this many times the resolution of ρ* and divide the one in
#: which the lift test passes (``PickupOptions.step_divisions``): the same ρ* as the fine increment throughout,
#: for a quarter of its lift tests (the shipped scenes at a quarter of their increment: ρ* within one
#: sub-increment, the finger forces within 0.6 %, in 0.4–1× the time of the coarse increment).
STEP_DIVISIONS = 4


def predicted_mesh_error(levels: Sequence[AccuracyLevel]) -> float | None:
    """The mesh's part of the next level's error, predicted from the last two levels: their change less the
    coarser one's resolution of ρ* (its quantisation, not the mesh's), halved (convergence linear in the spacing),
    the larger over ρ* and Σ f·n̂; None before two levels that lifted the object."""
    if len(levels) < 2 or levels[-1].change is None:
        return None
    a, b = levels[-2].answer, levels[-1].answer
    if not (passed(a) and passed(b)) or not b.squeeze_depth > 0:
        return None
    res = a.resolution / b.squeeze_depth
    return max(max(0.0, levels[-1].change[q] - res) for q in ("squeeze_depth", "finger_force")) / LEVEL_RATIO


def next_step(step: float, before: GraspAnswer, accuracy: float, predicted: float | None = None) -> float:
    """The next level's resolution of ρ* (its squeeze increment over ``STEP_DIVISIONS``): at most
    ``STEP_SHARE × accuracy × ρ*`` of the level before (so the quantisation of ρ* by the lift test, at most one
    resolution, takes at most that share of the target) where the ``predicted`` mesh error of the next level
    (:func:`predicted_mesh_error`) leaves it less than the rest of the target, so that a level not expected to
    converge costs few lift tests; else ``FINE_STEP_SHARE`` (also with no prediction yet, as for level 1), never
    larger than the last, so that a level expected to converge follows one resolved as finely (two levels at
    different resolutions differ by the coarser one's quantisation); halved when the level before found no ρ*
    (its verdict: not lifted).  The share is of the force's target as well: an error of ρ* carries into the force
    read at it :func:`~fem_grasp.grasp.level_error.force_factor` times over, by which the resolution is divided."""
    if not passed(before) or not before.squeeze_depth > 0:
        return step / LEVEL_RATIO
    target = accuracy * before.squeeze_depth / force_factor(before)
    if predicted is None or predicted <= (1.0 - FINE_STEP_SHARE) * accuracy:
        return min(step, FINE_STEP_SHARE * target)
    return STEP_SHARE * target


def single_run_report(result: Any, target: float | None, expected_error: float | None, note: str, *,
                      refinable: bool = False) -> dict[str, Any]:
    """The ``accuracy`` block of a run made without the loop (``--quick``): one level, not converged, and the
    error the scene states for such a run (``[solver] expected_error``, measured by the convergence study).
    ``refinable``: the loop could have refined it (the accuracy was set off), which the block records."""
    from ..mesh.remesh import spacing

    ans = answer_of(result)
    nodes = finger_nodes(result)
    level = AccuracyLevel(0, spacing(result.body.mesh, nodes) if len(nodes) else math.nan,
                          spacing(result.body.mesh), ans)
    err = math.inf if expected_error is None else float(expected_error)
    rep = AccuracyReport(math.nan if target is None else float(target),
                         {"squeeze_depth": err, "finger_force": err}, False, [level], note)
    out = rep.to_dict()
    out["expected_error_stated"] = expected_error is not None
    out["refinable"] = bool(refinable)
    return out
