"""Lifting the object (paper §III-C last paragraph, Algorithm 1 step 5).

Once the lift test passes, both fingertips translate upward (velocity +z
per unit lift height) from the squeeze configuration.  The contacts with the
table 𝒫 break gradually (event B) as the fingers take over the weight; finger
contacts may slide, stick, establish or break like during the squeeze —
"modeling, however, is no different from that of squeezing", so the same
:class:`~fem_grasp.contact.tracking.Tracker` runs with the lift height as parameter.

* **Failure**: every contact node of one finger slides ("the object slides on
  the finger"), or the tracking finds no quasi-static state (gross slip,
  lost support), or ``max_height`` is reached with the object still on the
  table.
* **Success**: the last table contact breaks — the object has left the plane.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from ..contact.obstacles import FINGER1, FINGER2, TABLE
from ..contact.tracking import ContactEvent, ContactState, Parameter, Tracker, run
from ..errors import TrackingError

__all__ = ["LiftOutcome", "lift"]

log = logging.getLogger(__name__)


@dataclass
class LiftOutcome:
    """Result of :func:`lift`.

    Attributes
    ----------
    state : the last state (at lift-off on success)
    events : every event of the lift, in order
    success : the object left the table
    reason : why not (empty on success)
    """

    state: ContactState
    events: list[ContactEvent] = field(default_factory=list)
    success: bool = False
    reason: str = ""


def finger_sliding(state: ContactState) -> int | None:
    """The finger (0 or 1) all of whose contacts slide, or None."""
    for f in (FINGER1, FINGER2):
        on = state.owner == f
        if on.any() and state.sliding[on].all():
            return f
    return None


def lift(tracker: Tracker, state: ContactState, *, max_height: float, step: float,
         on_event: Callable[[ContactState, list[ContactEvent]], None] | None = None) -> LiftOutcome:
    """Translate both fingers upward from ``state`` until the object leaves the table (module notes)."""
    velocities = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    state = replace(state, phase="lift")
    out = LiftOutcome(state)
    verdict: list[str] = []

    def record(st: ContactState, events: list[ContactEvent]) -> None:
        out.events.extend(events)
        if on_event is not None:
            on_event(st, events)

    def after(st: ContactState, events: list[ContactEvent]) -> bool:
        out.state = st
        f = finger_sliding(st)
        if f is not None:
            verdict.append(f"every contact of finger {f + 1} slides at lift height {1e3 * st.lift_height:.4g} mm: "
                           "the object slides on the finger")
            return True
        if not (st.owner == TABLE).any():
            verdict.append("")
            return True
        return False

    try:
        final, _, stopped = run(tracker, state, velocities, stop=max_height, step=step, param=Parameter.LIFT_HEIGHT,
                                phase="lift", after_step=after, on_event=record)
    except TrackingError as exc:
        out.reason = (f"lift failed: {exc}" if "lift height " in str(exc) else
                      f"lift failed at lift height {1e3 * out.state.lift_height:.4g} mm: {exc}")
        return out
    out.state = final
    if stopped and verdict and not verdict[-1]:
        out.success = True
    elif stopped:
        out.reason = verdict[-1]
    else:
        out.reason = (f"the object is still on the table after lifting the fingers {1e3 * max_height:.4g} mm "
                      f"({int((final.owner == TABLE).sum())} table contacts left)")
    return out
