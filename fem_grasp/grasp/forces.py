"""The force each fingertip exerts on the object, measured the ways a reader of a grasp asks for.

"The finger force" of a soft grasp is ambiguous: the fingertip presses on a
patch of nodes whose normals fan out over the curved tip.  For each finger f
with contact nodes k (forces f_k on the object, inward normals n̂_k):

* **resultant** R_f = Σ_k f_k (a vector, newtons) and its magnitude |R_f|:
  what a force sensor in the finger reads;
* **grip** R_f · d̂_f: the part along the finger's squeeze direction (d̂₁ for
  ℱ₁, d̂₂ for ℱ₂), the squeezing force;
* **vertical** R_f · ẑ: the part of the weight this finger carries (at
  lift-off the two add up to mg);
* **normal sum** Σ_k f_k · n̂_k: the total normal force on the patch.

Table III of the paper compares "the total normal force needed to balance
the gravity and pick up an object": fem_grasp compares the normal sum over
both fingers (:attr:`~fem_grasp.grasp.PickupResult.finger_normal_force`) with
the rigid grasp's total normal force (:mod:`fem_grasp.grasp.rigid`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ..contact.obstacles import Fingertip

__all__ = ["FingerForce", "TABLE_III_MEASURE", "finger_forces"]

#: Which measure Table III's "total normal force" is compared with.
TABLE_III_MEASURE = ("the normal sum Σ f·n̂ over both fingers' contact patches (Table III's \"total normal "
                     "force\"), against the rigid grasp's total normal force at the same two contacts")


@dataclass(frozen=True)
class FingerForce:
    """The force one fingertip exerts on the object (module notes).

    Attributes
    ----------
    resultant : (3,) Σ f_k over the finger's contact nodes, newtons
    magnitude : |resultant|, newtons
    grip : resultant · d̂ (the finger's squeeze direction), newtons
    vertical : resultant · ẑ, newtons (positive: the finger carries weight)
    normal_sum : Σ f_k · n̂_k over the patch, newtons
    contacts : number of contact nodes on the finger
    """

    resultant: np.ndarray
    magnitude: float
    grip: float
    vertical: float
    normal_sum: float
    contacts: int

    def to_dict(self) -> dict[str, Any]:
        return {"resultant": [float(x) for x in self.resultant], "magnitude": self.magnitude, "grip": self.grip,
                "vertical": self.vertical, "normal_sum": self.normal_sum, "contacts": self.contacts}


def finger_forces(positions: Sequence[np.ndarray], forces: Sequence[np.ndarray], centers: np.ndarray,
                  radius: float, directions: Sequence[np.ndarray],
                  up: np.ndarray = np.array([0.0, 0.0, 1.0])) -> tuple[FingerForce, FingerForce]:
    """The :class:`FingerForce` of ℱ₁ and ℱ₂.

    Parameters
    ----------
    positions, forces : per finger, the (k, 3) deformed positions of its contact nodes and their (k, 3) forces
        on the object, newtons
    centers : (2, 3) fingertip centres
    radius : fingertip radius, metres
    directions : the squeeze directions (d̂₁, d̂₂), normalised here
    up : the vertical (opposite to gravity)
    """
    out = []
    for f in range(2):
        p = np.asarray(positions[f], dtype=float).reshape(-1, 3)
        fk = np.asarray(forces[f], dtype=float).reshape(-1, 3)
        d = np.asarray(directions[f], dtype=float)
        d = d / np.linalg.norm(d)
        resultant = fk.sum(axis=0)
        normal_sum = (float(np.einsum("ki,ki->", fk, Fingertip(centers[f], radius).inward_normals(p)))
                      if len(p) else 0.0)
        out.append(FingerForce(resultant, float(np.linalg.norm(resultant)), float(resultant @ d),
                               float(resultant @ np.asarray(up, dtype=float)), normal_sum, len(p)))
    return out[0], out[1]
