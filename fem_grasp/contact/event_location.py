"""The event tests of the contact tracking and the location of the first event (paper §III-C, events A–D).

At the end of every increment of :class:`~fem_grasp.contact.tracking.Tracker` (these methods are its own,
by :class:`EventLocation`) the continuous event functions are evaluated: A, a free node would penetrate
ℱ₁, ℱ₂ or 𝒫; B, a normal force becomes tensile; C, a sticking force leaves its friction cone; D, the slip
rate of a sliding contact reaches zero.

When one fires, the event's t is located to ``tol_locate`` × diameter (:class:`~fem_grasp.settings.EngineSettings`) by interpolation
(inverse quadratic, secant) of the continuous event function predicted to
fire first, safeguarded by Illinois regula falsi on the bracket — the
"Newton polish" of §III-C; about four trials per located event — and the
configuration is updated there.  Several events at the same t (symmetric
bodies give pairs) are applied together, and cascades (a release that makes
a neighbour tensile) are settled at the same t.

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
from dataclasses import replace

import numpy as np

from ..elastic.response import check_contact_set
from ..errors import CollinearContactError, TrackingError
from .kernels import events
from .obstacles import FINGER1, FINGER2, OBSTACLES, TABLE, sphere_gaps
from .slip_system import SlipFailure
from .states import ContactEvent, ContactState, Parameter
from .states import Trial as _Trial
from .states import where as _where

__all__ = ["EventLocation"]

log = logging.getLogger(__name__)


class EventLocation:
    """The event functions, the location of the first event in an increment, and the application of events with
    their cascade: the methods of :class:`~fem_grasp.contact.tracking.Tracker` that test and place events A–D
    (module notes).  They read the tracker's geometry (``surface``, ``diameter``, ``radius``, ``up``, ``table``,
    ``mu``) and its tolerances (``settings``, :class:`~fem_grasp.settings.EngineSettings`) and call its :meth:`~fem_grasp.contact.tracking.Tracker.trial` and
    :meth:`~fem_grasp.contact.implicit_step.ImplicitStep.implicit_step`."""

    # --------------------------------------------------------------- events
    def obstacle_gaps(self, surface_positions: np.ndarray, centers: np.ndarray) -> np.ndarray:
        """(s, 3) signed distance of each surface node (at ``surface_positions``) from ℱ₁, ℱ₂ and 𝒫 (inf for
        no table)."""
        gaps = np.full((len(surface_positions), 3), np.inf)
        for code in (FINGER1, FINGER2):  # the obstacles' signed_distance, without building them at every trial
            gaps[:, code] = sphere_gaps(surface_positions, centers[code], self.radius)
        if self.table is not None:
            gaps[:, TABLE] = self.table.signed_distance(surface_positions)
        return gaps

    def force_scale(self, state: ContactState) -> float:
        return self.body.weight * max(state.load, 0.0) + float(np.abs(state.forces).max(initial=0.0))

    def event_values(self, trial: _Trial, fscale: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Normalised event functions (> 0: the event fires) with their ids.

        A: ids are (surface position, obstacle) pairs encoded as 3·s + obstacle;
        B, C, D: positions in the contact set.
        """
        st = trial.state
        s = self.settings
        if self.compiled:
            table = self.table
            a_val, b_val, c_val, d_val = events.event_functions(
                st.surface_positions, st.centers, self.radius, table is not None, self.up,
                0.0 if table is None else float(table.height), self.surface_index[st.nodes], st.owner, st.forces,
                st.normals, st.sliding, trial.rates, self.mu[st.owner], float(fscale), float(self.diameter),
                s.tol_penetration, s.tol_tensile, s.tol_cone, s.tol_force_floor, s.tol_rate, s.stick_hysteresis)
            ids = np.arange(st.n_contacts)
            return {"A": (a_val, np.arange(a_val.size)), "B": (b_val, ids), "C": (c_val, ids), "D": (d_val, ids)}
        gaps = self.obstacle_gaps(st.surface_positions, st.centers)
        own = self.surface_index[st.nodes]
        on = own >= 0
        gaps[own[on], st.owner[on]] = np.inf  # its own obstacle
        a_val = (-gaps / self.diameter - s.tol_penetration).reshape(-1)
        a_ids = np.arange(a_val.size)
        fn = st.normal_forces
        ft = st.tangential_forces
        b_val = -fn / fscale - s.tol_tensile
        mu = self.mu[st.owner]
        c_val = np.where(st.sliding, -np.inf, (ft - mu * fn - s.tol_cone * np.maximum(fn, 0.0)) / fscale
                         - s.tol_force_floor)
        slip_test = -trial.rates - s.tol_rate
        d_val = np.where(st.sliding, np.maximum(slip_test, s.stick_hysteresis * s.tol_force_floor - fn / fscale), -np.inf)
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
        if len(base.nodes) > self.settings.implicit_contacts:
            return self.implicit_step(base, dt, velocities, load_rate=load_rate, param=param, phase=phase)
        min_step = self.settings.min_step * self.diameter if min_step is None else min_step
        fscale = self.force_scale(base)
        h = dt
        halvings = 0
        while True:
            try:
                # Newton alone just after an implicit increment (the rate problem is likely to fail again) and on a
                # halved increment: a homotopy that found no root for the whole increment rarely finds one for a
                # part of it (the foam block's lift: 1 root in 205 paths).
                trial = self.trial(base, h, velocities, load_rate, param,
                                   methods=("newton",) if self.implicit or halvings else ("newton", "homotopy"))
                self.implicit = False
                break
            except SlipFailure as exc:
                h *= 0.5
                halvings += 1
                if (self.implicit or halvings > self.settings.increment_halvings) and h >= min_step:
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
        tol = self.settings.tol_locate * self.diameter
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
                try:  # Newton alone (warm-started from the roots nearby): a trial that fails only narrows the bracket
                    tr = self.trial(base, mid, velocities, load_rate, param, methods=("newton",))
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
        probe = max(self.settings.turning_probe * self.diameter, self.settings.turning_probe_rel * abs(getattr(st, param)))
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
                    if toggles[e.node] > self.settings.max_settle_toggles:
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
