"""The coverage study's headline checks and report section."""

from __future__ import annotations

import html
import math
from typing import Any

from .._common.html import fmt, table
from .._common.run import check
from .summary import REQUIRED_COVERAGE


def _num(x: Any) -> float:
    return math.nan if x is None else float(x)


def checks(part: dict[str, Any]) -> list[dict[str, Any]]:
    """The estimated error covers the actual one on at least 90 % of the objects; every verdict agrees with the
    reference's or says it is not settled."""
    cov = part.get("coverage")
    if not cov:
        return []
    s = cov["summary"]
    n = s["with_reference"]
    both = _num(s["coverage"]["both"])
    settled = s.get("verdicts_differ_settled", s["verdicts_differ"])
    return [check(f"objects whose estimated error of rho* and finger force covers the actual one ({n} with a "
                  f"reference of {s['objects']})", both, f">= {REQUIRED_COVERAGE:g}",
                  not math.isnan(both) and both >= REQUIRED_COVERAGE),
            check(f"objects whose verdict differs from the reference's although the answer called it settled ({n} "
                  f"compared; {s['verdicts_differ']} differ in all)", settled, "0", n > 0 and settled == 0)]


def _pct(x: Any) -> str:
    if x is None:
        return "–"
    x = float(x)
    return "–" if math.isnan(x) else "inf" if math.isinf(x) else f"{100 * x:.1f} %"


def _draws_text(summary: dict[str, Any]) -> str:
    counts = summary.get("reference_draws") or [1]
    most = max(counts)
    return f"{most} draws of its mesh" if most > 1 else "one draw of its mesh"


def section(part: dict[str, Any], images: dict[str, str]) -> str:
    """The report's section: the summary and one row per object."""
    cov = part.get("coverage")
    if not cov:
        return ""
    s, cfg = cov["summary"], part.get("config", {})
    n = s["with_reference"]
    settled = s.get("verdicts_differ_settled", s["verdicts_differ"])
    differ = (f" (of the {s['verdicts_differ']} that differ, {s['verdicts_differ'] - settled} said the verdict is not "
              "settled)" if s["verdicts_differ"] else "")
    parts = ["<h2>Does the stated error hold? (random objects)</h2>",
             f"<p>{s['objects']} random objects (gmsh ellipsoids, fused spheres and capsules of 2–4.5 cm; "
             f"E 5–100 kPa, ν 0.2–0.45, density 300–1500 kg/m³, μ 0.3–1.0, fingertip 0.3–0.6 × the smallest "
             f"radius, tilt 0–30°, ratio 0–1), each picked up with <code>accuracy={fmt(cfg.get('accuracy'))}"
             f"</code> and once more a level finer as the reference (the mean over {_draws_text(s)}). "
             f"{s['answered']} answered "
             f"({s['converged']} converged), {n} with a reference; the verdicts agree on {s['verdicts_agree']} of "
             f"{n}{differ}. The estimated error is at least the actual one for ρ* on "
             f"{s['covered']['squeeze_depth']}, for "
             f"the finger force on {s['covered']['finger_force']}, for both on {s['covered']['both']} of {n} "
             f"({_pct(s['coverage']['both'])}); with the reference's own spread added, on "
             f"{s.get('covered_with_reference', s['covered']['both'])} of {n}. Answers: median "
             f"{fmt(s['answer_seconds']['median'])} s, longest "
             f"{fmt(s['answer_seconds']['max'])} s; references: median {fmt(s['reference_seconds']['median'])} s, "
             f"longest {fmt(s['reference_seconds']['max'])} s.</p>"]
    if s.get("errors"):
        parts.append("<p>Runs that raised: " + html.escape(", ".join(f"{k} ({v})" for k, v in
                                                                     sorted(s["errors"].items()))) + ".</p>")
    rows = []
    for r in cov["objects"]:
        a, ref, c, o = r["answer"], r["reference"], r["comparison"], r["object"]
        est = a.get("estimated_error") or {}
        compared = c["status"] == "compared"
        rows.append([r["seed"], o["shape"], 10 ** o["log10_young"] / 1e3, o["density"], a.get("levels"),
                     a.get("status") if a.get("status") != "ok" else ("lifted" if a["success"] else "not lifted"),
                     _pct(est.get("squeeze_depth")) if est else "–", _pct(est.get("finger_force")) if est else "–",
                     ref.get("status") if ref.get("status") != "ok" else ("lifted" if ref["success"] else "not lifted"),
                     _pct(c["actual"]["squeeze_depth"]) if compared else "–",
                     _pct(c["actual"]["finger_force"]) if compared else "–",
                     ("yes" if c["covered_both"] else "no") if compared else "–", a.get("seconds"), ref.get("seconds")])
    parts.append(table(["seed", "shape", "E (kPa)", "density (kg/m³)", "levels", "answer", "est. ρ*", "est. force",
                        "reference", "actual ρ*", "actual force", "covered", "answer s", "reference s"], rows))
    parts.append("<p class='note'>Covered: the estimated error is at least |answer − reference| / |reference| "
                 "and the verdicts agree, or the estimate is infinite. " + html.escape(
                     "A reference is skipped when it would put more than "
                     f"{cfg.get('max_reference_contacts', 600)} contacts on a fingertip, and abandoned after "
                     f"{fmt(cfg.get('reference_seconds'))} s per draw.") + "</p>")
    return "\n".join(parts)
