"""The study's plots (error against run time, w(ρ) overlaid), tables (stdout, the README's markdown), and its
section and headline check in the full verification report."""

from __future__ import annotations

import html
import math
from pathlib import Path
from typing import Any

import numpy as np

from .._common.html import Markup, fmt, img, table


def plots(analysis: dict[str, Any], out: Path) -> dict[str, str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    images = {}
    names = list(analysis["objects"])
    styles = {"uniform": ("o-", "#1f77b4", "uniform"), "graded": ("s-", "#d62728", "graded at the fingertips"),
              "graded_table": ("^-", "#2ca02c", "graded at the fingertips and the table"),
              "adaptive": ("*", "#9467bd", "adaptive (accuracy = 10/5/2 %)"),
              "seed": ("x", "#7f7f7f", "seeds (same spacing)"), "reference": ("D", "k", "reference (step/2, /4)")}
    fig, axes = plt.subplots(len(names), 2, figsize=(11, 3.2 * len(names)), squeeze=False)
    for i, name in enumerate(names):
        obj = analysis["objects"][name]
        for j, (q, label) in enumerate((("rho", "ρ*"), ("force", "finger force Σ f·n̂"))):
            ax = axes[i][j]
            for r in obj["series"].get("adaptive", []):
                pts = [v for v in (r.get("targets") or {}).values() if v]
                if pts:
                    e = [min(max(v[f"{q}_error"], 1e-4), 2.0) if math.isfinite(v[f"{q}_error"]) else 2.0 for v in pts]
                    ax.loglog([v["seconds"] for v in pts], e, "*", color="#9467bd", ms=10,
                              label="adaptive: pickup(accuracy = 10, 5, 2 %)")
                    for v, ei in zip(pts, e):
                        ax.annotate(f"level {v['level']}", (v["seconds"], ei), fontsize=6, color="#9467bd")
            for s, (mk, col, lab) in styles.items():
                if s == "adaptive":
                    continue
                rows = [r for r in obj["series"].get(s, []) if "rho" in r]
                if not rows:
                    continue
                t = [r["seconds"] for r in rows]
                e = [min(max(r[f"{q}_error"], 1e-4), 2.0) if math.isfinite(r[f"{q}_error"]) else 2.0 for r in rows]
                ax.loglog(t, e, mk, color=col, label=lab, ms=5, fillstyle="none" if s == "seed" else "full")
                for r, ti, ei in zip(rows, t, e):
                    if not r["success"]:
                        ax.annotate("fails", (ti, ei), fontsize=6, color=col)
            for tgt in (0.1, 0.05, 0.02):
                ax.axhline(tgt, color="k", lw=0.5, ls=":")
            ax.set_title(f"{name}: {label}", fontsize=9)
            ax.set_xlabel("run time: meshing + pickup (s)", fontsize=8)
            ax.set_ylabel("relative error vs reference", fontsize=8)
            ax.grid(True, which="both", alpha=0.3)
            if i == 0 and j == 0 and ax.get_legend_handles_labels()[0]:  # none without cached series
                ax.legend(fontsize=6)
    fig.tight_layout()
    p = out / "converge_error_time.png"
    fig.savefig(p, dpi=100)
    plt.close(fig)
    images["converge_error_time"] = p.name

    fig, axes = plt.subplots(1, len(names), figsize=(3.6 * len(names), 3.4), squeeze=False)
    for i, name in enumerate(names):
        ax = axes[0][i]
        obj = analysis["objects"][name]
        rows = [r for r in obj["series"].get("uniform", []) if "liftable" in r]
        cmap = plt.get_cmap("viridis")
        for k, r in enumerate(rows):
            lv = np.array(r["liftable"]) if r["liftable"] else np.zeros((0, 2))
            if len(lv):
                ax.plot(1e3 * lv[:, 0], lv[:, 1], "-", color=cmap(k / max(len(rows) - 1, 1)), lw=1,
                        label=f"{r['vertices']:,} v" + ("" if r["success"] else " (fails)"))
        ref = [r for r in obj["series"].get("reference", []) if "liftable" in r and r["liftable"]]
        if ref:
            lv = np.array(ref[-1]["liftable"])
            ax.plot(1e3 * lv[:, 0], lv[:, 1], "k--", lw=1, label="reference (finest, step/4)")
        if rows:
            ax.axhline(rows[0]["weight"], color="r", lw=0.8, ls=":", label="weight mg")
        ax.set_title(f"{name}: w(ρ), uniform levels", fontsize=9)
        ax.set_xlabel("squeeze depth ρ (mm)", fontsize=8)
        ax.set_ylabel("liftable weight w (N)", fontsize=8)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=5)
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    p = out / "converge_liftable.png"
    fig.savefig(p, dpi=100)
    plt.close(fig)
    images["converge_liftable"] = p.name
    return images


