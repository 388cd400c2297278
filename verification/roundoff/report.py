"""The round-off study's headline check and report section."""

from __future__ import annotations

from typing import Any

from .._common.html import fmt, table
from .._common.run import check


def checks(part: dict[str, Any]) -> list[dict[str, Any]]:
    """No case and variant outside the promise."""
    pert = part.get("perturbation")
    if not pert:
        return []
    n = len(pert["violations"])
    return [check(f"round-off perturbations: cases × variants outside the promise ({len(pert['rows'])} runs)", n,
                  "0 (same verdict, ρ* within an increment, forces within "
                  f"{pert['tolerances']['force_of_weight']:g} mg, checks pass)", n == 0)]


def section(part: dict[str, Any], images: dict[str, str]) -> str:
    """The report's section: per case, the reference's answer and the largest spread over the variants."""
    pert = part.get("perturbation")
    if not pert:
        return ""
    parts = ["<h2>Same answer on every machine: round-off perturbations</h2>"]
    tol = pert["tolerances"]
    parts.append(f"<p class='note'>Each case picked up in a fresh process under each variant ({', '.join(pert['variants'])}): "
                 f"coordinates jittered by {fmt(tol['jitter'])} × the diameter, the plain-Python kernels, one "
                 "and two BLAS threads, other OpenBLAS kernels, numpy without its widest SIMD loops. Promised: "
                 f"the reference's verdict, ρ* within {fmt(tol['depth_steps'])} increment, finger forces within "
                 f"{fmt(tol['force_of_weight'])} mg, check() on every snapshot.</p>")
    rows = []
    for line in pert["table"].splitlines()[2:]:
        rows.append([c.strip() for c in line.strip("|").split("|")])
    parts.append(table(["case", "reference", "variants", "same events", "max Δρ* (increments)",
                        "max Δforce (mg)", "problems"], rows))
    return "\n".join(parts)
