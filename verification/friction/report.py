"""Figure, headline checks and report section of the frictional-contact comparison.

Everything is drawn from the dictionaries of :func:`verification.friction.compare.run_case`,
:func:`~verification.friction.compare.step_study` and :func:`verification.friction.random_scenes.compare_random`,
as stored in ``summary.json``.
"""

from __future__ import annotations

import html
import math
from pathlib import Path
from typing import Any

import numpy as np

from .._common.html import fmt, img, table, verdict
from .._common.run import check, finite_max
from .compare import FORCE_TOL


def convergence_plot(scenes: list[dict], studies: list[dict], path: str | Path) -> Path:
    """(a) max |Δf|/F_s against the reference's increment, each scene, with the reference against its own finest
    level; (b) the plateau against fem_grasp's own increment (the step study)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    for k, s in enumerate(scenes):
        lv = s["levels"]
        h = np.array([r["drho"] for r in lv]) * 1e3
        c = f"C{k % 10}"
        a.loglog(h, [r["force_max"] for r in lv], "o-", color=c, ms=4, label=f"{s['scene']} vs fem_grasp")
        sd = [(x, r.get("self_difference")) for x, r in zip(h, lv[:-1]) if r.get("self_difference")]
        if sd:
            a.loglog(*zip(*sd), "s--", color=c, ms=3, lw=0.8)
    if scenes:
        h = np.array([r["drho"] for s in scenes for r in s["levels"]]) * 1e3
        x = np.array([h.min(), h.max()])
        a.loglog(x, 3e-3 * x / x.max(), "k:", lw=1, label="slope 1")
    a.set_xlabel("reference increment Δρ (mm)")
    a.set_ylabel("max |Δf| / F_s at fem_grasp's snapshots")
    a.set_title("solid: vs fem_grasp; dashed: vs the reference's finest M", fontsize=9)
    a.legend(fontsize=6)
    for k, st in enumerate(studies):
        rows = st["rows"]
        steps = sorted({r["fem_step"] for r in rows})
        best = [min(r["force_max"] for r in rows if r["fem_step"] == s_) for s_ in steps]
        label = f"{st['scene']}{' (quick)' if st.get('quick') else ''}"
        b.loglog(np.array(steps) * 1e3, best, "o-", color=f"C{k}", label=f"{label}: slope {st['order_in_fem_step']:.2f}")
        for r in rows:
            b.loglog(r["fem_step"] * 1e3, r["force_max"], ".", color=f"C{k}", alpha=0.5)
    if studies:
        s_all = np.array([r["fem_step"] for st in studies for r in st["rows"]]) * 1e3
        x = np.array([s_all.min(), s_all.max()])
        b.loglog(x, 2e-2 * x / x.max(), "k:", lw=1, label="slope 1")
    b.set_xlabel("fem_grasp's increment (its scene step, mm)")
    b.set_ylabel("max |Δf| / F_s (finest reference increment)")
    b.set_title("the plateau is fem_grasp's own first-order error", fontsize=9)
    b.legend(fontsize=7)
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=130)
    plt.close(fig)
    return out


def _mm(x: Any) -> Any:
    return None if x is None or (isinstance(x, float) and math.isnan(x)) else 1e3 * x


def agreement_rows(scenes: list[dict]) -> list[list[Any]]:
    rows = []
    for s in scenes:
        f = s["levels"][-1]
        lo = f.get("lift_off") or {}
        fn = lambda d: None if not d else d["normal1"] + d["normal2"]  # noqa: E731
        sc = f["self_check"]
        rows.append([
            s["scene"] + (" (quick)" if s.get("quick") else ""), s["vertices"],
            "picked up" if s["verdict_fem_grasp"] else "not picked up",
            "picked up" if s["verdict_reference"] else "not picked up",
            verdict(s["verdicts_agree"]), _mm(s["rho_star_fem_grasp"]), _mm(s["rho_star_difference"]),
            f["increments"], f["force_max"], fn(lo.get("fem_grasp")), fn(lo.get("reference")),
            f"{f['set_mismatches']}/{f['set_mismatches_away']}/{f['set_mismatches_unexplained']}",
            f"{f['state_mismatches']}/{f['state_mismatches_away']}/{f['state_mismatches_unexplained']}",
            f"{len(f['liftable_mismatches'])}/{len(f['liftable_reference'])}",
            None if not s.get("own_chain") else ("picked up" if s["own_chain"]["verdict"] else "not picked up"),
            max(sc["gap"], sc["penetration"]), max(sc["stick_excess"], sc["slip_cone"], sc["tensile"]),
            sc["slip_direction"], sc["equilibrium"], s["seconds"]])
    return rows


AGREEMENT_HEADERS = ["scene", "vertices", "fem_grasp", "reference", "verdicts", "ρ* fem_grasp (mm)", "|Δρ*| (mm)",
                     "M", "max |Δf|/F_s", "Σf·n̂ lift-off fem_grasp (N)", "Σf·n̂ reference (N)",
                     "set mism. all/away/unexpl.", "state mism. all/away/unexpl.", "w(ρ) differs / tests",
                     "own chain", "gap, penetration /L", "cone / F_s", "slip direction", "equilibrium /mg", "s"]


def section(fr: dict[str, Any], images: dict[str, str]) -> str:
    """The report's section on the frictional-contact reference (agreement, convergence, rest, random scenes)."""
    parts = ["<h2>Frictional contact: fem_grasp against an independent reference</h2>"]
    parts.append("<p class='note'>The reference (verification/friction/reference/, formulation in "
                 "verification/friction/README.md) solves each increment of squeeze depth, lift height or "
                 "hanging weight as one static contact "
                 "problem with Coulomb friction — a semismooth Newton method on the Alart–Curnier equations, exact "
                 "sphere and plane gaps, slip measured from the previous increment — on K and G assembled by "
                 "dolfinx; it shares no code with fem_grasp's contact modules and takes only the placement from "
                 "fem_grasp's result. M = reference increments per lift-test interval. Forces are compared at every "
                 "fem_grasp snapshot; contact sets and stick/slip states at every reference increment, a mismatch "
                 "being <i>near an event</i> (either solver has an event of that node within two increments), "
                 "<i>marginal</i> (the deciding force within twice the local force difference of its threshold) or "
                 "<i>unexplained</i>. The self-check columns are the worst contact-law residuals of the reference's "
                 "own states.</p>")
    scenes = fr.get("scenes", [])
    if scenes:
        parts.append("<h3>Agreement on the listed scenes (finest M)</h3>")
        parts.append(table(AGREEMENT_HEADERS, agreement_rows(scenes)))
        rows = []
        for s in scenes:
            for r in s["levels"]:
                rows.append([s["scene"], r["increments"], _mm(r["drho"]), r["force_max"], r.get("self_difference"),
                             _mm(r["set_mismatch_length"]), _mm(r["state_mismatch_length"]),
                             len(r["liftable_mismatches"]), r["solves"], r.get("continued"), r["seconds"]])
        parts.append("<h3>Against the increment</h3>")
        parts.append(table(["scene", "M", "Δρ (mm)", "max |Δf|/F_s vs fem_grasp", "vs reference's finest M",
                            "set mismatch (node·mm)", "state mismatch (node·mm)", "w(ρ) differs", "static problems",
                            "by continuation", "s"], rows))
    parts.append(img(images.get("friction_convergence"), "force difference against the reference's increment and "
                                                          "against fem_grasp's own increment"))
    studies = fr.get("step_study", [])
    if studies:
        rows = [[st["scene"] + (" (quick)" if st.get("quick") else ""), r["divisor"], _mm(r["fem_step"]),
                 r["increments"], r["force_max"], _mm(r["state_mismatch_length"]),
                 f"{r['liftable_mismatches']}/{r['tests']}", "yes" if r["verdict_fem_grasp"] else "no",
                 "yes" if r["verdict_reference"] else "no", _mm(r["rho_star_fem_grasp"]),
                 _mm(r["rho_star_reference"])] for st in studies for r in st["rows"]]
        parts.append("<h3>fem_grasp's own increment</h3><p class='note'>fem_grasp re-run with its scene step "
                     "divided; the plateau of the force difference falls with it (fitted order "
                     + ", ".join(f"{html.escape(st['scene'])} {fmt(st['order_in_fem_step'])}" for st in studies)
                     + ").</p>")
        parts.append(table(["scene", "step ÷", "fem_grasp step (mm)", "M", "max |Δf|/F_s", "state mismatch (node·mm)",
                            "w(ρ) differs / tests", "fem_grasp picks up", "reference picks up", "ρ* fem_grasp",
                            "ρ* reference"], rows))
    if scenes:
        rows = [[s["scene"], r["increments"], r["force"], f"{r['contacts_reference']} / {r['contacts_fem_grasp']}",
                 r["set_mismatches"], f"{r['sliding_reference']} / {r['sliding_fem_grasp']}", _mm(r["sag_reference"]),
                 _mm(r["sag_fem_grasp"]), r["seconds"]] for s in scenes for r in s["rest"]["rows"]]
        parts.append("<h3>Resting state: the reference's gravity ramp against fem_grasp's rest</h3>")
        parts.append(table(["scene", "load increments", "max |Δf|/F_s", "contacts ref / fem_grasp", "differ",
                            "sliding ref / fem_grasp", "sag ref (mm)", "sag fem_grasp (mm)", "s"], rows))
    rnd = fr.get("random", [])
    if rnd:
        agree = sum(r["verdicts_agree"] for r in rnd)
        parts.append(f"<h3>Random valid small scenes ({len(rnd)}, seeded)</h3><p class='note'>Verdicts agree on "
                     f"{agree} of {len(rnd)}.</p>")
        parts.append(table(AGREEMENT_HEADERS, agreement_rows(rnd)))
    return "\n".join(parts)


