"""The engine's numerical settings in one immutable record: :class:`EngineSettings`.

The event tracking of the squeeze and the lift (:class:`~fem_grasp.contact.tracking.Tracker`, paper §III-C) has
tolerances, limits, cache sizes and a choice of compiled or numpy trials; the compliance solves it asks for have a
batch size, and its contact responses may be derived from a neighbouring contact set's; its return mapping (the
implicit steps and the lift test's hanging weights) has iteration bounds, and the lift test halves a failing
load step.  Each is a field here,
with its unit and the reason for its default.  A tracker holds one :class:`EngineSettings` (``Tracker.settings``)
and reads nothing else, so two trackers with different settings can run side by side, and a setting is changed by
building a new record::

    from fem_grasp.settings import DEFAULT_SETTINGS, EngineSettings

    strict = DEFAULT_SETTINGS.replace(tol_locate=1e-12)           # by keyword
    every_increment_implicit = EngineSettings.from_overrides({"implicit_contacts": 0})
    result = pickup(body, settings=every_increment_implicit)

Unknown names are refused with a message naming them (and the nearest known name).  The defaults are the values
the engine's answers, tests and benchmarks are recorded with; the numerical tolerances that describe the answer
itself (the contact-law checks of :mod:`fem_grasp.grasp.checks`) are not settings.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, fields
from typing import Any, Mapping

from .validation import check_names

__all__ = ["DEFAULT_SETTINGS", "EngineSettings"]


@dataclass(frozen=True)
class EngineSettings:
    """The numerical settings of the contact tracking and of the compliance solves it asks for (module notes).

    Immutable: derive another with :meth:`replace` or :meth:`from_overrides`.  L below is the mesh diameter, F_s
    the force scale of a state (mg + max |f_k|) and t the tracked parameter (squeeze depth, lift height, metres;
    or the gravity load factor).

    Attributes
    ----------
    tol_penetration : float
        Event A fires when a free surface node is deeper than this × L inside an obstacle (1e-10: far inside the
        1e-9 L geometric checks of a result, far above round-off).
    tol_tensile : float
        Event B fires when a normal force is below −this × F_s (1e-11: tensile beyond round-off of the solve).
    tol_cone : float
        Event C: a sticking contact leaves its cone when ``|f_t| − μ f·n̂`` exceeds this × f·n̂ plus the force
        floor (1e-9, relative).
    tol_force_floor : float
        × F_s: contacts carrying less are "just touching" and exempt from event C (1e-7: their stick/slip state is
        decided by round-off).
    tol_rate : float
        Event D fires when the slip rate of a sliding contact is below −this (slip per unit t; 1e-9).
    stick_hysteresis : float
        A sliding contact whose normal force falls below this fraction of the force floor sticks (event D); the
        factor ten below the floor of event C keeps lightly loaded nodes from chattering between C and D (0.1).
    tol_locate : float
        Events are located in t to this × L (1e-10: well inside the checks; 1e-13 cost three times the time for the
        same events).
    increment_halvings : int
        Failed halvings of an increment whose slip system has no root before it is taken as one implicit step
        (2).
    min_step : float
        Smallest increment of t, × L, before the halvings of a failing slip solve give up (1e-9).
    max_slip : float
        A contact sliding further than this × L in one implicit step is gross slip (0.1).
    implicit_contacts : int
        With more contacts than this every increment is implicit (a return mapping): a flat base of a hundred
        table contacts fires hundreds of events per millimetre event by event (40; 0 makes every increment
        implicit).
    max_settle_toggles : int
        A node toggling between stick and slip more often than this within one settle has no rate solution
        there: the settle is finished by an implicit step (3).
    chatter_toggles : int
        A node switching between stick and slip more than this many times within ``chatter_window`` × L of t
        is chattering: the run crosses the spot with one implicit increment (8).
    chatter_window : float
        × L, the window of ``chatter_toggles`` (1e-6).
    crawl_toggles : int
        ... or more than this many times within one increment: a node that sticks and slides again every few
        tens of nanometres crawls through the increment (40; without it the quick tomato at 20 kPa crawled 0.04
        mm in 5,000 events).
    turning_probe : float
        Beyond a turning point of the slip system a candidate sticking node is accepted when t can advance by
        max(this × L, ``turning_probe_rel`` × |t|) from the new state (1e-6).
    turning_probe_rel : float
        Relative part of that probe (1e-3).
    direction_floor : float
        A held force's tangential part shorter than this fraction of the force has no direction, so no slip
        axis (1e-12).
    response_cache : int
        Contact responses (one per contact set) a tracker keeps, the oldest dropped first (16).
    response_cache_bytes : int
        ... and at most this many bytes of them (256 MiB: each holds dense (3m+6)² matrices; 16 responses of 600
        contacts took 1.3 GB at 100k vertices).
    zero_field_cache : int
        Gravity's own fields (contacts held at zero) kept per tracker for states below full load (16: the lift
        test's hanging weights revisit a few contact sets).
    latest_fields : int
        Full-gravity fields of the latest contact displacements kept per tracker (4: a lift-test weight and the
        implicit step's last round reuse them).
    compiled_trials : bool or None
        Trial states assembled, solved and read out by the compiled kernels (True) or by the numpy reference
        path (False, :class:`~fem_grasp.contact.slip_system.MixedSlipSystem`); None: compiled where numba is
        installed.  The two differ by round-off only.
    prefetch_nodes : int
        Nodes whose compliance columns are solved for together when a new contact needs its own (30: at 31k
        vertices a column costs 10.7 ms in batches of 90, 12.2 in batches of 30, 40 for one node's three).
    solve_ahead : bool
        While the squeeze and the lift of a body of 2,000 vertices or more are tracked, the columns of the next
        likely contacts are solved in a background thread on the other core (True;
        :meth:`~fem_grasp.elastic.compliance.Compliance.solve_ahead`, with a CHOLMOD library whose solves release
        the GIL).  The same answers either way, to round-off (the
        columns are solved in other batches, on one BLAS thread).  A placement search's candidates use False
        (their workers fill the cores).
    neighbour_updates : bool
        A tracker (and the rest on a frictionless table) derives a new contact set's response from a cached
        neighbouring set's by rank-3 updates (True) instead of factorising every set afresh (False, the
        reference; the same answers to round-off).
    drift_sweeps : int
        Return mapping (:func:`~fem_grasp.contact.relaxation.relax_contacts`): sweeps of unchanged statuses over
        which a steady drift, whose motion still to come at its rate of decay would carry a contact past the
        slip bound, is gross slip (300).
    drift_slip : float
        ... once some contact has moved this fraction of the slip bound (0.01; also the threshold of
        ``growth_sweeps``).
    drift_decay : float
        ... and the motion per sweep has not fallen below this fraction of its value ``drift_sweeps`` sweeps
        before (0.5).
    growth_sweeps : int
        A motion per sweep that has decayed over neither half of this many sweeps (whatever the statuses did) is
        gross slip: the sweeps of a problem with no static state drift or grow, those of one with a static state
        contract, after a transient bump on an ill-conditioned body (20; replayed on 2,200 return mappings of
        the shipped scenes, the graded tomato and the 10k orange, no outcome changed and failures ended 2–5×
        sooner than at the slip bound).
    stuck_sweeps : int
        Consecutive sweeps in which some contact has no local solution before the relaxation gives up (50).
    stall_sweeps : int
        Sweeps without halving the largest force change (statuses that keep cycling) before it gives up (1000).
    polish_iterations : int
        Newton iterations of one polish of the return mapping's smooth system (30).
    polish_halvings : int
        Halvings of a polish Newton step (down to 1/16) before the polish gives up and the sweeps go on (4).
    chord_contraction : float
        A polish reuses its Jacobian's LU factors (a chord step, O(n²)) while a full step still cuts the residual
        to this fraction of its norm; a slower step factorises a new Jacobian (0.25).
    single_precision_factors : bool
        The polish factorises its Jacobians in single precision (half the time at the 1,100–1,600 unknowns of a
        fine patch) and refines each new Newton step once against the Jacobian in double precision; Jacobians too
        ill-conditioned for that are factorised in double precision (True; False: always double precision).  The
        residual, its tolerance and the root are double precision's either way.
    compiled_polish : bool or None
        The polish runs as one compiled kernel (True) or as its numpy reference (False); None: compiled where
        numba is installed.  The two differ by round-off only.
    polish_adoptions : int
        Times per return mapping that the sweeps go on from a polish that converged to a state where some status
        does not hold (a sticking contact just outside its cone, say), rather than from where they were: the
        sweeps then put the few wrong statuses right and the next polish usually holds (4; 0: a polish whose
        statuses do not hold is discarded).
    load_halvings : int
        Lift test (:mod:`~fem_grasp.grasp.lift_test`): halvings of a load step with no static state before the
        weight counts as not held (3, steps down to h/8: they resolve the load path near the weight a finger lets
        go; with none, 6 of the tomato's 64 search placements lift one or two squeeze increments later, 4 of
        them by more than one: ``python -m bench.tracker --against settings.load_halvings=0 --search tomato``).
    parallel_lift_tests : bool
        A squeeze whose first lift test is at a given depth (the accuracy loop's finer levels) tests the end of the
        sub-increment below it too, for the case the first passes, and each end of the walk down from a passing first
        test the one below it (:class:`~fem_grasp.grasp.lift_test.SpeculativeTest`): beside it in a second thread
        (True, where numba compiles the kernels, which release the GIL) or after it in the same thread (False); the
        same numbers either way.  A placement search's candidates use False (their workers fill the cores:
        :data:`~fem_grasp.grasp.evaluation.SEARCH_SETTINGS`).
    """

    # events A-D (contact.event_location)
    tol_penetration: float = 1e-10
    tol_tensile: float = 1e-11
    tol_cone: float = 1e-9
    tol_force_floor: float = 1e-7
    tol_rate: float = 1e-9
    stick_hysteresis: float = 0.1
    tol_locate: float = 1e-10
    # stepping and its fallbacks (contact.tracking, contact.implicit_step)
    increment_halvings: int = 2
    min_step: float = 1e-9
    max_slip: float = 0.1
    implicit_contacts: int = 40
    max_settle_toggles: int = 3
    chatter_toggles: int = 8
    chatter_window: float = 1e-6
    crawl_toggles: int = 40
    turning_probe: float = 1e-6
    turning_probe_rel: float = 1e-3
    direction_floor: float = 1e-12
    # caches of a tracker
    response_cache: int = 16
    response_cache_bytes: int = 256 * 2**20
    zero_field_cache: int = 16
    latest_fields: int = 4
    # paths
    compiled_trials: bool | None = None
    prefetch_nodes: int = 30
    solve_ahead: bool = True
    neighbour_updates: bool = True
    # the return mapping (contact.relaxation)
    drift_sweeps: int = 300
    drift_slip: float = 0.01
    drift_decay: float = 0.5
    growth_sweeps: int = 20
    stuck_sweeps: int = 50
    stall_sweeps: int = 1000
    polish_iterations: int = 30
    polish_halvings: int = 4
    chord_contraction: float = 0.25
    single_precision_factors: bool = True
    compiled_polish: bool | None = None
    polish_adoptions: int = 4
    # the lift test (grasp.lift_test)
    load_halvings: int = 3
    parallel_lift_tests: bool = True

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            kind, _, rest = str(f.type).partition("|")  # the annotation says the kind: "int", "float", "bool | None"
            kind, optional = kind.strip(), "None" in rest
            if kind == "bool":
                ok = isinstance(value, bool) or (value is None and optional)
                want = "True or False" + (" or None" if optional else "")
            elif kind == "int":
                ok = isinstance(value, int) and not isinstance(value, bool) and value >= 0
                want = "a whole number ≥ 0"
            else:
                ok = isinstance(value, (int, float)) and not isinstance(value, bool) and value >= 0 and value == value
                want = "a number ≥ 0"
            if not ok:
                raise ValueError(f"engine setting {f.name} must be {want}, got {value!r}")

    def replace(self, **changes: Any) -> EngineSettings:
        """A copy with ``changes`` (field=value); unknown names are refused as by :meth:`from_overrides`."""
        return self.from_overrides(changes, base=self)

    @classmethod
    def from_overrides(cls, overrides: Mapping[str, Any], base: EngineSettings | None = None) -> EngineSettings:
        """``base`` (default: the defaults) with the fields named in ``overrides`` changed.

        Raises
        ------
        ValueError
            Naming each unknown field, with the nearest known name where one is close, or a value of the wrong
            kind.
        """
        check_names(overrides, [f.name for f in fields(cls)], "engine setting", "settings")
        return dataclasses.replace(cls() if base is None else base, **dict(overrides))

    def changed(self) -> dict[str, Any]:
        """The fields that differ from the defaults, by name (for logs and benchmark labels)."""
        default = EngineSettings()
        return {f.name: getattr(self, f.name) for f in fields(self) if getattr(self, f.name) != getattr(default, f.name)}



#: The engine's defaults (what a :class:`~fem_grasp.contact.tracking.Tracker` built without settings uses).
DEFAULT_SETTINGS = EngineSettings()
