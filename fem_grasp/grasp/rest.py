"""Initial resting configuration of a soft object on a table (paper §III-A, Algorithm 1 step 2).

The object is first placed rigidly on a stable support triangle △p_q p_r p_s
(:mod:`fem_grasp.grasp.pose`), then sags under gravity while its contact region
with the table 𝒫 grows.  :func:`rest` follows the paper's iteration:

1. P ← ∅ (no sliding node yet in this iteration).
2. Solve the deformation with every contact node held where it is
   (eqs. 3–5, :class:`~fem_grasp.elastic.response.ContactResponse`), and
3. update the displacements and the contact forces.
4. Stop if no node lies below 𝒫, every contact force is compressive and
   inside its friction cone.
5. New contact (event A): the node furthest below 𝒫 joins the contact set.
   Because the model is affine we do not scale the step as the paper does;
   the node's displacement is prescribed so that it lands on 𝒫 (its vertical
   displacement) and keeps its horizontal displacement.  Contacts whose
   normal force is tensile are released (event B), the most tensile first,
   until a node comes below the table (then the next iteration lands it
   first: the object rocks onto a new support).
6. Contacts whose force lies outside the friction cone form the sliding set P.
7. Their slip distances d_k solve the quadratic system (6) (node k moves by
   −d_k t̂_k, t̂_k its tangential force direction at the start of the slip);
   see :func:`fem_grasp.contact.plane_slip.settle_plane_slip`.

The state is kept as total contact displacements, so "holding" a contact
means keeping its prescribed displacement; step 2 of a later iteration then
reproduces the state left by step 7.

Gravity ramp (event-driven loading)
-----------------------------------
The paper applies the whole weight at once to the support triangle.  For the
stiff objects of Table I that is harmless, but a soft object on a small hull
facet then sags far through the table (centimetres at E = 1e4 Pa: a point
support has no continuum limit) before the second contact is found, and the
linearised rigid rotation of that first state is meaningless.  By default
(``load_ramp=True``) gravity is therefore scaled by a load factor λ that
rises from 0 to 1 in the event-driven manner of the paper's §I: with the
contact set and displacements fixed, every quantity is affine in λ
(``F̄(λ) = F̄(Δ̄, 0) + λ F̄_g``), so λ is advanced exactly to the next value at
which a free node touches 𝒫; that node (with any that touch at the same λ)
becomes a contact there, and events B and C are settled at that λ as in
steps 5–7.  With ``load_ramp=False`` the iteration starts at λ = 1, the
paper's literal procedure.

Frictionless table (μ = 0)
--------------------------
Every contact then slides freely and the cone is its axis: each iteration
sets the tangential contact displacements so that every friction force
vanishes (:func:`fem_grasp.contact.plane_slip.frictionless_tangential_displacements`).
The horizontal rigid motion (two translations and the spin about the
vertical) is then undetermined; it is fixed by holding the centre of mass's
horizontal position and the body's mean spin about the vertical axis through
it (mass-weighted least squares over all nodes) at zero.

Tolerances
----------
* a node is below the plane when it is deeper than ``penetration_tol ×
  diameter`` (default 1e-9 × diameter);
* a contact force is outside its cone when ``|f_t| − μ f·n̂ > cone_rtol ·
  f·n̂`` (default 1e-9);
* :meth:`RestState.check` holds the result to the one contact-law table of
  :mod:`fem_grasp.grasp.checks`, as every pickup snapshot.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..contact import friction, plane_slip
from ..contact.obstacles import TABLE, TablePlane
from ..contact.warm_up import prepare_kernels
from ..elastic.body import Body
from ..elastic.compliance import PREFETCH_NODES
from ..elastic.response import (
    CollinearContactError,
    ContactResponse,
    ContactSolution,
    check_contact_set,
    contact_dofs,
    contact_response,
)
from ..errors import RestCheckError, RestConvergenceError
from .checks import contact_law_figures
from .pose import RestingPose, resting_pose

__all__ = ["RestState", "RestIteration", "RestConvergenceError", "RestCheckError", "rest"]

log = logging.getLogger(__name__)

#: Node penetration tolerance, relative to the mesh diameter.
PENETRATION_TOL = 1e-9
#: Force round-off tolerance, relative to the weight (see ``_Solver.force_tol``).
FORCE_TOL = 1e-10


@dataclass(frozen=True)
class RestIteration:
    """One iteration of the resting procedure (paper §III-A).

    Attributes
    ----------
    iteration : 1-based iteration number
    contacts : contact nodes at the start of the iteration
    max_penetration : deepest node below the plane at the start (m, 0 if none)
    new_nodes : nodes added as contacts (event A): the deepest one, or those
        touching the table at the new load factor
    load_factor : gravity load factor λ at the end of the iteration
    released : nodes released because their normal force was tensile (event B)
    sliding : number of nodes that slid in this iteration (event C)
    max_slip : largest slip distance in this iteration (m)
    slip_rounds : slip systems (6) solved in this iteration
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
        """The (first) node added in this iteration, or None."""
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