def checks(fric: dict[str, Any]) -> list[dict[str, Any]]:
    """Headline checks: verdicts agree, forces within tolerance at the finest increment, the reference's own
    contact-law residuals at round-off, no unexplained set or state mismatch on the shipped scenes."""
    out = []

    def add(name: str, value: float, threshold: str, ok: bool) -> None:
        out.append(check(name, value, threshold, ok))

    scenes = fric.get("scenes", [])
    rnd = fric.get("random", [])
    if scenes:
        n_bad = sum(not s["verdicts_agree"] for s in scenes)
        add(f"frictional contact: verdicts differ on shipped scenes (of {len(scenes)})", n_bad, "= 0", n_bad == 0)
        v = finite_max(s["force_max_finest"] for s in scenes)
        add("frictional contact: max |Δf|/F_s at the finest increment, shipped scenes", v, f"≤ {FORCE_TOL:g}",
            v <= FORCE_TOL)
        v = sum(s["levels"][-1]["set_mismatches_unexplained"] + s["levels"][-1]["state_mismatches_unexplained"]
                for s in scenes)
        add("frictional contact: unexplained set/state mismatches, shipped scenes", v, "= 0", v == 0)
    states = scenes + rnd
    if states:
        worst = {k: finite_max(s["levels"][-1]["self_check"][k] for s in states) for k in states[0]["levels"][-1]["self_check"]}
        add("reference self-check: |gap| and penetration / diameter", max(worst["gap"], worst["penetration"]),
            "≤ 1e-10", max(worst["gap"], worst["penetration"]) <= 1e-10)
        cone = max(worst["tensile"], worst["stick_excess"], worst["slip_cone"])
        add("reference self-check: cone and complementarity / F_s", cone, "≤ 1e-10", cone <= 1e-10)
        add("reference self-check: friction opposite the slip (1 + cos)", worst["slip_direction"], "≤ 1e-7",
            worst["slip_direction"] <= 1e-7)
        add("reference self-check: equilibrium / mg", worst["equilibrium"], "≤ 1e-12", worst["equilibrium"] <= 1e-12)
    if rnd:
        n_bad = sum(not r["verdicts_agree"] for r in rnd)
        # Reported, not failed: random scenes include ill-posed lift tests (verification/friction/README.md).
        add(f"frictional contact: verdicts differ on random scenes (of {len(rnd)}; reported)", n_bad,
            "reported", True)
    return out


__all__ = ["AGREEMENT_HEADERS", "agreement_rows", "checks", "convergence_plot", "section"]
