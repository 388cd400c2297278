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
   footnote 2) as fallback.  The warm start took the football's lift from
   24 s to 6 s (756 homotopy paths to 24).

The event tests are evaluated at the end of every increment; when one fires,
the event's t is located to ``TOL_LOCATE`` × diameter by interpolation
(inverse quadratic, secant) of the continuous event function predicted to
fire first, safeguarded by Illinois regula falsi on the bracket — the
"Newton polish" of §III-C; about four trials per located event — and the
configuration is updated there.  Several events at the same t (symmetric
bodies give pairs) are applied together, and cascades (a release that makes
a neighbour tensile) are settled at the same t.

Where the rate problem has no solution
--------------------------------------
With μ = 0.3–0.5 and the strong coupling between tangential slip and normal
force of coarse P1 patches, the stick/slip rate problem can have no solution:
a contact leaves its cone when it sticks, yet its slip rate is negative when
it slides, or the slip system of several coupled sliding nodes loses its
root.  The body then reaches a static state by a finite slip.  The tracker
takes that step as a return mapping (:meth:`Tracker.implicit_step`):
every contact held, then the static stick / slide / release state of all of
them at once (:func:`fem_grasp.contact.relaxation.relax_contacts`), with new
contacts added as they appear.  This is used (i) when a settle after events
finds no slip solution or a node toggles more than three times, (ii) when an
increment's slip system still fails after ``INCREMENT_HALVINGS`` halvings (the
increment is then taken implicitly, and the next one tries Newton alone), and (iii) when a node chatters between stick and slip
without progress in the parameter (one implicit increment of ``step``).
Events inside an implicit increment are recorded at its end.

Large contact sets: (iv) with more than ``IMPLICIT_CONTACTS`` contacts
every increment is implicit.  Event by event, each event costs a slip solve
of size |ℙ|; a flat base of 100–200 table contacts (the steam bun) fires
hundreds of events per millimetre of squeeze — most of them rim nodes
toggling between A and B at one ρ — and the slip systems of a hundred
sliding table nodes defeat Newton's method, so the homotopy runs: 15
minutes for 3 mm of the steam bun's squeeze, against 45 s implicitly; the
quick bun (45 table contacts) took 156 s event by event and 5 s implicitly
for its whole 2 cm squeeze, to the same final state.  The price is that
events are located only to the increment.  Only if no
static state exists either (gross slip) does the tracking stop with
:class:`TrackingError`.  The lift test's hanging settles use the same
return mapping (:mod:`fem_grasp.grasp.lift_test`).

Compiled trials
---------------
A trial state is ~6 numpy-sized steps on arrays of tens of contacts: the
held prediction, the slip system's assembly, Newton's method (the homotopy
where it fails), the read-out of forces, slips and rates, and the event
functions.  Where numba is installed (:data:`COMPILED_TRIALS`) each is one
kernel call (:mod:`~fem_grasp.contact.kernels.slip_trial`,
:mod:`~fem_grasp.contact.kernels.events`, :class:`CompiledSlipSystem`);
the numpy versions (:class:`MixedSlipSystem`, :meth:`Tracker._held_prediction`,
the body of :meth:`Tracker.event_values`) are the reference path
(``Tracker.compiled = False``), which the tests compare with it.  The two
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

Tolerances
----------
With F_s = mg + max |f_k| (the force scale of the state) and L the mesh
diameter, an event fires when a free node is deeper than ``1e-10 L``
(A), a normal force is below ``−1e-11 F_s`` (B), a sticking contact has
``|f_t| − μ f·n̂ > 1e-9 f·n̂ + 1e-7 F_s`` (C; contacts carrying almost no
force are exempt), or a slip rate is below −1e-9 (D).  A sliding contact whose normal force
falls below a tenth of the force floor, ``1e-8 F_s``, also sticks (recorded
as D): near the apex of its cone its slip is poorly resolved (the factor ten
is a hysteresis that keeps a lightly loaded node from chattering between C
and D).  Event
parameters are located to ``1e-10 L`` in t (well inside the 1e-9 L geometric checks; 1e-13 cost
3× the time for the same events).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace
from enum import Enum
from functools import cached_property
from typing import Any, Callable, Sequence

import numpy as np

from ..elastic.body import Body
from ..elastic.compliance import PREFETCH_NODES
from ..elastic.response import ContactResponse, check_contact_set, contact_response
from ..errors import CollinearContactError, RelaxationFailure, TrackingError
from ..threads import one_blas_thread
from .kernels import events, jit, slip_trial
from .kernels.jit import sample_contacts, warm_up_sample
from .obstacles import FINGER1, FINGER2, OBSTACLES, TABLE, Fingertip, TablePlane
from .relaxation import RELEASE, SLIDE, STICK, relax_contacts
from .slip_system import NEWTON_MAX_ITER, NEWTON_TOL, CompiledSlipSystem, MixedSlipSystem, SlipFailure

__all__ = ["FINGER1", "FINGER2", "OBSTACLES", "TABLE", "ContactEvent", "ContactState", "MixedSlipSystem", "Parameter",
           "SlipFailure", "Tracker", "TrackingError", "run"]

log = logging.getLogger(__name__)

