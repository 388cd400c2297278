"""Initial resting configuration of a soft object on a table (paper §III-A, Algorithm 1 step 2).

The object is first placed rigidly on a stable support triangle △p_q p_r p_s
(:mod:`fem_grasp.grasp.pose`), then sags under gravity while its contact region
with the table 𝒫 grows.  The paper's iteration for this — hold every contact,
solve eqs. (3)–(5), land the node furthest below 𝒫 (event A), release tensile
contacts (event B), slide the contacts outside their cones onto them by the
quadratic system (6) (event C) — is the event-driven tracking of §III-C with
the gravity load factor λ as its parameter, and :func:`rest` runs it on the
one engine the squeeze, the lift and the lift test use,
:class:`~fem_grasp.contact.tracking.Tracker`:

1. the support triangle is the contact set 𝕂, held, while λ rises from 0 to
   λ₁, where the first free node touches 𝒫 (heights are affine in λ); that
   node joins 𝕂 there (event A).  The tangential forces of three point
   supports often leave their cones at once, and a slip system of two or
   three sliding supports is singular, so the stick/slip state is settled
   from λ₁ on.  On a flat base λ₁ = 0: the nodes lying on 𝒫 that gravity
   pushes into it join at once, those it would pull off are released one at
   a time, the most tensile first (event B), and as every force is then
   proportional to λ until the next event, the configuration is settled at
   a small load, λ = :data:`START_LOAD`, and its slips solved again at once
   at the first load step :data:`LOAD_STEP`;
2. λ rises to 1 (:func:`~fem_grasp.contact.tracking.run` with
   :attr:`~fem_grasp.contact.tracking.Parameter.LOAD`, the fingertips far
   away: they never touch).  With the contact set and the sliding set ℙ
   fixed the forces are affine in λ, ``F̄(λ) = C Δ̄ + λ F̄₀`` (eq. 5), so each
   event is located at the λ where it fires: a free node touches 𝒫 (A, it
   becomes a contact where it touches), a normal force turns tensile (B), a
   force leaves its cone (C: the node slides in the plane by −d_k t̂_k,
   eq. 6), a slip rate reaches zero (D); cascades are settled at the same λ;
3. where the stick/slip rate problem has no solution, or the contact set is
   large (a flat base), the tracker takes the increment as a return mapping
   (:meth:`~fem_grasp.contact.tracking.Tracker.implicit_step`), exactly as in
   the squeeze (see :mod:`fem_grasp.contact.tracking`);
4. the state at λ = 1 is the resting state: :class:`RestState` holds its
   contacts, Δ̄, F̄ and the field Δ (eq. 4) solved at full gravity.

The history holds one :class:`RestIteration` per event, then one for the
settled state.

Gravity ramp
------------
The paper applies the whole weight at once to the support triangle.  For the
stiff objects of Table I that is harmless, but a soft object on a small hull
facet then sags far through the table (centimetres at E = 1e4 Pa: a point
support has no continuum limit) before the second contact is found, and the
linearised rigid rotation of that first state is meaningless.  By default
(``load_ramp=True``) gravity therefore rises event by event as above, in
increments of at most :data:`LOAD_STEP` (the increment matters only where the
tracker takes return mappings).  With ``load_ramp=False`` the full weight is
applied at once and the configuration settled at λ = 1 by the tracker
(:meth:`~fem_grasp.contact.tracking.Tracker.settle`): the nodes below 𝒫 land,
tensile contacts are released and the stick/slip state is found at that λ,
the paper's literal procedure.

Frictionless table (μ = 0)
--------------------------
Every contact then slides freely and the cone is its axis, which the
tracker's slip systems (a slip direction from the friction force) cannot
represent.  The resting state is then the classical roller support, unique
whatever the loading path: at full gravity, every contact's tangential
displacement is set so that its friction force vanishes, nodes below 𝒫 land
(A) and the most tensile contact is released (B) until neither is left.  The
horizontal rigid motion (two translations and the spin about the vertical)
is then undetermined; it is fixed by holding the centre of mass's horizontal
position and the body's mean spin about the vertical axis through it
(mass-weighted least squares over all nodes) at zero.

Tolerances
----------
* with friction, the tracker's event thresholds (:mod:`fem_grasp.contact.tracking`,
  "Tolerances": a node deeper than 1e-10 × diameter touches, a normal force
  below −1e-11 F_s is tensile, …); a node within ``penetration_tol ×
  diameter`` (default 1e-9 × diameter) of 𝒫 in the rigid pose lies on it;
* on a frictionless table, a node is below the plane when it is deeper than
  ``penetration_tol × diameter`` and a contact is tensile below
  ``−FORCE_TOL × mg``;
* :meth:`RestState.check` holds the result to the one contact-law table of
  :mod:`fem_grasp.grasp.checks`, as every pickup snapshot.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..contact import friction
from ..contact.obstacles import TABLE, TablePlane, tangent_basis
from ..contact.tracking import ContactEvent, ContactState, Parameter, Tracker, run
from ..contact.warm_up import prepare_kernels
from ..elastic.body import Body
from ..elastic.response import (
    CollinearContactError,
    ContactResponse,
    ContactSolution,
    check_contact_set,
    contact_dofs,
    contact_response,
)
from ..errors import RestCheckError, RestConvergenceError, TrackingError
from ..settings import DEFAULT_SETTINGS, EngineSettings
from ..threads import one_blas_thread
from .checks import contact_law_figures
from .pose import RestingPose, resting_pose

__all__ = ["RestState", "RestIteration", "RestConvergenceError", "RestCheckError", "rest"]

log = logging.getLogger(__name__)

#: Frictionless table: node penetration tolerance, relative to the mesh diameter.
PENETRATION_TOL = 1e-9
#: Frictionless table: a contact is tensile below −FORCE_TOL × mg (round-off of a node that only touches).
FORCE_TOL = 1e-10
#: Largest increment of the gravity load factor λ in the ramp.  Events split increments; the increment itself
#: matters only where the tracker takes return mappings (large contact sets, friction limits).
LOAD_STEP = 0.1
#: A flat base's stick/slip/release configuration is found at this load factor (module notes, step 1) and its slips
#: are solved again at once at LOAD_STEP.  Settled at LOAD_STEP directly, the cascade slides the base's nodes one at
#: a time, in an order round-off chooses between mirror images, and a mirror-symmetric box would rest asymmetric by
#: 1e-8 of its size (and its squeeze's mirror events fall apart).
START_LOAD = 1e-8
#: The fingertips of the rest's tracker sit this many mesh diameters above the body: they never touch.
FAR_AWAY = 1e3


@dataclass(frozen=True)
class RestIteration:
    """One entry of the resting procedure's history (paper §III-A): an event, or the settled state.

    Attributes
    ----------
    iteration : 1-based entry number
    contacts : contact nodes before the event
    max_penetration : deepest free surface node below the plane in the state the event's step started from
        (m, 0 if none); in the last entry, in the settled state
    new_nodes : the node that became a contact (event A), or ()
    released : the node released because its normal force was tensile (event B), or ()
    sliding : 1 if the event made a contact slide (event C), else 0
    max_slip : the slip of the event's node in the step that ended in the event (m)
    slip_rounds : trial solves of that step (each a slip system, eqs. 6–8; 0 on a frictionless table)
    load_factor : gravity load factor λ at the event
    """

    iteration: int
    contacts: int
    max_penetration: float
    new_nodes: tuple[int, ...]
    released: tuple[int, ...]
    sliding: int
    max_slip: float
    slip_rounds: int = 0
    load_factor: float = 1.0

    @property
    def new_node(self) -> int | None:
        """The node added by this event, or None."""
        return self.new_nodes[0] if self.new_nodes else None


@dataclass(frozen=True)
class RestState:
    """The object resting on the table ``z = table_z`` (paper §III-A).

    Attributes
    ----------
    body : Body
        The posed body: reference positions in the table frame, gravity −z,
        table at ``z = table_z`` touching the support triangle.
    table_z : float
    mu_table : float
        Friction coefficient μ_𝒫 between object and table.
    positions : (n, 3) deformed node positions p̃ = p + δ
    displacements : (n, 3) displacement field Δ
    contact_nodes : (m,) contact index set 𝕂 (= ℂ)
    contact_forces : (m, 3) forces on the object at the contacts, newtons
    contact_displacements : (m, 3) prescribed contact displacements Δ̄
    sliding : (m,) bool, contacts that slid and sit on the cone boundary
        (all True when μ = 0)
    support_triangle : (3,) the initial support triangle △p_q p_r p_s
    history : list of RestIteration
    iterations : number of iterations run (the last one found nothing to do)
    wall_time : seconds, posing included
    pose : RestingPose, the rigid placement
    solution : ContactSolution of the final contact set
    """

    body: Body
    table_z: float
    mu_table: float
    positions: np.ndarray
    displacements: np.ndarray
    contact_nodes: np.ndarray
    contact_forces: np.ndarray
    contact_displacements: np.ndarray
    sliding: np.ndarray
    support_triangle: np.ndarray
    history: list[RestIteration]
    iterations: int
    wall_time: float
    pose: RestingPose
    solution: ContactSolution = field(repr=False)

    @property
    def table(self) -> TablePlane:
        return TablePlane(self.table_z)

    @property
    def normal_forces(self) -> np.ndarray:
        """(m,) f·ẑ at each contact, newtons (positive: compressive)."""
        return self.contact_forces[:, 2]

    @property
    def tangential_forces(self) -> np.ndarray:
        """(m, 3) friction part of each contact force."""
        return friction.tangential_component(self.contact_forces, self.table.up)

    @property
    def max_sag(self) -> float:
        """Largest downward displacement of any node, metres."""
        return float(max(0.0, -self.displacements[:, 2].min()))

    @property
    def n_contacts(self) -> int:
        return len(self.contact_nodes)

    def check(self, raise_on_failure: bool = True, tolerances: dict[str, float] | None = None) -> dict[str, Any]:
        """Verify the contact laws and equilibrium of the resting state (:mod:`fem_grasp.grasp.checks`).

        Returns
        -------
        dict
            The figures of :func:`~fem_grasp.grasp.checks.contact_law_figures`: ``max_penetration`` (m,
            deepest node below the table), ``max_contact_gap`` (m), ``min_normal_force`` (N),
            ``max_stick_cone_violation`` and ``max_slide_cone_error`` ((|f_t| − μ f·n̂)/f·n̂ for sticking
            contacts, its absolute value for sliding ones; None when there is no such contact),
            ``force_residual`` and ``torque_residual`` (relative), ``n_contacts``, ``n_sliding``, ``ok``
            and ``failures`` (list of messages).

        Raises
        ------
        RestCheckError
            If ``raise_on_failure`` and any figure exceeds its tolerance
            (:data:`~fem_grasp.grasp.checks.CHECK_TOLERANCES`).
        """
        m = len(self.contact_nodes)
        surface = self.body.mesh.surface_nodes
        figures = contact_law_figures(self.body, (None, None, self.table), np.full(m, TABLE), self.contact_nodes,
                                      self.positions[self.contact_nodes], self.contact_forces, self.sliding,
                                      np.full(m, self.mu_table), surface, self.positions[surface], tolerances)
        if figures["failures"] and raise_on_failure:
            raise RestCheckError("resting state fails its checks: " + "; ".join(figures["failures"]))
        return figures


class _History:
    """The rest's history: one :class:`RestIteration` per event, within an iteration budget."""

    def __init__(self, body: Body, table: TablePlane, max_iterations: int) -> None:
        self.entries: list[RestIteration] = []
        self.body = body
        self.table = table
        self.max_iterations = int(max_iterations)

    def depth(self, nodes: np.ndarray, surface_positions: np.ndarray) -> float:
        """The deepest free surface node's depth below the table (m, 0 if none is below)."""
        height = self.table.signed_distance(surface_positions)
        height[self.body.mesh.surface_index[np.asarray(nodes, dtype=np.int64)]] = np.inf
        return float(max(-height.min(initial=np.inf), 0.0))

    def add(self, entry: RestIteration) -> None:
        self.entries.append(entry)
        if len(self.entries) >= self.max_iterations:
            raise RestConvergenceError(
                f"the resting iteration did not settle in {self.max_iterations} iterations (load factor "
                f"{entry.load_factor:.4g}, {entry.contacts} contacts, last penetration {entry.max_penetration:.3g} m); "
                "raise max_iterations or check the mesh")

    def events(self, before: ContactState, after: ContactState, events: list[ContactEvent], trials: int) -> None:
        """Record the events of one step of the tracker, from state ``before`` to ``after``."""
        depth = self.depth(before.nodes, before.surface_positions)
        slip0 = dict(zip(before.nodes.tolist(), before.slip.tolist()))
        slip1 = dict(zip(after.nodes.tolist(), after.slip.tolist()))
        count = before.n_contacts
        for e in events:
            slid = slip1.get(e.node, 0.0) - slip0[e.node] if e.node in slip0 else 0.0
            self.add(RestIteration(len(self.entries) + 1, count, depth, (e.node,) if e.kind == "A" else (),
                                   (e.node,) if e.kind == "B" else (), int(e.kind == "C"), max(slid, 0.0), trials,
                                   float(after.load)))
            trials = 0
            count += {"A": 1, "B": -1}.get(e.kind, 0)
            log.debug("rest: event %s, node %d at λ = %.6g", e.kind, e.node, after.load)


