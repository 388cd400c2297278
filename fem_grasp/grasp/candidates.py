"""Where to grasp: candidate finger placements and squeezes for a placement search (Algorithm 1, step 1, many times).

The paper answers "will this grasp lift?" for one placement p_i, p_j and one squeeze (d̂₁, s d̂₂); its future
work is choosing them.  A search asks Algorithm 1 the question for many placements, and this module makes
the candidates.  A candidate is a squeeze axis and a pair of finger nodes:

* an **azimuth** φ of the squeeze axis around the vertical: ĥ = (cos φ, sin φ, 0) (φ = 90° is the paper's
  §IV, d̂₁ = (0, 0.974, −0.227));
* a downward **tilt** τ of both squeeze directions: d̂₁ = cos τ ĥ − sin τ ẑ, d̂₂ = −cos τ ĥ − sin τ ẑ (the
  paper's τ = asin 0.227 = 13.1°, :data:`PAPER_TILT`);
* a squeeze **ratio** s (ℱ₂ moves s ρ d̂₂ while ℱ₁ moves ρ d̂₁; the paper's s = 1);
* a **height** h: p_i, p_j are the surface nodes extreme along ∓ĥ near h
  (:func:`~fem_grasp.grasp.placement.finger_contact_nodes`, the rule of
  :func:`~fem_grasp.grasp.pickup.default_finger_contacts`).

The grid of heights × azimuths × tilts × ratios is regular: heights from just above the table clearance to
the top of the resting object, azimuths over [0°, 180°) when every ratio is 1 (φ and φ + 180° are then the
same grasp with the fingers' names swapped) and over [0°, 360°) otherwise.  A grid point becomes a
candidate when, on the resting shape (Algorithm 1 step 2 comes first: step 1 needs the resting shape),

1. both tangent fingertips clear the table by max(R/10, sin τ × the maximum squeeze), as
   :func:`~fem_grasp.grasp.pickup.default_finger_contacts` asks;
2. they start outside the object, and each squeeze direction points into it
   (:func:`~fem_grasp.grasp.placement.check_finger_placement`);
3. the contacts are **antipodal within a cone**: the line p_i p_j makes an angle of at most α with each
   inward surface normal (default α = atan μ_ℱ, the friction cone: the classical antipodal grasp);
4. p_i, p_j and the support triangle's centre are **force closure** on a rigid body of the resting shape
   (:func:`~fem_grasp.grasp.closure.placement_closure`, Algorithm 1 step 1).

Grid points that give the same node pair along the same squeeze are one candidate.  When more candidates
are valid than asked for, ``seed`` picks which: farthest-point sampling over the contact positions, the
squeeze axis, the tilt and the ratio from a seeded start, so the chosen ones spread over the surface.  The same rest, settings
and seed give the same candidates, in the same order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ..errors import PlacementError, SceneError
from .closure import placement_closure
from .pickup import default_max_squeeze
from .placement import check_directions, check_finger_placement, finger_contact_nodes
from .rest import RestState

__all__ = ["Candidate", "CandidateSet", "MAX_REFINEMENTS", "PAPER_TILT", "REJECTIONS", "candidate_grid", "placement_candidates",
           "squeeze_directions"]

#: The paper's downward tilt of the squeeze directions (§IV: d̂·ẑ = −0.227), degrees.
PAPER_TILT = math.degrees(math.asin(0.227))
#: How many times the default grid is refined when it holds fewer valid candidates than asked for.
MAX_REFINEMENTS = 3
#: Why a grid point is not a candidate (:attr:`CandidateSet.rejected` counts them by these keys).
REJECTIONS = {
    "no nodes": "no surface nodes near this height",
    "table": "a fingertip would reach the table within the maximum squeeze",
    "placement": "a fingertip starts inside the object, misses it, or squeezes out of it",
    "not antipodal": "the line between the contacts leaves an inward normal's cone",
    "not force closure": "the contacts and the support triangle's centre are not force closure (Algorithm 1 step 1)",
    "duplicate": "the same node pair and squeeze as another grid point",
}


@dataclass(frozen=True)
class Candidate:
    """One placement and squeeze to evaluate with Algorithm 1.

    Attributes
    ----------
    index : position in the search's candidate list
    finger_nodes : (p_i, p_j), node indices of the posed body
    azimuth : φ of the squeeze axis ĥ around the vertical, degrees
    tilt : downward tilt τ of the squeeze directions, degrees
    ratio : s
    height : mean height of p_i, p_j above the table at rest, metres
    max_squeeze : the maximum squeeze depth, metres
    points : (2, 3) p_i, p_j at rest
    closure_quality : Ferrari–Canny ε of the force-closure test
    """

    index: int
    finger_nodes: tuple[int, int]
    azimuth: float
    tilt: float
    ratio: float
    height: float
    max_squeeze: float
    points: tuple[tuple[float, float, float], tuple[float, float, float]] = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    closure_quality: float = 0.0

    @property
    def directions(self) -> tuple[np.ndarray, np.ndarray]:
        """(d̂₁, d̂₂) of the module notes."""
        return squeeze_directions(self.azimuth, self.tilt)

    @property
    def key(self) -> str:
        """A name that identifies the candidate across runs (what ``--resume`` matches)."""
        i, j = self.finger_nodes
        return f"{i}-{j}-a{self.azimuth:.3f}-t{self.tilt:.3f}-s{self.ratio:.6g}"

    def to_dict(self) -> dict[str, Any]:
        return {"index": self.index, "key": self.key, "finger_nodes": list(self.finger_nodes),
                "azimuth": self.azimuth, "tilt": self.tilt, "ratio": self.ratio, "height": self.height,
                "max_squeeze": self.max_squeeze, "points": [list(p) for p in self.points],
                "closure_quality": self.closure_quality}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "Candidate":
        return cls(int(d["index"]), tuple(int(k) for k in d["finger_nodes"]), float(d["azimuth"]),
                   float(d["tilt"]), float(d["ratio"]), float(d["height"]), float(d["max_squeeze"]),
                   tuple(tuple(float(x) for x in p) for p in d["points"]), float(d.get("closure_quality", 0.0)))


@dataclass
class CandidateSet:
    """The candidates of a search and what the grid held.

    Attributes
    ----------
    candidates : the chosen candidates, in grid order (``index`` 0, 1, …)
    valid : how many grid points were valid candidates before the choice
    grid : the grid: {"heights": fractions of the object's height, "azimuths", "tilts": degrees, "ratios"}
    rejected : grid points that are not candidates, counted by :data:`REJECTIONS` key
    seed : the seed of the choice
    """

    candidates: list[Candidate]
    valid: int
    grid: dict[str, list[float]]
    rejected: dict[str, int] = field(default_factory=dict)
    seed: int = 0

    def __len__(self) -> int:
        return len(self.candidates)

    def __iter__(self):
        return iter(self.candidates)


def squeeze_directions(azimuth: float, tilt: float) -> tuple[np.ndarray, np.ndarray]:
    """(d̂₁, d̂₂) for an azimuth and a downward tilt in degrees (module notes)."""
    a, t = math.radians(azimuth), math.radians(tilt)
    h = np.array([math.cos(a), math.sin(a), 0.0])
    down = np.array([0.0, 0.0, -math.sin(t)])
    return math.cos(t) * h + down, -math.cos(t) * h + down


def _levels(spec: Any, lo: float, hi: float, what: str, *, endpoint: bool = False) -> list[float]:
    """Grid levels: a count n (n cell centres in [lo, hi], or n points over [lo, hi) with ``endpoint``), a
    (lo, hi, n) range, or explicit values."""
    if isinstance(spec, (int, np.integer)) and not isinstance(spec, bool):
        n = int(spec)
        if n < 1:
            raise SceneError(f"{what}: the number of levels must be >= 1, got {n}")
        if endpoint:
            return [lo + (hi - lo) * k / n for k in range(n)]
        return [lo + (hi - lo) * (k + 0.5) / n for k in range(n)]
    if isinstance(spec, tuple) and len(spec) == 3 and isinstance(spec[2], (int, np.integer)):
        a, b, n = float(spec[0]), float(spec[1]), int(spec[2])
        if n < 1:
            raise SceneError(f"{what}: the number of levels must be >= 1, got {n}")
        return [a] if n == 1 else [a + (b - a) * k / (n - 1) for k in range(n)]
    values = [float(v) for v in spec]
    if not values:
        raise SceneError(f"{what}: give at least one value")
    if not all(math.isfinite(v) for v in values):
        raise SceneError(f"{what}: values must be finite, got {values}")
    return values


def candidate_grid(count: int, heights: Any = None, azimuths: Any = None, tilts: Any = None,
                   ratios: Any = None) -> dict[str, Any]:
    """The grid's specification with defaults filled in.

    ``heights`` are fractions of the way from the lowest admissible height (the table clearance) to the top
    of the resting object; ``azimuths`` and ``tilts`` are degrees.  Each may be a count, a ``(lo, hi, n)``
    tuple with an integer n (n values from lo to hi inclusive) or a list of values.  By default the tilts are
    the paper's, the ratio is 1, and heights × azimuths hold about twice ``count`` points (at least 4 × 4).
    """
    tilts = [PAPER_TILT] if tilts is None else _levels(tilts, 0.0, 45.0, "tilts")
    ratios = [1.0] if ratios is None else _levels(ratios, 0.0, 2.0, "ratios")
    for t in tilts:
        if not -1e-9 <= t < 90.0:
            raise SceneError(f"tilts: a squeeze tilt must be in [0°, 90°) downward (upward squeezes lift the object "
                             f"before the lift test, Algorithm 1), got {t:g}°")
    for s in ratios:
        if not s >= 0:
            raise SceneError(f"ratios: the squeeze ratio s must be >= 0, got {s:g}")
    n = max(4, math.ceil(math.sqrt(2.0 * max(int(count), 1) / (len(tilts) * len(ratios)))))
    symmetric = all(s == 1.0 for s in ratios)
    span = 180.0 if symmetric else 360.0
    return {"heights": n if heights is None else heights,
            "azimuths": _levels(n if azimuths is None else azimuths, 0.0, span, "azimuths", endpoint=True),
            "tilts": [float(t) for t in tilts], "ratios": [float(s) for s in ratios]}


def placement_candidates(rest_state: RestState, *, mu_finger: float, mu_table: float, radius: float,
                         count: int = 64, heights: Any = None, azimuths: Any = None, tilts: Any = None,
                         ratios: Any = None, seed: int = 0, max_squeeze: float | None = None,
                         cone: float | None = None) -> CandidateSet:
    """The candidate placements of a search (module notes).

    Parameters
    ----------
    rest_state : the object resting on the table (its posed body's node numbering)
    mu_finger, mu_table : friction coefficients μ_ℱ, μ_𝒫
    radius : fingertip radius R, metres
    count : at most this many candidates
    heights, azimuths, tilts, ratios : the grid (:func:`candidate_grid`); when neither heights nor azimuths
        are given and the default grid holds fewer than ``count`` valid candidates, it is refined (× 1.5 in
        both, up to :data:`MAX_REFINEMENTS` times)
    seed : picks the candidates when more are valid than ``count``
    max_squeeze : the maximum squeeze depth, metres (default: 40 % of the width along ĥ, as ``pickup()``)
    cone : half-angle α of the antipodal cone, degrees (default atan μ_ℱ)
    """
    if int(count) < 1:
        raise SceneError(f"the number of candidates must be >= 1, got {count}")
    spec = candidate_grid(count, heights, azimuths, tilts, ratios)
    found = _grid_candidates(rest_state, spec, mu_finger, mu_table, radius, max_squeeze, cone)
    if heights is None and azimuths is None:
        n = int(spec["heights"])
        for _ in range(MAX_REFINEMENTS):
            if len(found[0]) >= count:
                break
            n = math.ceil(1.5 * n)
            spec = candidate_grid(count, n, n, tilts, ratios)
            found = _grid_candidates(rest_state, spec, mu_finger, mu_table, radius, max_squeeze, cone)
    valid, rejected, fractions = found
    chosen = _spread(valid, int(count), int(seed), float(rest_state.body.mesh.diameter), spec)
    candidates = [Candidate(k, v["ij"], v["azimuth"], v["tilt"], v["ratio"], v["height"], v["max_squeeze"],
                            tuple(tuple(float(x) for x in p) for p in v["points"]), v["quality"])
                  for k, v in enumerate(valid[i] for i in chosen)]
    grid = {"heights": [float(f) for f in fractions], "azimuths": [float(a) for a in spec["azimuths"]],
            "tilts": spec["tilts"], "ratios": spec["ratios"]}
    return CandidateSet(candidates, len(valid), grid, {k: v for k, v in rejected.items() if v}, int(seed))


def _grid_candidates(rest_state: RestState, spec: dict[str, Any], mu_finger: float, mu_table: float,
                     radius: float, max_squeeze: float | None, cone: float | None
                     ) -> tuple[list[dict[str, Any]], dict[str, int], list[float]]:
    """Every valid grid point of ``spec`` (module notes), the rejections by reason, and the height fractions."""
    posed = rest_state.body
    mesh = posed.mesh
    pos = rest_state.positions
    out = mesh.outward_normals(pos)
    surf = mesh.surface_nodes
    z0, z1 = float(pos[surf, 2].min()), float(pos[surf, 2].max())
    table_z = float(rest_state.table_z)
    alpha = math.atan(mu_finger) if cone is None else math.radians(float(cone))
    cos_alpha = math.cos(alpha) - 1e-12
    widths = {}

    def max_depth(d1: np.ndarray, azimuth: float) -> float:
        if max_squeeze is not None:
            return float(max_squeeze)
        if azimuth not in widths:
            widths[azimuth] = default_max_squeeze(pos, d1)
        return widths[azimuth]

    # The lowest admissible height: the smallest clearance any squeeze of the grid asks for.
    low_clear = min(max(0.1 * radius, math.sin(math.radians(t)) * max_depth(squeeze_directions(a, t)[0], a))
                    for a in spec["azimuths"] for t in spec["tilts"])
    h_lo = min(z0 + low_clear, z1)
    fractions = _levels(spec["heights"], 0.0, 1.0, "heights")
    for f in fractions:
        if not 0.0 <= f <= 1.0:
            raise SceneError(f"heights: give fractions of the object's height in [0, 1], got {f:g}")
    levels = [h_lo + f * (z1 - h_lo) for f in fractions]
    # finger_contact_nodes looks at the posed body's reference heights (as default_finger_contacts does)
    ref_offset = float(mesh.points[surf, 2].min()) - z0

    rejected = {k: 0 for k in REJECTIONS}
    valid: list[dict[str, Any]] = []
    seen: set[tuple] = set()
    for t in spec["tilts"]:
        for s in spec["ratios"]:
            for a in spec["azimuths"]:
                d1, d2 = check_directions(*squeeze_directions(a, t), ratio=s)
                velocities = np.stack([d1, s * d2])
                depth = max_depth(d1, a)
                clearance = max(0.1 * radius, abs(float(d1[2])) * depth)
                for h in levels:
                    try:
                        ij = finger_contact_nodes(mesh, h + ref_offset, d1)
                    except ValueError:
                        rejected["no nodes"] += 1
                        continue
                    key = (ij, round(a, 9), round(t, 9), s)
                    if key in seen:
                        rejected["duplicate"] += 1
                        continue
                    seen.add(key)
                    nodes = list(ij)
                    centers = pos[nodes] + radius * out[nodes]
                    if (centers[:, 2] - radius - table_z).min() < clearance:
                        rejected["table"] += 1
                        continue
                    try:
                        check_finger_placement(pos, surf, centers, radius, contact_nodes=ij, normals=out,
                                               directions=velocities)
                    except PlacementError:
                        rejected["placement"] += 1
                        continue
                    line = pos[ij[1]] - pos[ij[0]]
                    length = float(np.linalg.norm(line))
                    inward = -out[nodes] / np.linalg.norm(out[nodes], axis=1, keepdims=True)
                    if length == 0 or inward[0] @ line / length < cos_alpha or -inward[1] @ line / length < cos_alpha:
                        rejected["not antipodal"] += 1
                        continue
                    closure = placement_closure(posed, pos, ij, rest_state.support_triangle, mu_finger, mu_table)
                    if not closure.closed:
                        rejected["not force closure"] += 1
                        continue
                    valid.append({"ij": ij, "azimuth": float(a), "tilt": float(t), "ratio": float(s),
                                  "height": float(pos[nodes, 2].mean() - table_z), "max_squeeze": depth,
                                  "points": pos[nodes].copy(), "quality": float(closure.quality)})
    return valid, rejected, fractions


def _spread(valid: Sequence[dict[str, Any]], count: int, seed: int, diameter: float,
            spec: dict[str, Any]) -> list[int]:
    """Indices (in grid order) of ``count`` of ``valid`` spread out: farthest-point sampling from a seeded start."""
    n = len(valid)
    if n <= count:
        return list(range(n))
    tilt_span = max(np.ptp(spec["tilts"]), 1.0)
    ratio_span = max(np.ptp(spec["ratios"]), 1.0)
    feats = np.array([np.concatenate([v["points"].ravel() / diameter,
                                      [math.cos(math.radians(v["azimuth"])), math.sin(math.radians(v["azimuth"])),
                                       v["tilt"] / tilt_span, v["ratio"] / ratio_span]]) for v in valid])
    rng = np.random.default_rng(seed)
    order = rng.permutation(n)  # ties go to this order
    first = int(order[0])
    chosen = [first]
    dist = np.linalg.norm(feats - feats[first], axis=1)
    rank = np.empty(n, dtype=np.int64)
    rank[order] = np.arange(n)
    free = np.ones(n, dtype=bool)
    free[first] = False
    while len(chosen) < count:
        far = dist[free].max()
        ties = np.flatnonzero(free & (dist >= far * (1 - 1e-12)))
        nxt = int(ties[np.argmin(rank[ties])])
        chosen.append(nxt)
        free[nxt] = False
        dist = np.minimum(dist, np.linalg.norm(feats - feats[nxt], axis=1))
    return sorted(chosen)