@dataclass(frozen=True)
class _State:
    """Contact forces and the displacement field on the surface (``mesh.surface_nodes`` order) at the solver's
    load factor: the events of the resting iteration look at surface nodes only."""

    forces: np.ndarray
    displacements: np.ndarray  # (s, 3)
    positions: np.ndarray  # (s, 3)
    gravity_displacements: np.ndarray | None  # (s, 3) ∂Δ/∂λ: full gravity with the contacts held at zero


class _Solver:
    """The state of the resting iteration: contact set, prescribed displacements, sliding flags, load factor."""

    def __init__(self, body: Body, table: TablePlane, mu: float, backend: str, cone_rtol: float,
                 penetration_tol: float, load_factor: float) -> None:
        self.body = body
        self.table = table
        self.mu = mu
        self.backend = backend
        self.cone_rtol = cone_rtol
        self.penetration_tol = penetration_tol
        self.lam = load_factor
        #: Normal forces within ± this of zero are neither tensile nor tested against their cone while λ < 1:
        #: a node that has just touched the table carries zero force up to round-off.
        self.force_tol = FORCE_TOL * body.weight
        self.points = body.mesh.points
        self.surface = body.mesh.surface_nodes
        self._surface_points = body.mesh.surface_points
        self.contacts: list[int] = []
        self.disp: dict[int, np.ndarray] = {}
        self.sliding: set[int] = set()
        self._responses: dict[tuple[int, ...], ContactResponse] = {}
        self._gravity_field: np.ndarray | None = None
        mass = -body.gravity_loads.reshape(-1, 3)[:, 2]
        self._mass = mass / mass.sum()

    # ---------------------------------------------------------------- helpers
    def response(self) -> ContactResponse:
        key = tuple(self.contacts)
        if key not in self._responses:
            # derived from the last set (a node or two away) where that pays
            self._responses = {key: contact_response(self.body, np.array(key), backend=self.backend,
                                                     cached=self._responses.values())}
            self._gravity_field = None
        return self._responses[key]

    def gravity_field(self, resp: ContactResponse) -> np.ndarray:
        """The surface displacements of gravity alone, contacts held at zero (once per contact set)."""
        if self._gravity_field is None:
            self._gravity_field = resp.surface_displacements(np.zeros((resp.n_contacts, 3)))
        return self._gravity_field

    def prescribed(self) -> np.ndarray:
        return np.array([self.disp[k] for k in self.contacts])

    def prefetch_columns(self, nodes: np.ndarray, surface_positions: np.ndarray) -> None:
        """With the sparse backend, when new contact ``nodes`` lack their compliance columns, compute them
        together with those of the lowest uncached free surface nodes (the likely next contacts):
        PREFETCH_NODES in one solve."""
        nodes = np.asarray(nodes, dtype=np.int64)
        comp = self.body.compliance
        if self.backend != "sparse" or all(comp.is_cached(k) for k in nodes):
            return
        free_at = ~np.isin(self.surface, np.concatenate([self.contacts, nodes]))
        height = self.table.signed_distance(surface_positions[free_at])
        comp.prefetch(nodes, likely=self.surface[free_at][np.argsort(height, kind="stable")], count=PREFETCH_NODES)

    def add(self, node: int, displacement: np.ndarray) -> None:
        d = np.array(displacement, dtype=float)
        # Land on the plane: move along the normal only.
        d += -self.table.signed_distance(self.points[node] + d) * self.table.up
        self.contacts.append(int(node))
        self.disp[int(node)] = d

    def remove(self, node: int) -> None:
        self.contacts.remove(node)
        self.disp.pop(node)
        self.sliding.discard(node)

    def _forces(self, resp: ContactResponse, d: np.ndarray) -> np.ndarray:
        """F̄(Δ̄, λ) = F̄(Δ̄) − (1 − λ) F̄₀: eq. (5) with gravity scaled by λ."""
        f = resp.forces(d)
        return f if self.lam == 1.0 else f - (1.0 - self.lam) * resp.gravity_forces

    def solve(self) -> _State:
        """Eqs. (3)–(5) at load factor λ for the held contacts; with μ = 0 first free every tangential force."""
        resp = self.response()
        if self.mu == 0.0:
            self._frictionless(resp)
        d = self.prescribed()
        forces, field = resp.forces(d), resp.surface_displacements(d)
        if self.lam == 1.0:
            return _State(forces, field, self._surface_points + field, None)
        grav = self.gravity_field(resp)
        field = field - (1.0 - self.lam) * grav
        return _State(forces - (1.0 - self.lam) * resp.gravity_forces, field, self._surface_points + field, grav)

    def solution(self) -> ContactSolution:
        """The final :class:`ContactSolution` (λ = 1)."""
        return self.response().solve(self.prescribed())

    def _frictionless(self, resp: ContactResponse) -> None:
        d = self.prescribed()
        nodes = np.array(self.contacts)
        dofs = contact_dofs(nodes)
        gauge = self.body.rigid_modes[dofs][:, [0, 1, 5]]  # t_x, t_y, r_z at the contacts
        d = d + plane_slip.frictionless_tangential_displacements(resp.reduced_stiffness, self._forces(resp, d),
                                                               self.table.up, gauge)
        # Hold the centre of mass horizontally and the mean spin about the vertical at zero.
        field = resp.solve(d).displacements
        if self.lam != 1.0:
            field = field - (1.0 - self.lam) * resp.solve(np.zeros_like(d)).displacements
        rel = self.points - self.body.center_of_mass
        w = self._mass
        tx, ty = w @ field[:, 0], w @ field[:, 1]
        spin = (w @ (rel[:, 0] * field[:, 1] - rel[:, 1] * field[:, 0])) / (w @ (rel[:, 0] ** 2 + rel[:, 1] ** 2))
        r = rel[nodes]
        d[:, 0] -= tx - spin * r[:, 1]
        d[:, 1] -= ty + spin * r[:, 0]
        for k, dk in zip(self.contacts, d):
            self.disp[k] = dk

    def normal_forces(self, forces: np.ndarray) -> np.ndarray:
        return friction.normal_component(forces, self.table.up)

    def _zero_force(self) -> float:
        return self.force_tol if self.lam < 1.0 else 0.0

    def tensile(self, forces: np.ndarray) -> np.ndarray:
        """Mask of contacts whose normal force is tensile (event B)."""
        return self.normal_forces(forces) < (-self._zero_force() if self.lam < 1.0 else np.finfo(float).tiny)

    def outside_cone(self, forces: np.ndarray) -> np.ndarray:
        """Positions of contacts whose force lies outside the friction cone (event C)."""
        if self.mu == 0.0:
            return np.zeros(0, dtype=np.int64)
        fn = self.normal_forces(forces)
        viol = friction.cone_violation(forces, self.table.up, self.mu)
        return np.flatnonzero((fn > self._zero_force()) & (viol > self.cone_rtol * fn))

    def update_stick(self, forces: np.ndarray) -> None:
        """Event D: a sliding contact whose force moved strictly inside its cone sticks again."""
        if self.mu == 0.0:
            self.sliding = set(self.contacts)
            return
        fn = self.normal_forces(forces)
        viol = friction.cone_violation(forces, self.table.up, self.mu)
        for j, k in enumerate(self.contacts):
            if k in self.sliding and viol[j] < -self.cone_rtol * fn[j]:
                self.sliding.discard(k)

    def deepest(self, state: _State) -> tuple[int, float]:
        """The non-contact surface node furthest below the table and its depth (0 if none is below)."""
        in_contact = np.isin(self.surface, self.contacts)
        height = self.table.signed_distance(state.positions)
        height[in_contact] = np.inf
        j = int(np.argmin(height))
        return int(self.surface[j]), float(max(-height[j], 0.0))

    def next_touch(self, state: _State) -> tuple[float, np.ndarray]:
        """The next load factor λ' ≥ λ at which free surface nodes touch the table, and those nodes.

        Heights are affine in λ, ``h(λ') = h(λ) + (λ' − λ) ∂h/∂λ``; a node on
        the table that moves down as λ grows touches at λ' = λ.  Nodes whose
        touching values agree to 1e-12 touch together.  Returns (inf, []) when
        no node would touch.
        """
        free_at = ~np.isin(self.surface, self.contacts)
        free = self.surface[free_at]
        h = self.table.signed_distance(state.positions[free_at])
        rate = state.gravity_displacements[free_at] @ self.table.up
        down = rate < 0
        if not down.any():
            return np.inf, np.zeros(0, dtype=np.int64)
        lam = self.lam + np.maximum(h[down], 0.0) / -rate[down]
        first = float(lam.min())
        return first, free[down][lam <= first + 1e-12 * max(first, 1.0)]

    def release_tensile(self) -> tuple[_State, list[int]]:
        """Event B: release tensile contacts, the most tensile first.

        Releasing stops early when a node has come below the table (event A
        comes first in the next iteration), and a contact whose release would
        leave fewer than three or collinear contacts is kept while some node
        is below the table (the object is rocking onto a new support);
        otherwise the object would tip and :class:`RestConvergenceError` is
        raised.
        """
        released: list[int] = []
        state = self.solve()
        while True:
            fn = self.normal_forces(state.forces)
            if not self.tensile(state.forces).any():
                return state, released
            below = self.deepest(state)[1] > self.penetration_tol
            if released and below:
                return state, released
            j = int(np.argmin(fn))
            node = self.contacts[j]
            remaining = [k for k in self.contacts if k != node]
            try:
                check_contact_set(self.points, np.array(remaining))
            except CollinearContactError:
                if below:
                    return state, released
                raise RestConvergenceError(
                    f"contact node {node} pulls on the table (normal force {fn[j]:.3g} N) and releasing it would "
                    f"leave {len(remaining)} collinear or too few contacts: the object would tip off its support") from None
            self.remove(node)
            released.append(node)
            log.debug("event B: released node %d (normal force %.3g N, λ = %.4g)", node, fn[j], self.lam)
            state = self.solve()

    def slip(self, state: _State) -> tuple[_State, int, float, int]:
        """Steps 6–7: slide the contacts outside their cones back onto them (eq. 6).

        Returns the new state, the number of nodes that slid, the largest slip
        (m) and the number of slip systems solved.
        """
        if not len(self.outside_cone(state.forces)):
            return state, 0, 0.0, 0
        resp = self.response()
        held = self.prescribed()
        result = plane_slip.settle_plane_slip(resp.reduced_stiffness, state.forces, self.table.up, self.mu,
                                            rtol=self.cone_rtol, min_normal_force=self._zero_force())
        if not len(result.slid):
            return state, 0, 0.0, result.rounds
        for j, k in enumerate(self.contacts):
            self.disp[k] = held[j] + result.displacements[j]
        for j in result.slid:
            self.sliding.add(self.contacts[int(j)])
        slips = np.linalg.norm(result.displacements[result.slid], axis=1)
        log.debug("event C: %d node(s) slid in %d round(s) (%d fallback), max slip %.3g m", len(result.slid),
                  result.rounds, result.fallbacks, slips.max())
        return self.solve(), len(result.slid), float(slips.max()), result.rounds


