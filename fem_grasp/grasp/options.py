"""The options of one grasp in one immutable record: :class:`PickupOptions`.

Algorithm 1 of *Picking up Soft 3D Objects with Two Fingers* (Lin, Guo, Wang, Jia, ICRA 2014) is run for one
object with a handful of choices: the two friction coefficients μ_ℱ and μ_𝒫, the fingertip radius R, the initial
finger contacts p_i, p_j (or the rule that picks them), the squeeze directions d̂₁, d̂₂ and ratio s, the maximum
squeeze depth and its increment, the lift test's step h, the lift, and, beyond the paper, the compliance backend
and an accuracy target for the answer.  Each is a field here with its unit and its default; the defaults are the
paper's §IV where it gives one and our choice where it is silent (:mod:`fem_grasp.grasp.pickup`).  One record
travels from a scene (:meth:`fem_grasp.io.scene.Scene.pickup_options`) or a placement search
(:class:`~fem_grasp.grasp.evaluation.SearchSetup`) to :func:`~fem_grasp.grasp.pickup.pickup` and through the
accuracy loop (:func:`~fem_grasp.grasp.accuracy.converged_pickup`); an option is changed by building a new
record::

    from fem_grasp.grasp import PickupOptions, pickup

    wet = PickupOptions(mu_finger=0.2, finger_radius=0.015)
    result = pickup(body, wet)                     # the same as pickup(body, mu_finger=0.2, finger_radius=0.015)
    longer = wet.replace(max_squeeze=0.03)         # by keyword
    again = pickup(body, wet, lift=False)          # keywords override the record's fields

Unknown names are refused with a message naming them (and the nearest known name).  The values that can be
checked without the object (friction, radius, ratio, directions, lengths, counts, the rule, the backend, the
accuracy target) are checked when the record is built, before anything is solved; the contact nodes are checked
against the object's mesh by :func:`~fem_grasp.grasp.pickup.pickup`.  What is not an option of the grasp stays
apart: the resting state (``pickup(..., rest_state=)``, a state of the object) and the engine's numerical settings
(:class:`~fem_grasp.settings.EngineSettings`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field, fields
from typing import Any, Mapping

import numpy as np

from ..contact.obstacles import DEFAULT_RADIUS
from ..elastic.response import BACKENDS
from ..errors import DirectionError, SceneError
from ..validation import check_finger_friction, check_friction, check_names, check_positive, check_real
from .placement import DEFAULT_PLACEMENT_RULE, PAPER_SQUEEZE_DIRECTIONS, PLACEMENT_RULES, check_directions

__all__ = ["DEFAULT_FRICTION", "DEFAULT_OPTIONS", "MAX_FINGER_CONTACTS", "PickupOptions", "REFINEMENTS"]

#: Friction coefficient used when none is given (μ_ℱ; μ_𝒫 follows it unless given).
DEFAULT_FRICTION = 0.5

#: The accuracy loop's bound on the contacts of one fingertip patch (:attr:`PickupOptions.max_finger_contacts`),
#: measured by the convergence study on the orange: 36 contacts per finger (grading R/4) took 10 s, 141 (R/8)
#: 112 s, and R/16 (about 560) did not finish in 40 min.
MAX_FINGER_CONTACTS = 300

#: How the accuracy loop makes a level's mesh finer (:attr:`PickupOptions.refinement`).
REFINEMENTS = ("remesh", "nested")

#: The paper's squeeze directions (§IV) as plain tuples, the default of :attr:`PickupOptions.directions`.
_PAPER_DIRECTIONS = tuple(tuple(float(x) for x in d) for d in PAPER_SQUEEZE_DIRECTIONS)


@dataclass(frozen=True)
class PickupOptions:
    """The options of one run of Algorithm 1 (module notes); defaults as :func:`~fem_grasp.grasp.pickup.pickup`.

    Immutable: derive another with :meth:`replace` or :meth:`from_overrides`.  ``None`` in a field means "the
    default rule of :mod:`fem_grasp.grasp.pickup`", computed from the object at run time.

    Attributes
    ----------
    mu_finger : float
        μ_ℱ, the Coulomb friction coefficient between the object and each fingertip (dimensionless, > 0: two
        frictionless fingers have no force-closure grasp).  Default :data:`DEFAULT_FRICTION`; ``None`` given is
        taken as the default.
    mu_table : float or None
        μ_𝒫, the friction coefficient between the object and the table (dimensionless, ≥ 0).  None: equal to
        ``mu_finger`` (the paper gives one μ per object); :attr:`table_friction` is the value in effect.
    finger_radius : float
        R, the radius of each hemispherical fingertip, metres (default
        :data:`~fem_grasp.contact.obstacles.DEFAULT_RADIUS`).
    contacts : (int, int) or None
        (p_i, p_j), the surface nodes of the posed body the fingertips first touch (Algorithm 1 step 1).  None:
        chosen by ``placement_rule`` (:func:`~fem_grasp.grasp.default_contacts.default_finger_contacts`).
    directions : ((3,), (3,)) tuple of floats
        (d̂₁, d̂₂), the directions in which fingers ℱ₁ and ℱ₂ translate during the squeeze (any length > 0, not
        upward); default the paper's (0, ±0.974, −0.227) (§IV).  Stored as tuples, as given (pickup normalises
        them).
    ratio : float
        s ≥ 0: ℱ₂ moves s ρ d̂₂ while ℱ₁ moves ρ d̂₁ (§III-B; default 1, a symmetric squeeze).
    max_squeeze : float or None
        The squeeze depth ρ at which Algorithm 1 gives up (step 6), metres.  None: 40 % of the object's width
        along the horizontal part of d̂₁.
    step : float or None
        The squeeze increment Δρ, metres: the lift test runs after every one (steps 3–4), so ρ* is found to
        within it; the lift rises by the same increment.  None: 1/20 of the depth at which the initial contact
        stiffness would hold the weight by friction, kept within 0.1 %–2 % of ``max_squeeze``.
    lift_test_step : float or None
        h, the load step of the lift test (§III-B), newtons: the liftable weight w(ρ) is found to within it.
        None: mg/20.
    step_divisions : int
        The increment in which the lift test first passes is squeezed again from its start in this many
        sub-increments with the lift test after each, stopping at the first that passes: ρ* is then found to
        within ``step / step_divisions`` for a few more lift tests, the answer of that finer increment wherever
        w(ρ) crosses mg once within the increment (≥ 1; default 1: Algorithm 1 as printed).
    first_lift_test : float or None
        The depth ρ of the first lift test, metres (None: a test after every increment, Algorithm 1 as printed),
        made at the first end of a sub-increment (``step / step_divisions``, counted from the start) at or past
        it: the squeeze reaches the increment below the one in which that falls untested, then goes on in
        sub-increments.  If the first test passes, the ends of the (sub-)increments below it are tested from the
        deepest down to the first that fails, and ρ* is the last that passed (where that failing end is a whole
        increment below, the increment is divided); if it fails, the next sub-increment is tested, and if that
        fails too the squeeze goes on as without a first test.  This is the answer of testing every sub-increment
        wherever w(ρ) crosses mg once; w(ρ) (``result.liftable``) has no entries below the tests made.  The
        accuracy loop sets it at the coarser level's ρ*: a level that agrees with it costs two lift tests.
    max_lift : float or None
        The lift height at which a lift that has not left the table fails, metres.  None: the object's height.
    lift : bool
        Run step 5, the lift (default True).  False stops the run when the lift test passes (``success`` stays
        False and the reason says the lift was not run).
    max_lift_attempts : int
        Lifts tried (≥ 1, default 4): a simulated lift that fails sends the squeeze on from the lift-start state
        to the next passing lift test (Algorithm 1 step 6, "go back to step 3").
    placement_rule : str
        How ``contacts`` are chosen when not given, one of
        :data:`~fem_grasp.grasp.placement.PLACEMENT_RULES` (default
        :data:`~fem_grasp.grasp.placement.DEFAULT_PLACEMENT_RULE`, the paper scenes' rule).
    backend : str
        The contact compliance, "sparse" (a sparse factorisation) or "spectral" (the dense eigendecomposition of
        the paper's eq. 3); :class:`~fem_grasp.elastic.response.ContactResponse`.  Default "sparse".
    accuracy : float or None
        Relative accuracy wanted of ρ* and of the finger force Σ f·n̂, in (0, 1) (e.g. 0.05).  None (default):
        one run on the body's mesh.  With a target the mesh is refined at the contact patches, and the
        increments with it, until two successive answers agree within it
        (:func:`~fem_grasp.grasp.accuracy.converged_pickup`).
    max_finger_contacts : int
        With ``accuracy``: a level predicted to put more contacts than this on one fingertip is not run, and the
        loop stops with the answer it has and its estimated error (≥ 1, default :data:`MAX_FINGER_CONTACTS`).  Each
        halving of the patch spacing quadruples a patch's contacts, and the hanging patch's contact algebra is
        dense in them: the level costs several times the one before.
    max_seconds : float or None
        With ``accuracy``: a time budget of the loop, seconds.  A level is not started once the levels so far
        took this long, nor when the last level's time, grown as the last two levels' times grew (at least
        fourfold), would carry the loop past it; the answer is then the last level's, with its estimated error.
        None (default): no budget.  The budget is wall-clock time, so how many levels it allows depends on the
        machine: an answer under a budget is reproducible only with its levels (``result.accuracy``).
    refinement : str
        With ``accuracy``: how each level's mesh is made finer, one of :data:`REFINEMENTS`.  "nested" (default):
        the level before bisected at the patches (:mod:`fem_grasp.mesh.bisection`), so that successive levels
        differ only in resolution; "remesh": the geometry meshed afresh by gmsh at each level, graded at the
        patches.  Level 0 is a gmsh mesh either way.
    geometry : Geometry or None
        What the ``accuracy`` loop remeshes (:class:`fem_grasp.mesh.remesh.Geometry`).  None: the body's boundary
        surface (:func:`fem_grasp.mesh.remesh.geometry_of_mesh`).  Not compared: two records that differ only
        here are equal (a surface geometry holds arrays).
    """

    mu_finger: float = DEFAULT_FRICTION
    mu_table: float | None = None
    finger_radius: float = DEFAULT_RADIUS
    contacts: tuple[int, int] | None = None
    directions: tuple[tuple[float, float, float], tuple[float, float, float]] = _PAPER_DIRECTIONS
    ratio: float = 1.0
    max_squeeze: float | None = None
    step: float | None = None
    lift_test_step: float | None = None
    step_divisions: int = 1
    first_lift_test: float | None = None
    max_lift: float | None = None
    lift: bool = True
    max_lift_attempts: int = 4
    placement_rule: str = DEFAULT_PLACEMENT_RULE
    backend: str = "sparse"
    accuracy: float | None = None
    max_finger_contacts: int = MAX_FINGER_CONTACTS
    max_seconds: float | None = None
    refinement: str = "nested"
    geometry: Any = field(default=None, compare=False)

    def __post_init__(self) -> None:
        put = object.__setattr__
        put(self, "mu_finger", check_finger_friction(DEFAULT_FRICTION if self.mu_finger is None else self.mu_finger,
                                                     "mu_finger"))
        if self.mu_table is not None:
            put(self, "mu_table", check_friction(self.mu_table, "mu_table"))
        put(self, "finger_radius", check_positive(self.finger_radius, "the fingertip radius R", "metres", SceneError))
        ratio = check_real(self.ratio, "the squeeze ratio s", SceneError)
        if not ratio >= 0:
            raise SceneError(f"the squeeze ratio s must be ≥ 0, got {self.ratio!r}")
        put(self, "ratio", ratio)
        put(self, "directions", _directions(self.directions, ratio))
        if self.contacts is not None and np.ndim(self.contacts) == 1:  # anything else: pickup names the problem
            put(self, "contacts", tuple(k.item() if isinstance(k, np.generic) else k for k in self.contacts))
        for name, what, unit in (("max_squeeze", "the maximum squeeze depth", "metres"),
                                 ("step", "the squeeze increment", "metres"),
                                 ("lift_test_step", "the lift-test step h", "newtons"),
                                 ("first_lift_test", "the depth of the first lift test", "metres"),
                                 ("max_lift", "the maximum lift height", "metres"),
                                 ("max_seconds", "the accuracy loop's time budget", "seconds")):
            value = getattr(self, name)
            if value is not None:
                put(self, name, check_positive(value, f"{what} ({name})", unit, SceneError))
        if not isinstance(self.lift, (bool, np.bool_)):
            raise ValueError(f"lift must be True or False, got {self.lift!r}")
        put(self, "lift", bool(self.lift))
        for name in ("max_finger_contacts", "step_divisions", "max_lift_attempts"):
            n = getattr(self, name)
            if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)) or n < 1:
                raise ValueError(f"{name} must be a whole number ≥ 1, got {n!r}")
            put(self, name, int(n))
        if self.placement_rule not in PLACEMENT_RULES:
            raise SceneError(f"unknown placement rule {self.placement_rule!r}; choose one of {PLACEMENT_RULES}")
        if self.refinement not in REFINEMENTS:
            raise ValueError(f"unknown refinement {self.refinement!r}; choose one of {REFINEMENTS}")
        if self.backend not in BACKENDS:
            raise ValueError(f"unknown backend {self.backend!r}; choose one of {BACKENDS}")
        if self.accuracy is not None:
            a = self.accuracy
            if isinstance(a, bool) or not (isinstance(a, (int, float)) and 0.0 < float(a) < 1.0):
                raise ValueError(f"accuracy must be a relative error in (0, 1), e.g. 0.05; got {a!r}")
            put(self, "accuracy", float(a))

    @property
    def table_friction(self) -> float:
        """μ_𝒫 in effect: ``mu_table``, or ``mu_finger`` where it is None."""
        return self.mu_finger if self.mu_table is None else self.mu_table

    def replace(self, **changes: Any) -> PickupOptions:
        """A copy with ``changes`` (field=value); unknown names are refused as by :meth:`from_overrides`."""
        return self.from_overrides(changes, base=self)

    @classmethod
    def from_overrides(cls, overrides: Mapping[str, Any], base: PickupOptions | None = None) -> PickupOptions:
        """``base`` (default: the defaults) with the fields named in ``overrides`` changed.

        Raises
        ------
        ValueError
            Naming each unknown field, with the nearest known name where one is close; or a value out of range
            (:class:`~fem_grasp.errors.SceneError` and its subclasses for the friction, the radius, the ratio, the
            directions and the lengths, as :func:`~fem_grasp.grasp.pickup.pickup` raises them).
        """
        check_names(overrides, [f.name for f in fields(cls)], "pickup option", "options")
        if base is None:
            return cls(**dict(overrides))
        return dataclasses.replace(base, **dict(overrides))

    def changed(self) -> dict[str, Any]:
        """The fields that differ from the defaults, by name (for logs and labels)."""
        default = PickupOptions()

        def differs(name: str, compare: bool) -> bool:
            mine, theirs = getattr(self, name), getattr(default, name)
            return mine != theirs if compare else mine is not theirs

        return {f.name: getattr(self, f.name) for f in fields(self) if differs(f.name, f.compare)}


def _directions(directions: Any, ratio: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """(d̂₁, d̂₂) checked (:func:`~fem_grasp.grasp.placement.check_directions`) and stored as given, as tuples."""
    try:
        d1, d2 = directions
    except (TypeError, ValueError):
        raise DirectionError(f"give two squeeze directions (d̂₁, d̂₂), got {directions!r}") from None
    check_directions(d1, d2, ratio=ratio)
    return tuple(tuple(float(x) for x in np.asarray(d, dtype=float).reshape(-1)) for d in (d1, d2))


#: The defaults (what ``pickup(body)`` runs with).
DEFAULT_OPTIONS = PickupOptions()
