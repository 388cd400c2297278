"""Algorithm 1 end to end: two-finger pickup of a soft 3D object (paper §III).

:func:`pickup` runs

* step 1, the force-closure test of the initial placement (:mod:`fem_grasp.grasp.closure`);
* step 2, the resting configuration on the table (:func:`fem_grasp.grasp.rest.rest`, §III-A);
* steps 3–4, the squeeze with the lift test after every increment
  (:mod:`fem_grasp.grasp.squeeze`, :mod:`fem_grasp.grasp.lift_test`, §III-B/C);
* step 5, the lift (:mod:`fem_grasp.grasp.lift`);
* step 6, failure when the squeeze reaches its maximum depth,

and returns a :class:`PickupResult` with the whole story: events, snapshots
at every event, liftable-weight history, forces, timings, and the rigid-body
comparison of Table III (:mod:`fem_grasp.grasp.rigid`).  Failures (no force
closure, gross slip, too little friction, …) are results, not exceptions.

Default scene (the paper's §IV, where it is silent our choice)
--------------------------------------------------------------
* squeeze directions d̂₁ = (0, 0.974, −0.227), d̂₂ = (0, −0.974, −0.227),
  ratio s = 1; fingertip radius :data:`fem_grasp.contact.obstacles.DEFAULT_RADIUS`;
* μ_ℱ = μ_𝒫 = :data:`DEFAULT_FRICTION` unless given (``mu_table`` defaults to
  ``mu_finger``, the paper has one μ per object);
* finger contacts p_i, p_j (:func:`default_finger_contacts`): among the
  pairs of surface nodes extreme along ∓ĥ (ĥ the horizontal part of d̂₁) at
  heights stepped by 2.5 % of the object's height, those whose tangent
  fingertips clear the table by max(R/10, |d̂₁·ẑ| × maximum squeeze), start
  outside the object and are force closure, by the rule
  ``placement_rule="centre-of-mass-height"`` (:data:`~fem_grasp.grasp.placement.DEFAULT_PLACEMENT_RULE`,
  the rule of the paper scenes and of a scene that names none, so that
  ``pickup()`` and ``fem-grasp run`` agree): the first valid pair from the
  centre of mass's height outwards whose rigid grasp is feasible — the
  fingers alone could hold a rigid body of the resting shape; where a dome's
  side leans further than the friction angle, the fingers move to where it is
  steeper — or the first valid pair if none is.  (``placement_rule="least-force"``:
  the pair whose rigid grasp needs the least total normal force, Table III's
  measure; contacts where the surface faces a little upward let the normal
  forces carry part of the weight, but a deep squeeze there can push a soft
  body up out of the grasp.)
* maximum squeeze depth: 40 % of the object's width along ĥ;
* squeeze increment: 1/20 of the depth ρ* = mg / (μ_ℱ k₀) at which a
  finger of the initial (point) contact stiffness k₀ would press hard enough
  to hold the weight by friction — so the increments adapt to E — kept
  between 0.1 % and 2 % of the maximum depth (the contact patch grows with
  the geometry, whatever E);
* a lift that fails (all contacts of a finger slide, or no quasi-static
  stick/slip state exists: the grip is lost) sends the run back to the
  squeeze from the lift-start state (Algorithm 1 step 6, "otherwise go back
  to step 3"): the lift test, path-independent, can pass where the real lift,
  which unloads the table gradually, slips; up to ``max_lift_attempts`` = 4
  lifts, each recorded in ``result.lift_attempts``;
* lift-test step h = mg/20; lift increment equal to the squeeze increment,
  maximum lift height equal to the object's height (a soft object stays on
  the table while its contacts with the fingers stretch: at E = 1e4 Pa the
  paper's objects need centimetres of lift to let go).

Checks (:meth:`Snapshot.check`)
-------------------------------
Every snapshot is held to the contact laws and equilibrium by the one checker
of :mod:`fem_grasp.grasp.checks` (its table :data:`~fem_grasp.grasp.checks.CHECK_TOLERANCES`,
with F_s = mg + max |f_k| and L the mesh diameter): equilibrium ≤ 1e-9
relative; no surface node inside an obstacle by more than 1e-9 L, every
contact node on its obstacle to 1e-9 L; normal forces ≥ −1e-9 F_s; sticking
contacts ``|f_t| − μ f·n̂ ≤ 1e-8 f·n̂ + 2e-7 F_s`` (2e-7 F_s covers contacts
carrying less than the force floor 1e-7 F_s of :mod:`fem_grasp.contact.tracking`,
whose stick/slip state is not assessed); sliding contacts on their cone,
``| |f_t| − μ f·n̂ | ≤ 1e-8 f·n̂ + 1e-9 F_s``.
"""

from __future__ import annotations

