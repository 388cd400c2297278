"""Event-driven quasi-static contact tracking (paper §III-C, events A–D, eqs. 5–8).

The squeeze, the lift and (with the load as parameter) the lift test are all
the same computation: a parameter t (squeeze depth ρ, lift height, …) moves
the two fingertips ℱ₁, ℱ₂ with constant velocities v₁, v₂ (per unit t) while
the contact configuration — which nodes touch ℱ₁, ℱ₂ and the table 𝒫 (the
index sets 𝕀, 𝕁, 𝕂) and which of them slide (ℙ) — stays fixed between
*events*:

* **A** contact establishment: a free surface node would penetrate ℱ₁, ℱ₂ or 𝒫;
* **B** contact break: the normal force at a contact becomes tensile;
* **C** stick-to-slip: the force at a sticking contact leaves its friction cone;
* **D** slip-to-stick: the slip rate d(slip)/dt of a sliding contact reaches zero.

Within one configuration the contact forces are affine in the contact
displacements, F̄ = C Δ̄ + λ F̄₀ (eq. 5, :class:`~fem_grasp.elastic.response.ContactResponse`,
λ the gravity load factor), so one increment t → t + Δt is:

1. *held* prediction: every finger contact moves with its finger by Δt v_f
   (the sliding ones too, before they slip), table contacts stay;
2. every sliding node slides back onto its cone: a table node by −d_k t̂_k in
   the plane (eq. 6), a finger node on the great circle of its fingertip,
   q_k = O + c_k r_k + s_k (N̂_k × r_k) with c_k² + s_k² = 1 (eqs. 7–8), r_k
   the node's position relative to the centre O before the increment; the
   coupled quadratic system (:class:`MixedSlipSystem`) is solved by Newton's
   method from the held state, then from the root already found for the
   same base state at the nearest parameter (continuation in t: the event
   location below solves the same system at many nearby t), with the
   Newton-homotopy continuation of :mod:`fem_grasp.contact.homotopy` (paper
   footnote 2) as fallback on an increment's first trial (a halved increment
   and the event location's trials try Newton alone).  The warm start took
   the football's lift from 24 s to 6 s (756 homotopy paths to 24).

The event tests are evaluated at the end of every increment; when one fires, the event's t is located
and the configuration is updated there (:mod:`~fem_grasp.contact.event_location`, with the event
tolerances).  Where the rate problem has no solution — a friction limit, chatter, a large contact set —
the increment is a return mapping instead (:mod:`~fem_grasp.contact.implicit_step`).  The records the
tracking reads and writes (:class:`ContactState`, :class:`ContactEvent`, :class:`Parameter`) are
:mod:`~fem_grasp.contact.states`.

Compiled trials
---------------
A trial state is ~6 numpy-sized steps on arrays of tens of contacts: the
held prediction, the slip system's assembly, Newton's method (the homotopy
where it fails), the read-out of forces, slips and rates, and the event
functions.  Where numba is installed (``EngineSettings.compiled_trials``) each is one
kernel call (:mod:`~fem_grasp.contact.kernels.slip_trial`,
:mod:`~fem_grasp.contact.kernels.events`, :class:`CompiledSlipSystem`);
the numpy versions (:class:`MixedSlipSystem`, :meth:`Tracker._held_prediction`,
the body of :meth:`Tracker.event_values`) are the reference path
(``compiled_trials=False``, or ``Tracker.compiled = False``), which the tests compare with it.  The two
differ by round-off, so a pickup that sits on a knife edge can take the other
branch: on the tomato a table node released in the lift penetrates the table
by 0.98e-10 or 1.005e-10 diameters (the A test's tolerance is 1e-10),
depending on where in its 1e-10 bracket the release was located, and
re-touches and is released again at the same height on one path only.

Modelling choices (the paper is silent or vague here)
-----------------------------------------------------
* **Slip directions are re-anchored every increment**: the great circle
  (axis N̂_k ∝ n̂_k × f_k⊥) and the table direction t̂_k are taken from the
  held (trial) force of each increment — the paper's "force out of the
  cone", as in a return mapping — not frozen for the whole period between
  two events.  With small increments this follows Coulomb's law
  (friction opposite to the slip) as the friction turns, and reduces to the
  paper's rule when it does not.
* **The cone of a sliding finger node uses the normal at its new position**
  q_k, n̂_k = (q_k − O)/R, not the one before the slip, so that the sliding
  contacts lie on their cones exactly (eq. 7 with n̂ evaluated at q_k).
* The slip rate of event D is the derivative of the slip along its
  direction, from the implicit-function theorem on the slip system at the
  current t (exact for the linearised system, no finite differences).
* Fingertips are whole spheres (only the half facing the object is ever
  touched) and contact is node-to-surface, as in the paper.
* A node that touches a second obstacle while in contact with another (e.g.
  pinched between a finger and the table) is not modelled: tracking stops
  with :class:`TrackingError`.
"""

