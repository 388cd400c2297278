"""The implicit increment of the contact tracking: a return mapping where the rate problem has no solution.

The event tracking of :mod:`~fem_grasp.contact.tracking` follows the stick/slip *rate* problem (paper §III-C);
this module is its fallback, :meth:`ImplicitStep.implicit_step`, a method of
:class:`~fem_grasp.contact.tracking.Tracker`.

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
increment's slip system still fails after ``increment_halvings`` halvings (the
increment is then taken implicitly, and the next one tries Newton alone), and (iii) when a node chatters between stick and slip
without progress in the parameter (one implicit increment of ``step``).
Events inside an implicit increment are recorded at its end.

Large contact sets: (iv) with more than ``implicit_contacts`` contacts (:class:`~fem_grasp.settings.EngineSettings`)
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
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from ..elastic.response import check_contact_set
from ..errors import CollinearContactError, RelaxationFailure, TrackingError
from .obstacles import FINGER1, FINGER2, OBSTACLES, TABLE
from .relaxation import RELEASE, SLIDE, STICK, relax_contacts
from .states import ContactEvent, ContactState, Parameter
from .states import where as _where

__all__ = ["ImplicitStep"]

log = logging.getLogger(__name__)


class ImplicitStep:
    """The implicit increment (return mapping) of :class:`~fem_grasp.contact.tracking.Tracker` (module notes)."""

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
                                     max_slip=self.settings.max_slip * self.diameter, start=start,
                                     settings=self.settings)
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
            deep = np.argwhere(-gaps / self.diameter - self.settings.tol_penetration > 0)
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
            if not added:
                # Released contacts carried no force in the relaxation, so the others' static state is the same
                # without them: no second relaxation, only the check that the remaining set still fixes the body.
                if released.any():
                    _check_held(self.points, nodes, param, at)
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
            _check_held(self.points, nodes, param, at)
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


def _check_held(points: np.ndarray, nodes: np.ndarray, param: Parameter, at: ContactState) -> None:
    """A changed contact set must still fix the body (Theorem 3), else the object is no longer held."""
    try:
        check_contact_set(points, nodes)
    except CollinearContactError as exc:
        raise TrackingError(f"the object is no longer held at {_where(param, at)}: {exc}") from None
