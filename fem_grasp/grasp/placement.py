"""Where the fingers first touch: documented rules for choosing contact nodes."""

from __future__ import annotations

import numpy as np

from ..mesh.tetmesh import TetMesh

#: Rules for choosing the initial finger contacts (:func:`fem_grasp.grasp.pickup.default_finger_contacts`).
PLACEMENT_RULES = ("least-force", "centre-of-mass-height")
#: ``pickup()``'s rule and a scene's when it names none (the paper scenes name "centre-of-mass-height").
DEFAULT_PLACEMENT_RULE = "least-force"

#: The paper's squeeze directions (§IV): d̂1 = (0, 0.974, −0.227), d̂2 = (0, −0.974, −0.227).
PAPER_SQUEEZE_DIRECTIONS = (np.array([0.0, 0.974, -0.227]), np.array([0.0, -0.974, -0.227]))


def spread_triple(points: np.ndarray, candidates: np.ndarray) -> np.ndarray:
    """Three of ``candidates`` spanning a wide triangle (far from the centroid, from each other, off their line)."""
    c = points[candidates]
    a = int(np.argmax(np.sum((c - c.mean(axis=0)) ** 2, axis=1)))
    b = int(np.argmax(np.sum((c - c[a]) ** 2, axis=1)))
    ab = (c[b] - c[a]) / np.linalg.norm(c[b] - c[a])
    rel = c - c[a]
    d = int(np.argmax(np.sum((rel - np.outer(rel @ ab, ab)) ** 2, axis=1)))
    return np.asarray(candidates)[[a, b, d]]


def lowest_nodes(mesh: TetMesh, band: float = 0.05) -> np.ndarray:
    """Surface nodes within ``band`` × height of the lowest point (z up)."""
    surf = mesh.surface_nodes
    z = mesh.points[surf, 2]
    return surf[z <= z.min() + band * (z.max() - z.min())]


def finger_contact_nodes(mesh: TetMesh, height: float, direction: np.ndarray = PAPER_SQUEEZE_DIRECTIONS[0],
                         band: float = 0.1) -> tuple[int, int]:
    """Initial finger contacts p_i, p_j: the surface nodes extreme along ∓d̂ at a height.

    Rule: among surface nodes within ``band`` × (object height) of ``height``,
    p_i minimises and p_j maximises the coordinate along the horizontal part
    of ``direction`` (finger 1 pushes along +d̂ from the −d̂ side).  Ties (a
    flat face across the squeeze direction) go to the node nearest the
    height and the middle of the face: not an edge or corner node, where the
    surface normal is the average of two faces'.
    """
    d = np.asarray(direction, dtype=float).copy()
    d[2] = 0.0
    if np.linalg.norm(d) == 0:
        raise ValueError("the squeeze direction has no horizontal component; fingers cannot face each other")
    d /= np.linalg.norm(d)
    p, surf = mesh.points, mesh.surface_nodes
    z = p[surf, 2]
    near = surf[np.abs(z - height) <= band * (z.max() - z.min())]
    if len(near) < 2:
        raise ValueError(f"no surface nodes near height {height:g} m; the fingers would miss the object")
    s = p[near] @ d
    tie = 1e-9 * float(np.ptp(p, axis=0).max())
    side = np.array([-d[1], d[0], 0.0])

    def pick(on: np.ndarray) -> int:
        if on.sum() == 1:
            return int(near[on][0])
        q = p[near[on]]
        lateral = q @ side
        off = (lateral - 0.5 * (lateral.min() + lateral.max())) ** 2 + (q[:, 2] - height) ** 2
        return int(near[on][np.argmin(off)])

    return pick(s <= s.min() + tie), pick(s >= s.max() - tie)