def _tracked_rest(posed: Body, table: TablePlane, triangle: np.ndarray, mu: float, backend: str, load_ramp: bool,
                  tol: float, history: _History, settings: EngineSettings | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, ContactResponse]:
    """The rest on a table with friction, by the event tracking with the load factor as parameter (module notes):
    the final contact nodes, their displacements Δ̄, sliding flags and contact response.  Raises
    :class:`TrackingError` where the tracker finds no quasi-static state."""
    tracker = Tracker(posed, radius=posed.mesh.diameter, mu_finger=mu, mu_table=mu, table=table, backend=backend,
                      settings=settings)
    far = posed.center_of_mass + FAR_AWAY * posed.mesh.diameter * table.up
    centers = np.stack([far, far + 3.0 * posed.mesh.diameter * tangent_basis(table.up)[0]])
    still = np.zeros((2, 3))

    def held(nodes: np.ndarray, load: float, disp: np.ndarray | None = None) -> ContactState:
        m = len(nodes)
        return tracker.make_state(phase="rest", squeeze_depth=0.0, lift_height=0.0, load=load, centers=centers,
                                  nodes=nodes, owner=np.full(m, TABLE), disp=np.zeros((m, 3)) if disp is None else disp,
                                  sliding=np.zeros(m, dtype=bool))

    state = held(np.asarray(triangle, dtype=np.int64), 1.0)
    first = np.inf
    if load_ramp:
        # Gravity rises on the support triangle alone, held, until the first free node touches the table (event
        # A, at λ₁; at λ₁ = 0 for a flat base, whose nodes on the table sink as soon as gravity acts): heights
        # are affine in λ, h(λ) = h(0) + λ ∂h/∂λ.  The stick/slip state is settled from there on, where the
        # contact set is more than the bare triangle: the tangential forces of three point supports often leave
        # their cones at once, and a slip system of two or three sliding supports is singular.
        surface = posed.mesh.surface_nodes
        height = np.maximum(table.signed_distance(posed.mesh.surface_points), 0.0)
        height[height <= tol] = 0.0
        rate = (state.surface_positions - posed.mesh.surface_points) @ table.up
        free = (rate < 0) & ~np.isin(surface, state.nodes)
        lam = np.full(len(surface), np.inf)
        lam[free] = height[free] / -rate[free]
        first = float(lam.min(initial=np.inf))
        if first < 1.0:
            at = lam <= first + 1e-12 * max(first, 1.0)
            touching = surface[at]
            # where they touch: their displacement at λ₁, onto the plane
            d = first * (state.surface_positions[at] - posed.mesh.surface_points[at])
            d -= table.signed_distance(posed.mesh.points[touching] + d)[:, None] * table.up
            before = held(state.nodes, first)
            state = held(np.concatenate([state.nodes, touching]), first, np.vstack([before.disp, d]))
            history.events(before, state, [ContactEvent("rest", "A", int(k), "table", 0.0, 0.0) for k in touching],
                           0)
        if first == 0.0:
            # A flat base: with every contact held, all forces grow in proportion to λ from zero, so that every
            # contact whose force gravity makes tensile would break at λ = 0⁺ together.  They are released one at
            # a time, the most tensile first (as in the paper's iteration), before the load is raised.
            while True:
                fn = friction.normal_component(tracker.response(state.nodes).gravity_forces, table.up)
                j = int(np.argmin(fn))
                if fn[j] >= 0:
                    break
                keep = np.arange(state.n_contacts) != j
                before, state = state, held(state.nodes[keep], 0.0)
                history.events(before, state, [ContactEvent("rest", "B", int(before.nodes[j]), "table", 0.0, 0.0)], 0)
            # The stick/slip state is proportional to λ too until the next event: it is settled at a small load
            # (at λ = 0 every force is zero; the tracker's thresholds are relative to the forces of the state).
            state = held(state.nodes, START_LOAD)
    last = [state, 0]

    def on_event(st: ContactState, ev: list[ContactEvent]) -> None:
        history.events(last[0], st, ev, tracker.solves - last[1])

    def after_step(st: ContactState, ev: list[ContactEvent]) -> bool:
        last[0], last[1] = st, tracker.solves
        return False

    def settled_step(st: ContactState, ev: list[ContactEvent]) -> None:  # a settle: its events, then its end
        on_event(st, ev)
        after_step(st, ev)

    with one_blas_thread():
        settled, ev = tracker.settle(state, still, phase="rest", param=Parameter.LOAD)
        settled_step(settled, ev)
        if load_ramp and first == 0.0 and settled.load < LOAD_STEP < 1.0:
            # Proportional loading up to the next event: the stick/slip/release configuration found at START_LOAD
            # is that of the first load step too (the tracker's first increment would otherwise be 1e7 times its
            # base).  Its slips are solved there at once, from every contact held where it touched: the cascade
            # at START_LOAD slid the nodes one at a time, in an order round-off chose between mirror images.
            # Events the step passed over fire there.
            start = dict(zip(state.nodes.tolist(), state.disp))
            base = np.array([start.get(n, d) for n, d in zip(settled.nodes.tolist(), settled.disp)]).reshape(-1, 3)
            scaled = tracker.make_state(phase="rest", squeeze_depth=0.0, lift_height=0.0, load=LOAD_STEP,
                                        centers=centers, nodes=settled.nodes, owner=settled.owner, disp=base,
                                        sliding=settled.sliding)
            settled, ev = tracker.settle(scaled, still, phase="rest", param=Parameter.LOAD)
            settled_step(settled, ev)
    final = settled
    if load_ramp:
        final, _, _ = run(tracker, settled, still, stop=1.0, step=LOAD_STEP, param=Parameter.LOAD, phase="rest",
                          after_step=after_step, on_event=on_event, max_events=history.max_iterations)
    return final.nodes, final.disp, final.sliding, tracker.response(final.nodes)