def print_tables(analysis: dict[str, Any]) -> None:
    for name, obj in analysis["objects"].items():
        print(f"\n== {name}")
        ref = obj.get("reference")
        if ref:
            print(f"reference: {reference_line(ref)}")
        for s, rows in obj["series"].items():
            print(f"  {s}:")
            for r in rows:
                if "rho" in r:
                    fg = r["fingers"]
                    print(f"    {str(r['spec'].get('target', r['spec'].get('factor', r['spec'].get('inner', r['spec'].get('divisor', r['spec'].get('seed')))))):>8} "
                          f"{r['vertices'] or 0:>7,} v  {'ok ' if r['success'] else 'NO '} rho {1e3 * r['rho']:7.3f} mm "
                          f"({100 * r['rho_error']:5.1f} %)  F {r['force']:7.3f} N ({100 * r['force_error']:5.1f} %)  "
                          f"|F1| {fg[0]['resultant']:.3f} {fg[0]['along_squeeze']:.3f} {fg[0]['vertical']:.3f}  "
                          f"w_max {r['max_liftable'] / r['weight']:.2f} mg (w error {100 * r.get('w_error', math.nan):4.1f} %)  "
                          f"nodes {fg[0]['nodes']}/{fg[1]['nodes']}/{r['table_nodes']}  {r['seconds']:.1f} s")
                else:
                    print(f"    {r['spec']}: {'timeout' if r['timeout'] else 'error ' + r['error'][-200:]}")
        for f in obj["flips"]:
            d = f.get("diagnosis", {})
            print(f"  flip ({f['series']}, {f['kind']}) at {f['row']['vertices']} vertices: {d.get('verdict', '(not diagnosed)')}")


def reference_line(ref: dict[str, Any]) -> str:
    """The reference in words: its mesh, its increments, and ρ* and Σ f·n̂ with their bands, or, where the finest
    level does not pick the object up, the largest weight it holds."""
    def band(est: dict[str, Any]) -> str:
        e = est.get("error")  # inf is null in converge.json
        return (f"{100 * e:.1f} % ({est['method']})" if e is not None and math.isfinite(e) else
                f"unknown ({est['method']}: one run)")

    head = (f"{ref['vertices']:,} vertices, squeeze increment {1e3 * ref['step']:.3g} mm, lift-test step "
            f"{ref['h'] / ref['weight']:.3g} mg")
    if not ref["success"]:
        return (f"{head}: NOT picked up; the fingers hold at most {ref['max_liftable'] / ref['weight']:.2f} mg "
                f"(w(ρ) peaks below the weight)")
    slope = ref.get("slope")
    cond = (f"; dw/dρ = {slope * 1e-3 / ref['weight']:.3g} mg/mm at ρ*, so an error of h in w moves ρ* by "
            f"{1e3 * ref['h'] / slope:.2g} mm" if slope and slope > 0 else "")
    mb = ref.get("mesh_band") or {}
    meshes = ""
    if mb.get("levels"):
        which = ", ".join(f"{x['series']} {x['vertices']:,} v" for x in mb["levels"])
        meshes = (f"; the finest levels of the other series ({which}) differ from it by up to {_pct(mb['rho'])} "
                  f"in ρ* and {_pct(mb['force'])} in the force")
    return (f"{head}: ρ* = {1e3 * ref['rho']['value']:.2f} mm ± {band(ref['rho'])}, finger force "
            f"{ref['force']['value']:.3f} N ± {band(ref['force'])}{cond}{meshes}")


