"""The coverage arithmetic: per object, the actual error of the answer against its reference and whether the
estimated error covers it; over the objects, the coverage fractions, the verdict agreement and the times.

Works on the rows alone (:func:`verification.coverage.runner.run_object`), so that a saved JSON can be
analysed again (``python -m verification coverage --reanalyse FILE``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .runner import QUANTITIES, combine_draws, relative_error

#: Share of the objects with a reference whose estimated error must cover the actual one (both quantities).
REQUIRED_COVERAGE = 0.9
#: An actual error this small (relative) is round-off, covered by any estimate: a failure that squeezed to the
#: deepest squeeze states no error for ρ (the setting every level and the reference share), and the mean of the
#: reference's draws, each at that depth, differs from it in the last bit.
ROUNDOFF = 1e-12


def _estimate(value: Any) -> float:
    """An estimated error as a float: a missing or null one is unknown, so infinite (JSON writes inf as null)."""
    return math.inf if value is None else float(value)


def reference_of(row: dict[str, Any]) -> dict[str, Any]:
    """A row's reference, its draws combined again (:func:`~verification.coverage.runner.combine_draws`), so that
    a saved run is analysed by today's rules; its ``seconds`` stay the time it took (a reference that ended early
    spent time on a draw that did not finish)."""
    ref = row.get("reference") or {}
    if not ref.get("draws"):
        return ref
    combined = combine_draws(ref["draws"])
    combined["seconds"] = ref.get("seconds", combined["seconds"])
    return dict(ref, **combined)


def _unsettled(answer: dict[str, Any]) -> bool:
    """Whether the answer said its verdict is not settled (module notes of :func:`evaluate`)."""
    est = answer["accuracy"]["estimated_error"]
    return bool(answer["accuracy"].get("verdict")) or all(math.isinf(_estimate(est.get(q))) for q in QUANTITIES)


def evaluate(row: dict[str, Any]) -> dict[str, Any]:
    """One object's comparison.

    Returns
    -------
    dict
        ``status``: "compared", "no answer" (the answer failed or ran out of time) or "no reference" (too large,
        timed out, failed); when compared, ``verdicts_agree``, per quantity ``estimated``, ``actual`` (|answer −
        reference| / |reference|) and ``covered``, and ``covered_both``.  A quantity is covered when its estimate
        is at least its actual error (less :data:`ROUNDOFF`) and the verdicts agree, or when its estimate is
        infinite (the answer says it does not know).  ``verdict_unsettled``: the answer said its verdict is not
        settled (the accuracy block's ``verdict``, or, in rows saved before it, infinite estimates of both
        quantities).
        ``covered_with_reference``: the same with the reference's own uncertainty (the spread of its draws,
        :func:`~verification.coverage.runner.combine_draws`) added to the estimate, and ``reference_spread``.
    """
    ans, ref = row.get("answer") or {}, reference_of(row)
    if ans.get("status") != "ok":
        return {"status": "no answer", "why": ans.get("status", "missing")}
    unsettled = _unsettled(ans)
    if ref.get("status") != "ok":
        return {"status": "no reference", "why": ref.get("status", "missing"), "verdict_unsettled": unsettled}
    agree = bool(ans["success"]) == bool(ref["success"])
    est = ans["accuracy"]["estimated_error"]
    out: dict[str, Any] = {"status": "compared", "verdicts_agree": agree, "verdict_unsettled": unsettled,
                           "estimated": {}, "actual": {}, "covered": {}, "covered_with_reference": {},
                           "reference_spread": {}}
    spread = ref.get("spread") or {}
    for q in QUANTITIES:
        e = _estimate(est.get(q))
        a = relative_error(float(ans[q]), float(ref[q]))
        out["estimated"][q], out["actual"][q] = e, a
        out["reference_spread"][q] = float(spread.get(q, 0.0))
        out["covered"][q] = bool(math.isinf(e) or (agree and e + ROUNDOFF >= a))
        out["covered_with_reference"][q] = bool(math.isinf(e) or (agree and e + out["reference_spread"][q] + ROUNDOFF
                                                                  >= a))
    out["covered_both"] = all(out["covered"].values())
    out["covered_both_with_reference"] = all(out["covered_with_reference"].values())
    return out


def _median_max(values: list[float]) -> dict[str, float]:
    v = [float(x) for x in values if x is not None]
    return {"median": float(np.median(v)) if v else math.nan, "max": max(v) if v else math.nan}


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Over the objects: how many ran, had an answer, had a reference; verdict agreement; coverage per quantity
    and for both together (fractions of the objects with a reference; NaN when none has one); times."""
    ev = [evaluate(r) for r in rows]
    compared = [e for e in ev if e["status"] == "compared"]
    n = len(compared)
    refs = [reference_of(r) for r in rows]  # the draws combined once
    ran = [ref for ref in refs if ref.get("status") == "ok"]
    reference_status: dict[str, int] = {}
    for r, ref in zip(rows, refs):
        if (r.get("answer") or {}).get("status") == "ok":
            s = ref.get("status", "missing")
            reference_status[s] = reference_status.get(s, 0) + 1
    answer_status: dict[str, int] = {}
    for r in rows:
        s = (r.get("answer") or {}).get("status", "missing")
        answer_status[s] = answer_status.get(s, 0) + 1
    errors: dict[str, int] = {}
    for r in rows:
        for part in ("answer", "reference"):
            p = r.get(part) or {}
            if p.get("status") == "failed":
                key = f"{part}: {str(p.get('error', '')).split(':')[0] or 'unknown'}"
                errors[key] = errors.get(key, 0) + 1
    coverage = {q: (sum(e["covered"][q] for e in compared) / n if n else math.nan) for q in QUANTITIES}
    coverage["both"] = sum(e["covered_both"] for e in compared) / n if n else math.nan
    answered = [r for r in rows if (r.get("answer") or {}).get("status") == "ok"]
    return {
        "objects": len(rows),
        "answered": len(answered),
        "answer_status": answer_status,
        "reference_status": reference_status,
        "errors": errors,
        "with_reference": n,
        "verdicts_agree": sum(e["verdicts_agree"] for e in compared),
        "verdicts_differ": sum(not e["verdicts_agree"] for e in compared),
        "verdicts_differ_settled": sum(not e["verdicts_agree"] and not e.get("verdict_unsettled") for e in compared),
        # the reference's draws split on the verdict although the answer called its verdict settled
        "draws_disagree_settled": sum(e.get("why") == "draws disagree" and not e["verdict_unsettled"] for e in ev),
        "covered": {q: sum(e["covered"][q] for e in compared) for q in QUANTITIES}
        | {"both": sum(e["covered_both"] for e in compared)},
        "covered_with_reference": sum(e["covered_both_with_reference"] for e in compared),
        "reference_draws": [int(ref.get("draws_ok") or 1) for ref in ran],
        "reference_spread": {q: _median_max([e["reference_spread"][q] for e in compared]) for q in QUANTITIES},
        "coverage": coverage,
        "converged": sum(bool(r["answer"]["accuracy"]["converged"]) for r in answered),
        "answer_seconds": _median_max([r["answer"]["seconds"] for r in answered]),
        "reference_seconds": _median_max([ref["seconds"] for ref in ran]),
    }


