"""The softness study's report section (no headline check: the study measures, it does not promise)."""

from __future__ import annotations

import math
from typing import Any

from .._common.html import img, table


def _mm(x: Any) -> Any:
    return None if x is None or (isinstance(x, float) and math.isnan(x)) else 1e3 * x


def checks(part: dict[str, Any]) -> list[dict[str, Any]]:
    """None: the study reports how the forces compare with the rigid grasp's, it has no pass/fail bound."""
    return []


def section(part: dict[str, Any], images: dict[str, str]) -> str:
    """The report's section: deformable against rigid finger forces at lift-off, per object and modulus."""
    soft = part.get("softness")
    if not soft:
        return ""
    parts = ["<h2>Softness against the rigid grasp (paper Table III)</h2>",
             "<p class='note'>fem_grasp's pickup of each paper scene with E over three decades (everything else as "
             "shipped), forces at lift-off against the least-normal-force rigid two-point grasp at the same "
             "contacts. Ratios deformable / rigid for each measure; wrap = Σ f·n̂ over the normal part of each "
             "patch's resultant (1 for a flat patch); tilt = angle of the patch's mean normal from the rigid "
             "contact normal; utilisation = Σ|f_t| / μ Σ f·n̂ (1 for the rigid least-force grasp); w/mg = the "
             "liftable weight at the passing test. The paper's ratios: "
             + ", ".join(f"{k} {v[0] / v[1]:.2f}" for k, v in soft["table_iii"].items()) + ".</p>"]
    rows = []
    for r in soft["rows"]:
        q = r.get("ratio") or {}
        rows.append([r["object"], r["mesh"], r["vertices"], r["young"], "yes" if r["success"] else "no",
                     _mm(r["squeeze_depth"]), r.get("normal"), (r.get("rigid") or {}).get("normal"), q.get("normal"),
                     q.get("grip"), q.get("resultant"), r.get("wrap"),
                     None if "tilt" not in r else max(r["tilt"]), r.get("utilisation"), r.get("liftable_excess")])
    parts.append(table(["object", "mesh", "vertices", "E (Pa)", "picked up", "ρ* (mm)", "Σf·n̂ (N)", "rigid (N)",
                        "ratio Σf·n̂", "ratio grip", "ratio resultant", "wrap", "tilt (°)", "utilisation", "w/mg"],
                       rows))
    con = soft.get("conclusions", {})
    if con:
        rows = [[k, v["below_rigid"], v["paper_like"], v["runs"], v["min"], v["max"]] for k, v in con.items()
                if isinstance(v, dict) and "runs" in v]
        parts.append(table(["mesh / measure", "runs below rigid", "in the paper's 0.80–0.95", "runs", "min ratio",
                            "max ratio"], rows))
    parts.append(img(images.get("softness"), "deformable / rigid finger force at lift-off against E"))
    return "\n".join(parts)