def rest(body: Body, mu_table: float, *, down: np.ndarray | None = None, table_z: float = 0.0,
         support: np.ndarray | None = None, backend: str = "sparse", max_iterations: int | None = None,
         load_ramp: bool = True, penetration_tol: float = PENETRATION_TOL,
         cone_rtol: float = friction.CONE_RTOL) -> RestState:
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
        Iteration budget; default three times the number of surface nodes
        (an iteration adds contacts, and a node may be released and land again).
    load_ramp : bool
        Raise gravity from 0 to 1 event by event (default), or apply it at once
        as the paper does (module notes, "Gravity ramp").
    penetration_tol : float
        A node deeper than ``penetration_tol × diameter`` below the table is
        a new contact.
    cone_rtol : float
        A contact is outside its cone when ``|f_t| − μ f·n̂ > cone_rtol f·n̂``.

    Returns
    -------
    RestState
        Deformed shape, contact set and forces, sliding flags, history.

    Raises
    ------
    ValueError
        Bad arguments, or a named support triangle on which the object would tip.
    RestConvergenceError
        If the iteration does not settle within ``max_iterations`` or loses
        its support (tensile contacts leaving fewer than three or collinear
        contacts).
    fem_grasp.errors.FrictionError
        If a slip system (6) has no admissible solution.
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
    tol = penetration_tol * posed.mesh.diameter
    solver = _Solver(posed, table, float(mu_table), backend, cone_rtol, tol, 0.0 if load_ramp else 1.0)
    for k in pose.triangle:
        solver.add(int(k), np.zeros(3))
    history: list[RestIteration] = []
    state = solver.solve()
    converged = False
    for it in range(1, int(max_iterations) + 1):
        # Steps 2-3: the state with every contact held, then the event tests of step 4 (at λ > 0).
        loaded = solver.lam > 0
        if loaded:
            solver.update_stick(state.forces)
        deepest, depth = solver.deepest(state)
        unsettled = loaded and (solver.tensile(state.forces).any() or len(solver.outside_cone(state.forces)) > 0)
        contacts_before = len(solver.contacts)
        if solver.lam == 1.0 and depth <= tol and not unsettled:
            history.append(RestIteration(it, contacts_before, depth, (), (), 0, 0.0, 0, 1.0))
            converged = True
            break
        new: list[int] = []
        if depth > tol:  # step 5, event A: the deepest node lands on the table
            new = [deepest]
            solver.prefetch_columns([deepest], state.positions)
            solver.add(deepest, state.displacements[posed.mesh.surface_index[deepest]])
            log.debug("event A: node %d was %.3g m below the table (λ = %.4g)", deepest, depth, solver.lam)
        elif not unsettled:  # raise the load to the next touch (event A at the new λ) or to 1
            lam_next, touching = solver.next_touch(state)
            if lam_next > 1.0:
                lam_next, touching = 1.0, touching[:0]
            solver.lam = lam_next
            if len(touching):
                moved = solver.solve()
                solver.prefetch_columns(touching, moved.positions)
                for k in touching:
                    solver.add(int(k), moved.displacements[posed.mesh.surface_index[k]])
                new = [int(k) for k in touching]
                log.debug("event A: %d node(s) touch the table at λ = %.6g", len(new), lam_next)
        released: list[int] = []
        n_slid, max_slip, rounds = 0, 0.0, 0
        if solver.lam > 0:
            state, released = solver.release_tensile()  # event B
            state, n_slid, max_slip, rounds = solver.slip(state)  # steps 6-7, event C
        else:
            state = solver.solve()
        history.append(RestIteration(it, contacts_before, depth, tuple(new), tuple(released), n_slid, max_slip,
                                     rounds, solver.lam))
        log.debug("iteration %d: λ = %.4g, %d contacts, penetration %.3g m, %d sliding", it, solver.lam,
                  len(solver.contacts), depth, n_slid)
    if not converged:
        raise RestConvergenceError(
            f"the resting iteration did not settle in {max_iterations} iterations (load factor {solver.lam:.4g}, "
            f"{len(solver.contacts)} contacts, last penetration {history[-1].max_penetration:.3g} m); raise "
            "max_iterations or check the mesh")
    sol = solver.solution()
    solver.update_stick(sol.forces)
    nodes = np.array(solver.contacts, dtype=np.int64)
    sliding = np.array([k in solver.sliding for k in solver.contacts], dtype=bool)
    wall = time.perf_counter() - start
    log.info("resting state: %d contacts (%d sliding) after %d iterations, max sag %.3g m, %.2f s",
             len(nodes), sliding.sum(), len(history), -sol.displacements[:, 2].min(), wall)
    return RestState(posed, float(table_z), float(mu_table), sol.positions, sol.displacements, nodes, sol.forces,
                     solver.prescribed(), sliding, pose.triangle.copy(), history, len(history), wall, pose, sol)
