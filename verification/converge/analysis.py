"""The study's analysis: the reference, each run's error against it, the converged estimates, the cheapest
resolution per target, the seeds' scatter, the adaptive loop's answers, and the verdict flips with their diagnoses."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .specs import case_key


def _err(q: float | None, ref: float | None) -> float:
    if q is None or ref is None or not (math.isfinite(q) and math.isfinite(ref)) or ref == 0:
        return math.nan
    return abs(q - ref) / abs(ref)


def _row(rec: dict[str, Any]) -> dict[str, Any]:
    a = rec.get("answer")
    sp = rec["spec"]
    row = {"series": sp["series"], "spec": sp, "vertices": rec.get("vertices"), "seconds": rec.get("seconds"),
           "pickup_seconds": rec.get("pickup_seconds"), "timeout": bool(rec.get("timeout")),
           "error": rec.get("error", "")[-300:] if rec.get("error") else "", "peak_mib": rec.get("peak_mib"),
           "spacing": rec.get("spacing"), "patch_spacing": rec.get("patch_spacing"), "code": rec.get("code")}
    if a:
        row.update(success=a["success"], reason=a["reason"], rho=a["squeeze_depth"], force=a["finger_force"],
                   fingers=a["fingers"], table_nodes=a["table_nodes"], max_liftable=a["max_liftable"],
                   weight=a["weight"], step=a["step"], lift_test_step=a["lift_test_step"], liftable=a["liftable"],
                   bracket=rec.get("bracket"), lift_attempts=len(rec.get("lift_attempts", [])) or None)
    if rec.get("accuracy"):
        row["accuracy"] = rec["accuracy"]
    if rec.get("diagnosis"):
        row["diagnosis"] = {k: v for k, v in rec["diagnosis"].items() if k != "rows"}
        row["diagnosis_rows"] = [{k: v for k, v in r.items() if k != "finger_nodes"} for r in rec["diagnosis"]["rows"]]
    return row


def _level(sp: dict[str, Any]) -> float:
    for k in ("target", "factor", "inner", "divisor", "seed"):
        if k in sp:
            return -sp[k] if k == "inner" else sp[k]
    return 0.0


def liftable_gap(curve: list, ref: list, weight: float) -> float:
    """max |w(ρ) − w_ref(ρ)| / mg over the depths both lift-test histories reach (w_ref interpolated linearly
    between its depths): the error of the liftable-weight curve, which stays well defined where ρ* does not
    (w(ρ) flat near mg, or a verdict that flips)."""
    a = np.asarray(curve, float).reshape(-1, 2)
    b = np.asarray(ref, float).reshape(-1, 2)
    if not len(a) or len(b) < 2 or not weight > 0:
        return math.nan
    inside = (a[:, 0] >= b[0, 0]) & (a[:, 0] <= b[-1, 0])
    if not inside.any():
        return math.nan
    return float(np.max(np.abs(a[inside, 1] - np.interp(a[inside, 0], b[:, 0], b[:, 1]))) / weight)


def liftable_slope(curve: list, rho: float) -> float | None:
    """dw/dρ of a lift-test history about ρ (N/m, the secant over the two increments before ρ): how far an error
    δw of the liftable weight moves ρ*, δρ* ≈ δw / (dw/dρ)."""
    a = np.asarray(curve, float).reshape(-1, 2)
    if len(a) < 3 or rho is None:
        return None
    k = int(np.clip(np.searchsorted(a[:, 0], rho), 2, len(a) - 1))
    d = a[k, 0] - a[k - 2, 0]
    return float((a[k, 1] - a[k - 2, 1]) / d) if d > 0 else None


def mesh_band(series: dict[str, list[dict]], fine: dict[str, Any], reference: dict[str, Any]) -> dict[str, Any]:
    """How far the other fine meshes are from the reference: per quantity, the largest relative difference between
    the reference's value and the next-finest uniform level and the finest graded and graded + table levels (those
    that pick the object up).  The reference's own band covers only its increments; this one says whether the
    meshes agree, which a converged answer needs."""
    uni = sorted((r for r in series.get("uniform", []) if r.get("success") and r is not fine),
                 key=lambda r: r["vertices"])
    others = uni[-1:] + [max((r for r in series.get(s, []) if r.get("success")), key=lambda r: r["vertices"],
                             default=None) for s in ("graded", "graded_table")]
    others = [r for r in others if r is not None]
    out: dict[str, Any] = {"levels": [{"series": r["series"], "vertices": r["vertices"], "rho": r["rho"],
                                       "force": r["force"]} for r in others]}
    for q in ("rho", "force"):
        ref = reference[q]["value"]
        out[q] = max((abs(r[q] - ref) / abs(ref) for r in others), default=math.nan) if ref else math.nan
    return out


def within(row: dict[str, Any], target: float, picked: bool) -> bool:
    """A run is within ``target`` of the reference: same verdict, and ρ* and Σ f·n̂ within it (a reference that
    picks the object up) or its w(ρ) within target × mg (one that does not)."""
    if not row.get("verdict_ok", True):
        return False
    if picked:
        return max(row["rho_error"], row["force_error"]) <= target
    return row.get("w_error", math.nan) <= target


def adaptive_at(acc: dict[str, Any], target: float) -> dict[str, Any] | None:
    """What ``pickup(..., accuracy=target)`` returns, read off a run of the loop at a finer target: the first level
    ≥ 1 with the verdict of the one before whose estimated error meets ``target`` by the loop's own rule
    (:func:`fem_grasp.grasp.level_error.estimated_error`: the change from the level before, or the uncertainty of
    the last three levels where larger, plus the resolution of ρ*, one squeeze increment or sub-increment,
    relative; for ρ* at least twice the resolution; for the force at least ρ*'s times the force's exponent over ρ,
    Hertz's 3/2 in records made before the levels carried it), and its cumulative time.  The finer target's run
    took finer increments, so the time is an upper bound on that of a run at ``target``."""
    from types import SimpleNamespace

    from fem_grasp.grasp.answer import HERTZ_EXPONENT
    from fem_grasp.grasp.level_error import estimated_error, three_level_errors

    levels = acc.get("levels", [])
    seconds = 0.0
    for i, lv in enumerate(levels):
        seconds += (lv.get("seconds") or 0.0) + (lv.get("mesh_seconds") or 0.0)
        ch = lv.get("change")
        if not i or not ch or levels[i - 1]["success"] != lv["success"]:
            continue
        # a level's record holds what estimated_error reads of its GraspAnswer
        step = lv.get("step") or 0.0
        answer = SimpleNamespace(success=lv["success"], reason=lv.get("reason", ""),
                                 squeeze_depth=lv.get("squeeze_depth") or 0.0, step=step,
                                 resolution=lv.get("resolution") or step / (lv.get("step_divisions") or 1),
                                 force_exponent=lv.get("force_exponent", HERTZ_EXPONENT))
        est = estimated_error(ch, answer, three_level_errors(levels[:i + 1]))
        if max(est.values()) <= target:
            return {"level": lv, "seconds": seconds,
                    "estimated_error": {k: est[k] for k in ("squeeze_depth", "finger_force")}}
    return None


def analyse(records: dict[str, dict], objects: tuple[str, ...], cfg: dict[str, Any]) -> dict[str, Any]:
    """Tables, estimates, errors against the reference, resolutions per target, scatter, flips."""
    from fem_grasp.grasp.estimates import estimate

    out: dict[str, Any] = {"objects": {}, "codes": sorted({r.get("code", "?") for r in records.values()})}
    for name in objects:
        # the diagnoses (slow lift tests rerunning a level) are not levels of their own
        recs = [r for r in records.values() if r["spec"]["object"] == name and not r["spec"].get("diagnose")]
        series: dict[str, list[dict]] = {}
        for r in recs:
            series.setdefault(r["spec"]["series"], []).append(_row(r))
        for rows in series.values():
            rows.sort(key=lambda x: _level(x["spec"]))
        obj: dict[str, Any] = {"series": series}
        # --- the reference: the finest uniform level with the increment and h halved (Richardson in the step)
        ref_rows = [r for r in series.get("uniform", []) if "rho" in r]
        reference = None
        if ref_rows:
            refined = [r for r in series.get("reference", []) if "rho" in r]
            # the increments are refined on one uniform mesh (the finest that ran fast enough): the chain starts
            # there, and finer uniform levels, if any, count in the mesh band
            on = [r for r in ref_rows if refined and all(r["spec"].get(k) == refined[0]["spec"].get(k)
                                                         for k in ("target", "factor"))]
            fine = on[0] if on else max(ref_rows, key=lambda r: r["vertices"])
            chain = [fine] + refined
            chain.sort(key=lambda r: -r["step"])
            ok = [r for r in chain if r["success"]]
            # the verdict of the finest increments decides; w(ρ) is the finest run's
            finest = chain[-1]
            reference = {"vertices": fine["vertices"], "success": bool(finest["success"]),
                         "max_liftable": finest["max_liftable"], "weight": finest["weight"],
                         "liftable": finest["liftable"], "step": finest["step"], "h": finest["lift_test_step"]}
            if ok and finest["success"]:
                reference["levels"] = [
                    {"step": r["step"], "h": r["lift_test_step"], "rho": r["rho"], "force": r["force"],
                     "bracket": r.get("bracket"), "seconds": r["seconds"]} for r in ok]
                for q in ("rho", "force"):
                    reference[q] = estimate([r[q] for r in ok], [r["step"] for r in ok])
                br = ok[-1].get("bracket")
                if br:
                    # ρ* of each run lies in its bracket (the last failing test, the pass): the finest run's
                    # bracket bounds the quantisation error, whatever the estimate's method.
                    reference["rho_bracket"] = br
                    if reference["rho"]["method"] != "richardson":
                        # the pass is within one increment of the last failing test: midpoint ± half of it
                        reference["rho"] = {"value": 0.5 * (br[0] + br[1]), "error": (br[1] - br[0]) / (br[0] + br[1]),
                                            "method": "bracket", "order": None}
                reference["slope"] = liftable_slope(reference["liftable"], reference["rho"]["value"])
                reference["mesh_band"] = mesh_band(series, fine, reference)
        obj["reference"] = reference
        picked = bool(reference and reference["success"])
        rho_ref = reference["rho"]["value"] if picked else None
        f_ref = reference["force"]["value"] if picked else None
        for rows in series.values():
            for r in rows:
                if "rho" in r:
                    r["verdict_ok"] = reference is None or bool(r["success"]) == reference["success"]
                    wrong = not r["success"] or not r["verdict_ok"]
                    r["rho_error"] = math.inf if wrong else _err(r["rho"], rho_ref)
                    r["force_error"] = math.inf if wrong else _err(r["force"], f_ref)
                    r["w_error"] = (liftable_gap(r["liftable"], reference["liftable"], r["weight"])
                                    if reference is not None else math.nan)
        # --- estimates per series (Richardson or band), by spacing
        est = {}
        for s in ("uniform", "graded", "graded_table"):
            rows = [r for r in series.get(s, []) if r.get("success")]
            if len(rows) >= 2:
                h = [r["patch_spacing"] for r in rows]
                est[s] = {q: estimate([r[q] for r in rows], h) for q in ("rho", "force")}
        obj["estimates"] = est
        # --- cheapest resolution per target: the first level of a series from which every finer one is within it
        res = {}
        for s in ("uniform", "graded", "graded_table"):
            rows = [r for r in series.get(s, []) if "rho" in r or r["timeout"]]
            res[s] = {}
            for tgt in (0.10, 0.05, 0.02):
                hit = None
                for i, r in enumerate(rows):
                    tail = rows[i:]
                    if all("rho" in t and within(t, tgt, picked) for t in tail):
                        hit = r
                        break
                res[s][f"{tgt:g}"] = None if hit is None else {
                    "vertices": hit["vertices"], "patch_spacing": hit["patch_spacing"], "seconds": hit["seconds"],
                    "rho_error": hit["rho_error"], "force_error": hit["force_error"], "w_error": hit["w_error"],
                    "spec": hit["spec"]}
        obj["resolution"] = res
        # --- the adaptive loop's answer at each target (one run at the finest target, read off level by level)
        for r in series.get("adaptive", []):
            acc = r.get("accuracy")
            if not acc:
                continue
            r["targets"] = {}
            for tgt in (0.10, 0.05, 0.02):
                at = adaptive_at(acc, tgt)
                if at is None:
                    r["targets"][f"{tgt:g}"] = None
                    continue
                lv = at["level"]
                ok = reference is None or bool(lv["success"]) == reference["success"]
                r["targets"][f"{tgt:g}"] = {
                    "level": lv["level"], "vertices": lv["vertices"], "seconds": at["seconds"],
                    "success": lv["success"], "rho": lv["squeeze_depth"], "force": lv["finger_force"],
                    "estimated_error": at["estimated_error"], "verdict_ok": ok,
                    "rho_error": math.inf if not (ok and lv["success"]) else _err(lv["squeeze_depth"], rho_ref),
                    "force_error": math.inf if not (ok and lv["success"]) else _err(lv["finger_force"], f_ref),
                    # a reference that is not picked up: the largest weight held, against the reference's
                    "w_error": (abs(lv["max_liftable"] - reference["max_liftable"]) / reference["weight"]
                                if ok and reference is not None and not picked else math.nan)}
        # --- scatter of the seeds (seed 1 is the uniform level of the same size)
        sc = {}
        for r in series.get("seed", []):
            key = str(r["spec"].get("target", r["spec"].get("factor")))
            sc.setdefault(key, []).append(r)
        for r in series.get("uniform", []):
            key = str(r["spec"].get("target", r["spec"].get("factor")))
            if key in sc:
                sc[key].insert(0, r)
        scatter = {}
        for key, rows in sc.items():
            ok = [r for r in rows if r.get("success")]
            vals = {q: [r[q] for r in ok] for q in ("rho", "force")}
            scatter[key] = {"runs": len(rows), "picked_up": len(ok),
                            "vertices": [r["vertices"] for r in rows],
                            **{f"{q}_{stat}": (float(fn(v)) if v else None) for q, v in vals.items()
                               for stat, fn in (("mean", np.mean), ("std", np.std), ("min", np.min),
                                                ("max", np.max))}}
            for q in ("rho", "force"):
                m, s_ = scatter[key][f"{q}_mean"], scatter[key][f"{q}_std"]
                scatter[key][f"{q}_rel_std"] = None if not m else s_ / m
        obj["scatter"] = scatter
        obj["flips"] = flips(series)
        out["objects"][name] = obj
    return out


def flips(series: dict[str, list[dict]], jump: float = 0.05) -> list[dict[str, Any]]:
    """Verdict failures, and steps of ρ* between levels that reverse the trend by more than ``jump``."""
    found = []
    for s in ("uniform", "graded", "graded_table", "seed"):
        rows = [r for r in series.get(s, []) if "rho" in r]
        for i, r in enumerate(rows):
            if not r["success"]:
                found.append({"series": s, "kind": "verdict", "row": r})
                continue
            if s == "seed" or i == 0 or i + 1 >= len(rows):
                continue
            a, b = rows[i - 1], rows[i + 1]
            if not (a.get("success") and b.get("success")):
                continue
            d1, d2 = r["rho"] - a["rho"], b["rho"] - r["rho"]
            if d1 * d2 < 0 and min(abs(d1), abs(d2)) > jump * r["rho"]:
                found.append({"series": s, "kind": "jump", "row": r, "before": a["rho"], "after": b["rho"]})
    return found


def diagnosis_cases(analysis: dict[str, Any], cfg: dict[str, Any]) -> list[dict[str, Any]]:
    """Cases re-run with the slow lift test: every flip cheap enough (``diagnose_max_seconds``)."""
    out = []
    for name, obj in analysis["objects"].items():
        for f in obj["flips"]:
            r = f["row"]
            if r.get("pickup_seconds") and r["pickup_seconds"] <= cfg["diagnose_max_seconds"] and "diagnosis" not in r:
                out.append(dict(r["spec"], diagnose=True))
    return out


def attach_diagnoses(analysis: dict[str, Any], records: dict[str, dict]) -> None:
    for name, obj in analysis["objects"].items():
        for f in obj["flips"]:
            spec = dict(f["row"]["spec"], diagnose=True)
            rec = records.get(case_key(spec))
            if rec and rec.get("diagnosis"):
                d = rec["diagnosis"]
                f["diagnosis"] = {k: v for k, v in d.items() if k != "rows"}
                f["diagnosis"]["rows"] = [{k: v for k, v in r.items() if k != "finger_nodes"} for r in d["rows"]]
                f["diagnosis"]["verdict"] = explain(f, d)


def _cause(reason: str) -> str:
    """The cause in a lift test's failure message: the part after its last "not found: " (the failed search's
    own words are the cause, the lines before it only say which search failed)."""
    head, sep, cause = reason.rpartition("not found: ")
    return cause if sep else reason


def explain(flip: dict[str, Any], d: dict[str, Any]) -> str:
    """One sentence: is the flip the lift test's step h (the peak of w(ρ) within h of mg), a physical outcome of
    that mesh (even a slower loading holds less than mg), or a jump of the discretised w(ρ) itself?"""
    w = d["weight"]
    r = flip["row"]
    peak = d.get("slow_peak") or 0.0
    if flip["kind"] == "verdict":
        if d.get("slow_pass") is not None:
            # The library loads in steps of h, the slow test in steps of h/8: both are the same quasi-static path,
            # so a pass of the slow one only says the peak of w(ρ) lies within one step h of mg.
            test_peak = max((row["test_w"] for row in d.get("rows", [])), default=0.0)
            return (f"within the lift test's step h: loaded in steps of h/8 the fingers hold mg = {w:.3g} N at "
                    f"ρ = {1e3 * d['slow_pass']:.2f} mm, in steps of h at most {test_peak / w:.2f} mg; the peak of "
                    "w(ρ) on this mesh is within one step of the weight (the h series measures the effect)")
        patch = d.get("peak_patch") or {}
        fg = patch.get("fingers") or []
        where = ""
        if fg:
            where = "; held by " + " and ".join(
                f"finger {i + 1}: {f['contacts']} contacts ({f['above_centre']} above its centre, {f['sliding']} "
                f"sliding) carrying {f['vertical']:.3g} N" for i, f in enumerate(fg))
        if "failing_node" in patch:
            where += (f"; the next weight loses node {patch['failing_node']} of finger {patch['failing_finger']}"
                      f" ({'above' if patch['failing_above_centre'] else 'below'} the fingertip's centre)")
        return (f"physical outcome of this mesh: even loaded in steps of h/8 the fingers hold at most {peak:.3g} N "
                f"= {peak / w:.2f} mg (at ρ = {1e3 * (d.get('slow_peak_rho') or 0):.2f} mm{where}; "
                f"{_cause(d.get('peak_reason') or '')})")
    tp, sp = d.get("test_pass"), d.get("slow_pass")
    if tp is not None and sp is not None and abs(tp - sp) <= 1.01 * (r.get("step") or 0):
        return (f"the slow lift test passes at {1e3 * sp:.2f} mm too (the library's at {1e3 * tp:.2f} mm): the jump is "
                "in the discretised w(ρ) itself, not in the test")
    if sp is not None:
        return (f"the slow lift test passes at {1e3 * sp:.2f} mm against the library's {1e3 * (tp or math.nan):.2f} mm: "
                "the loading path of the test moves ρ*")
    return f"the slow lift test never holds mg (peak {peak:.3g} N)"

