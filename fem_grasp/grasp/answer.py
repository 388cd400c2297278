"""The pickup's answer: what a user of *Picking up Soft 3D Objects with Two Fingers* reads off Algorithm 1.

The accuracy loop (:mod:`fem_grasp.grasp.accuracy`) compares these quantities between levels, the placement
search ranks them, and the benchmarks measure their errors against the convergence study's references.

Definitions (:class:`GraspAnswer`)
----------------------------------
* ρ*: ``result.squeeze_depth``, the squeeze depth when the successful lift
  started (or where the squeeze stopped, on failure);
* per finger, at the final snapshot (lift-off on success): the resultant
  F_f = Σ f_k of its contact forces on the object — its norm |F_f|, its
  component F_f·d̂_f along the finger's own squeeze direction (the grip) and
  F_f·ẑ (the part of the weight it carries) — and its contact-node count;
* the finger force: Σ f·n̂ over both patches (Table III's total normal force,
  ``result.finger_normal_force``);
* the table's contact-node count at the lift start;
* w(ρ): ``result.liftable``;
* the force's exponent: d ln(Σ f·n̂) / d ln ρ near ρ* along the squeeze (:func:`force_exponent`), what turns an
  error of ρ* into one of the force read at it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["EXPONENT_WINDOW", "HERTZ_EXPONENT", "GraspAnswer", "answer_of", "failure_kind", "finger_nodes",
           "force_exponent", "passed", "patch_points"]

#: Hertz's exponent of a sphere's force over its indentation, the force's exponent where the squeeze does not
#: measure one (:func:`force_exponent`).
HERTZ_EXPONENT = 1.5
#: Where along the squeeze the force's exponent is measured from: ρ = this × ρ*.
EXPONENT_WINDOW = 0.75


@dataclass(frozen=True)
class GraspAnswer:
    """The quantities a pickup answers (module notes, "Definitions").

    Attributes
    ----------
    success : the object was lifted off the table
    reason : why not (empty on success)
    squeeze_depth : ρ*, metres
    finger_force : Σ f·n̂ over both fingers' contacts at the final snapshot, newtons
    fingers : per finger, {"resultant", "along_squeeze", "vertical", "nodes"} (newtons; count)
    table_nodes : table contacts at the lift start (at the end of the squeeze on failure)
    max_liftable : the largest w(ρ) of the lift test, newtons
    weight : mg, newtons
    liftable : [(ρ, w)] of the lift test
    n_vertices : vertices of the mesh
    step, lift_test_step : squeeze increment (m) and lift-test step h (N) used
    seconds : wall time of the pickup (rest included)
    step_divisions : sub-increments of the passing increment (``PickupOptions.step_divisions``)
    max_squeeze : the deepest squeeze the pickup would make, metres (inf: not known)
    force_exponent : d ln(Σ f·n̂) / d ln ρ near ρ* along the squeeze (:func:`force_exponent`)
    """

    success: bool
    reason: str
    squeeze_depth: float
    finger_force: float
    fingers: tuple[dict[str, float], dict[str, float]]
    table_nodes: int
    max_liftable: float
    weight: float
    liftable: tuple[tuple[float, float], ...]
    n_vertices: int
    step: float
    lift_test_step: float
    seconds: float
    step_divisions: int = 1
    max_squeeze: float = math.inf
    force_exponent: float = HERTZ_EXPONENT

    @property
    def resolution(self) -> float:
        """The resolution of ρ*, metres: the increment in which the lift test passed, divided as it was."""
        return self.step / self.step_divisions

    def to_dict(self) -> dict[str, Any]:
        return {"success": self.success, "reason": self.reason, "squeeze_depth": self.squeeze_depth,
                "finger_force": self.finger_force, "fingers": [dict(f) for f in self.fingers],
                "table_nodes": self.table_nodes, "max_liftable": self.max_liftable, "weight": self.weight,
                "liftable": [list(x) for x in self.liftable], "n_vertices": self.n_vertices, "step": self.step,
                "lift_test_step": self.lift_test_step, "seconds": self.seconds,
                "step_divisions": self.step_divisions, "max_squeeze": self.max_squeeze,
                "force_exponent": self.force_exponent}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "GraspAnswer":
        return cls(bool(d["success"]), d.get("reason", ""), float(d["squeeze_depth"]), float(d["finger_force"]),
                   tuple(dict(f) for f in d["fingers"]), int(d["table_nodes"]), float(d["max_liftable"]),
                   float(d["weight"]), tuple(tuple(x) for x in d["liftable"]), int(d["n_vertices"]),
                   float(d["step"]), float(d["lift_test_step"]), float(d["seconds"]),
                   int(d.get("step_divisions", 1)), float(d.get("max_squeeze", math.inf)),
                   float(d.get("force_exponent", HERTZ_EXPONENT)))


def answer_of(result: Any, seconds: float | None = None) -> GraspAnswer:
    """The :class:`GraspAnswer` of a :class:`~fem_grasp.grasp.pickup.PickupResult`."""
    from ..contact.obstacles import FINGER1, FINGER2

    fin = result.final
    fingers = []
    table_nodes = 0
    if fin is not None:
        for f, name in ((FINGER1, "finger1"), (FINGER2, "finger2")):
            total = np.asarray(fin.contact_forces[name], float).sum(axis=0) if len(fin.contact_nodes[name]) \
                else np.zeros(3)
            d = np.asarray(result.directions[f], float)
            d = d / np.linalg.norm(d)
            fingers.append({"resultant": float(np.linalg.norm(total)), "along_squeeze": float(total @ d),
                            "vertical": float(total[2]), "nodes": int(len(fin.contact_nodes[name]))})
        start = next((s for s in reversed(result.snapshots) if s.label.startswith("lift start")), fin)
        table_nodes = int(len(start.contact_nodes["table"]))
    else:
        fingers = [{"resultant": 0.0, "along_squeeze": 0.0, "vertical": 0.0, "nodes": 0}] * 2
    lt = float(getattr(result, "lift_test_step", 0.0) or 0.0)
    return GraspAnswer(bool(result.success), str(result.reason), float(result.squeeze_depth),
                       float(result.finger_normal_force), (fingers[0], fingers[1]), table_nodes,
                       float(max((w for _, w in result.liftable), default=0.0)), float(result.body.weight),
                       tuple((float(r), float(w)) for r, w in result.liftable), int(result.body.n_nodes),
                       float(result.step), lt,
                       float(result.timings.get("total", 0.0) if seconds is None else seconds),
                       int(getattr(result, "step_divisions", 1)),
                       float(getattr(result, "max_squeeze", 0.0) or math.inf),
                       force_exponent(result) if passed(result) else HERTZ_EXPONENT)


def force_exponent(result: Any) -> float:
    """d ln(Σ f·n̂) / d ln ρ at ρ*, read off the squeeze: the secant from the squeeze's snapshot nearest
    :data:`EXPONENT_WINDOW` × ρ* below it to the lift start (:data:`HERTZ_EXPONENT` where the squeeze has no
    earlier snapshot with the fingers pressing).

    An error of ρ* carries this many times over into the force read at ρ*: a Hertzian contact's force grows as
    the indentation to the power 3/2, the shipped tomato's Σ f·n̂ as ρ^1.33, ρ^1.38 and ρ^1.39 on the three
    levels of its default run (``result.accuracy["levels"][k]["force_exponent"]``).
    The secant over a quarter of ρ* rather than the last increment: a node entering contact makes the force
    jump within one increment.
    """
    rho = float(result.squeeze_depth)
    table = result.rest.table
    start = next((s for s in reversed(result.snapshots) if s.label.startswith("lift start")), None)
    if start is None or not rho > 0:
        return HERTZ_EXPONENT
    f_star = start.finger_normal_force(table)
    earlier = [s for s in result.snapshots if s.phase == "squeeze" and 0.0 < s.squeeze_depth < rho * (1.0 - 1e-9)]
    if not earlier or not f_star > 0:
        return HERTZ_EXPONENT
    s1 = min(earlier, key=lambda s: abs(s.squeeze_depth - EXPONENT_WINDOW * rho))
    r1, f1 = s1.squeeze_depth, s1.finger_normal_force(table)
    if not f1 > 0:
        return HERTZ_EXPONENT
    return math.log(f_star / f1) / math.log(rho / r1)


def patch_points(result: Any) -> tuple[np.ndarray, np.ndarray]:
    """Where the contacts were: (finger points (k, 3), table points (l, 3)) in the frame of the body's mesh.

    Every node that touched a fingertip in any snapshot of the squeeze and the
    lift, and every node that touched the table at rest or later, at its
    reference position (node indices are shared by the posed and the given
    body, so no pose is needed).
    """
    pts = result.body.mesh.points  # the posed body: same numbering, posed frame
    rs = result.rest
    # Positions in the frame of the body as given: undo the rest's rigid motion (posed = R p + t).
    rot, trans = rs.pose.rotation, rs.pose.translation
    ref = (pts - trans) @ rot  # R^T (q - t), row-wise
    fingers, table = set(), set(int(k) for k in rs.contact_nodes)
    for s in list(result.snapshots) + ([result.final] if result.final is not None else []):
        fingers.update(int(k) for k in s.contact_nodes["finger1"])
        fingers.update(int(k) for k in s.contact_nodes["finger2"])
        table.update(int(k) for k in s.contact_nodes["table"])
    fingers.update(int(k) for k in result.finger_nodes if k >= 0)
    return ref[sorted(fingers)], ref[sorted(table)]


def passed(ans: Any) -> bool:
    """Picked up, or (``lift=False``) stopped because the lift test passed: the verdict the levels compare (of a
    :class:`GraspAnswer` or a :class:`~fem_grasp.grasp.pickup.PickupResult`: their ``success`` and ``reason``)."""
    return ans.success or "lift was not run" in ans.reason


def failure_kind(reason: str) -> str:
    """The class of a failed pickup's reason: where Algorithm 1 stopped."""
    for key in ("no initial finger placement", "not force closure", "cannot be placed", "squeeze failed",
                "lift test did not pass", "lift failed", "slides on the finger", "still on the table",
                "lift was not run"):
        if key in reason:
            return key
    return reason.split(":")[0]


def finger_nodes(result: Any) -> np.ndarray:
    fin = result.final
    if fin is None:
        return np.asarray([k for k in result.finger_nodes if k >= 0], dtype=np.int64)
    nodes = np.concatenate([fin.contact_nodes["finger1"], fin.contact_nodes["finger2"]])
    return nodes if len(nodes) else np.asarray([k for k in result.finger_nodes if k >= 0], dtype=np.int64)