def passed(summary: dict[str, Any]) -> tuple[bool, bool]:
    """(coverage of both quantities at least :data:`REQUIRED_COVERAGE`, no verdict differing from its reference
    where the answer called it settled); an empty comparison passes neither.  An answer that says its verdict is
    not settled says it does not know: a finer mesh deciding otherwise is what it warned of."""
    cov = summary["coverage"]["both"]
    return (bool(cov >= REQUIRED_COVERAGE) if not math.isnan(cov) else False,
            summary["with_reference"] > 0 and _differ_settled(summary) == 0)


def _differ_settled(summary: dict[str, Any]) -> int:
    return summary.get("verdicts_differ_settled", summary["verdicts_differ"])


def _pct(x: float | None) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "-"
    return "inf" if math.isinf(x) else f"{100 * x:.1f}%"


def _s(x: float | None) -> str:
    return "-" if x is None or math.isnan(x) else f"{x:.0f}"


#: Columns of :func:`table_line`.
HEADER = (f"{'seed':>5} {'shape':<13} {'E kPa':>6} {'kg/m3':>6} {'lvls':>4} {'answer':<10} {'est rho*':>8} "
          f"{'est F':>8} {'reference':<12} {'act rho*':>8} {'act F':>8} {'covered':<9} {'ans s':>6} {'ref s':>6}")


def _verdict(part: dict[str, Any]) -> str:
    if part.get("status") != "ok":
        return part.get("status", "-")
    return "lifted" if part["success"] else "not lifted"