#: Event thresholds (see module notes).
TOL_PENETRATION = 1e-10  # × diameter
TOL_TENSILE = 1e-11  # × force scale
TOL_CONE = 1e-9  # × f·n̂
TOL_FORCE_FLOOR = 1e-7  # × force scale: contacts carrying less are 'just touching'
TOL_RATE = 1e-9  # slip per unit parameter
#: Event localisation tolerance in t, × diameter.
TOL_LOCATE = 1e-10
#: Failed halvings of an increment before it is taken as one implicit step (:meth:`Tracker.implicit_step`).
INCREMENT_HALVINGS = 2
#: A contact sliding further than this × diameter in one implicit step is gross slip.
MAX_SLIP = 0.1
#: With more contacts than this, increments are taken implicitly (module notes, "Large contact sets").
IMPLICIT_CONTACTS = 40
#: A tracker keeps the contact responses of its latest contact sets, at most this many and this many bytes
#: (each holds dense (3m+6)² matrices: 16 responses of 600 contacts took 1.3 GB at 100k vertices).
RESPONSE_CACHE = 16
RESPONSE_CACHE_BYTES = 256 * 2**20
#: Gravity's own fields (contacts held at zero) kept per tracker for states below full load (the lift test's
#: hanging weights revisit a few contact sets).
ZERO_FIELD_CACHE = 16
#: Trackers assemble, solve and read out their slip systems with compiled kernels (:class:`CompiledSlipSystem`)
#: where numba is installed; False: with :class:`MixedSlipSystem` (numpy), the reference path the tests compare.
COMPILED_TRIALS = jit.ENABLED
#: Full-gravity fields of the latest contact displacements kept per tracker (whole body and surface; see
#: ``Tracker._at_load``): a lift-test weight and the implicit step's last round reuse them.
LATEST_FIELDS = 4
#: A sliding contact whose normal force falls below this fraction of the force floor sticks (event D): the
#: factor ten below the floor of event C is a hysteresis against C/D chatter of lightly loaded nodes.
STICK_HYSTERESIS = 0.1
#: A node toggling between stick and slip more often than this within one settle has no rate solution there
#: (a friction limit): the settle is finished by an implicit step.
MAX_SETTLE_TOGGLES = 3
#: A node switching between stick and slip more than this many times within ``CHATTER_WINDOW`` × diameter of
#: the parameter is chattering: the run crosses the spot with one implicit increment.
CHATTER_TOGGLES = 8
CHATTER_WINDOW = 1e-6
#: ... or more than this many times within one increment ``step``: a node that sticks and slides again at every
#: few tens of nanometres crawls through the increment (the quick tomato at 20 kPa: node 118 toggled 2,000 times
#: between ρ = 13.737 and 13.777 mm, 40 nm apart, until the run gave up after 5,000 events).
CRAWL_TOGGLES = 40
#: Beyond a turning point of the slip system, a candidate sticking node is accepted when the parameter can
#: advance by max(``TURNING_PROBE`` × diameter, ``TURNING_PROBE_REL`` × |t|) from the new state.
TURNING_PROBE = 1e-6
TURNING_PROBE_REL = 1e-3
#: Smallest increment of the parameter, × diameter, before the halvings of a failing slip solve give up.
MIN_STEP = 1e-9
#: A held force's tangential part shorter than this fraction of the force has no direction (no slip axis).
DIRECTION_FLOOR = 1e-12


class Parameter(str, Enum):
    """What the tracked parameter t is: the attribute of :class:`ContactState` it moves.

    The squeeze (§III-C) moves the fingers with ρ, the lift with the lift height, and the resting
    iteration and the lift test's hanging settles raise the gravity load factor λ.
    """

    SQUEEZE_DEPTH = "squeeze_depth"
    LIFT_HEIGHT = "lift_height"
    LOAD = "load"

    __str__ = str.__str__  # messages and getattr read the attribute name
    __format__ = str.__format__


def _where(param: "Parameter | str", state: Any) -> str:
    """Where the tracking is, for messages, in millimetres: "ρ = 12.35 mm", "lift height 3.2 mm", "load λ = 0.5"."""
    value = float(getattr(state, str(param)))
    if str(param) == "squeeze_depth":
        return f"ρ = {1e3 * value:.6g} mm"
    if str(param) == "lift_height":
        return f"lift height {1e3 * value:.6g} mm"
    return f"gravity load λ = {value:.6g}"


def _key(nodes: np.ndarray) -> tuple[int, ...]:
    """A contact set's key in the tracker's caches: its node indices, in order."""
    return tuple(np.asarray(nodes).tolist())


# ======================================================================= state
@dataclass(frozen=True)
class ContactState:
    """The object's contact configuration and deformation at one parameter value.

    Attributes
    ----------
    phase : "squeeze", "lift" or "rest"
    squeeze_depth : ρ, metres
    lift_height : upward finger translation, metres
    load : gravity load factor λ (1: the real weight)
    centers : (2, 3) fingertip centres O₁, O₂
    nodes : (m,) contact nodes (𝕀 ∪ 𝕁 ∪ 𝕂)
    owner : (m,) 0 (finger 1), 1 (finger 2) or 2 (table) for each contact
    disp : (m, 3) prescribed contact displacements Δ̄
    sliding : (m,) whether each contact slides (ℙ)
    forces : (m, 3) contact forces on the object, newtons
    normals : (m, 3) inward unit normals n̂ at the contacts
    surface_positions : (s, 3) deformed positions p̃ of the surface nodes (``mesh.surface_nodes``)
    slip : (m,) slip accumulated by each contact since it was established, metres
    position_source : computes the (n, 3) deformed positions of every node (:attr:`ContactState.positions`)
    """

    phase: str
    squeeze_depth: float
    lift_height: float
    load: float
    centers: np.ndarray
    nodes: np.ndarray
    owner: np.ndarray
    disp: np.ndarray
    sliding: np.ndarray
    forces: np.ndarray
    normals: np.ndarray
    surface_positions: np.ndarray
    slip: np.ndarray
    position_source: Callable[[], np.ndarray] = field(repr=False, compare=False)

    @cached_property
    def positions(self) -> np.ndarray:
        """(n, 3) deformed node positions p̃, computed at first use: the tracking itself reads only the
        surface, and on a large mesh the whole field costs several times more."""
        return self.position_source()

    @property
    def n_contacts(self) -> int:
        return len(self.nodes)

    def on(self, owner: int) -> np.ndarray:
        """Boolean mask of the contacts on one obstacle (FINGER1, FINGER2 or TABLE)."""
        return self.owner == owner

    @property
    def normal_forces(self) -> np.ndarray:
        """(m,) f·n̂ at each contact."""
        return np.einsum("ki,ki->k", self.forces, self.normals)

    @property
    def tangential_forces(self) -> np.ndarray:
        """(m,) |f − (f·n̂)n̂| at each contact."""
        return np.linalg.norm(self.forces - self.normal_forces[:, None] * self.normals, axis=1)


