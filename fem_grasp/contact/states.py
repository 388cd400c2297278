"""The records of the contact tracking: the tracked parameter, the contact state, the events (paper §III-C).

A :class:`ContactState` is the object's contact configuration and deformation at one value of the parameter
t (:class:`Parameter`: the squeeze depth ρ, the lift height or the gravity load factor λ) — which nodes touch
ℱ₁, ℱ₂ and 𝒫 (the index sets 𝕀, 𝕁, 𝕂), which of them slide (ℙ), their forces and the deformed surface.  A
:class:`ContactEvent` records one change of that configuration (events A–D of
:mod:`~fem_grasp.contact.tracking`), and a :class:`Trial` is the state one increment reaches with the
configuration held, with its slips and slip rates.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from functools import cached_property
from typing import Any, Callable

import numpy as np

from .friction import normal_component, tangential_component

__all__ = ["ContactEvent", "ContactState", "Parameter", "Trial", "contact_set_key", "where"]


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


def where(param: "Parameter | str", state: Any) -> str:
    """Where the tracking is, for messages, in millimetres: "ρ = 12.35 mm", "lift height 3.2 mm", "load λ = 0.5"."""
    value = float(getattr(state, str(param)))
    if str(param) == "squeeze_depth":
        return f"ρ = {1e3 * value:.6g} mm"
    if str(param) == "lift_height":
        return f"lift height {1e3 * value:.6g} mm"
    return f"gravity load λ = {value:.6g}"


def contact_set_key(nodes: np.ndarray) -> tuple[int, ...]:
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
        return normal_component(self.forces, self.normals)

    @property
    def tangential_forces(self) -> np.ndarray:
        """(m,) |f − (f·n̂)n̂| at each contact."""
        return np.linalg.norm(tangential_component(self.forces, self.normals), axis=1)


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


# ====================================================================== trial
@dataclass
class Trial:
    """The state reached from a base state by one increment, with its slip data."""

    state: ContactState
    amounts: np.ndarray  # (m,) slip in this increment (0 for sticking contacts)
    rates: np.ndarray  # (m,) slip rates (0 for sticking contacts)
    values: dict = field(default_factory=dict)  # event kind -> (array of values, array of ids)