from __future__ import annotations

import logging
from typing import Callable, Sequence

import numpy as np

from ..elastic.body import Body
from ..elastic.response import ContactResponse, contact_response
from ..errors import CollinearContactError, TrackingError
from ..settings import DEFAULT_SETTINGS, EngineSettings
from ..threads import one_blas_thread
from .event_location import EventLocation
from .implicit_step import ImplicitStep
from .kernels import events, jit, slip_trial
from .kernels.jit import sample_contacts, warm_up_sample
from .obstacles import FINGER1, FINGER2, OBSTACLES, TABLE, Fingertip, TablePlane, sphere_normals
from .slip_system import NEWTON_MAX_ITER, NEWTON_TOL, CompiledSlipSystem, MixedSlipSystem, SlipFailure
from .states import ContactEvent, ContactState, Parameter
from .states import Trial as _Trial
from .states import contact_set_key as _key
from .states import where as _where  # noqa: F401 - the name the tests and tools know

__all__ = ["COMPILED_TRIALS", "CRAWL_TOGGLES", "FINGER1", "FINGER2", "OBSTACLES", "TABLE", "TOL_LOCATE", "ContactEvent",
           "ContactState", "EngineSettings", "MixedSlipSystem", "Parameter", "SlipFailure", "Tracker", "TrackingError",
           "run"]

log = logging.getLogger(__name__)

# The engine's knobs are fields of :class:`~fem_grasp.settings.EngineSettings`, read from ``Tracker.settings``.
# These names are aliases of three defaults, for the readers that know them from here; setting them changes
# nothing.
#: Default events location tolerance, × diameter (``EngineSettings.tol_locate``).
TOL_LOCATE = DEFAULT_SETTINGS.tol_locate
#: Default stick/slip switches of one node within one increment before it is crossed implicitly
#: (``EngineSettings.crawl_toggles``).
CRAWL_TOGGLES = DEFAULT_SETTINGS.crawl_toggles
#: Whether a tracker with the default settings uses the compiled trials (numba installed;
#: ``EngineSettings.compiled_trials``).
COMPILED_TRIALS = jit.ENABLED if DEFAULT_SETTINGS.compiled_trials is None else DEFAULT_SETTINGS.compiled_trials
#: The squeeze's and the lift's tracker queues the columns of the surface nodes that would touch an obstacle
#: within this many more calls of :meth:`Tracker.prefetch_columns` at the rate their gaps closed since the last.
AHEAD_CALLS = 3.0
#: A pickup solves columns ahead (``EngineSettings.solve_ahead``) on bodies of at least this many vertices: below,
#: a batch of columns costs milliseconds, and ranking the surface at every new contact cost the shipped scenes'
#: one-run pickups 4 % (0.47 against 0.49 s, the tomato).
AHEAD_MIN_VERTICES = 2000