import json
import logging
import time
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from ..contact.obstacles import DEFAULT_RADIUS, FINGER1, FINGER2, OBSTACLES, TABLE, Fingertip, TablePlane
from ..contact.tracking import ContactEvent, ContactState, Tracker
from ..contact.warm_up import prepare_kernels
from ..elastic.body import Body
from ..errors import ContactNodeError, PickupCheckError, PlacementError, SceneError, TrackingError
from ..validation import check_finger_friction, check_friction, check_positive
from . import placement
from .checks import contact_law_figures
from .closure import ClosureResult, placement_closure
from .forces import TABLE_III_MEASURE, FingerForce, finger_forces
from .lift import lift as run_lift
from .lift_test import LiftTest
from .placement import (
    DEFAULT_PLACEMENT_RULE,
    PAPER_SQUEEZE_DIRECTIONS,
    PLACEMENT_RULES,
    check_contact_nodes,
    check_directions,
    check_finger_placement,
)
from .rest import RestState, rest
from .rigid import RigidGrasp, rigid_grasp
from .squeeze import initial_state, squeeze

__all__ = ["DEFAULT_FRICTION", "OUTCOMES", "LiftAttempt", "PickupCheckError", "PickupResult", "Snapshot",
           "default_finger_contacts", "default_max_squeeze", "pickup"]

log = logging.getLogger(__name__)

#: Friction coefficient used when none is given.
DEFAULT_FRICTION = 0.5
#: How a pickup can end (:attr:`PickupResult.outcome`); ``reason`` says why in words.  docs/limits.md lists
#: each with its message.  Every valid scene ends in one of these (or the object does not come to rest:
#: ``RestConvergenceError``).
OUTCOMES: dict[str, str] = {
    "picked up": "the object left the table (Algorithm 1 step 5)",
    "lift not run": "the lift test passed; the lift was not simulated (lift=False)",
    "no placement": "no finger placement along the squeeze direction is valid (default contacts only)",
    "not force closure": "the initial placement is not force closure (Algorithm 1 step 1)",
    "placement failed": "the fingers touching at the placement have no quasi-static state",
    "squeeze failed": "no quasi-static state during the squeeze (gross slip, lost support, a pinched node)",
    "not liftable": "the lift test did not pass by the maximum squeeze depth (Algorithm 1 step 6)",
    "lift failed": "every simulated lift failed: the object slid on a finger, friction could not hold it, "
                   "or it was still on the table at the maximum lift height",
}