def table_line(row: dict[str, Any]) -> str:
    """One object as a line of the progress table (:data:`HEADER`)."""
    o = row["object"]
    ans, ref = row.get("answer") or {}, reference_of(row)
    e = evaluate(row)
    est = (ans.get("accuracy") or {}).get("estimated_error", {})
    levels = len((ans.get("accuracy") or ans.get("levels_so_far") or {}).get("levels", [])) or "-"
    if e["status"] == "compared":
        act = [_pct(e["actual"][q]) for q in QUANTITIES]
        cov = "+".join("y" if e["covered"][q] else "n" for q in QUANTITIES)
        if not e["verdicts_agree"]:
            cov += " V"
    else:
        act, cov = ["-", "-"], "-"
    ref_s = f"{ref['seconds']:.0f}" if ref.get("seconds") is not None else "-"
    ans_s = f"{ans['seconds']:.0f}" if ans.get("seconds") is not None else "-"
    return (f"{row['seed']:>5} {o['shape']:<13} {10 ** o['log10_young'] / 1e3:>6.1f} {o['density']:>6.0f} "
            f"{levels!s:>4} {_verdict(ans):<10} {_pct(_estimate(est.get('squeeze_depth')) if est else None):>8} "
            f"{_pct(_estimate(est.get('finger_force')) if est else None):>8} {_verdict(ref):<12} {act[0]:>8} "
            f"{act[1]:>8} {cov:<9} {ans_s:>6} {ref_s:>6}")


def _draws(counts: list[int]) -> str:
    """"3 draws each", or the counts where they differ (a reference that ran out of time keeps the draws done)."""
    if not counts:
        return "none"
    if len(set(counts)) == 1:
        return f"{counts[0]} draw{'s' if counts[0] != 1 else ''} of the mesh each"
    return "draws of the mesh: " + ", ".join(str(c) for c in counts)


def _spread(summary: dict[str, Any], q: str, stat: str) -> float | None:
    return ((summary.get("reference_spread") or {}).get(q) or {}).get(stat)


def summary_lines(summary: dict[str, Any]) -> list[str]:
    """The summary in a few lines of text."""
    s = summary
    cov, cnt = s["coverage"], s["covered"]
    n = s["with_reference"]
    ok_cov, ok_verdict = passed(s)
    return [
        f"{s['objects']} objects: {s['answered']} answered ({s['converged']} converged), {n} with a reference "
        f"(references: {', '.join(f'{k} {v}' for k, v in sorted(s['reference_status'].items())) or 'none'})"
        + (f"; where the reference's draws disagree on the verdict, {s['draws_disagree_settled']} answer(s) called "
           "theirs settled" if s["reference_status"].get("draws disagree") else ""),
        f"answers: {', '.join(f'{k} {v}' for k, v in sorted(s['answer_status'].items()))}"
        + (f"; errors: {', '.join(f'{k} {v}' for k, v in sorted(s.get('errors', {}).items()))}"
           if s.get("errors") else ""),
        f"verdicts agree on {s['verdicts_agree']} of {n}"
        + (f"; of the {s['verdicts_differ']} that differ, {s['verdicts_differ'] - _differ_settled(s)} said the "
           "verdict is not settled" if s["verdicts_differ"] else ""),
        f"estimated error >= actual: rho* {cnt['squeeze_depth']}/{n} ({_pct(cov['squeeze_depth'])}), finger force "
        f"{cnt['finger_force']}/{n} ({_pct(cov['finger_force'])}), both {cnt['both']}/{n} ({_pct(cov['both'])})",
        f"references: {_draws(s.get('reference_draws', []))}; their spread over the draws: rho* median "
        f"{_pct(_spread(s, 'squeeze_depth', 'median'))}, max {_pct(_spread(s, 'squeeze_depth', 'max'))}, finger "
        f"force median {_pct(_spread(s, 'finger_force', 'median'))}, max {_pct(_spread(s, 'finger_force', 'max'))}; "
        f"with it added to the estimate, both covered on {s.get('covered_with_reference', cnt['both'])}/{n}",
        f"answer seconds: median {_s(s['answer_seconds']['median'])}, max {_s(s['answer_seconds']['max'])}; "
        f"reference seconds: median {_s(s['reference_seconds']['median'])}, max {_s(s['reference_seconds']['max'])}",
        f"{'PASS' if ok_cov else 'FAIL'}  coverage of both quantities >= {100 * REQUIRED_COVERAGE:.0f} %",
        f"{'PASS' if ok_verdict else 'FAIL'}  every verdict agrees with its reference or says it is not settled",
    ]