class Tracker(EventLocation, ImplicitStep):
    """Event-driven tracking of the contact configuration as the fingers move (module notes).

    The event tests and their location are :class:`~fem_grasp.contact.event_location.EventLocation`'s methods,
    the implicit increment :class:`~fem_grasp.contact.implicit_step.ImplicitStep`'s.

    Parameters
    ----------
    body : Body
        The posed body (reference positions in the table frame, gravity −z).
    radius : fingertip radius R, metres
    mu_finger, mu_table : friction coefficients μ_ℱ, μ_𝒫 (> 0)
    table : TablePlane or None
        The supporting plane (None: no table, the object hangs from the fingers).
    backend : "sparse" or "spectral" (see :class:`~fem_grasp.elastic.response.ContactResponse`)
    settings : EngineSettings, optional
        The tolerances, limits, caches and paths of the tracking (:class:`~fem_grasp.settings.EngineSettings`);
        default :attr:`default_settings`, the engine's defaults.
    """

    #: The settings of a tracker built without any: the engine's defaults (:data:`~fem_grasp.settings.DEFAULT_SETTINGS`).
    #: ``bench.tracker --against settings.FIELD=VALUE`` replaces it in its worker process, so that every pickup there
    #: runs with the changed field; library code passes ``settings`` instead.
    default_settings: EngineSettings = DEFAULT_SETTINGS

    def __init__(self, body: Body, *, radius: float, mu_finger: float, mu_table: float,
                 table: TablePlane | None, backend: str = "sparse", settings: EngineSettings | None = None) -> None:
        if not (mu_finger > 0 and mu_table > 0):
            raise ValueError("event tracking needs positive friction coefficients (μ = 0 has no slip direction)")
        if settings is not None and not isinstance(settings, EngineSettings):
            raise TypeError(f"settings must be an EngineSettings, got {type(settings).__name__}")
        #: The engine's knobs this tracker reads (immutable; :class:`~fem_grasp.settings.EngineSettings`).
        self.settings: EngineSettings = self.default_settings if settings is None else settings
        self.body = body
        self.radius = float(radius)
        self.mu = np.array([mu_finger, mu_finger, mu_table], dtype=float)
        self.table = table
        self.backend = backend
        self.points = body.mesh.points
        self.surface = body.mesh.surface_nodes
        self.surface_index = body.mesh.surface_index  # each node's position in ``surface`` (−1: interior)
        self.surface_points = body.mesh.surface_points  # their reference positions
        self.diameter = body.mesh.diameter
        # A writable copy: the table's own is read-only, and numba compiles a kernel again for a read-only array
        # (the warm-up's samples are writable), so a pickup would pay a second compilation.
        self.up = np.array(table.up if table is not None else [0.0, 0.0, 1.0], dtype=float)
        self._responses: dict[tuple[int, ...], ContactResponse] = {}
        self._zero_fields: dict[tuple[int, ...], np.ndarray] = {}
        self._zero_surface_fields: dict[tuple[int, ...], np.ndarray] = {}
        self._latest_full: dict[tuple, np.ndarray] = {}
        self._ahead_gaps: np.ndarray | None = None  # the gaps at the last prefetch_columns (solve_ahead's rates)
        self.solves = 0
        #: The slip systems are assembled, solved and read out by compiled kernels (:class:`CompiledSlipSystem`);
        #: False: by :class:`MixedSlipSystem` (numpy; the reference path the tests compare with).
        self.compiled = jit.ENABLED if self.settings.compiled_trials is None else self.settings.compiled_trials
        #: Slip forms tried in order: False = great circle (the paper's), True = free direction.
        self.forms: tuple[bool, ...] = (False, True)
        #: The last increment was implicit (the next one tries the rate problem with Newton only).
        self.implicit = False
        #: Slip roots found from the latest base state and motion, per form: (dt, x) (warm starts for nearby dt).
        self._warm_key: tuple | None = None
        self._warm: dict[bool, list[tuple[float, np.ndarray]]] = {}
        #: For one base state and motion, the smallest dt at which Newton found no root, per form.
        self._fail_key: tuple | None = None
        self._newton_fails: dict[bool, float] = {}
        #: The trial whose state the latest advance or settle returned: the zero increment of the next advance
        #: from that state (its event values, rates), which need not be solved again.
        self._returned: _Trial | None = None

    def branch(self) -> "Tracker":
        """A tracker of the same body, obstacles and settings, starting from copies of this one's caches (contact
        responses, fields; its body's :meth:`~fem_grasp.elastic.body.Body.branch`): for a second thread, whose
        numbers do not depend on what this one computes meanwhile."""
        twin = Tracker(self.body.branch(), radius=self.radius, mu_finger=float(self.mu[FINGER1]),
                       mu_table=float(self.mu[TABLE]), table=self.table, backend=self.backend, settings=self.settings)
        twin._responses = {k: r.branch(twin.body) for k, r in self._responses.items()}
        twin._zero_fields, twin._zero_surface_fields = dict(self._zero_fields), dict(self._zero_surface_fields)
        twin._latest_full = dict(self._latest_full)
        return twin

    # ------------------------------------------------------------ responses
    def response(self, nodes: np.ndarray) -> ContactResponse:
        key = _key(nodes)
        resp = self._responses.get(key)
        if resp is None:
            # Derived from the cached set nearest in nodes where that pays (a node or two joined or left).
            cached = self._responses.values() if self.settings.neighbour_updates else ()
            try:
                resp = contact_response(self.body, np.asarray(key, dtype=np.int64), backend=self.backend,
                                        cached=cached)
            except CollinearContactError as exc:
                raise TrackingError(f"the object is no longer held: {exc}") from None
            self._responses[key] = resp
            while len(self._responses) > 1 and (
                    len(self._responses) > self.settings.response_cache
                    or sum(r.nbytes for r in self._responses.values()) > self.settings.response_cache_bytes):
                self._responses.pop(next(iter(self._responses)))  # the oldest
        return resp

    def prefetch_columns(self, nodes: Sequence[int], surface_positions: np.ndarray, centers: np.ndarray) -> None:
        """With the sparse backend, when new contact ``nodes`` lack their compliance columns, compute them
        together with those of the uncached surface nodes nearest an obstacle (the likely next contacts):
        ``settings.prefetch_nodes`` in one solve (a new contact's own three columns alone cost
        several times more per column).  Inside a :meth:`~fem_grasp.elastic.compliance.Compliance.solving_ahead`
        section the tracker with the table also queues the nodes that would touch next, at the rate the gaps
        closed since its last call, for the background thread
        (:meth:`~fem_grasp.elastic.compliance.Compliance.solve_ahead`)."""
        comp = self.body.compliance if self.backend == "sparse" else None
        if comp is None:
            return
        missing = not all(comp.is_cached(k) for k in nodes)
        # The tracker with the table (squeeze, lift) queues the next likely contacts' columns for the other core
        # while its compliance is in a solving_ahead section (the pickup decides where); the lift test's two
        # trackers fill both cores.
        ahead = self.table is not None and comp.solving_ahead_now
        if not (missing or ahead):
            return
        gaps = self.obstacle_gaps(surface_positions, centers)
        if missing:
            comp.prefetch(np.asarray(nodes, dtype=np.int64),
                          likely=self.surface[np.argsort(gaps.min(axis=1), kind="stable")],
                          count=self.settings.prefetch_nodes)
        if ahead:
            # Ranked by when each node would touch at the rate its gaps closed since the last call (in calls,
            # about one increment each): the nodes near the static table that stay clear of it are not queued.
            before, self._ahead_gaps = self._ahead_gaps, gaps
            if before is not None and before.shape == gaps.shape:
                closing = before - gaps
                with np.errstate(divide="ignore", invalid="ignore"):
                    calls = np.where(closing > 0, gaps / closing, np.inf).min(axis=1)
                order = np.argsort(calls, kind="stable")
                order = order[calls[order] <= AHEAD_CALLS]
                comp.solve_ahead(self.surface[order], self.settings.prefetch_nodes)

    def field(self, nodes: np.ndarray, disp: np.ndarray, load: float) -> np.ndarray:
        """(n, 3) displacement field for prescribed contact displacements at gravity factor λ (eq. 4)."""
        return self._at_load(nodes, disp, load, lambda r, d: r.solve(d).displacements, self._zero_fields)

    def surface_field(self, nodes: np.ndarray, disp: np.ndarray, load: float) -> np.ndarray:
        """(s, 3) :meth:`field` at the surface nodes only (what the event functions and gaps need)."""
        return self._at_load(nodes, disp, load, lambda r, d: r.surface_displacements(d), self._zero_surface_fields)

    def _at_load(self, nodes: np.ndarray, disp: np.ndarray, load: float, solve: Callable,
                 zero_fields: dict) -> np.ndarray:
        """solve(response, disp) at gravity factor λ: the full-gravity solution less (1 − λ) times gravity's
        own (contacts held at zero), the latter cached per contact set."""
        key = _key(nodes)
        # The lift test's ramp asks again for the field of the contact displacements it has just settled (at
        # the next weight) and an implicit step for the field of its last round: the full-gravity solution
        # of the latest displacements is kept (the same numbers as a re-solve).
        memo = (id(zero_fields), key, np.asarray(disp, float).tobytes())
        full = self._latest_full.get(memo)
        if full is None:
            full = solve(self.response(nodes), disp)
            full.setflags(write=False)
            self._latest_full[memo] = full
            while len(self._latest_full) > self.settings.latest_fields:
                self._latest_full.pop(next(iter(self._latest_full)))
        if load == 1.0:
            return full
        zero = zero_fields.get(key)
        if zero is None:
            zero = solve(self.response(nodes), np.zeros_like(disp))
            if len(zero_fields) >= self.settings.zero_field_cache:
                zero_fields.pop(next(iter(zero_fields)))
            zero_fields[key] = zero
        return full - (1.0 - load) * zero

    def _position_source(self, nodes: np.ndarray, disp: np.ndarray, load: float) -> Callable[[], np.ndarray]:
        """The deferred whole-body positions of a state (:attr:`ContactState.positions`)."""
        nodes, disp = np.array(nodes, dtype=np.int64), np.array(disp, float)
        return lambda: self.points + self.field(nodes, disp, load)

    def fingertips(self, centers: np.ndarray) -> tuple[Fingertip, Fingertip]:
        """ℱ₁ and ℱ₂ at ``centers`` (2, 3)."""
        return Fingertip(centers[FINGER1], self.radius), Fingertip(centers[FINGER2], self.radius)

    def obstacles(self, centers: np.ndarray) -> tuple[Fingertip, Fingertip, TablePlane | None]:
        """Every obstacle, indexed by the owner codes (the table is None without one)."""
        return (*self.fingertips(centers), self.table)

    def normals(self, owner: np.ndarray, positions: np.ndarray, centers: np.ndarray) -> np.ndarray:
        """(m, 3) inward normals of contacts at ``positions`` (m, 3): ``up`` on the table, (p − O)/|p − O| on a
        fingertip (:meth:`Fingertip.inward_normals`, without building the obstacles at every trial); compiled
        (:func:`~fem_grasp.contact.kernels.events.contact_normals`) with the tracker's other kernels."""
        if self.compiled:
            return events.contact_normals(np.asarray(owner, dtype=np.int64), np.ascontiguousarray(positions, float),
                                          np.ascontiguousarray(centers, float), self.up, TABLE)
        out = np.empty(positions.shape)
        out[:] = self.up
        for f in (FINGER1, FINGER2):
            on = owner == f
            if on.any():
                out[on] = sphere_normals(positions[on], np.asarray(centers, float)[f])
        return out

    # --------------------------------------------------------------- states
    def make_state(self, *, phase: str, squeeze_depth: float, lift_height: float, load: float,
                   centers: np.ndarray, nodes: np.ndarray, owner: np.ndarray, disp: np.ndarray,
                   sliding: np.ndarray, slip: np.ndarray | None = None) -> ContactState:
        """A state with every contact held at ``disp`` (no slip solve): forces and field from eq. (5), (4)."""
        nodes = np.asarray(nodes, dtype=np.int64)
        resp = self.response(nodes)
        forces = (resp.reduced_stiffness @ np.asarray(disp, float).reshape(-1)).reshape(-1, 3) \
            + load * resp.gravity_forces
        surface = self.surface_points + self.surface_field(nodes, disp, load)
        # A contact node sits exactly at its prescribed position (the field restores it).
        normals = self.normals(np.asarray(owner), self.points[nodes] + np.asarray(disp, float).reshape(-1, 3), centers)
        return ContactState(phase, float(squeeze_depth), float(lift_height), float(load), np.array(centers, float),
                            nodes, np.asarray(owner, dtype=np.int64), np.array(disp, float),
                            np.asarray(sliding, dtype=bool), forces, normals, surface,
                            np.zeros(len(nodes)) if slip is None else np.asarray(slip, float),
                            self._position_source(nodes, disp, load))

    def trial(self, base: ContactState, dt: float, velocities: np.ndarray, load_rate: float = 0.0,
              param: Parameter = Parameter.SQUEEZE_DEPTH, methods: Sequence[str] = ("newton", "homotopy")) -> _Trial:
        """The state after an increment dt of the parameter with the configuration of ``base`` held fixed.

        Raises :class:`SlipFailure` when the slip system has no admissible root.
        """
        self.solves += 1
        resp = self.response(base.nodes)
        c = resp.reduced_stiffness
        f0 = resp.gravity_forces
        m = base.n_contacts
        centers = base.centers + dt * np.asarray(velocities, float)
        if param == Parameter.LOAD:  # the gravity load factor itself is the parameter
            load_rate = 1.0
        load = base.load + dt * load_rate
        sl = np.flatnonzero(base.sliding)
        kinds = base.owner[sl]
        velocities = np.asarray(velocities, float)
        # Roots are reused only for the same base state moved the same way (not, e.g., a squeeze root for a lift).
        warm_key = (base, param, velocities.tobytes(), float(load_rate))
        if not self._same_motion(warm_key, self._fail_key):
            self._fail_key, self._newton_fails = warm_key, {}
        zero_start = None  # Newton from zero slip on the first form, already run: (form, found, x)
        outcome = None  # the kernel's (forces, contact displacements, normals, slip amounts, slip rates)
        if self.compiled and methods[0] == "newton":
            # The whole trial in one kernel where Newton from zero finds the first form's root (most of them).
            first = self._newton_order(dt)[0]
            (code, disp_h, fh, dfh, t_hat, r, found, x, forces, disp, normals, amounts,
             rates) = slip_trial.newton_trial(
                c, f0, base.disp, base.owner, velocities, float(dt), float(load), float(load_rate), base.forces,
                base.normals, sl, kinds, self.points[base.nodes[sl]], base.centers, self.radius,
                self.settings.direction_floor, self.mu[kinds], self.up, first, NEWTON_TOL, NEWTON_MAX_ITER, self.points[base.nodes], centers, TABLE)
            if code == slip_trial.TRIAL_NO_DIRECTION:
                raise SlipFailure("a sliding contact has no tangential force, so no slip direction")
            if code == slip_trial.TRIAL_NO_ROOT:
                zero_start = (first, found, x)
            else:
                free, outcome = first, (forces, disp, normals, amounts, rates)
        elif self.compiled:
            disp_h, fh, dfh, t_hat, r, has_directions = slip_trial.held_prediction(
                c, f0, base.disp, base.owner, velocities, float(dt), float(load), float(load_rate), base.forces,
                base.normals, sl, kinds, self.points[base.nodes[sl]], base.centers, self.radius,
                self.settings.direction_floor)
            if not has_directions:
                raise SlipFailure("a sliding contact has no tangential force, so no slip direction")
        else:
            disp_h, fh, dfh, t_hat, r = self._held_prediction(base, c, f0, dt, velocities, load, load_rate, sl, kinds)
        if outcome is None:
            free, x, system = self._solve_slip(c, fh, dfh, sl, kinds, t_hat, r, dt, methods, warm_key, zero_start)
        if not self._same_motion(warm_key, self._warm_key):
            self._warm_key, self._warm = warm_key, {}
        self._warm.setdefault(free, []).append((dt, x))
        if outcome is None:
            outcome = self._read_out(system, x, disp_h, sl, m, base, centers)
        forces, disp, normals, amounts, rates = outcome
        if not np.isfinite(rates).all():
            raise SlipFailure("the slip system is singular (a limit of friction is reached)")
        surface = self.surface_points + self.surface_field(base.nodes, disp, load)
        at = {"squeeze_depth": base.squeeze_depth, "lift_height": base.lift_height}
        if param != Parameter.LOAD:
            at[str(param)] = getattr(base, param) + dt
        # The constructor, not dataclasses.replace (~15 µs more per trial state).
        state = ContactState(base.phase, at["squeeze_depth"], at["lift_height"], load, centers, base.nodes, base.owner,
                             disp, base.sliding, forces, normals, surface, base.slip + np.abs(amounts),
                             self._position_source(base.nodes, disp, load))
        return _Trial(state, amounts, rates)

    def _solve_slip(self, c: np.ndarray, fh: np.ndarray, dfh: np.ndarray, sl: np.ndarray, kinds: np.ndarray,
                    t_hat: np.ndarray, r: np.ndarray, dt: float, methods: Sequence[str], warm_key: tuple,
                    zero_start: tuple | None) -> tuple:
        """The slip system's root, form by form and method by method (:meth:`trial`'s order): (form, x, the
        system), whose outcome :meth:`_read_out` reads.  ``zero_start``: Newton from zero slip on the first form
        has been run (by the whole-trial kernel) and found no admissible root."""
        errors = []
        systems = {}
        fails = self._newton_fails
        # Great-circle form (the paper's) first, the free-direction form if it has no root; Newton on
        # both before the (costlier) homotopy continuation on both.
        for method in methods:
            order = self.forms if method != "newton" else self._newton_order(dt)
            for free in order:
                if free not in systems:
                    system_type = CompiledSlipSystem if self.compiled else MixedSlipSystem
                    systems[free] = system_type(c, fh, dfh, sl, kinds, self.mu[kinds], t_hat, r, self.up,
                                                self.radius, free)
                near = None
                if method == "newton" and self._same_motion(warm_key, self._warm_key) and self._warm.get(free):
                    near = min(self._warm[free], key=lambda e: abs(e[0] - dt))[1]
                tried = {}
                if method == "newton" and zero_start is not None and zero_start[0] == free:
                    tried = {"zero_start": zero_start[1:]}
                    zero_start = None
                try:
                    x = systems[free].solve(methods=(method,), start=near, **tried)
                    return free, x, systems[free]
                except SlipFailure as exc:
                    errors.append(str(exc))
                    if method == "newton":
                        fails[free] = min(fails.get(free, np.inf), dt)
        raise SlipFailure("; ".join(errors))

    def _newton_order(self, dt: float) -> list[bool]:
        """The slip forms in the order Newton's method tries them at increment dt: a form whose Newton found no root
        at a smaller dt of the same motion is tried last (its root is lost beyond a turning point, and each failing
        Newton costs ~40 residuals)."""
        return sorted(self.forms, key=lambda fr: dt >= self._newton_fails.get(fr, np.inf))

    def _read_out(self, system: CompiledSlipSystem | MixedSlipSystem, x: np.ndarray, disp_h: np.ndarray,
                  sl: np.ndarray, m: int, base: ContactState, centers: np.ndarray) -> tuple:
        """(forces, contact displacements, normals, slip amounts, slip rates) of a trial at the root x of
        ``system`` (what the whole-trial kernel returns): the amounts and rates 0 where a contact sticks, the rates NaN
        at a friction limit."""
        forces, change, amounts_s, rates_s = system.outcome(x)
        amounts = np.zeros(m)
        rates = np.zeros(m)
        amounts[sl] = amounts_s
        rates[sl] = rates_s
        disp = disp_h + change
        normals = self.normals(base.owner, self.points[base.nodes] + disp, centers)
        return forces, disp, normals, amounts, rates

    def _held_prediction(self, base: ContactState, c: np.ndarray, f0: np.ndarray, dt: float, velocities: np.ndarray,
                         load: float, load_rate: float, sl: np.ndarray, kinds: np.ndarray) -> tuple:
        """Step 1 of an increment in numpy (the reference of :func:`~fem_grasp.contact.kernels.slip_trial.
        held_prediction`): (held displacements, held forces, their rate, slip directions t̂, fingertip r_k)."""
        m = base.n_contacts
        vel = np.zeros((m, 3))
        for f in (FINGER1, FINGER2):
            vel[base.owner == f] = velocities[f]
        disp_h = base.disp + dt * vel
        fh = (c @ disp_h.reshape(-1)).reshape(-1, 3) + load * f0
        dfh = (c @ vel.reshape(-1)).reshape(-1, 3) + load_rate * f0
        n_b = base.normals[sl]
        # Slip directions from the held (trial) force, as in a return mapping; the base force if that has
        # no tangential part.  For a node sliding steadily the two agree to O(dt).
        t_hat = np.zeros((len(sl), 3))
        for src in (base.forces[sl], fh[sl]):
            ft = src - np.einsum("ki,ki->k", src, n_b)[:, None] * n_b
            ftn = np.linalg.norm(ft, axis=1)
            ok = ftn > self.settings.direction_floor * max(float(np.abs(src).max(initial=0.0)), 1e-300)
            t_hat[ok] = ft[ok] / ftn[ok, None]
        if np.any(np.linalg.norm(t_hat, axis=1) == 0):
            raise SlipFailure("a sliding contact has no tangential force, so no slip direction")
        r = np.zeros((len(sl), 3))
        fing = kinds != TABLE
        if fing.any():
            p_b = self.points[base.nodes[sl[fing]]] + base.disp[sl[fing]]
            r[fing] = p_b - base.centers[kinds[fing]]
            r[fing] *= self.radius / np.linalg.norm(r[fing], axis=1, keepdims=True)
        return disp_h, fh, dfh, t_hat, r

    @staticmethod
    def _same_motion(key: tuple, old: tuple | None) -> bool:
        """Whether ``key`` (base state, parameter, velocities, load rate) names the same motion as ``old``;
        the base state by identity."""
        return old is not None and old[0] is key[0] and old[1:] == key[1:]