def _frictionless_tangential_displacements(stiffness: np.ndarray, held_forces: np.ndarray, normal: np.ndarray,
                                           gauge: np.ndarray) -> np.ndarray:
    """Tangential contact displacements that remove every friction force (μ = 0).

    With μ = 0 the cone degenerates to its axis and every contact slides
    freely in the plane.  Solve ``(C u)_t = −(F̄_held)_t`` for tangential
    increments u (m, 3), u·n̂ = 0.  The tangential block of C is singular: the
    in-plane rigid motions (two translations and the spin about n̂) change no
    force.  They are fixed by the gauge condition ``gaugeᵀ u = 0``, where
    ``gauge`` (3m, g) holds those rigid motions at the contact DOFs; the
    caller may add any rigid in-plane motion afterwards.

    Returns
    -------
    (m, 3) displacement increments; the forces ``F̄_held + C u`` are normal.
    """
    f0 = np.asarray(held_forces, dtype=float)
    m = len(f0)
    c = np.asarray(stiffness, dtype=float)
    normal = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    basis = tangent_basis(normal)  # (2, 3)
    # Tangential block of C and of the loads, in the (e1, e2) coordinates of every node.
    ctt = np.einsum("pa,kalb,qb->kplq", basis, c.reshape(m, 3, m, 3), basis, optimize=True).reshape(2 * m, 2 * m)
    rhs = -(f0 @ basis.T).reshape(-1)
    g = np.einsum("pa,kag->kpg", basis, np.asarray(gauge, dtype=float).reshape(m, 3, -1)).reshape(2 * m, -1)
    q, _ = np.linalg.qr(g)
    # Scale the border like the block it borders.
    s = max(float(np.abs(np.diag(ctt)).max()), np.finfo(float).tiny)
    ng = q.shape[1]
    mat = np.block([[ctt, s * q], [s * q.T, np.zeros((ng, ng))]])
    sol = np.linalg.solve(mat, np.concatenate([rhs, np.zeros(ng)]))
    return sol[:2 * m].reshape(m, 2) @ basis


