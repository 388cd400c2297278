"""The default finger placement of a pickup: the initial contacts p_i, p_j and the maximum squeeze depth.

:func:`default_finger_contacts` chooses the initial finger contacts by the rule of
:func:`fem_grasp.grasp.pickup.pickup`'s module notes ("Default scene"): among the pairs of surface nodes
extreme along ∓ĥ at heights stepped by 2.5 % of the object's height, those whose tangent fingertips clear
the table, start outside the object and are force closure, ranked by a placement rule
(:data:`~fem_grasp.grasp.placement.PLACEMENT_RULES`); when none passes, the error says how many passed each
condition and what to change.  :func:`default_max_squeeze` is 40 % of the object's width along ĥ.
"""

from __future__ import annotations

import numpy as np

from ..errors import PlacementError, SceneError
from . import placement
from .closure import ClosureResult, placement_closure
from .placement import DEFAULT_PLACEMENT_RULE, PLACEMENT_RULES, check_finger_placement
from .rest import RestState
from .rigid import rigid_grasp

__all__ = ["default_finger_contacts", "default_max_squeeze"]



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