def run(tracker: Tracker, state: ContactState, velocities: np.ndarray, *, stop: float, step: float,
        param: Parameter = Parameter.SQUEEZE_DEPTH, phase: str | None = None,
        after_step: Callable[[ContactState, list[ContactEvent]], bool] | None = None,
        on_event: Callable[[ContactState, list[ContactEvent]], None] | None = None,
        max_events: int = 5000) -> tuple[ContactState, list[ContactEvent], bool]:
    """Advance ``state`` until the parameter reaches ``stop`` or ``after_step`` returns True.

    ``after_step(state, events)`` is called after every increment (events of
    that increment, possibly none); ``on_event`` after every event.  Returns
    the final state, all events and whether ``after_step`` stopped the run.
    BLAS runs on one thread meanwhile (:func:`one_blas_thread`).
    """
    with one_blas_thread():
        return _run(tracker, state, velocities, stop=stop, step=step, param=param, phase=phase,
                    after_step=after_step, on_event=on_event, max_events=max_events)


def _run(tracker: Tracker, state: ContactState, velocities: np.ndarray, *, stop: float, step: float,
         param: Parameter, phase: str | None, after_step: Callable | None, on_event: Callable | None,
         max_events: int) -> tuple[ContactState, list[ContactEvent], bool]:
    events: list[ContactEvent] = []
    n_events = 0
    toggles: dict[int, list[float]] = {}
    settings = tracker.settings
    window = settings.chatter_window * tracker.diameter
    while getattr(state, param) < stop - 1e-15 * max(1.0, abs(stop)):
        dt = min(step, stop - getattr(state, param))
        state, ev = tracker.advance(state, dt, velocities, param=param, phase=phase)
        if ev:
            events += ev
            n_events += 1
            # A node switching between stick and slip again and again with no progress in the parameter
            # has no consistent rate solution (sticking, its force leaves the cone; sliding, its slip
            # rate is negative).
            now = getattr(state, param)
            chatter = None
            for e in ev:
                if e.kind in "CD":
                    hist = [t for t in toggles.get(e.node, []) if now - t <= step] + [now]
                    toggles[e.node] = hist
                    if (sum(now - t <= window for t in hist) > settings.chatter_toggles
                            or len(hist) > settings.crawl_toggles):
                        chatter = e
            if chatter is not None:
                # Sticking, its force leaves the cone; sliding, its slip rate is negative: the rate problem
                # has no solution here.  Cross it with implicit increments (return mapping) of one step.
                dt = min(step, stop - now)
                state, ev2 = tracker.implicit_step(
                    state, dt, velocities, param=param, phase=phase,
                    why=f"node {chatter.node} ({chatter.contact}) switches between stick and slip")
                events += ev2
                ev = ev + ev2
                toggles.clear()
            if on_event is not None:
                on_event(state, ev)
            if n_events > max_events:
                raise TrackingError(f"more than {max_events} events: the tracking is not progressing")
        if after_step is not None and after_step(state, ev):
            return state, events, True
    return state, events, False



