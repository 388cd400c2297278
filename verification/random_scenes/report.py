"""The random-scene study's headline check and report section."""

from __future__ import annotations

import html
from typing import Any

from .._common.html import fmt, table
from .._common.run import check


def checks(part: dict[str, Any]) -> list[dict[str, Any]]:
    """No random valid scene crashes or fails a check."""
    rnd = part.get("random_scenes")
    if not rnd:
        return []
    n = len(rnd["problems"])
    return [check(f"random valid scenes that crash or fail a check ({rnd['scenes']} scenes)", n, "0", n == 0)]


def section(part: dict[str, Any], images: dict[str, str]) -> str:
    """The report's section: the outcomes of the random scenes and any that crashed or failed a check."""
    rnd = part.get("random_scenes")
    if not rnd:
        return ""
    parts = ["<h2>Random valid scenes never crash</h2>"]
    counts = ", ".join(f"{k}: {v}" for k, v in sorted(rnd["outcomes"].items()))
    parts.append(f"<p>{rnd['scenes']} random valid scenes (gmsh ellipsoids and fused spheres; E 1e3–1e7 Pa, "
                 f"ν 0–0.45, μ 0.05–1.5, fingertip radius, tilt 0–40°, ratio 0–1): {html.escape(counts)}; "
                 f"median {fmt(rnd['median_seconds'])} s, longest {fmt(rnd['max_seconds'])} s. "
                 f"Crashes or failed checks: {len(rnd['problems'])}.</p>")
    if rnd["problems"]:
        parts.append(table(["seed", "problems"], [[p["seed"], "; ".join(p["problems"])] for p in rnd["problems"]]))
    return "\n".join(parts)