def markdown(analysis: dict[str, Any]) -> str:
    """The README's tables (``--markdown``): per object the reference, the uniform and graded levels, the cheapest
    resolution for 10 / 5 / 2 %, and the adaptive loop."""
    def pct(x: Any) -> str:
        if x is None or (isinstance(x, float) and math.isnan(x)):
            return "–"
        return "wrong verdict" if math.isinf(x) else f"{100 * x:.1f} %"

    def mm(x: Any) -> str:
        return "–" if x is None else f"{1e3 * x:.2f}"

    lines = []
    for name, obj in analysis["objects"].items():
        ref = obj.get("reference")
        lines.append(f"\n**{name}** — " + (f"reference: {reference_line(ref)}" if ref else "no reference"))
        lines.append("")
        lines.append("| series | level | vertices | spacing at patch (mm) | verdict | ρ* (mm) | error | Σ f·n̂ (N) | error | "
                     "max w / mg | w(ρ) error / mg | patches f1/f2/table | time (s) |")
        lines.append("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
        for s_ in ("shipped", "quick", "uniform", "graded", "graded_table", "step", "h"):
            for r in obj["series"].get(s_, []):
                sp = r["spec"]
                lvl = next((f"{k} {sp[k]:g}" if k != "inner" else f"R/{1 / sp[k]:g}") for k in
                           ("target", "factor", "inner", "divisor") if k in sp) if s_ not in ("quick", "shipped") \
                    else {"quick": "[quick]", "shipped": "the scene"}[s_]
                if "rho" not in r:
                    lines.append(f"| {s_} | {lvl} | {r.get('vertices') or '–'} | – | "
                                 f"{'timeout' if r['timeout'] else 'error'} | | | | | | | | {r['seconds']:.0f} |")
                    continue
                fg = r["fingers"]
                lines.append(f"| {s_} | {lvl} | {r['vertices']:,} | {mm(r.get('patch_spacing'))} | "
                             f"{'picked up' if r['success'] else 'NOT'} | {mm(r['rho'])} | {pct(r.get('rho_error'))} | "
                             f"{r['force']:.3f} | {pct(r.get('force_error'))} | {r['max_liftable'] / r['weight']:.2f} | "
                             f"{pct(r.get('w_error'))} | {fg[0]['nodes']}/{fg[1]['nodes']}/"
                             f"{r['table_nodes']} | {r['seconds']:.0f} |")
        for key, sc in obj.get("scatter", {}).items():
            if sc["rho_mean"] is not None:
                lines.append(f"\nSeeds at {key}: {sc['picked_up']}/{sc['runs']} picked up, ρ* {mm(sc['rho_mean'])} ± "
                             f"{mm(sc['rho_std'])} mm (range {mm(sc['rho_min'])}–{mm(sc['rho_max'])}), finger force "
                             f"{sc['force_mean']:.3f} ± {sc['force_std']:.3f} N.")
            else:
                lines.append(f"\nSeeds at {key}: {sc['picked_up']}/{sc['runs']} picked up.")
        if obj["flips"]:
            lines.append("\nVerdict flips and jumps against the trend, each with its diagnosis (a slow lift test in steps "
                         "of h/8 at every increment):\n")
            for f in obj["flips"]:
                d = f.get("diagnosis", {})
                lines.append(f"* {f['series']}, {f['kind']} at {f['row']['vertices']:,} vertices: "
                             f"{d.get('verdict', 'not diagnosed (beyond the diagnosis time limit)')}")
    lines.append("\nTime to a 10 % / 5 % / 2 % answer (the reference's verdict, and both ρ* and Σ f·n̂ within the target "
                 "of the reference's; where the reference is not picked up, the largest weight held within the target × "
                 "mg), from the first level of a series after which every finer one stays within it:\n")
    lines.append("| object | target | uniform | graded | graded + table | adaptive (levels, its estimate) |")
    lines.append("|---|---|---|---|---|---|")
    for name, obj in analysis["objects"].items():
        ad = next((r for r in obj["series"].get("adaptive", []) if r.get("targets")), None)
        for t in ("0.1", "0.05", "0.02"):
            cells = []
            for s_ in ("uniform", "graded", "graded_table"):
                v = obj["resolution"].get(s_, {}).get(t)
                cells.append("not reached" if v is None else f"{v['seconds']:.0f} s ({v['vertices']:,} v)")
            a = None if ad is None else ad["targets"].get(t)
            if a is None:
                cells.append("not reached" if ad is not None else "–")
            else:
                est = max(a["estimated_error"].values())
                picked = bool(obj.get("reference") and obj["reference"]["success"])
                err = max(a["rho_error"], a["force_error"]) if picked or not a.get("verdict_ok", True) else a["w_error"]
                cells.append(f"{a['seconds']:.0f} s ({a['level'] + 1} levels; error {pct(err)}, estimate {pct(est)})")
            lines.append(f"| {name} | {100 * float(t):g} % | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def scene_errors(analysis: dict[str, Any]) -> list[dict[str, Any]]:
    """Per object, the shipped scene's run and its ``[quick]`` variant's against the reference: verdict, ρ*, Σ f·n̂,
    their errors and the error a scene should state (``[solver] expected_error``: the larger of the two, or of the
    reference's mesh band if larger, rounded up to 5 %; inf where the verdict differs from the reference's)."""
    rows = []
    for name, obj in analysis["objects"].items():
        for series in ("shipped", "quick"):
            for r in obj["series"].get(series, []):
                if "rho" not in r:
                    continue
                err = max(r.get("rho_error", math.nan), r.get("force_error", math.nan))
                # against the reference, which itself is known only as well as the fine meshes agree
                band = (obj.get("reference") or {}).get("mesh_band") or {}
                err = max([err] + [band[q] for q in ("rho", "force") if band.get(q) is not None
                                   and math.isfinite(band[q])])
                if not r.get("verdict_ok", True):
                    err = math.inf
                stated = err if not math.isfinite(err) else math.ceil(20 * err - 1e-9) / 20
                rows.append({"object": name, "series": series, "vertices": r["vertices"], "success": r["success"],
                             "rho": r["rho"], "force": r["force"], "rho_error": r.get("rho_error"),
                             "force_error": r.get("force_error"), "expected_error": stated})
    return rows


def print_scene_errors(analysis: dict[str, Any]) -> None:
    print("\n== the shipped scenes against the reference (what [solver] expected_error states)")
    for r in scene_errors(analysis):
        e = r["expected_error"]
        print(f"  {r['object']:<11} {'' if r['series'] == 'shipped' else '[quick]':<8} {r['vertices']:>6,} v  "
              f"{'picked up' if r['success'] else 'NOT      '}  rho {1e3 * r['rho']:7.3f} mm  force {r['force']:.3f} N  "
              f"errors {_pct(r['rho_error'])} / {_pct(r['force_error'])}  ->  expected_error = "
              f"{'inf' if not math.isfinite(e) else f'{e:g}'}")


def _pct(x: Any) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "–"
    return "wrong verdict" if math.isinf(x) else f"{100 * x:.1f} %"


# ----------------------------------------------------------------- the pickup answer under refinement
SERIES_NOTES = {
    "uniform": "uniform meshes, ×2 vertices per level (shapes.paper_mesh; the box: grid × k)",
    "graded": "spacing R/2 … R/16 within 1.25 R of the finger contact points, paper-resolution spacing elsewhere",
    "graded_table": "the same spacing at the fingertips and around the resting table patch",
    "step": "the squeeze increment halved (one mesh)",
    "h": "the lift-test step h halved (one mesh)",
    "seed": "meshes of the same spacing (gmsh seeds; the box: jittered grid)",
    "reference": "the finest uniform level with the increment and h halved twice",
    "adaptive": "pickup(..., accuracy=target): the adaptive loop",
    "quick": "the scene's [quick] variant (fem-grasp run NAME --quick), one run",
    "shipped": "the scene as shipped (fem-grasp run NAME), one run on its committed mesh: its error is what the scene "
               "states as [solver] expected_error",
}


def _level_label(sp: dict) -> str:
    for k, fmt_ in (("target", "{:,} v target"), ("factor", "grid ×{}"), ("inner", "R/{:g}"), ("divisor", "÷{}"),
                    ("seed", "seed {}")):
        if k in sp:
            v = sp[k]
            if k == "inner":
                v = round(1 / v, 3)
            label = fmt_.format(v)
            if k == "divisor" and "target" in sp:
                label += f" at {sp['target']:,} v"
            if k == "seed":
                label += f" ({sp.get('target', sp.get('factor'))})"
            if k == "target" and sp.get("series") == "adaptive":
                label = f"accuracy {100 * v:g} %"
            return label
    return ""


def _pct_html(x: Any) -> Any:
    if x is None or (isinstance(x, float) and (math.isnan(x))):
        return None
    if isinstance(x, float) and math.isinf(x):
        return "verdict wrong"
    return f"{100 * x:.3g} %"


def section(part: dict[str, Any], images: dict[str, str]) -> str:
    """The report's section: the pickup answer (verdict, ρ*, forces, patches, w(ρ)) under refinement, per object."""
    gc = part.get("grasp_convergence")
    if not gc:
        return ""
    out = ["<h2>Convergence of the pickup answer</h2>",
           "<p class='note'>The answer of Algorithm 1 on each shipped scene (tomato, orange, steam bun, football, foam "
           "block) under the refinements below (<code>make converge</code>, <code>python -m verification converge"
           "</code>; cached runs in <code>verification/out/converge/cache</code>). ρ* is the squeeze depth at which the "
           "lift starts; the finger force is Σ f·n̂ over both patches at lift-off; per finger: the resultant's norm, its "
           "component along the finger's squeeze direction and its vertical component (N); patches: contact nodes of "
           "finger 1 / finger 2 / table. Errors are against each object's reference (finest uniform mesh, increments "
           "halved twice; its own uncertainty is stated). Times: meshing + pickup (assembly, rest, squeeze, lift), "
           "one process, on a machine shared with other jobs (timings vary by up to 2×).</p>"]
    out.append(img(images.get("converge_error_time"), "error against run time, log–log: ρ* (left), finger force "
                                                       "(right); dotted lines 10 %, 5 %, 2 %"))
    out.append(img(images.get("converge_liftable"), "liftable weight w(ρ) of the uniform levels"))
    for name, obj in gc.get("objects", {}).items():
        out.append(f"<h3>{html.escape(name)}</h3>")
        ref = obj.get("reference")
        if ref:
            out.append(f"<p>Reference: {html.escape(reference_line(ref))}.</p>")
        res = obj.get("resolution", {})
        if res:
            rows = []
            for s_, per in res.items():
                rows.append([s_] + [None if per.get(t) is None else
                                    Markup(f"{per[t]['vertices']:,} v, {fmt(1e3 * per[t]['patch_spacing'])} mm, "
                                           f"{fmt(per[t]['seconds'])} s") for t in ("0.1", "0.05", "0.02")])
            out.append("<p class='note'>Cheapest level from which every finer level of the series is within the "
                       "target (the reference's verdict, and both ρ* and the finger force; where the reference is not "
                       "picked up, the largest weight held; vertices, spacing at the patches, time); – : not "
                       "reached:</p>")
            out.append(table(["series", "10 %", "5 %", "2 %"], rows))
        for s_, rows in obj.get("series", {}).items():
            body = []
            for r in rows:
                if "rho" not in r:
                    body.append([_level_label(r["spec"]), r.get("vertices"), "timeout" if r["timeout"] else "error",
                                 None, None, None, None, None, None, None, None, None, r.get("seconds")])
                    continue
                fg = r["fingers"]
                body.append([_level_label(r["spec"]), r["vertices"], "picked up" if r["success"] else "NOT",
                             1e3 * r["rho"], _pct_html(r.get("rho_error")), r["force"], _pct_html(r.get("force_error")),
                             r["max_liftable"] / r["weight"], _pct_html(r.get("w_error")),
                             Markup(" / ".join(f"{f['resultant']:.3g}, {f['along_squeeze']:.3g}, {f['vertical']:.3g}"
                                               for f in fg)),
                             Markup(f"{fg[0]['nodes']} / {fg[1]['nodes']} / {r['table_nodes']}"),
                             None if r.get("patch_spacing") is None else 1e3 * r["patch_spacing"], r.get("seconds")])
            out.append(f"<p class='note'><b>{html.escape(s_)}</b>: {html.escape(SERIES_NOTES.get(s_, ''))}</p>")
            out.append(table(["level", "vertices", "verdict", "ρ* (mm)", "error", "finger force (N)", "error",
                              "max w / mg", "w(ρ) error / mg", "per finger |F|, F·d̂, F_z (N)", "patches",
                              "spacing at patch (mm)", "s"], body))
        for key, sc in obj.get("scatter", {}).items():
            out.append(f"<p class='note'>Seeds at {html.escape(key)}: {sc['picked_up']} of {sc['runs']} picked up; ρ* "
                       f"{fmt(1e3 * (sc['rho_mean'] or math.nan))} mm ± {fmt(1e3 * (sc['rho_std'] or math.nan))} "
                       f"(range {fmt(1e3 * (sc['rho_min'] or math.nan))}–{fmt(1e3 * (sc['rho_max'] or math.nan))}), "
                       f"finger force {fmt(sc['force_mean'])} ± {fmt(sc['force_std'])} N.</p>")
        if obj.get("flips"):
            out.append("<p class='note'>Verdict flips and non-monotone jumps, with the slow lift test's verdict "
                       "(weights raised in steps of h/8 from zero at every increment):</p>")
            out.append(table(["series", "kind", "vertices", "ρ* (mm)", "diagnosis"],
                             [[f["series"], f["kind"], f["row"]["vertices"], 1e3 * f["row"]["rho"],
                               (f.get("diagnosis") or {}).get("verdict", "not diagnosed (too slow to re-run)")]
                              for f in obj["flips"]]))
    return "\n".join(out)


def checks(part: dict[str, Any]) -> list[dict[str, Any]]:
    """The adaptive loop's estimated error against its actual error (against the study's reference), wherever a
    target was reached; the reference's own uncertainty is added to the estimate."""
    from .._common.run import check

    gc = part.get("grasp_convergence")
    if not gc:
        return []
    worst, n = 0.0, 0
    for obj in gc.get("objects", {}).values():
        ref = obj.get("reference") or {}
        band = {q: (ref.get(q) or {}).get("error", np.inf) for q in ("rho", "force")}
        for r in obj.get("series", {}).get("adaptive", []):
            for v in (r.get("targets") or {}).values():
                if not v or not ref:
                    continue
                for q, key in (("rho", "squeeze_depth"), ("force", "finger_force")):
                    allowed = v["estimated_error"][key] + (band[q] if np.isfinite(band[q]) else 0.0)
                    worst = max(worst, v[f"{q}_error"] / allowed if allowed > 0 else np.inf)
                    n += 1
    if not n:
        return []
    return [check(f"grasp convergence: adaptive error / (its estimate + the reference's band), {n} answers", worst,
                  "≤ 1", worst <= 1.0)]