def _roller_solution(body: Body, table: TablePlane, resp: ContactResponse, held: np.ndarray) -> ContactSolution:
    """Eqs. (3)–(5) at full gravity with every contact on the plane and free in it (μ = 0): the contact
    displacements ``held`` keep their normal parts; their tangential parts remove every friction force, with
    the centre of mass's horizontal position and the mean spin about the vertical held at zero."""
    nodes = resp.nodes
    d = held + _frictionless_tangential_displacements(resp.reduced_stiffness, resp.forces(held), table.up,
                                                      body.rigid_modes[contact_dofs(nodes)][:, [0, 1, 5]])
    field = resp.solve(d).displacements
    mass = -body.gravity_loads.reshape(-1, 3)[:, 2]
    w = mass / mass.sum()
    rel = body.mesh.points - body.center_of_mass
    tx, ty = w @ field[:, 0], w @ field[:, 1]
    spin = (w @ (rel[:, 0] * field[:, 1] - rel[:, 1] * field[:, 0])) / (w @ (rel[:, 0] ** 2 + rel[:, 1] ** 2))
    r = rel[nodes]
    d[:, 0] -= tx - spin * r[:, 1]
    d[:, 1] -= ty + spin * r[:, 0]
    return resp.solve(d)


def _frictionless_rest(posed: Body, table: TablePlane, triangle: np.ndarray, backend: str, tol: float,
                       history: _History, neighbour_updates: bool = True
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, ContactResponse]:
    """The rest on a frictionless table (module notes): the roller support's contact set, by landing the nodes
    below the table (A) and releasing the most tensile contact (B) until neither is left; the final contact
    nodes, their displacements Δ̄, sliding flags (all set) and contact response; ``neighbour_updates``: each set's
    response derived from the last one's (``EngineSettings.neighbour_updates``)."""
    points = posed.mesh.points
    surface = posed.mesh.surface_nodes
    nodes = np.asarray(triangle, dtype=np.int64)
    held = np.zeros((len(nodes), 3))
    force_tol = FORCE_TOL * posed.weight
    resp: ContactResponse | None = None
    while True:
        resp = contact_response(posed, nodes, backend=backend,
                                cached=() if resp is None or not neighbour_updates else (resp,))
        sol = _roller_solution(posed, table, resp, held)
        held = sol.displacements[nodes]
        height = table.signed_distance(sol.positions[surface])
        height[np.isin(surface, nodes)] = np.inf
        depth = float(max(-height.min(), 0.0))
        deep = np.flatnonzero(-height > tol)
        if deep.size:  # event A: every node below the table lands on it, deepest first
            for j in deep[np.argsort(height[deep], kind="stable")]:
                history.add(RestIteration(len(history.entries) + 1, len(nodes), depth, (int(surface[j]),), (), 0,
                                          0.0, 0, 1.0))
                d = sol.displacements[surface[j]].copy()
                d -= table.signed_distance(points[surface[j]] + d) * table.up
                nodes = np.append(nodes, surface[j])
                held = np.vstack([held, d])
            continue
        fn = friction.normal_component(sol.forces, table.up)
        j = int(np.argmin(fn))
        if fn[j] >= -force_tol:
            return nodes, held, np.ones(len(nodes), dtype=bool), resp
        keep = np.arange(len(nodes)) != j  # event B: the most tensile contact is released
        try:
            check_contact_set(points, nodes[keep])
        except CollinearContactError:
            raise RestConvergenceError(
                f"contact node {nodes[j]} pulls on the table (normal force {fn[j]:.3g} N) and releasing it would "
                f"leave {int(keep.sum())} collinear or too few contacts: the object would tip off its support") from None
        history.add(RestIteration(len(history.entries) + 1, len(nodes), depth, (), (int(nodes[j]),), 0, 0.0, 0, 1.0))
        nodes, held = nodes[keep], held[keep]