# ================================================================ snapshots
@dataclass(frozen=True)
class Snapshot:
    """The object and its contacts at one moment of the pickup.

    Attributes
    ----------
    label : "initial", "event", "lift start", "lift-off", "final", …
    phase : "squeeze" or "lift"
    squeeze_depth, lift_height : metres
    surface_nodes : (s,) the body's surface nodes (``mesh.surface_nodes``)
    surface_positions : (s, 3) their deformed positions, in the frame of the posed body
    finger_centers : (2, 3) fingertip centres
    finger_radius : metres
    contact_nodes : {"finger1", "finger2", "table"} → (k,) node indices
    contact_forces : same keys → (k, 3) forces on the object, newtons
    sliding : same keys → (k,) bool
    events : the events that produced this snapshot
    position_source : computes the (n, 3) deformed positions of every node (:attr:`Snapshot.positions`)
    """

    label: str
    phase: str
    squeeze_depth: float
    lift_height: float
    surface_nodes: np.ndarray
    surface_positions: np.ndarray
    finger_centers: np.ndarray
    finger_radius: float
    contact_nodes: dict[str, np.ndarray]
    contact_forces: dict[str, np.ndarray]
    sliding: dict[str, np.ndarray]
    events: tuple[ContactEvent, ...] = ()
    position_source: Callable[[], np.ndarray] | None = field(default=None, repr=False, compare=False)

    @cached_property
    def positions(self) -> np.ndarray:
        """(n, 3) deformed positions of every node, computed at first use (outputs need them; the checks,
        normals and forces do not, and on a large mesh each costs a sparse solve or a pass over many
        cached columns)."""
        return np.array(self.position_source(), dtype=float)

    def node_positions(self, nodes: np.ndarray) -> np.ndarray:
        """(k, 3) deformed positions of ``nodes``, from the surface when they all lie on it."""
        nodes = np.asarray(nodes, dtype=np.int64)
        idx = np.minimum(np.searchsorted(self.surface_nodes, nodes), len(self.surface_nodes) - 1)
        if len(nodes) and not np.array_equal(self.surface_nodes[idx], nodes):
            return self.positions[nodes]
        return self.surface_positions[idx]

    def __getstate__(self) -> dict[str, Any]:
        """Pickled with its positions computed (the source is a closure over the tracker)."""
        self.positions  # noqa: B018 - computed and cached in __dict__
        return {**self.__dict__, "position_source": None}

    @classmethod
    def from_state(cls, state: ContactState, radius: float, label: str, events: Sequence[ContactEvent] = (),
                   *, surface_nodes: np.ndarray) -> "Snapshot":
        """The snapshot of a tracked state; ``surface_nodes`` are the body's (those of ``state.surface_positions``)."""
        nodes, forces, sliding = {}, {}, {}
        for code, name in enumerate(OBSTACLES):
            on = state.owner == code
            nodes[name] = state.nodes[on].copy()
            forces[name] = state.forces[on].copy()
            sliding[name] = state.sliding[on].copy()
        return cls(label, state.phase, state.squeeze_depth, state.lift_height, surface_nodes,
                   state.surface_positions.copy(), state.centers.copy(), radius, nodes, forces, sliding, tuple(events),
                   state.position_source)


    @property
    def all_nodes(self) -> np.ndarray:
        return np.concatenate([self.contact_nodes[k] for k in OBSTACLES])

    @property
    def all_forces(self) -> np.ndarray:
        return np.concatenate([self.contact_forces[k] for k in OBSTACLES])

    def normals(self, table: TablePlane) -> dict[str, np.ndarray]:
        """Inward normals n̂ at the contacts of each body."""
        out = {}
        for f, name in ((FINGER1, "finger1"), (FINGER2, "finger2")):
            d = self.node_positions(self.contact_nodes[name]) - self.finger_centers[f]
            out[name] = d / np.linalg.norm(d, axis=1, keepdims=True) if len(d) else np.zeros((0, 3))
        out["table"] = np.broadcast_to(table.up, (len(self.contact_nodes["table"]), 3)).copy()
        return out

    def finger_forces(self, directions: Sequence[np.ndarray]) -> tuple[FingerForce, FingerForce]:
        """Each finger's force on the object: resultant, grip along its squeeze direction (d̂₁, d̂₂), vertical
        part and normal sum (:mod:`fem_grasp.grasp.forces`)."""
        names = ("finger1", "finger2")
        return finger_forces([self.node_positions(self.contact_nodes[n]) for n in names],
                             [self.contact_forces[n] for n in names], self.finger_centers, self.finger_radius,
                             directions)

    def finger_normal_force(self, table: TablePlane) -> float:
        """Σ f·n̂ over both fingers' contacts, newtons."""
        nrm = self.normals(table)
        return float(sum(np.einsum("ki,ki->k", self.contact_forces[k], nrm[k]).sum() for k in ("finger1", "finger2")))

    def check(self, body: Body, table: TablePlane, mu_finger: float, mu_table: float,
              tolerances: dict[str, float] | None = None, raise_on_failure: bool = True) -> dict[str, Any]:
        """Verify equilibrium, non-penetration and Coulomb's law (:mod:`fem_grasp.grasp.checks`); return the figures."""
        owner = np.concatenate([np.full(len(self.contact_nodes[name]), code) for code, name in enumerate(OBSTACLES)])
        nodes = self.all_nodes
        mu = np.where(owner == TABLE, mu_table, mu_finger)
        fingertips = [Fingertip(c, self.finger_radius) for c in self.finger_centers]
        figures = {"label": self.label, "squeeze_depth": self.squeeze_depth, "lift_height": self.lift_height}
        figures.update(contact_law_figures(
            body, (*fingertips, table), owner, nodes, self.node_positions(nodes), self.all_forces,
            np.concatenate([self.sliding[name] for name in OBSTACLES]), mu, self.surface_nodes,
            self.surface_positions, tolerances))
        if figures["failures"] and raise_on_failure:
            raise PickupCheckError(f"snapshot '{self.label}' at ρ = {self.squeeze_depth:.6g} m, lift "
                                   f"{self.lift_height:.6g} m fails its checks: " + "; ".join(figures["failures"]))
        return figures

    def to_dict(self) -> dict[str, Any]:
        return {
            "label": self.label, "phase": self.phase, "squeeze_depth": self.squeeze_depth,
            "lift_height": self.lift_height, "finger_radius": self.finger_radius,
            "finger_centers": self.finger_centers.tolist(), "positions": self.positions.tolist(),
            "contact_nodes": {k: v.tolist() for k, v in self.contact_nodes.items()},
            "contact_forces": {k: v.tolist() for k, v in self.contact_forces.items()},
            "sliding": {k: v.tolist() for k, v in self.sliding.items()},
            "events": [e.to_dict() for e in self.events],
        }


# =================================================================== result
@dataclass(frozen=True)
class LiftAttempt:
    """One simulated lift (Algorithm 1 step 5).

    Attributes
    ----------
    squeeze_depth : ρ at which the lift started, metres
    success : the object left the table
    reason : why not (empty on success)
    lift_height : how far the fingers rose, metres
    n_events : events during this lift
    """

    squeeze_depth: float
    success: bool
    reason: str
    lift_height: float
    n_events: int

    def to_dict(self) -> dict[str, Any]:
        return {"squeeze_depth": self.squeeze_depth, "success": self.success, "reason": self.reason,
                "lift_height": self.lift_height, "n_events": self.n_events}