@dataclass(frozen=True)
class ContactEvent:
    """One event of the tracking (paper §III-C).

    Attributes
    ----------
    phase : "squeeze" or "lift"
    kind : "A", "B", "C" or "D"
    node : mesh node index
    contact : "finger1", "finger2" or "table"
    squeeze_depth, lift_height : where it happened, metres
    """

    phase: str
    kind: str
    node: int
    contact: str
    squeeze_depth: float
    lift_height: float

    def to_dict(self) -> dict:
        return {"phase": self.phase, "kind": self.kind, "node": int(self.node), "contact": self.contact,
                "squeeze_depth": float(self.squeeze_depth), "lift_height": float(self.lift_height)}


# ==================================================================== tracker
@dataclass
class _Trial:
    """The state reached from a base state by one increment, with its slip data."""

    state: ContactState
    amounts: np.ndarray  # (m,) slip in this increment (0 for sticking contacts)
    rates: np.ndarray  # (m,) slip rates (0 for sticking contacts)
    values: dict = field(default_factory=dict)  # event kind -> (array of values, array of ids)


class Tracker:
    """Event-driven tracking of the contact configuration as the fingers move (module notes).

    Parameters
    ----------
    body : Body
        The posed body (reference positions in the table frame, gravity −z).
    radius : fingertip radius R, metres
    mu_finger, mu_table : friction coefficients μ_ℱ, μ_𝒫 (> 0)
    table : TablePlane or None
        The supporting plane (None: no table, the object hangs from the fingers).
    backend : "sparse" or "spectral" (see :class:`~fem_grasp.elastic.response.ContactResponse`)
    """

    def __init__(self, body: Body, *, radius: float, mu_finger: float, mu_table: float,
                 table: TablePlane | None, backend: str = "sparse") -> None:
        if not (mu_finger > 0 and mu_table > 0):
            raise ValueError("event tracking needs positive friction coefficients (μ = 0 has no slip direction)")
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
        self.solves = 0
        #: The slip systems are assembled, solved and read out by compiled kernels (:class:`CompiledSlipSystem`);
        #: False: by :class:`MixedSlipSystem` (numpy; the reference path the tests compare with).
        self.compiled = COMPILED_TRIALS
        #: Slip forms tried in order: False = great circle (the paper's), True = free direction.
        self.forms: tuple[bool, ...] = (False, True)
        #: The last increment was implicit (the next one tries the rate problem with Newton only).
        self.implicit = False
        #: Above this many contacts every increment is implicit (module notes).
        self.implicit_contacts = IMPLICIT_CONTACTS
        #: Slip roots found from the latest base state and motion, per form: (dt, x) (warm starts for nearby dt).
        self._warm_key: tuple | None = None
        self._warm: dict[bool, list[tuple[float, np.ndarray]]] = {}
        #: For one base state and motion, the smallest dt at which Newton found no root, per form.
        self._fail_key: tuple | None = None
        self._newton_fails: dict[bool, float] = {}
        #: The trial whose state the latest advance or settle returned: the zero increment of the next advance
        #: from that state (its event values, rates), which need not be solved again.
        self._returned: _Trial | None = None

    # ------------------------------------------------------------ responses
    def response(self, nodes: np.ndarray) -> ContactResponse:
        key = _key(nodes)
        resp = self._responses.get(key)
        if resp is None:
            try:  # derived from the cached set nearest in nodes where that pays (a node or two joined or left)
                resp = contact_response(self.body, np.asarray(key, dtype=np.int64), backend=self.backend,
                                        cached=self._responses.values())
            except CollinearContactError as exc:
                raise TrackingError(f"the object is no longer held: {exc}") from None
            self._responses[key] = resp
            while len(self._responses) > 1 and (
                    len(self._responses) > RESPONSE_CACHE
                    or sum(r.nbytes for r in self._responses.values()) > RESPONSE_CACHE_BYTES):
                self._responses.pop(next(iter(self._responses)))  # the oldest
        return resp

    def prefetch_columns(self, nodes: Sequence[int], surface_positions: np.ndarray, centers: np.ndarray) -> None:
        """With the sparse backend, when new contact ``nodes`` lack their compliance columns, compute them
        together with those of the uncached surface nodes nearest an obstacle (the likely next contacts):
        ``compliance.PREFETCH_NODES`` in one solve (a new contact's own three columns alone cost
        several times more per column)."""
        comp = self.body.compliance if self.backend == "sparse" else None
        if comp is None or all(comp.is_cached(k) for k in nodes):
            return
        gap = self.obstacle_gaps(surface_positions, centers).min(axis=1)
        comp.prefetch(np.asarray(nodes, dtype=np.int64), likely=self.surface[np.argsort(gap, kind="stable")],
                      count=PREFETCH_NODES)

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
            while len(self._latest_full) > LATEST_FIELDS:
                self._latest_full.pop(next(iter(self._latest_full)))
        if load == 1.0:
            return full
        zero = zero_fields.get(key)
        if zero is None:
            zero = solve(self.response(nodes), np.zeros_like(disp))
            if len(zero_fields) >= ZERO_FIELD_CACHE:
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
        tip = owner != TABLE
        if tip.any():
            d = positions[tip] - np.asarray(centers, float)[owner[tip]]
            out[tip] = d / np.linalg.norm(d, axis=1, keepdims=True)
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
                base.normals, sl, kinds, self.points[base.nodes[sl]], base.centers, self.radius, DIRECTION_FLOOR,
                self.mu[kinds], self.up, first, NEWTON_TOL, NEWTON_MAX_ITER, self.points[base.nodes], centers, TABLE)
            if code == slip_trial.TRIAL_NO_DIRECTION:
                raise SlipFailure("a sliding contact has no tangential force, so no slip direction")
            if code == slip_trial.TRIAL_NO_ROOT:
                zero_start = (first, found, x)
            else:
                free, outcome = first, (forces, disp, normals, amounts, rates)
        elif self.compiled:
            disp_h, fh, dfh, t_hat, r, has_directions = slip_trial.held_prediction(
                c, f0, base.disp, base.owner, velocities, float(dt), float(load), float(load_rate), base.forces,
                base.normals, sl, kinds, self.points[base.nodes[sl]], base.centers, self.radius, DIRECTION_FLOOR)
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
            ok = ftn > DIRECTION_FLOOR * max(float(np.abs(src).max(initial=0.0)), 1e-300)
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

    # --------------------------------------------------------------- events
    def obstacle_gaps(self, surface_positions: np.ndarray, centers: np.ndarray) -> np.ndarray:
        """(s, 3) signed distance of each surface node (at ``surface_positions``) from ℱ₁, ℱ₂ and 𝒫 (inf for
        no table)."""
        gaps = np.full((len(surface_positions), 3), np.inf)
        # The obstacles' signed_distance, without building them at every trial.
        for code in (FINGER1, FINGER2):
            gaps[:, code] = np.linalg.norm(surface_positions - centers[code], axis=1) - self.radius
        if self.table is not None:
            gaps[:, TABLE] = surface_positions @ self.table.up - self.table.height
        return gaps

    def force_scale(self, state: ContactState) -> float:
        return self.body.weight * max(state.load, 0.0) + float(np.abs(state.forces).max(initial=0.0))

    def event_values(self, trial: _Trial, fscale: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Normalised event functions (> 0: the event fires) with their ids.

        A: ids are (surface position, obstacle) pairs encoded as 3·s + obstacle;
        B, C, D: positions in the contact set.
        """
        st = trial.state
        if self.compiled:
            table = self.table
            a_val, b_val, c_val, d_val = events.event_functions(
                st.surface_positions, st.centers, self.radius, table is not None, self.up,
                0.0 if table is None else float(table.height), self.surface_index[st.nodes], st.owner, st.forces,
                st.normals, st.sliding, trial.rates, self.mu[st.owner], float(fscale), float(self.diameter),
                TOL_PENETRATION, TOL_TENSILE, TOL_CONE, TOL_FORCE_FLOOR, TOL_RATE, STICK_HYSTERESIS)
            ids = np.arange(st.n_contacts)
            return {"A": (a_val, np.arange(a_val.size)), "B": (b_val, ids), "C": (c_val, ids), "D": (d_val, ids)}
        gaps = self.obstacle_gaps(st.surface_positions, st.centers)
        own = self.surface_index[st.nodes]
        on = own >= 0
        gaps[own[on], st.owner[on]] = np.inf  # its own obstacle
        a_val = (-gaps / self.diameter - TOL_PENETRATION).reshape(-1)
        a_ids = np.arange(a_val.size)
        fn = st.normal_forces
        ft = st.tangential_forces
        b_val = -fn / fscale - TOL_TENSILE
        mu = self.mu[st.owner]
        c_val = np.where(st.sliding, -np.inf, (ft - mu * fn - TOL_CONE * np.maximum(fn, 0.0)) / fscale
                         - TOL_FORCE_FLOOR)
        slip_test = -trial.rates - TOL_RATE
        d_val = np.where(st.sliding, np.maximum(slip_test, STICK_HYSTERESIS * TOL_FORCE_FLOOR - fn / fscale), -np.inf)
        ids = np.arange(st.n_contacts)
        return {"A": (a_val, a_ids), "B": (b_val, ids), "C": (c_val, ids), "D": (d_val, ids)}

    @staticmethod
    def _gmax(values: dict) -> float:
        return max((float(v.max()) if v.size else -np.inf) for v, _ in values.values())

    @staticmethod
    def _flat(values: dict) -> np.ndarray:
        """Every event function's value, in one array (the same order for every trial of one motion)."""
        return np.concatenate([v for v, _ in values.values()])

    @staticmethod
    def _first_to_fire(g_lo: np.ndarray | None, g_hi: np.ndarray | None) -> int | None:
        """Index of the event function whose linear interpolation between a trial with no event (g_lo ≤ 0)
        and one past an event crosses zero first; None without both."""
        if g_lo is None or g_hi is None:
            return None
        fire = np.flatnonzero((g_hi > 0) & np.isfinite(g_lo) & np.isfinite(g_hi))
        if not fire.size:
            return None
        frac = -g_lo[fire] / (g_hi[fire] - g_lo[fire])
        return int(fire[np.argmin(frac)])

    @staticmethod
    def _interpolated_root(points: list[tuple[float, float]]) -> float | None:
        """Zero of the event function through its latest trials ``points`` [(t, g), …], newest first: inverse
        quadratic interpolation through three, the secant through two; None if they do not define one."""
        if len(points) >= 3:
            (a, fa), (b, fb), (c, fc) = points[:3]
            if fa != fb and fa != fc and fb != fc:
                return (a * fb * fc / ((fa - fb) * (fa - fc)) + b * fa * fc / ((fb - fa) * (fb - fc))
                        + c * fa * fb / ((fc - fa) * (fc - fb)))
        if len(points) >= 2:
            (a, fa), (b, fb) = points[:2]
            if fa != fb:
                return a - fa * (a - b) / (fa - fb)
        return None

    # ------------------------------------------------------------- stepping
    def advance(self, base: ContactState, dt: float, velocities: np.ndarray, *, load_rate: float = 0.0,
                param: Parameter = Parameter.SQUEEZE_DEPTH, phase: str | None = None,
                min_step: float | None = None) -> tuple[ContactState, list[ContactEvent]]:
        """Advance by ``dt`` or up to the first event (applied, with its cascade).

        Returns the new state and the events applied (empty if ``dt`` was
        completed without event).  The slip increment is halved when its
        system has no root, down to ``min_step``; then :class:`TrackingError`.
        """
        phase = phase or base.phase
        if len(base.nodes) > self.implicit_contacts:
            return self.implicit_step(base, dt, velocities, load_rate=load_rate, param=param, phase=phase)
        min_step = MIN_STEP * self.diameter if min_step is None else min_step
        fscale = self.force_scale(base)
        h = dt
        halvings = 0
        while True:
            try:
                # Just after an implicit increment the rate problem is likely to fail again: Newton only.
                trial = self.trial(base, h, velocities, load_rate, param,
                                   methods=("newton",) if self.implicit else ("newton", "homotopy"))
                self.implicit = False
                break
            except SlipFailure as exc:
                h *= 0.5
                halvings += 1
                if (self.implicit or halvings > INCREMENT_HALVINGS) and h >= min_step:
                    # The rate problem has no solution near here (a friction limit): one implicit step.
                    log.debug("%s = %.6g: slip system fails (%s); implicit step of %.3g", param,
                              getattr(base, param), exc, 2.0 * h if self.implicit else h)
                    return self.implicit_step(base, 2.0 * h if halvings == 1 else h, velocities,
                                              load_rate=load_rate, param=param, phase=phase)
                if h < min_step:
                    try:
                        t0 = self.trial(base, 0.0, velocities, load_rate, param)
                        t0.values = self.event_values(t0, fscale)
                    except SlipFailure:
                        t0 = None
                    return self._turning_point(t0, exc, velocities, phase, load_rate, param)
        trial.values = self.event_values(trial, fscale)
        if self._gmax(trial.values) <= 0.0:
            self._returned = trial
            return trial.state, []
        # Locate the first event in (0, h] on the event function predicted to fire first (smooth in the
        # parameter, unlike the max of them all, which switches between functions): interpolation through
        # its latest trials, safeguarded by Illinois regula falsi on the bracket.
        tol = TOL_LOCATE * self.diameter
        lo, g_lo = 0.0, None
        try:
            t0 = self._zero_trial(base, velocities, load_rate, param)
            t0.values = self.event_values(t0, fscale)
            g_lo = self._gmax(t0.values)
        except SlipFailure:
            g_lo = None
        if g_lo is not None and g_lo > 0:
            hi_trial, hi = t0, 0.0
        else:
            lo_trial = t0 if g_lo is not None else None
            all_lo = None if g_lo is None else self._flat(t0.values)
            g_lo = -1.0 if g_lo is None else g_lo
            hi, g_hi, hi_trial = h, self._gmax(trial.values), trial
            all_hi = self._flat(trial.values)
            history = [(h, all_hi)] + ([(0.0, all_lo)] if all_lo is not None else [])  # newest first
            widths = [hi - lo]
            side, lead, w_lo, w_hi = 0, None, 1.0, 1.0
            while hi - lo > tol:
                new_lead = self._first_to_fire(all_lo, all_hi)
                if new_lead != lead:
                    lead, w_lo, w_hi = new_lead, 1.0, 1.0
                mid = None
                # Interpolation while it shrinks the bracket at least twofold every two trials (Brent's rule).
                if lead is not None and (len(widths) < 3 or widths[-1] <= 0.5 * widths[-3]):
                    pts = [(t, float(v[lead])) for t, v in history if np.isfinite(v[lead])]
                    mid = self._interpolated_root(pts)
                if mid is None or not (lo < mid < hi):
                    a, b = (g_lo, g_hi) if lead is None else (w_lo * all_lo[lead], w_hi * all_hi[lead])
                    mid = hi - b * (hi - lo) / (b - a) if b > a else 0.5 * (lo + hi)
                if not (lo < mid < hi) or (hi - lo) < 4.0 * tol:
                    mid = 0.5 * (lo + hi)
                elif mid - lo < 0.9 * tol:
                    # The estimate is within tol of an end (it is accurate far below the bracket): a trial
                    # just past it, on the far side of the root, closes the bracket.
                    mid += 0.1 * tol
                elif hi - mid < 0.9 * tol:
                    mid -= 0.1 * tol
                try:
                    tr = self.trial(base, mid, velocities, load_rate, param)
                except SlipFailure:
                    hi, hi_trial, all_hi = mid, None, None
                    g_hi = 1.0
                    widths.append(hi - lo)
                    continue
                tr.values = self.event_values(tr, fscale)
                g = self._gmax(tr.values)
                history.insert(0, (mid, self._flat(tr.values)))
                del history[3:]  # the interpolation reads the latest three
                if g > 0:
                    hi, g_hi, hi_trial, all_hi, w_hi = mid, g, tr, history[0][1], 1.0
                    if side == 1:
                        g_lo *= 0.5
                        w_lo *= 0.5
                    side = 1
                else:
                    lo, g_lo, lo_trial, all_lo, w_lo = mid, g, tr, history[0][1], 1.0
                    if side == -1:
                        g_hi *= 0.5
                        w_hi *= 0.5
                    side = -1
                widths.append(hi - lo)
            if hi_trial is None:
                try:
                    hi_trial = self.trial(base, hi, velocities, load_rate, param)
                    hi_trial.values = self.event_values(hi_trial, fscale)
                except SlipFailure as exc:
                    # The slip system loses its root at ``hi`` (a turning point) before any event fired.
                    return self._turning_point(lo_trial, exc, velocities, phase, load_rate, param)
        state, events = self._apply(hi_trial, phase)
        state, more = self.settle(state, velocities, phase=phase, load_rate=load_rate, param=param)
        return state, events + more

    def _zero_trial(self, base: ContactState, velocities: np.ndarray, load_rate: float, param: Parameter) -> _Trial:
        """The zero increment from ``base``: the trial that produced it, if an advance or settle just returned
        it, else :meth:`trial` at dt = 0.  A re-solve would reach the same state and differ only in its slip
        rates, anchored on the new increment's held forces (an O(step) difference)."""
        made = self._returned
        if made is not None and made.state is base:
            return _Trial(made.state, made.amounts, made.rates)
        return self.trial(base, 0.0, velocities, load_rate, param)

    def _turning_point(self, trial: _Trial | None, exc: Exception, velocities: np.ndarray, phase: str,
                       load_rate: float, param: Parameter) -> tuple[ContactState, list[ContactEvent]]:
        """Handle a turning point of the slip system: its root disappears as the parameter grows.

        The sliding set cannot be kept beyond it.  Events that fire at the
        last solvable state are applied.  Otherwise one sliding node must
        stick (event D): the candidates are tried in order of increasing slip
        rate, and the first whose sticking lets the parameter advance again
        is taken.  If none does, the sliding runs away — gross slip — and
        :class:`TrackingError` is raised.
        """
        if trial is None:
            raise TrackingError(f"no quasi-static equilibrium: the slip system has no solution ({exc})")
        if self._gmax(trial.values) > 0:
            state, events = self._apply(trial, phase)
            state, more = self.settle(state, velocities, phase=phase, load_rate=load_rate, param=param)
            return state, events + more
        st = trial.state
        rates = np.where(st.sliding, trial.rates, np.inf)
        probe = max(TURNING_PROBE * self.diameter, TURNING_PROBE_REL * abs(getattr(st, param)))
        for j in np.argsort(rates)[: int(st.sliding.sum())]:
            vals = {k: (np.full_like(v, -np.inf), i) for k, (v, i) in trial.values.items()}
            vals["D"][0][j] = 1.0
            cand = _Trial(st, trial.amounts, trial.rates, vals)
            try:
                state, events = self._apply(cand, phase)
                state, more = self.settle(state, velocities, phase=phase, load_rate=load_rate, param=param)
                self.trial(state, probe, velocities, load_rate, param)
            except (TrackingError, SlipFailure):
                continue
            log.debug("turning point of the slip system: node %d sticks", st.nodes[j])
            return state, events + more
        raise TrackingError(f"no quasi-static equilibrium beyond {_where(param, st)}: the sliding "
                            f"runs away whichever sliding node sticks (gross slip); {exc}")

    def settle(self, state: ContactState, velocities: np.ndarray, *, phase: str, load_rate: float = 0.0,
               param: Parameter = Parameter.SQUEEZE_DEPTH, max_cascade: int = 200) -> tuple[ContactState, list[ContactEvent]]:
        """Re-solve at the same parameter after a configuration change; apply cascading events."""
        events: list[ContactEvent] = []
        toggles: dict[int, int] = {}
        for _ in range(max_cascade):
            try:
                tr = self.trial(state, 0.0, velocities, load_rate, param)
            except SlipFailure as exc:
                # The sliding set reached one toggle at a time has no root: find the static state directly.
                log.debug("settle at %s = %.6g: %s; relaxing", param, getattr(state, param), exc)
                state, ev = self.implicit_step(state, 0.0, velocities, load_rate=load_rate, param=param,
                                               phase=phase, why=f"no slip solution after a change of contact "
                                                                f"configuration ({exc})")
                return state, events + ev
            tr.values = self.event_values(tr, self.force_scale(tr.state))
            if self._gmax(tr.values) <= 0.0:
                self._returned = tr
                return tr.state, events
            state, ev = self._apply(tr, phase)
            events += ev
            for e in ev:
                if e.kind in "CD":
                    toggles[e.node] = toggles.get(e.node, 0) + 1
                    if toggles[e.node] > MAX_SETTLE_TOGGLES:
                        # Friction limit of the rate problem: sticking, the node leaves its cone; sliding,
                        # its slip rate is negative.  The static state is reached by a finite slip.
                        state, ev2 = self.implicit_step(
                            state, 0.0, velocities, load_rate=load_rate, param=param, phase=phase,
                            why=f"friction limit at {_where(param, state)}: node {e.node} "
                                f"({e.contact}) leaves its friction cone when it sticks, yet its slip rate is "
                                "negative when it slides")
                        return state, events + ev2
        raise TrackingError(f"contact events keep cascading at {_where(param, state)} "
                            f"({max_cascade} rounds): the configuration chatters")


    def implicit_step(self, base: ContactState, dt: float, velocities: np.ndarray, *, load_rate: float = 0.0,
                      param: Parameter = Parameter.SQUEEZE_DEPTH, phase: str | None = None, why: str = "",
                      max_rounds: int = 50) -> tuple[ContactState, list[ContactEvent]]:
        """Advance by ``dt`` (0: stay) in one implicit increment, as a return mapping.

        Every contact is held (fingertip contacts move with their finger),
        then :func:`~fem_grasp.contact.relaxation.relax_contacts` finds the static
        stick / slide / release state of all of them at once; nodes that would
        penetrate an obstacle are added and the relaxation repeated.  Used
        where the rate problem of the event tracking has no solution (module
        notes); the events of the increment are recorded at its end, in the
        order release (B), new contact (A), then the stick/slip changes (C, D).
        """
        phase = phase or base.phase
        self.implicit = True
        if param == Parameter.LOAD:
            load_rate = 1.0
        m = base.n_contacts
        vel = np.zeros((m, 3))
        for f in (FINGER1, FINGER2):
            vel[base.owner == f] = velocities[f]
        centers = base.centers + dt * np.asarray(velocities, float)
        load = base.load + dt * load_rate
        nodes, owner = base.nodes.copy(), base.owner.copy()
        disp = base.disp + dt * vel
        slip = base.slip.copy()
        # Every round relaxes from the held state of the increment (the contacts where the increment began, moved
        # with their finger; added contacts where they touched), not from the previous round's result: the
        # increment is one static problem, and a contact that slid in an earlier round with the wrong contact set
        # must not keep that slip while it sticks in the final one (a contact that slides ends on its cone).
        held_disp, held_slip = disp.copy(), slip.copy()
        fscale = self.force_scale(base)
        kw = {} if param == Parameter.LOAD else {param: getattr(base, param) + dt}
        at = replace(base, **kw)
        events: list[ContactEvent] = []

        def record(kind: str, node: int, o: int) -> None:
            events.append(ContactEvent(phase, kind, int(node), OBSTACLES[o], at.squeeze_depth, at.lift_height))

        status = np.zeros(m, dtype=np.int64)
        start = None  # the sweeps of a later round begin at the earlier round's state (only where they begin)
        for _ in range(max_rounds):
            resp = self.response(nodes)
            forces = (resp.reduced_stiffness @ held_disp.reshape(-1)).reshape(-1, 3) + load * resp.gravity_forces
            q0 = self.points[nodes] + held_disp
            cen = [None if o == TABLE else centers[o] for o in owner]
            try:
                rel = relax_contacts(resp.reduced_stiffness, forces, q0, cen, self.up, self.mu[owner], fscale,
                                     max_slip=MAX_SLIP * self.diameter, start=start)
            except RelaxationFailure as exc:
                raise TrackingError(f"no quasi-static equilibrium at {_where(param, at)}"
                                    f"{': ' + why if why else ''}; a static stick/slip state was sought and "
                                    f"not found: {exc}") from None
            disp = held_disp + rel.displacements
            slip = held_slip + rel.slips
            status = rel.status
            released = status == RELEASE
            for j in np.flatnonzero(released):
                record("B", nodes[j], owner[j])
            keep = ~released
            nodes, owner, disp, slip, status = nodes[keep], owner[keep], disp[keep], slip[keep], status[keep]
            held_disp, held_slip = held_disp[keep], held_slip[keep]
            start = (status, rel.displacements[keep], rel.motions[keep])
            surface = self.surface_points + self.surface_field(nodes, disp, load)
            gaps = self.obstacle_gaps(surface, centers)
            in_contact = set(int(k) for k in nodes)
            deep = np.argwhere(-gaps / self.diameter - TOL_PENETRATION > 0)
            added = []
            for s_pos, o in deep:
                k = int(self.surface[s_pos])
                if k in in_contact:
                    if int(owner[np.flatnonzero(nodes == k)[0]]) != o:
                        raise TrackingError(f"node {k} touches {OBSTACLES[o]} while in contact with another "
                                            "obstacle: pinched nodes are not modelled")
                    continue
                if any(k == a[0] for a in added):
                    continue
                added.append((k, int(o), self.obstacles(centers)[int(o)].project_point(surface[s_pos]) - self.points[k]))
                record("A", k, int(o))
            if not added and not released.any():
                break
            self.prefetch_columns([a[0] for a in added], surface, centers)
            nodes = np.concatenate([nodes, [a[0] for a in added]]).astype(np.int64)
            owner = np.concatenate([owner, [a[1] for a in added]]).astype(np.int64)
            disp = np.vstack([disp] + [a[2][None, :] for a in added])
            slip = np.concatenate([slip, np.zeros(len(added))])
            held_disp = np.vstack([held_disp] + [a[2][None, :] for a in added])
            held_slip = np.concatenate([held_slip, np.zeros(len(added))])
            start = (np.concatenate([start[0], np.full(len(added), STICK)]),
                     np.vstack([start[1], np.zeros((len(added), 3))]),
                     np.vstack([start[2], np.zeros((len(added), 2))]))
            try:
                check_contact_set(self.points, nodes)
            except CollinearContactError as exc:
                raise TrackingError(f"the object is no longer held at {_where(param, at)}: "
                                    f"{exc}") from None
        else:
            raise TrackingError(f"contacts keep being made and released at {_where(param, at)} "
                                f"({max_rounds} rounds)")
        sliding = status == SLIDE
        before = dict(zip(base.nodes.tolist(), base.sliding.tolist()))
        for j, k in enumerate(nodes.tolist()):
            if k in before and before[k] != bool(sliding[j]):
                record("C" if sliding[j] else "D", k, int(owner[j]))
        state = self.make_state(phase=base.phase, squeeze_depth=at.squeeze_depth, lift_height=at.lift_height,
                                load=load, centers=centers, nodes=nodes, owner=owner, disp=disp,
                                sliding=sliding, slip=slip)
        log.debug("implicit step to %s = %.6g: %d contacts, %d sliding, events %s", param, getattr(at, param),
                  len(nodes), int(sliding.sum()), "".join(e.kind for e in events))
        return state, events

    def _apply(self, trial: _Trial, phase: str) -> tuple[ContactState, list[ContactEvent]]:
        """Apply every event that fires at the trial state; return the new (unsettled) state."""
        st = trial.state
        vals = trial.values
        nodes = list(st.nodes)
        owner = list(st.owner)
        disp = list(st.disp)
        sliding = list(st.sliding)
        slip = list(st.slip)
        events: list[ContactEvent] = []

        def record(kind: str, node: int, o: int) -> None:
            events.append(ContactEvent(phase, kind, int(node), OBSTACLES[o], st.squeeze_depth, st.lift_height))

        c_val, _ = vals["C"]
        d_val, _ = vals["D"]
        # Stick/slip changes are made one node at a time (the most negative slip rate first, else the
        # force furthest outside its cone): the sliding set is a complementarity problem, and changing
        # several coupled nodes at once can cycle.  The cascade of :meth:`settle` makes the others.
        if (d_val > 0).any():
            j = int(np.argmax(d_val))
            sliding[j] = False
            record("D", st.nodes[j], st.owner[j])
        elif (c_val > 0).any():
            j = int(np.argmax(c_val))
            sliding[j] = True
            record("C", st.nodes[j], st.owner[j])
        b_val, _ = vals["B"]
        remove = set(int(j) for j in np.flatnonzero(b_val > 0))
        for j in sorted(remove):
            record("B", st.nodes[j], st.owner[j])
        a_val, _ = vals["A"]
        new = np.flatnonzero(a_val > 0)
        in_contact = set(int(k) for k in st.nodes)
        added: list[tuple[int, int, np.ndarray]] = []
        for code in new:
            s, o = divmod(int(code), 3)
            k = int(self.surface[s])
            if k in in_contact:
                raise TrackingError(f"node {k} touches {OBSTACLES[o]} while in contact with "
                                    f"{OBSTACLES[owner[nodes.index(k)]]}: pinched nodes are not modelled")
            if any(k == a[0] for a in added):
                continue
            added.append((k, o, self.obstacles(st.centers)[o].project_point(st.surface_positions[s]) - self.points[k]))
            record("A", k, o)
        self.prefetch_columns([a[0] for a in added], st.surface_positions, st.centers)
        keep = [j for j in range(len(nodes)) if j not in remove]
        nodes = [nodes[j] for j in keep] + [a[0] for a in added]
        owner = [owner[j] for j in keep] + [a[1] for a in added]
        disp = [disp[j] for j in keep] + [a[2] for a in added]
        sliding = [sliding[j] for j in keep] + [False] * len(added)
        slip = [slip[j] for j in keep] + [0.0] * len(added)
        forces = [st.forces[j] for j in keep] + [np.zeros(3)] * len(added)
        normals = [st.normals[j] for j in keep] + [np.zeros(3)] * len(added)
        for ev in events:
            log.debug("event %s: node %d, %s, ρ = %.6g, lift = %.6g", ev.kind, ev.node, ev.contact,
                      ev.squeeze_depth, ev.lift_height)
        try:
            if remove or added:  # (a stick/slip change keeps a set that was checked when it was formed)
                check_contact_set(self.points, np.asarray(nodes, dtype=np.int64))
        except CollinearContactError as exc:
            raise TrackingError(f"the object is no longer held after events "
                                f"{[(e.kind, e.node, e.contact) for e in events]}: {exc}") from None
        new_state = replace(st, nodes=np.asarray(nodes, dtype=np.int64), owner=np.asarray(owner, dtype=np.int64),
                            disp=np.asarray(disp, float).reshape(-1, 3), sliding=np.asarray(sliding, bool),
                            slip=np.asarray(slip, float), forces=np.asarray(forces, float).reshape(-1, 3),
                            normals=np.asarray(normals, float).reshape(-1, 3))
        # Normals of the added contacts (forces are recomputed by the settling solve).
        own = np.asarray(owner, dtype=np.int64)
        p_c = self.points[new_state.nodes] + new_state.disp
        new_state = replace(new_state, normals=self.normals(own, p_c, st.centers))
        return new_state, events


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
    window = CHATTER_WINDOW * tracker.diameter
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
                    if (sum(now - t <= window for t in hist) > CHATTER_TOGGLES
                            or len(hist) > CRAWL_TOGGLES):
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
    owner = np.array([TABLE, FINGER1])
    sl = np.array([0, 1])
    normals = np.array([s["up"], [0.0, 0.0, 1.0]])
    slip_trial.held_prediction(100.0 * np.eye(6), s["forces"], np.zeros((2, 3)), owner, np.zeros((2, 3)), 0.0, 1.0,
                               0.0, s["forces"], normals, sl, owner[sl], s["positions"],
                               np.array([s["centre"], s["centre"]]), 0.01, DIRECTION_FLOOR)
    for free in (False, True):
        slip_trial.newton_trial(100.0 * np.eye(6), s["forces"], np.zeros((2, 3)), owner, np.zeros((2, 3)), 0.0, 1.0,
                                0.0, s["forces"], normals, sl, owner[sl], s["positions"],
                                np.array([s["centre"], s["centre"]]), 0.01, DIRECTION_FLOOR, s["mu"], s["up"], free,
                                NEWTON_TOL, NEWTON_MAX_ITER, s["positions"], np.array([s["centre"], s["centre"]]),
                                TABLE)
    events.contact_normals(owner, s["positions"], np.array([s["centre"], s["centre"]]), s["up"], TABLE)
    for has_table in (True, False):
        events.event_functions(s["positions"], np.array([s["centre"], s["centre"]]), 0.01, has_table, s["up"], 0.0,
                               np.array([0, 1]), owner, s["forces"], normals, np.array([False, True]), np.zeros(2),
                               s["mu"], 1.0, 0.1, TOL_PENETRATION, TOL_TENSILE, TOL_CONE, TOL_FORCE_FLOOR, TOL_RATE,
                               STICK_HYSTERESIS)
