"""The diagnosis of a verdict flip: the pickup re-run with a slow, independent lift test beside the library's.

At every squeeze increment the hanging configuration is loaded from zero in steps of h/8 (the library's lift test
loads in steps of h): the largest weight held is the slow w(ρ).  Where it reaches mg at a depth the library's test
did not pass, the verdict is within the lift test's step h; where it does not, that mesh holds less than mg
(a physical outcome of the discretisation).
"""

from __future__ import annotations

import time
from typing import Any


def diagnose(body, kw: dict[str, Any], scene, fraction: float = 0.125) -> dict[str, Any]:
    """Re-run the pickup with a slow, independent lift test beside the library's.

    At every squeeze increment the lift test's hanging configuration is loaded
    from zero in steps of ``fraction`` × h (each settled from the previous one
    by the same return mapping, with its halvings), up to 1.6 mg: the largest
    weight held is the slow w(ρ).  Where the slow w reaches mg at a depth the
    lift test did not pass, a state the test missed exists (a numerical
    failure of the test); where it does not, the discretisation holds less
    (a physical outcome of that mesh).  Also records the finger patch (node
    count, heights) and the reason the slow loading stops at its peak.
    """
    import sys as _sys

    from fem_grasp.grasp import lift_test as lt_mod
    from fem_grasp.grasp.pickup import pickup

    pk = _sys.modules["fem_grasp.grasp.pickup"]
    rows: list[dict[str, Any]] = []
    orig_cls = lt_mod.LiftTest

    class Slow(orig_cls):  # type: ignore[misc, valid-type]
        def update(self, state):  # noqa: D401 - same contract
            w = super().update(state)
            base = lt_mod.hanging_state(self.tracker, state)
            ws, reason, st = 0.0, base.reason, None
            if base.held:
                st, dw, k = base.state, fraction * self.step, 1
                while k * dw <= 1.6 * self.weight:
                    r = lt_mod.hang(self.tracker, st, k * dw)
                    if not r.held:
                        reason = r.reason
                        break
                    st, ws, k = r.state, k * dw, k + 1
            fingers = state.owner != 2
            rows.append({"rho": state.squeeze_depth, "test_w": w, "slow_w": ws, "reason": reason,
                         "finger_contacts": [int((state.owner == f).sum()) for f in (0, 1)],
                         "finger_nodes": state.nodes[fingers].tolist(), "held": _held_patch(self.tracker, st, reason)})
            return w

    kw = dict(kw, lift=False)
    pk.LiftTest = Slow
    try:
        t0 = time.perf_counter()
        res = pickup(body, **kw)
    finally:
        pk.LiftTest = orig_cls
    weight = body.weight
    test_pass = next((r["rho"] for r in rows if r["test_w"] >= weight * (1 - 1e-9)), None)
    slow_pass = next((r["rho"] for r in rows if r["slow_w"] >= weight * (1 - 1e-9)), None)
    peak = max(rows, key=lambda r: r["slow_w"]) if rows else None
    return {"rows": rows, "weight": weight, "test_pass": test_pass, "slow_pass": slow_pass,
            "slow_peak": None if peak is None else peak["slow_w"], "slow_peak_rho": None if peak is None else peak["rho"],
            "peak_reason": None if peak is None else peak["reason"], "peak_patch": None if peak is None else peak["held"],
            "reason": res.reason, "seconds": time.perf_counter() - t0}


def _held_patch(tracker, st, reason: str) -> dict[str, Any] | None:
    """At the largest weight held: per finger its contacts, how many sit above the fingertip's centre (whose
    normal forces push the object up), how many slide, and the vertical force it carries; and the node and
    finger the failing settle names (its "contact k" indexes the held state's contact set)."""
    import re

    if st is None:
        return None
    out: dict[str, Any] = {"fingers": []}
    pos = st.surface_positions[tracker.surface_index[st.nodes]]
    for f in (0, 1):
        on = st.owner == f
        up = (pos[on, 2] - st.centers[f][2]) > 0
        out["fingers"].append({"contacts": int(on.sum()), "above_centre": int(up.sum()),
                               "sliding": int(st.sliding[on].sum()), "vertical": float(st.forces[on, 2].sum())})
    m = re.search(r"contact (\d+)", reason or "")
    if m and int(m.group(1)) < st.n_contacts:
        k = int(m.group(1))
        out["failing_node"] = int(st.nodes[k])
        out["failing_finger"] = int(st.owner[k]) + 1
        out["failing_above_centre"] = bool(pos[k, 2] > st.centers[st.owner[k]][2])
    return out