@dataclass
class PickupResult:
    """Everything :func:`pickup` found out.

    Attributes
    ----------
    success : the object was lifted off the table
    reason : why not (empty on success)
    outcome : how the pickup ended, a key of :data:`OUTCOMES`
    body : the posed body (frame of every position)
    rest : the resting state
    finger_nodes : (p_i, p_j)
    closure : force-closure test of step 1
    mu_finger, mu_table, finger_radius, directions, ratio : the scene
    squeeze_depth : ρ when the lift started (or where the squeeze stopped), metres
    liftable : [(ρ, w(ρ))] history of the lift test
    events : every event (squeeze and lift), in order
    snapshots : initial state, every event, lift start, final
    final : the last snapshot (lift-off on success)
    finger_normal_force : total finger normal force Σ f·n̂ in the final snapshot, newtons (Table III's measure)
    finger_forces : each finger's resultant, grip, vertical part and normal sum (property)
    rigid : the rigid comparison (Table III) for the same shape and contacts
    timings : wall time per phase, seconds
    lift_attempts : every simulated lift, in order (more than one when a lift failed and the squeeze
        went on, Algorithm 1 step 6)
    lift_test_step : the lift-test step h used, newtons
    accuracy : with ``pickup(..., accuracy=...)``, what the levels of :func:`fem_grasp.grasp.accuracy.converged_pickup`
        found (target, estimated errors, levels), as in result.json; else None
    """

    success: bool
    reason: str
    body: Body
    rest: RestState | None
    finger_nodes: tuple[int, int]
    closure: ClosureResult | None
    mu_finger: float
    mu_table: float
    finger_radius: float
    directions: tuple[np.ndarray, np.ndarray]
    ratio: float
    squeeze_depth: float = 0.0
    liftable: list[tuple[float, float]] = field(default_factory=list)
    events: list[ContactEvent] = field(default_factory=list)
    snapshots: list[Snapshot] = field(default_factory=list)
    final: Snapshot | None = None
    finger_normal_force: float = 0.0
    rigid: RigidGrasp | None = None
    timings: dict[str, float] = field(default_factory=dict)
    max_squeeze: float = 0.0
    step: float = 0.0
    lift_attempts: list[LiftAttempt] = field(default_factory=list)
    outcome: str = ""
    lift_test_step: float = 0.0
    accuracy: dict[str, Any] | None = None

    @property
    def table(self) -> TablePlane:
        return TablePlane(self.rest.table_z if self.rest is not None else 0.0)

    @property
    def n_final_contacts(self) -> int:
        """Contact nodes in the final configuration (Table II's first figure)."""
        return 0 if self.final is None else len(self.final.all_nodes)

    @property
    def finger_forces(self) -> tuple[FingerForce, FingerForce] | None:
        """Each finger's force on the object in the final snapshot (at lift-off on success); None before any
        (:mod:`fem_grasp.grasp.forces`)."""
        return None if self.final is None else self.final.finger_forces(self.directions)

    def event_counts(self) -> dict[str, int]:
        counts = {k: 0 for k in "ABCD"}
        for e in self.events:
            counts[e.kind] += 1
        return counts

    def check(self, raise_on_failure: bool = True) -> list[dict[str, Any]]:
        """Run :meth:`Snapshot.check` on every snapshot (and ``final``); return their figures."""
        out = []
        snaps = list(self.snapshots)
        if self.final is not None and (not snaps or snaps[-1] is not self.final):
            snaps.append(self.final)
        for s in snaps:
            out.append(s.check(self.body, self.table, self.mu_finger, self.mu_table,
                               raise_on_failure=raise_on_failure))
        return out

    def to_dict(self) -> dict[str, Any]:
        rigid = None
        if self.rigid is not None:
            rigid = {"feasible": self.rigid.feasible, "total_normal_force": self.rigid.total_normal_force,
                     "forces": np.nan_to_num(self.rigid.forces).tolist(), "reason": self.rigid.reason}
        return {
            "success": self.success, "reason": self.reason, "outcome": self.outcome,
            "finger_nodes": list(self.finger_nodes),
            "mu_finger": self.mu_finger, "mu_table": self.mu_table, "finger_radius": self.finger_radius,
            "directions": [np.asarray(d).tolist() for d in self.directions], "ratio": self.ratio,
            "weight": self.body.weight, "young": self.body.young, "poisson": self.body.poisson,
            "squeeze_depth": self.squeeze_depth, "max_squeeze": self.max_squeeze, "step": self.step,
            "closure": None if self.closure is None else {"closed": self.closure.closed,
                                                          "margin": self.closure.margin,
                                                          "quality": self.closure.quality,
                                                          "reason": self.closure.reason},
            "liftable": [[float(r), float(w)] for r, w in self.liftable],
            "events": [e.to_dict() for e in self.events],
            "event_counts": self.event_counts(),
            "finger_normal_force": self.finger_normal_force, "n_final_contacts": self.n_final_contacts,
            "finger_forces": None if self.finger_forces is None else [f.to_dict() for f in self.finger_forces],
            "table_iii_measure": TABLE_III_MEASURE,
            "rigid": rigid, "timings": self.timings,
            "lift_attempts": [a.to_dict() for a in self.lift_attempts],
            "lift_test_step": self.lift_test_step, "accuracy": self.accuracy,
            "reference_points": self.body.mesh.points.tolist(),
            "tets": self.body.mesh.tets.tolist(),
            "snapshots": [s.to_dict() for s in self.snapshots],
            "final": None if self.final is None else self.final.to_dict(),
        }

    def to_json(self, path: str | Path | None = None, indent: int | None = None) -> str:
        """The whole result as JSON; written to ``path`` when given (atomically: never half a file)."""
        text = json.dumps(self.to_dict(), indent=indent, allow_nan=True)
        if path is not None:
            from .._files import atomic_write_text

            atomic_write_text(path, text)
        return text


