"""The Hertz study's figure, headline checks and report section."""

from __future__ import annotations

import html
from pathlib import Path
from typing import Any

import numpy as np

from .._common.html import fmt, img, table
from .._common.run import check


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: str | Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    _plt().close(fig)
    return Path(path)


def hertz_plot(study: dict, path: str | Path) -> Path:
    """Force against indentation for each mesh level with Hertz's curve; ratio against (δ/R)^½."""
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    d_rel = np.array(study["deltas_rel"])
    fine = np.geomspace(d_rel.min() * 0.8, d_rel.max() * 1.2, 50)
    r, e, nu = study["radius"], study["young"], study["poisson"]
    f_h = 4.0 / 3.0 * e / (1 - nu**2) * np.sqrt(r) * (fine * r) ** 1.5
    axes[0].loglog(fine, f_h, "k-", label="Hertz  F = 4/3 E* R^½ δ^3/2")
    for lev in study["levels"]:
        f = [row["force"] for row in lev["rows"]]
        lbl = f"h = {lev['pole_size_rel']:g} R ({lev['n_vertices']} vertices), slope {lev['exponent']:.3f}"
        axes[0].loglog(d_rel, f, "o--", label=lbl, fillstyle="none")
        q = [row["ratio"] for row in lev["rows"]]
        s = np.sqrt(d_rel)
        axes[1].plot(s, q, "o", fillstyle="none", label=f"h = {lev['pole_size_rel']:g} R")
        xs = np.linspace(0, s.max() * 1.05, 20)
        axes[1].plot(xs, lev["extrapolated_ratio"] + lev["sqrt_slope"] * xs, ":", color=axes[1].lines[-1].get_color())
    axes[0].set_xlabel("indentation δ / R")
    axes[0].set_ylabel("force F (N)")
    axes[0].set_title("Sphere between rigid planes (frictionless)")
    axes[0].legend(fontsize=7)
    axes[0].grid(True, which="both", alpha=0.3)
    axes[1].axhline(1.0, color="k", lw=0.8)
    axes[1].set_xlabel("(δ / R)^½")
    axes[1].set_ylabel("F / F_Hertz")
    axes[1].set_title("Ratio to Hertz; dotted: linear fit, intercept = δ→0 limit")
    axes[1].legend(fontsize=7)
    axes[1].grid(True, alpha=0.3)
    axes[1].set_xlim(left=0)
    return _save(fig, path)


def checks(part: dict[str, Any]) -> list[dict[str, Any]]:
    """Hertz's exponent 3/2 and force at δ → 0 on the finest mesh, the ratio within the finite-size effect."""
    out: list[dict[str, Any]] = []
    hz = part.get("hertz")
    if hz:
        fine = hz["levels"][-1]
        out.append(check("Hertz: fitted exponent of F(δ), finest mesh", fine["exponent"], "1.5 ± 0.05",
                         abs(fine["exponent"] - 1.5) <= 0.05))
        out.append(check("Hertz: F/F_Hertz extrapolated to δ → 0, finest mesh", fine["extrapolated_ratio"], "1 ± 0.05",
                         abs(fine["extrapolated_ratio"] - 1) <= 0.05))
        worst_ratio = max(abs(r["ratio"] - 1) for r in fine["rows"])
        out.append(check("Hertz: max |F/F_Hertz − 1| over δ/R ≤ 0.02, finest mesh", worst_ratio,
                         "≤ 0.15 (finite-size effect)", worst_ratio <= 0.15))
    return out


def section(s: dict[str, Any], images: dict[str, str]) -> str:
    """The report's section: force against indentation at each mesh level, against Hertz."""
    parts: list[str] = []
    hz = s.get("hertz")
    if hz:
        parts.append("<h2>Hertz contact</h2>")
        parts.append(f"<p class='note'>Model: {html.escape(hz['model'])}. R = {fmt(hz['radius'])} m, "
                     f"E = {fmt(hz['young'])} Pa, ν = {fmt(hz['poisson'])}; the mesh is refined to h at the pole. "
                     "Contact is frictionless (normal displacement prescribed on touching nodes, tangential motion "
                     "free; tensile nodes released, penetrating nodes added, iterated to a fixed point). Hertz's "
                     "half-space formula F = (4/3) E* R^½ δ^3/2 ignores the compliance distribution of the finite "
                     "sphere (δ here is each plane's approach to the centre); that effect is of relative order "
                     "(δ/R)^½, so the ratio is also fitted as c0 + c1 (δ/R)^½ and c0 is the δ → 0 limit.</p>")
        rows = []
        for lev in hz["levels"]:
            for r in lev["rows"]:
                rows.append([lev["pole_size_rel"], lev["n_vertices"], r["delta"] / hz["radius"], r["force"],
                             r["hertz_force"], r["ratio"], r["radius_ratio"], r["n_active"], r["iterations"]])
        parts.append(table(["h/R", "vertices", "δ/R", "F (N)", "F Hertz (N)", "F/F_H", "a/a_H", "active nodes",
                            "iterations"], rows))
        parts.append(table(["h/R", "vertices", "fitted exponent (Hertz 1.5)", "F/F_H at δ→0 (fit)",
                            "slope in (δ/R)^½", "seconds"],
                           [[lev["pole_size_rel"], lev["n_vertices"], lev["exponent"], lev["extrapolated_ratio"],
                             lev["sqrt_slope"], lev["seconds"]] for lev in hz["levels"]]))
        parts.append(img(images.get("hertz"), "force against indentation"))

    return "\n".join(parts)


#: Each contact discretisation's marker, line style and colour in :func:`indenter_plot`.
_METHOD_STYLE = {"node": ("o", "-", "C0"), "weighted": ("s", "--", "C3"), "dual": ("^", ":", "C2")}


