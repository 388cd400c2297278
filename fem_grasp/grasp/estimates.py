"""Discretisation error of an answer computed on a sequence of refinement levels.

The accuracy loop (:mod:`fem_grasp.grasp.accuracy`) runs Algorithm 1 of *Picking up Soft 3D Objects with Two
Fingers* on meshes whose contact patches are resolved ever more finely, and states the error of its last level.
This module holds the arithmetic of that statement, on plain numbers:

* :func:`relative_change`, the difference of two levels relative to the last (the loop's two-level estimate);
* :func:`estimate`, Richardson extrapolation of a monotone sequence, or its scatter as a band;
* :func:`sequence_uncertainty`, the uncertainty of the finest of three levels after the procedure of Eça and
  Hoekstra (*A procedure for the estimation of the numerical uncertainty of CFD calculations based on grid
  refinement studies*, J. Comput. Phys. 262, 2014): an extrapolation with a safety factor of 1.25 where the
  levels converge monotonically with an order of at least 0.5, the last difference where they oscillate and
  contract, and a safety factor of 3 on their scatter where they do neither.

Why the third level matters: the difference of the last two levels bounds the last one's error only for a
sequence converging monotonically at least linearly in the spacing (ratio 2).  Node-on-sphere contact converges
neither smoothly nor always monotonically (a contact ring enters at a time), so a small last difference may be a
swing that happens to pass near the previous value; three levels show whether the levels contract.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

__all__ = ["relative_change", "estimate", "observed_order", "sequence_uncertainty", "SAFETY_FACTOR",
           "SCATTER_FACTOR", "ORDER_RANGE", "OSCILLATION_CONTRACTION"]

#: Safety factor on the extrapolated error where three levels converge monotonically with an order in
#: :data:`ORDER_RANGE` (Eça and Hoekstra's, and Roache's for three or more grids).
SAFETY_FACTOR = 1.25
#: Safety factor on the scatter of three levels (their largest difference) where they do not contract, converge
#: too slowly, or oscillate without halving (Eça and Hoekstra's for data out of the asymptotic range).
SCATTER_FACTOR = 3.0
#: Observed orders trusted for extrapolation: below 0.5 the extrapolated limit lies many differences away; above 2
#: (beyond P1's order in the displacement) the coarse level is taken to lie outside the asymptotic range, and the
#: extrapolation uses order 2.
ORDER_RANGE = (0.5, 2.0)
#: Oscillating levels whose last difference is at most this share of the one before converge like an alternating
#: geometric series, whose limit lies within c/(1 + c) ≤ 1/3 of the last difference from the last level (so the
#: last difference itself carries a safety factor of at least 3); above it the oscillation is scatter.
OSCILLATION_CONTRACTION = 0.5


def relative_change(a: float, b: float) -> float:
    """|a − b| / |b| (inf when b = 0 and a ≠ 0)."""
    if a == b:
        return 0.0
    return abs(a - b) / abs(b) if b != 0 else math.inf


def observed_order(values: Sequence[float], sizes: Sequence[float], *, min_order: float = 0.0,
                   max_order: float = 8.0) -> float | None:
    """The order p of three monotone values q₁, q₂, q₃ at sizes h₁ > h₂ > h₃: the root of
    (q₂ − q₁)/(q₃ − q₂) = (h₁ᵖ − h₂ᵖ)/(h₂ᵖ − h₃ᵖ) in [``min_order``, ``max_order``], or None (not monotone, not
    decreasing sizes, or no root there)."""
    (q1, q2, q3), (h1, h2, h3) = [float(v) for v in values], [float(s) for s in sizes]
    d1, d2 = q2 - q1, q3 - q2
    if d1 == 0 or d2 == 0 or (d1 > 0) != (d2 > 0) or not h1 > h2 > h3 > 0:
        return None
    target = d1 / d2

    def ratio(p: float) -> float:
        if p == 0.0:  # the limit p → 0: ln(h₁/h₂) / ln(h₂/h₃)
            return math.log(h1 / h2) / math.log(h2 / h3)
        return (h1**p - h2**p) / (h2**p - h3**p)

    lo, hi = min_order, max_order
    rlo, rhi = ratio(lo) - target, ratio(hi) - target
    if rlo * rhi > 0:
        return None
    for _ in range(100):  # bisection: the ratio is monotone in p for h₁ > h₂ > h₃
        mid = 0.5 * (lo + hi)
        rm = ratio(mid) - target
        if (rm > 0) == (rlo > 0):
            lo, rlo = mid, rm
        else:
            hi = mid
    return 0.5 * (lo + hi)


def estimate(values: Sequence[float], sizes: Sequence[float], *, min_order: float = 0.25,
             max_order: float = 4.0) -> dict[str, Any]:
    """The converged value of a sequence computed at decreasing sizes, and the last value's error.

    Richardson extrapolation from the last three values when their two
    differences have the same sign (monotone) and the observed order p
    (:func:`observed_order`) lies in [``min_order``, ``max_order``] (outside it
    the "order" is noise: 0.25 would take sixteen halvings per halving of the
    error, 4 is beyond P1); then q∞ = q₃ + (q₃ − q₂) h₃ᵖ/(h₂ᵖ − h₃ᵖ).
    Otherwise the finest value with a band: the largest difference between the
    last value and the two before it (the scatter of the finest levels).

    Returns
    -------
    dict
        ``value`` (the estimate), ``error`` (|last − value| / |value|, or the
        band relative to the last value), ``method`` ("richardson", "band" or
        "single"), ``order`` (p or None).
    """
    q = [float(v) for v in values]
    h = [float(s) for s in sizes]
    if len(q) != len(h):
        raise ValueError("values and sizes differ in length")
    if not q:
        return {"value": math.nan, "error": math.inf, "method": "none", "order": None}
    if len(q) == 1:
        return {"value": q[0], "error": math.inf, "method": "single", "order": None}
    if len(q) >= 3:
        p = observed_order(q[-3:], h[-3:], min_order=min_order, max_order=max_order)
        if p is not None:
            (q2, q3), (h2, h3) = q[-2:], h[-2:]
            value = q3 + (q3 - q2) * h3**p / (h2**p - h3**p)
            return {"value": value, "error": relative_change(q3, value), "method": "richardson", "order": p}
    band = max(abs(q[-1] - x) for x in q[-3:-1])
    return {"value": q[-1], "error": band / abs(q[-1]) if q[-1] != 0 else math.inf, "method": "band",
            "order": None}


def sequence_uncertainty(values: Sequence[float], sizes: Sequence[float],
                         resolutions: Sequence[float] | None = None) -> dict[str, Any]:
    """The uncertainty of the finest of three levels q₁, q₂, q₃ computed at sizes h₁ > h₂ > h₃ (module notes).

    With d₁ = q₂ − q₁, d₂ = q₃ − q₂, the contraction c = |d₂| / |d₁| and the spread Δ of the three net of
    their quantisation (the largest |qᵢ − qⱼ| less the coarser resolution of the two, ``resolutions``):

    * ``"monotone"`` (d₁, d₂ of one sign, observed order p ≥ 0.5): U = 1.25 |q₃ − q∞|, q∞ the Richardson
      limit at order min(p, 2) (:data:`SAFETY_FACTOR`, :data:`ORDER_RANGE`); where p > 2 (or d₂ = 0), at least
      1.25 Δ: convergence faster than believed says the coarsest level lies outside the asymptotic range, and
      the next level may move as far as these did;
    * ``"oscillating"`` (opposite signs, c ≤ 0.5): U = |d₂|, three times the distance c/(1 + c) |d₂| ≤ |d₂|/3
      from q₃ to the limit of an alternating sequence contracting by c (:data:`OSCILLATION_CONTRACTION`); where
      c < 1/4 (an apparent order above 2), at least 1.25 Δ, as above;
    * ``"scatter"`` (the levels do not contract, c > 1; converge slower than order 0.5; or oscillate with
      c > 0.5): U = 3 Δ (:data:`SCATTER_FACTOR`);
    * ``"constant"``: the three agree, U = 0.

    Parameters
    ----------
    values : the three levels' values, coarsest first (more are allowed: the last three are used)
    sizes : their mesh sizes (the spacing at the contact patches), decreasing
    resolutions : how far each value may be off by its own quantisation (ρ*: one squeeze increment or
        sub-increment), in the values' unit; default none

    Returns
    -------
    dict
        ``error``: U, in the values' unit; ``relative``: U / |q₃| (inf when q₃ = 0 and U > 0); ``method``;
        ``order``: the observed order p (monotone levels) or None; ``contraction``: c (inf when d₁ = 0 ≠ d₂);
        ``spread``: Δ.
    """
    q = [float(v) for v in values][-3:]
    h = [float(s) for s in sizes][-3:]
    if len(q) != 3 or len(h) != 3:
        raise ValueError("sequence_uncertainty needs three values and three sizes")
    if not h[0] > h[1] > h[2] > 0:
        raise ValueError(f"the sizes must decrease and be positive, got {h}")
    r = [0.0, 0.0, 0.0] if resolutions is None else [abs(float(x)) for x in resolutions][-3:]
    if len(r) != 3:
        raise ValueError("sequence_uncertainty needs a resolution per value")
    d1, d2 = q[1] - q[0], q[2] - q[1]
    contraction = abs(d2) / abs(d1) if d1 != 0 else (0.0 if d2 == 0 else math.inf)
    spread = max(max(0.0, abs(q[i] - q[j]) - max(r[i], r[j])) for i, j in ((0, 1), (0, 2), (1, 2)))
    order = None
    if max(q) == min(q):
        u, method = 0.0, "constant"
    elif d1 * d2 > 0 and contraction <= 1:
        order = observed_order(q, h)
        if order is None and contraction < 2.0 ** -ORDER_RANGE[1]:
            order = math.inf  # faster than any order the bisection brackets
        if order is not None and order >= ORDER_RANGE[0]:
            p = min(order, ORDER_RANGE[1])
            u, method = SAFETY_FACTOR * abs(d2) * h[2]**p / (h[1]**p - h[2]**p), "monotone"
            if order > ORDER_RANGE[1]:
                u = max(u, SAFETY_FACTOR * spread)
        else:
            u, method = SCATTER_FACTOR * spread, "scatter"
    elif d2 == 0:  # the last two agree after a change: an order beyond any
        u, method = SAFETY_FACTOR * spread, "monotone"
    elif d1 * d2 < 0 and contraction <= OSCILLATION_CONTRACTION:
        u, method = abs(d2), "oscillating"
        if contraction < 2.0 ** -ORDER_RANGE[1]:
            u = max(u, SAFETY_FACTOR * spread)
    else:
        u, method = SCATTER_FACTOR * spread, "scatter"
    rel = u / abs(q[2]) if q[2] != 0 else (0.0 if u == 0 else math.inf)
    return {"error": u, "relative": rel, "method": method, "order": order, "contraction": contraction,
            "spread": spread}