@warm_up_sample
def _compile_the_trial_kernels() -> None:
    """A trial's held prediction, the whole-trial kernel and the event functions (the kernels of
    :mod:`~fem_grasp.contact.kernels.slip_trial` and :mod:`~fem_grasp.contact.kernels.events` that
    :meth:`Tracker.trial` and :meth:`Tracker.event_values` call), on the warm-up's two contacts."""
    s = sample_contacts()
    d = DEFAULT_SETTINGS
    owner = np.array([TABLE, FINGER1])
    sl = np.array([0, 1])
    normals = np.array([s["up"], [0.0, 0.0, 1.0]])
    slip_trial.held_prediction(100.0 * np.eye(6), s["forces"], np.zeros((2, 3)), owner, np.zeros((2, 3)), 0.0, 1.0,
                               0.0, s["forces"], normals, sl, owner[sl], s["positions"],
                               np.array([s["centre"], s["centre"]]), 0.01, d.direction_floor)
    for free in (False, True):
        slip_trial.newton_trial(100.0 * np.eye(6), s["forces"], np.zeros((2, 3)), owner, np.zeros((2, 3)), 0.0, 1.0,
                                0.0, s["forces"], normals, sl, owner[sl], s["positions"],
                                np.array([s["centre"], s["centre"]]), 0.01, d.direction_floor, s["mu"], s["up"], free,
                                NEWTON_TOL, NEWTON_MAX_ITER, s["positions"], np.array([s["centre"], s["centre"]]),
                                TABLE)
    events.contact_normals(owner, s["positions"], np.array([s["centre"], s["centre"]]), s["up"], TABLE)
    for has_table in (True, False):
        events.event_functions(s["positions"], np.array([s["centre"], s["centre"]]), 0.01, has_table, s["up"], 0.0,
                               np.array([0, 1]), owner, s["forces"], normals, np.array([False, True]), np.zeros(2),
                               s["mu"], 1.0, 0.1, d.tol_penetration, d.tol_tensile, d.tol_cone, d.tol_force_floor, d.tol_rate,
                               d.stick_hysteresis)