def rest(body: Body, mu_table: float, *, down: np.ndarray | None = None, table_z: float = 0.0,
         support: np.ndarray | None = None, backend: str = "sparse", max_iterations: int | None = None,
         load_ramp: bool = True, penetration_tol: float = PENETRATION_TOL,
         cone_rtol: float = friction.CONE_RTOL, settings: EngineSettings | None = None) -> RestState:
    """Compute the object's initial resting configuration on the table (paper §III-A).

    Parameters
    ----------
    body : Body
        The object in any orientation.
    mu_table : float
        Coefficient of friction μ_𝒫 between the object and the table, ≥ 0
        (μ = 0: frictionless table, see the module notes).
    down : (3,) array_like, optional
        Which way is down in the body's frame (default −z); selects the
        stable hull facet it rests on (:func:`fem_grasp.grasp.pose.resting_pose`).
    table_z : float
        Height of the table plane z = table_z in the output frame.
    support : (3,) int, optional
        A user-named support triangle △p_q p_r p_s.
    backend : {"sparse", "spectral"}
        Backend of :class:`~fem_grasp.elastic.response.ContactResponse`.
    max_iterations : int, optional
        Budget of history entries (events, and the settled state); default
        three times the number of surface nodes (a node may be released and
        land again).
    load_ramp : bool
        Raise gravity from 0 to 1 event by event (default), or apply it at once
        as the paper does (module notes, "Gravity ramp").  A frictionless
        table's resting state does not depend on the path.
    penetration_tol : float
        Frictionless table: a node deeper than ``penetration_tol × diameter``
        below the table is a new contact.  With friction, a node that close to
        the table in the rigid pose lies on it, and the tracker's event
        thresholds apply (module notes, "Tolerances").
    cone_rtol : float
        Not used: the cone test is the tracker's event C (module notes, "Tolerances").
    settings : EngineSettings, optional
        The event tracking's numerical settings (:class:`~fem_grasp.settings.EngineSettings`; default: the
        engine's defaults).

    Returns
    -------
    RestState
        Deformed shape, contact set and forces, sliding flags, history.

    Raises
    ------
    ValueError
        Bad arguments, or a named support triangle on which the object would tip.
    RestConvergenceError
        If the iteration does not settle within ``max_iterations``, or the
        object finds no quasi-static state on the table (it loses its support
        and would tip, or slides off).
    """
    prepare_kernels()  # once per process: compile or load the kernels, or say they run as plain Python
    start = time.perf_counter()
    if not np.isfinite(mu_table) or mu_table < 0:
        raise ValueError(f"mu_table must be a finite friction coefficient >= 0, got {mu_table!r}")
    if max_iterations is None:
        max_iterations = 3 * len(body.mesh.surface_nodes)
    if int(max_iterations) < 1:
        raise ValueError(f"max_iterations must be positive, got {max_iterations!r}")
    pose = resting_pose(body, down=down, table_z=table_z, support=support)
    posed = pose.body
    table = TablePlane(table_z)
    history = _History(posed, table, int(max_iterations))
    if mu_table == 0:
        nodes, disp, sliding, resp = _frictionless_rest(posed, table, pose.triangle, backend,
                                                        penetration_tol * posed.mesh.diameter, history,
                                                        (settings or DEFAULT_SETTINGS).neighbour_updates)
    else:
        try:
            nodes, disp, sliding, resp = _tracked_rest(posed, table, pose.triangle, float(mu_table), backend,
                                                       load_ramp, penetration_tol * posed.mesh.diameter, history,
                                                       settings)
        except TrackingError as exc:
            raise RestConvergenceError(f"the object does not come to rest on the table: {exc}") from None
    sol = resp.solve(disp)  # at full gravity (λ = 1)
    history.entries.append(RestIteration(len(history.entries) + 1, len(nodes),
                                         history.depth(nodes, sol.positions[posed.mesh.surface_nodes]), (), (), 0,
                                         0.0, 0, 1.0))
    wall = time.perf_counter() - start
    log.info("resting state: %d contacts (%d sliding) after %d events, max sag %.3g m, %.2f s",
             len(nodes), sliding.sum(), len(history.entries) - 1, -sol.displacements[:, 2].min(), wall)
    return RestState(posed, float(table_z), float(mu_table), sol.positions, sol.displacements, nodes, sol.forces,
                     disp, sliding, pose.triangle.copy(), history.entries, len(history.entries), wall, pose, sol)