# ================================================================ placement


def default_max_squeeze(positions: np.ndarray, direction: np.ndarray) -> float:
    """The default maximum squeeze depth: 40 % of the object's width along ĥ, the horizontal part of d̂₁."""
    d = np.asarray(direction, float)
    return 0.4 * float(np.ptp(positions @ np.array([d[0], d[1], 0.0]) / max(np.hypot(d[0], d[1]), 1e-300)))


def default_finger_contacts(rest_state: RestState, direction: np.ndarray, mu_finger: float, mu_table: float,
                            radius: float, velocities: np.ndarray | None = None, *,
                            rule: str = DEFAULT_PLACEMENT_RULE, max_squeeze: float | None = None
                            ) -> tuple[tuple[int, int], ClosureResult]:
    """Initial finger contacts by the rule of the module notes; returns them and their closure test.

    Candidates are the surface nodes extreme along ∓ĥ at heights stepped by
    2.5 % of the object's height, kept when the fingertips tangent there
    clear the table by ``max(R/10, |d̂₁·ẑ| max_squeeze)`` (they do not reach
    it within the maximum squeeze), start outside the object, and are force
    closure.  ``rule="least-force"`` takes the candidate whose rigid grasp
    (:func:`fem_grasp.grasp.rigid.rigid_grasp`, Table III's measure) needs the
    least total normal force, ties going to the height nearest the centre of
    mass; ``rule="centre-of-mass-height"`` the first valid candidate from the
    centre of mass's height outwards whose rigid grasp is feasible (else the
    first valid one).

    Raises ``ValueError`` if no height gives a valid placement.
    """
    if rule not in PLACEMENT_RULES:
        raise SceneError(f"unknown placement rule {rule!r}; choose one of {PLACEMENT_RULES}")
    body = rest_state.body
    mesh = body.mesh
    pos = rest_state.positions
    out = mesh.outward_normals(pos)
    z = pos[mesh.surface_nodes, 2]
    z0, z1 = float(z.min()), float(z.max())
    height = z1 - z0
    com_point = (mesh.volumes @ pos[mesh.tets].mean(axis=1)) / mesh.volume
    com = float(com_point[2])
    table_z = rest_state.table_z
    clearance = max(0.1 * radius, abs(float(direction[2])) * (max_squeeze or 0.0))
    tried: set[tuple[int, int]] = set()
    # how many candidates pass each condition in turn (the message when none passes all of them)
    n_clear = n_outside = n_closed = 0
    last: ClosureResult | None = None
    best: tuple[float, int, tuple[int, int], ClosureResult] | None = None
    first: tuple[tuple[int, int], ClosureResult] | None = None
    for k in range(0, 81):
        h = com + (-1) ** k * ((k + 1) // 2) * 0.025 * height
        if not z0 < h < z1:
            continue
        try:
            ij = placement.finger_contact_nodes(mesh, h, direction)
        except ValueError:
            continue
        if ij in tried:
            continue
        tried.add(ij)
        centers = pos[list(ij)] + radius * out[list(ij)]
        if (centers[:, 2] - radius - table_z).min() < clearance:
            continue
        n_clear += 1
        try:
            check_finger_placement(pos, mesh.surface_nodes, centers, radius, contact_nodes=ij, normals=out,
                                   directions=velocities)
        except PlacementError:
            continue
        n_outside += 1
        closure = placement_closure(body, pos, ij, rest_state.support_triangle, mu_finger, mu_table)
        last = closure
        if not closure.closed:
            continue
        n_closed += 1
        grasp = rigid_grasp(pos[list(ij)], -out[list(ij)], com_point, body.weight, mu_finger)
        if rule == "centre-of-mass-height":
            if grasp.feasible:
                return ij, closure
            if first is None:
                first = (ij, closure)
            continue
        force = grasp.total_normal_force if grasp.feasible else np.inf
        if best is None or force < best[0] * (1 - 1e-9):
            best = (force, k, ij, closure)
    if first is not None:
        return first
    if best is not None:
        return best[2], best[3]
    raise ValueError(_no_placement_message(len(tried), n_clear, n_outside, n_closed, clearance, radius, height,
                                           last))


def _no_placement_message(n: int, n_clear: int, n_outside: int, n_closed: int, clearance: float, radius: float,
                          height: float, last: ClosureResult | None) -> str:
    """Why :func:`default_finger_contacts` found no placement: how many candidates passed each condition in turn
    (clear of the table, outside the object, force closure), and what to change."""
    if n == 0:
        return ("no finger placement is valid: no two surface nodes lie at opposite extremes along the squeeze "
                "direction at any height of the object; try another squeeze direction (fingers.directions)")
    mm = 1e3
    parts = [f"of {n} candidate placement{'s' if n != 1 else ''} (the surface nodes extreme along the squeeze "
             f"direction, at heights stepped by 2.5 % of the object's {height * mm:.3g} mm height), {n_clear} "
             f"clear{'s' if n_clear == 1 else ''} the table by {clearance * mm:.3g} mm with a {radius * mm:.3g} mm "
             "fingertip radius"]
    hints: list[str] = []
    if n_clear < n:
        hints += [f"a smaller fingertip (fingers.radius, now {radius * mm:.3g} mm)",
                  "squeeze directions tilted less downward or a smaller solver.max_squeeze"]
    if n_clear:
        parts.append(f"of these, {n_outside} start{'s' if n_outside == 1 else ''} outside the object without "
                     "touching the other fingertip")
        if n_outside < n_clear:
            hints += [f"a smaller fingertip (fingers.radius, now {radius * mm:.3g} mm)",
                      "another squeeze direction (fingers.directions)"]
    if n_outside:
        parts.append(f"of these, {n_closed} {'is' if n_closed == 1 else 'are'} force closure" + (f" (the last: {last.reason})" if last is not None and not last.closed else ""))
        if n_closed < n_outside:
            hints += ["more friction at the fingers (friction.finger)", "another squeeze direction (fingers.directions)"]
    hints = list(dict.fromkeys(hints))
    return "no finger placement is valid: " + "; ".join(parts) + (". Try " + ", or ".join(hints) if hints else "")


def _initial_stiffness(tracker: Tracker, placed: ContactState, velocities: np.ndarray) -> float:
    """k₀: rate of the normal force at the initial contact of finger 1 per unit ρ, N/m.

    ``placed`` is the state of :func:`~fem_grasp.grasp.squeeze.initial_state`, before it is settled: both
    fingertips touch there by construction.  (The settle may release a touch that carries no force, by
    round-off; the finger then re-establishes contact by event A as it moves in, and the increment must
    not depend on which way the round-off went.)
    """
    on = np.flatnonzero(placed.owner == FINGER1)
    if not on.size:
        raise ValueError("the initial placement has no contact on finger 1")
    resp = tracker.response(placed.nodes)
    vel = np.zeros((placed.n_contacts, 3))
    for f in (FINGER1, FINGER2):
        vel[placed.owner == f] = velocities[f]
    rate = (resp.reduced_stiffness @ vel.reshape(-1)).reshape(-1, 3)
    j = int(on[0])
    return float(max(rate[j] @ placed.normals[j], np.linalg.norm(rate[j]) * 1e-3))


# =================================================================== pickup
def pickup(body: Body, *, mu_finger: float | None = None, mu_table: float | None = None,
           finger_radius: float = DEFAULT_RADIUS, contacts: tuple[int, int] | None = None,
           directions: tuple[np.ndarray, np.ndarray] = PAPER_SQUEEZE_DIRECTIONS, ratio: float = 1.0,
           max_squeeze: float | None = None, step: float | None = None, backend: str = "sparse",
           rest_state: RestState | None = None, lift_test_step: float | None = None,
           max_lift: float | None = None, lift: bool = True, max_lift_attempts: int = 4,
           placement_rule: str = DEFAULT_PLACEMENT_RULE, accuracy: float | None = None,
           geometry: Any = None) -> PickupResult:
    """Run Algorithm 1: will two hemispherical fingers pick ``body`` up from the table?

    Parameters
    ----------
    body : Body
        The object, in any orientation (it is posed on the table by
        :func:`fem_grasp.grasp.rest.rest`; ``result.body`` is the posed body).
    mu_finger, mu_table : friction coefficients μ_ℱ, μ_𝒫 (module notes for defaults)
    finger_radius : fingertip radius R, metres
    contacts : (p_i, p_j), node indices of the posed body; default rule in the module notes
    directions : squeeze directions (d̂₁, d̂₂)
    ratio : s ≥ 0: ℱ₂ moves s ρ d̂₂ while ℱ₁ moves ρ d̂₁
    max_squeeze, step : maximum squeeze depth and squeeze increment, metres (module notes)
    backend : "sparse" or "spectral" (:class:`~fem_grasp.elastic.response.ContactResponse`)
    rest_state : a resting state of ``body`` computed before (skips step 2)
    lift_test_step : h of the lift test, newtons (default mg/20)
    max_lift : maximum lift height, metres (default: the object's height)
    lift : run step 5; with False the run stops when the lift test passes
        (``success`` stays False and ``reason`` says the lift was not run)
    placement_rule : how ``contacts`` are chosen when not given, "least-force" or
        "centre-of-mass-height" (:func:`default_finger_contacts`)
    max_lift_attempts : when a simulated lift fails (the object slides on a
        finger, or friction cannot hold it), the squeeze resumes from the
        lift-start state and the lift is tried again at the next passing lift
        test (Algorithm 1 step 6, "go back to step 3"), up to this many lifts
    accuracy : relative accuracy wanted of ρ* and the finger force (e.g. 0.05); None runs once on ``body``'s
        mesh.  With a target, :func:`fem_grasp.grasp.accuracy.converged_pickup` refines the mesh at the contact
        patches and the increments until two successive answers agree within it, and the result (the last
        level's) carries the estimated error in ``result.accuracy``
    geometry : what to remesh for ``accuracy`` (:class:`fem_grasp.mesh.remesh.Geometry`); default: the body's
        boundary surface (:func:`fem_grasp.mesh.remesh.geometry_of_mesh`)

    Returns
    -------
    PickupResult
        ``success`` and ``reason``; see its attributes.  Failures are results.
    """
    prepare_kernels()  # once per process: compile or load the kernels, or say they run as plain Python
    if accuracy is not None:
        from .accuracy import converged_pickup

        return converged_pickup(body, solve=pickup, accuracy=accuracy, geometry=geometry, mu_finger=mu_finger, mu_table=mu_table,
                                finger_radius=finger_radius, contacts=contacts, directions=directions, ratio=ratio,
                                max_squeeze=max_squeeze, step=step, backend=backend, rest_state=rest_state,
                                lift_test_step=lift_test_step, max_lift=max_lift, lift=lift,
                                max_lift_attempts=max_lift_attempts, placement_rule=placement_rule)
    t_start = time.perf_counter()
    mu_f = check_finger_friction(DEFAULT_FRICTION if mu_finger is None else mu_finger, "mu_finger")
    mu_t = mu_f if mu_table is None else check_friction(mu_table, "mu_table")
    finger_radius = check_positive(finger_radius, "the fingertip radius R", "metres", SceneError)
    if not ratio >= 0:
        raise SceneError(f"the squeeze ratio s must be ≥ 0, got {ratio!r}")
    if int(max_lift_attempts) < 1:
        raise ValueError(f"max_lift_attempts must be ≥ 1, got {max_lift_attempts!r}")
    d1, d2 = check_directions(*directions, ratio=ratio)
    timings: dict[str, float] = {}

    # Step 2 (computed first: step 1 needs the resting shape).
    t0 = time.perf_counter()
    rs = rest_state if rest_state is not None else rest(body, mu_t, backend=backend)
    timings["rest"] = time.perf_counter() - t0
    posed = rs.body
    table = rs.table
    result = PickupResult(False, "", posed, rs, (-1, -1), None, mu_f, mu_t, float(finger_radius), (d1, d2),
                          float(ratio), timings=timings)

    if max_squeeze is None:
        max_squeeze = default_max_squeeze(rs.positions, d1)

    # Step 1: force closure of p_i, p_j and the support-triangle centre.
    t0 = time.perf_counter()
    if contacts is None:
        try:
            ij, closure = default_finger_contacts(rs, d1, mu_f, mu_t, finger_radius, np.stack([d1, ratio * d2]),
                                                  rule=placement_rule, max_squeeze=max_squeeze)
        except ValueError as exc:
            result.reason = str(exc) if str(exc).startswith("no finger placement") else \
                f"no initial finger placement: {exc}"
            result.outcome = "no placement"
            timings["closure"] = time.perf_counter() - t0
            timings["total"] = time.perf_counter() - t_start
            return result
    else:
        ij = tuple(int(k) for k in check_contact_nodes(posed.mesh, rs.positions, contacts,
                                                          what="finger contact node"))
        if len(ij) != 2:
            raise ContactNodeError(f"give two finger contact nodes (p_i, p_j), got {len(ij)}")
        out = posed.mesh.outward_normals(rs.positions)
        check_finger_placement(rs.positions, posed.mesh.surface_nodes,
                               rs.positions[list(ij)] + finger_radius * out[list(ij)], finger_radius,
                               contact_nodes=ij, normals=out, directions=np.stack([d1, ratio * d2]))
        closure = placement_closure(posed, rs.positions, ij, rs.support_triangle, mu_f, mu_t)
    result.finger_nodes = ij
    result.closure = closure
    timings["closure"] = time.perf_counter() - t0
    com = (posed.mesh.volumes @ rs.positions[posed.mesh.tets].mean(axis=1)) / posed.mesh.volume
    out = posed.mesh.outward_normals(rs.positions)
    result.rigid = rigid_grasp(rs.positions[list(ij)], -out[list(ij)], com, posed.weight, mu_f)
    if not closure.closed:
        result.reason = f"the initial placement is not force closure (Algorithm 1 step 1): {closure.reason}"
        result.outcome = "not force closure"
        timings["total"] = time.perf_counter() - t_start
        return result

    # Steps 3-4: squeeze with the lift test.
    t0 = time.perf_counter()
    tracker = Tracker(posed, radius=finger_radius, mu_finger=mu_f, mu_table=mu_t, table=table, backend=backend)
    hanging = Tracker(posed, radius=finger_radius, mu_finger=mu_f, mu_table=mu_t, table=None, backend=backend)
    velocities = np.stack([d1, ratio * d2])

    surface = posed.mesh.surface_nodes

    def snap(st: ContactState, label: str, events: Sequence[ContactEvent] = ()) -> None:
        result.snapshots.append(Snapshot.from_state(st, finger_radius, label, events, surface_nodes=surface))

    try:
        placed = initial_state(tracker, rs, ij)
        state, ev0 = tracker.settle(placed, velocities, phase="squeeze")
    except (TrackingError, ValueError) as exc:
        result.reason = f"the fingers cannot be placed: {exc}"
        result.outcome = "placement failed"
        timings["total"] = time.perf_counter() - t_start
        return result
    result.events.extend(ev0)
    snap(state, "initial", ev0)
    if step is None:
        k0 = _initial_stiffness(tracker, placed, velocities)
        rho_star = posed.weight / (max(mu_f, 1e-3) * k0)
        step = min(0.02 * max_squeeze, max(rho_star / 20.0, 1e-3 * max_squeeze))
    result.max_squeeze = float(max_squeeze)
    result.step = float(step)
    lt = LiftTest(hanging, posed.weight, lift_test_step)
    result.lift_test_step = float(lt.step)
    t_squeeze = t0
    timings["squeeze"] = timings["lift_test"] = timings["lift"] = 0.0
    while True:
        sq = squeeze(tracker, state, (d1, d2), ratio, lt, max_squeeze=max_squeeze, step=step,
                     on_event=lambda st, ev: snap(st, "event", ev))
        result.events.extend(sq.events)
        result.liftable.extend(sq.liftable)
        result.squeeze_depth = sq.state.squeeze_depth
        timings["lift_test"] += sq.lift_test_time
        timings["squeeze"] += time.perf_counter() - t_squeeze - sq.lift_test_time
        if not sq.passed:
            result.outcome = "squeeze failed" if sq.failed else "not liftable"
            result.reason = sq.reason + "".join(
                f"; lift attempt at ρ = {1e3 * a.squeeze_depth:.4g} mm failed: {a.reason}" for a in result.lift_attempts)
            result.final = Snapshot.from_state(sq.state, finger_radius, "final", surface_nodes=surface)
            result.finger_normal_force = result.final.finger_normal_force(table)
            timings["total"] = time.perf_counter() - t_start
            return result

        # Step 5: lift.
        t0 = time.perf_counter()
        attempt = len(result.lift_attempts) + 1
        snap(sq.state, "lift start" if attempt == 1 else f"lift start (attempt {attempt})")
        if not lift:
            result.reason = "the lift test passed; the lift was not run (lift=False)"
            result.outcome = "lift not run"
            result.final = result.snapshots[-1]
            result.finger_normal_force = result.final.finger_normal_force(table)
            timings["total"] = time.perf_counter() - t_start
            return result
        if max_lift is None:
            max_lift = float(np.ptp(rs.positions[:, 2]))
        lf = run_lift(tracker, sq.state, max_height=max_lift, step=step,
                      on_event=lambda st, ev: snap(st, "event", ev))
        timings["lift"] += time.perf_counter() - t0
        result.events.extend(lf.events)
        result.lift_attempts.append(LiftAttempt(sq.state.squeeze_depth, lf.success, lf.reason,
                                                lf.state.lift_height, len(lf.events)))
        if lf.success or attempt >= max_lift_attempts or sq.state.squeeze_depth >= max_squeeze * (1 - 1e-9):
            break
        # Algorithm 1 step 6, "otherwise go back to step 3": the simulated lift predicts a slip, so the
        # planner squeezes on from the lift-start state and tries again at the next passing lift test.
        log.info("lift attempt %d at ρ = %.4g m failed (%s); squeezing further", attempt,
                 sq.state.squeeze_depth, lf.reason)
        snap(lf.state, f"lift failed (attempt {attempt})")
        state = replace(sq.state, phase="squeeze")
        t_squeeze = time.perf_counter()
    result.success = lf.success
    result.outcome = "picked up" if lf.success else "lift failed"
    result.reason = lf.reason if attempt == 1 or lf.success else (
        f"{lf.reason} (after {attempt} lift attempts from ρ = {1e3 * result.lift_attempts[0].squeeze_depth:.4g} mm)")
    result.final = Snapshot.from_state(lf.state, finger_radius, "lift-off" if lf.success else "final",
                                       surface_nodes=surface)
    result.snapshots.append(result.final)
    result.finger_normal_force = result.final.finger_normal_force(table)
    timings["total"] = time.perf_counter() - t_start
    log.info("pickup %s: ρ = %.4g m, %d events, %d final contacts, finger normal force %.4g N, %.2f s",
             "succeeded" if result.success else f"failed ({result.reason})", result.squeeze_depth,
             len(result.events), result.n_final_contacts, result.finger_normal_force, timings["total"])
    return result
