"""What a pickup returns: the snapshots, the lift attempts and the whole :class:`PickupResult` (paper §III).

A :class:`PickupResult` is the story of one run of Algorithm 1 (:func:`fem_grasp.grasp.pickup.pickup`):
how it ended (:data:`OUTCOMES`), the events, a :class:`Snapshot` of the object and its contacts at every
event, the liftable-weight history, each :class:`LiftAttempt`, forces and timings, as a dictionary or
JSON for the command line and the batch runs.

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
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from ..contact.obstacles import FINGER1, FINGER2, OBSTACLES, TABLE, Fingertip, TablePlane, sphere_normals
from ..contact.tracking import ContactEvent, ContactState
from ..elastic.body import Body
from ..errors import PickupCheckError
from .checks import contact_law_figures
from .closure import ClosureResult
from .forces import TABLE_III_MEASURE, FingerForce, finger_forces
from .rest import RestState
from .rigid import RigidGrasp

__all__ = ["OUTCOMES", "LiftAttempt", "PickupCheckError", "PickupResult", "Snapshot"]

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
            p = self.node_positions(self.contact_nodes[name])
            out[name] = sphere_normals(p, self.finger_centers[f]) if len(p) else np.zeros((0, 3))
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

    def to_dict(self, geometry: bool = True) -> dict[str, Any]:
        """The snapshot as JSON-ready values; ``geometry=False`` leaves out the node positions."""
        out = {
            "label": self.label, "phase": self.phase, "squeeze_depth": self.squeeze_depth,
            "lift_height": self.lift_height, "finger_radius": self.finger_radius,
            "finger_centers": self.finger_centers.tolist(),
            "contact_nodes": {k: v.tolist() for k, v in self.contact_nodes.items()},
            "contact_forces": {k: v.tolist() for k, v in self.contact_forces.items()},
            "sliding": {k: v.tolist() for k, v in self.sliding.items()},
            "events": [e.to_dict() for e in self.events],
        }
        if geometry:
            out["positions"] = self.positions.tolist()
        return out


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
    step_divisions : sub-increments of the increment in which the lift test first passed (ρ* is found to
        within ``step / step_divisions``; :attr:`~fem_grasp.grasp.options.PickupOptions.step_divisions`)
    lift_test_step : the lift-test step h used, newtons
    accuracy : with ``pickup(..., accuracy=...)``, what the levels of :func:`fem_grasp.grasp.accuracy.converged_pickup`
        found (target, estimated errors, levels), as in result.json; a scene's one run (``--accuracy off``,
        ``--quick``) the error the scene states for it; else None
    estimated_error : ``accuracy``'s estimated relative errors of ρ* and Σ f·n̂ (property)
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
    step_divisions: int = 1
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

    @property
    def estimated_error(self) -> dict[str, float] | None:
        """The answer's estimated relative error, ``{"squeeze_depth": …, "finger_force": …}`` (ρ* and Σ f·n̂; inf:
        not known, or the verdict itself may differ on a finer mesh), from ``accuracy``; None without one."""
        if not self.accuracy:
            return None
        return {k: float(self.accuracy["estimated_error"][k]) for k in ("squeeze_depth", "finger_force")}

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

    def to_dict(self, geometry: bool = True) -> dict[str, Any]:
        """The result as JSON-ready values; ``geometry=False`` leaves out the mesh (``reference_points``,
        ``tets``) and every snapshot's node positions, which a time series holds."""
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
            "step_divisions": self.step_divisions,
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
            **({"reference_points": self.body.mesh.points.tolist(), "tets": self.body.mesh.tets.tolist()}
               if geometry else {}),
            "snapshots": [s.to_dict(geometry) for s in self.snapshots],
            "final": None if self.final is None else self.final.to_dict(geometry),
        }

    def to_json(self, path: str | Path | None = None, indent: int | None = None) -> str:
        """The whole result as JSON; written to ``path`` when given (atomically: never half a file)."""
        text = json.dumps(self.to_dict(), indent=indent, allow_nan=True)
        if path is not None:
            from .._files import atomic_write_text

            atomic_write_text(path, text)
        return text