def indenter_plot(study: dict, path: str | Path) -> Path:
    """F/F_Hertz against the contact radius for each contact discretisation on each spacing (seed 1), and their
    errors against the fine mesh: RMS and swing against the spacing."""
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    d_rel = np.array(study["deltas_rel"])
    a_rel = np.sqrt(d_rel)  # a / R
    hertz = np.array(study["hertz_force"])
    ref = study["reference"]
    axes[0].plot(a_rel, np.array(ref["force"]) / hertz, "k-", lw=2,
                 label=f"fine mesh, h = {ref['contact_size_rel']:g} a_max ({ref['vertices']} vertices)")
    for level in study["levels"]:
        colour = None
        for method, (marker, dash, _) in _METHOD_STYLE.items():
            f = np.array(level["methods"][method]["forces"][0]) / hertz
            line, = axes[0].plot(a_rel, f, marker + dash, ms=3, lw=0.9, color=colour, fillstyle="none",
                                 label=f"{method}, h = {level['contact_size_rel']:g} a_max")
            colour = line.get_color()
    axes[0].set_xlabel("contact radius a / R = (δ / R)^½")
    axes[0].set_ylabel("F / F_Hertz (half-space)")
    axes[0].set_title("Rigid sphere into an elastic block (frictionless)")
    axes[0].legend(fontsize=6, ncol=2)
    axes[0].grid(True, alpha=0.3)
    sizes = [level["contact_size_rel"] for level in study["levels"]]
    for method, (marker, _, colour) in _METHOD_STYLE.items():
        rms = [100 * level["methods"][method]["rms_error"] for level in study["levels"]]
        swing = [100 * level["methods"][method]["swing"] for level in study["levels"]]
        axes[1].loglog(sizes, rms, marker + "-", color=colour, label=f"{method}: RMS error against the fine mesh")
        axes[1].loglog(sizes, swing, marker + ":", color=colour, fillstyle="none",
                       label=f"{method}: swing (kinks of F(δ))")
    axes[1].set_xlabel("edge length at the contact h / a_max")
    axes[1].set_ylabel("per cent")
    axes[1].set_title("Errors over δ and gmsh seeds")
    axes[1].legend(fontsize=7)
    axes[1].grid(True, which="both", alpha=0.3)
    return _save(fig, path)


def indenter_checks(part: dict[str, Any]) -> list[dict[str, Any]]:
    """Every discretisation solved exactly, all converging to one answer near Hertz's."""
    out: list[dict[str, Any]] = []
    st = part.get("indenter")
    if st:
        ref = st["reference"]
        out.append(check("Indenter: the contacts' forces on the fine mesh, largest relative difference",
                         ref["methods_differ_rel"], "≤ 0.01", ref["methods_differ_rel"] <= 0.01))
        ratio = np.array(ref["force"]) / np.array(st["hertz_force"])
        worst = float(np.abs(ratio - 1).max())
        out.append(check("Indenter: max |F/F_Hertz − 1| on the fine mesh", worst, "≤ 0.2 (finite, clamped block)",
                         worst <= 0.2))
        finest = st["levels"][-1]["methods"]
        for method in finest:
            out.append(check(f"Indenter: {method} contact's RMS error against the fine mesh, finest spacing",
                             finest[method]["rms_error"], "≤ 0.05", finest[method]["rms_error"] <= 0.05))
        residual = max(level["methods"][m][key] for level in st["levels"] for m in level["methods"]
                       for key in ("max_complementarity_rel", "max_tension_rel", "max_penetration_rel"))
        out.append(check("Indenter: complementarity, tension and penetration residuals (relative)", residual,
                         "≤ 1e-9", residual <= 1e-9))
    return out


def indenter_section(st: dict[str, Any] | None, image: str | None) -> str:
    """The report's section on the node contact against the weighted gaps."""
    if not st:
        return ""
    ref = st["reference"]
    parts = ["<h2>Node contact or a weighted gap: a rigid fingertip pressed into a block</h2>",
             "<p class='note'>A rigid sphere (R = " + fmt(st["radius"]) + " m) pressed by δ into an elastic block "
             f"(E = {fmt(st['young'])} Pa, ν = {fmt(st['poisson'])}; a quarter {fmt(st['block_rel'])} R wide and "
             "deep, clamped below, refined at the contact), frictionless. <b>Node contact</b>: every node on its own "
             "(the paper's); <b>weighted</b>: the gap integrated against each node's hat function, with the "
             "mortar's consistent forces; <b>dual</b>: the gap weighed by the dual basis (the dual mortar), forces on "
             "the nodes. Errors are against a fine mesh of the same block (h = "
             f"{fmt(ref['contact_size_rel'])} a_max, {ref['vertices']} vertices; the methods differ there by "
             f"{100 * ref['methods_differ_rel']:.2f} %), over δ/R from {fmt(st['deltas_rel'][0])} to "
             f"{fmt(st['deltas_rel'][-1])} and {len(st['levels'][0]['vertices'])} gmsh seeds per spacing; the "
             "swing is the largest departure of a seed's errors from their own quadratic in a (the kinks of F(δ) "
             "as rings of nodes enter contact).</p>"]
    rows = []
    for level in st["levels"]:
        for method, s in level["methods"].items():
            rows.append([level["contact_size_rel"], int(np.median(level["vertices"])), method,
                         100 * s["mean_error"], 100 * s["rms_error"], 100 * s["max_error"], 100 * s["seed_spread"],
                         100 * s["swing"]])
    parts.append(table(["h / a_max", "vertices", "contact", "mean error %", "RMS error %", "largest error %",
                        "seed spread %", "swing %"], rows))
    parts.append(img(image, "node contact against weighted gaps"))
    return "\n".join(parts)
