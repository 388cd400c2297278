"""Figures, headline checks and report sections of the dolfinx study (matplotlib Agg, PNG files)."""

from __future__ import annotations

import html
import logging
from pathlib import Path
from typing import Any

import numpy as np

from .._common.html import fmt, img, table
from .._common.run import check, finite_max
from .crosscheck import worst

log = logging.getLogger(__name__)

COLORS = {"fem_grasp P1": "#1f77b4", "dolfinx P1": "#ff7f0e", "dolfinx P2": "#2ca02c"}
MARKERS = {"fem_grasp P1": "o", "dolfinx P1": "x", "dolfinx P2": "s"}


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _null_formatter():
    from matplotlib.ticker import NullFormatter

    return NullFormatter()


def _save(fig, path: str | Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    _plt().close(fig)
    log.info("wrote %s", path)
    return Path(path)


def convergence_plot(study: dict, path: str | Path) -> Path:
    """Relative L2 and energy errors against cell size, with fitted rates in the legend."""
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    for ax, key, label in ((axes[0], "l2", "L2"), (axes[1], "energy", "energy norm")):
        for name, rows in study["runs"].items():
            if not rows:
                continue
            h = np.array([r["cell_size"] for r in rows])
            e = np.array([r[f"{key}_error"] / r[f"{key}_norm"] for r in rows])
            rate = study["rates"][name][key]
            ax.loglog(h, e, marker=MARKERS[name], color=COLORS[name], label=f"{name} (rate {rate:.2f})",
                      fillstyle="none" if name == "dolfinx P1" else "full")
        ax.set_xlabel("cell size h = 1/N")
        ax.xaxis.set_minor_formatter(_null_formatter())
        ax.set_ylabel(f"relative {label} error")
        ax.set_title(f"Manufactured solution, {label}")
        ax.grid(True, which="both", alpha=0.3)
        ax.invert_xaxis()
        ax.legend(fontsize=8)
    return _save(fig, path)


def error_time_plot(study: dict, path: str | Path) -> Path:
    """Relative errors against wall time (assembly + solve) for the three discretisations."""
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    for ax, key, label in ((axes[0], "energy", "energy norm"), (axes[1], "l2", "L2")):
        for name, rows in study["runs"].items():
            if not rows:
                continue
            t = np.array([r["seconds"] for r in rows])
            e = np.array([r[f"{key}_error"] / r[f"{key}_norm"] for r in rows])
            ax.loglog(t, e, marker=MARKERS[name], color=COLORS[name], label=name,
                      fillstyle="none" if name == "dolfinx P1" else "full")
            for r, ti, ei in zip(rows, t, e):
                ax.annotate(f"N={r['N']}", (ti, ei), fontsize=6, xytext=(3, 3), textcoords="offset points")
        ax.set_xlabel("wall time, assembly + solve (s)")
        ax.set_ylabel(f"relative {label} error")
        ax.set_title(f"Error against cost ({label})")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    return _save(fig, path)


def locking_plot(study: dict, beam: dict | None, path: str | Path) -> Path:
    """Locking against ν: cantilever tip deflection (ratio to P2 reference) and manufactured energy error."""
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    if beam:
        nus = np.array([r["poisson"] for r in beam["rows"]])
        for name in COLORS:
            axes[0].semilogx(1.0 / (1.0 - 2.0 * nus), [r[name]["tip_ratio"] for r in beam["rows"]],
                             marker=MARKERS[name], color=COLORS[name], label=name,
                             fillstyle="none" if name == "dolfinx P1" else "full")
        axes[0].axhline(1.0, color="k", lw=0.8)
        axes[0].set_ylim(0, 1.1)
        axes[0].set_xlabel("1 / (1 − 2ν)")
        axes[0].set_ylabel("tip deflection / P2 reference")
        axes[0].set_title(f"Cantilever under gravity, mesh {'x'.join(map(str, beam['divisions']))}")
        axes[0].grid(True, which="both", alpha=0.3)
        axes[0].legend(fontsize=8)
    nus = np.array([r["poisson"] for r in study["rows"]])
    for name in COLORS:
        axes[1].loglog(1.0 / (1.0 - 2.0 * nus), [r[name]["energy_rel"] for r in study["rows"]], marker=MARKERS[name],
                       color=COLORS[name], label=name, fillstyle="none" if name == "dolfinx P1" else "full")
    axes[1].set_xlabel("1 / (1 − 2ν)")
    axes[1].set_ylabel("relative energy-norm error")
    axes[1].set_title(f"Divergence-free manufactured field, N = {study['divisions']}")
    axes[1].grid(True, which="both", alpha=0.3)
    axes[1].legend(fontsize=8)
    for ax in axes:
        ax.text(0.02, 0.02, "ν = " + ", ".join(f"{v:g}" for v in nus), transform=ax.transAxes, fontsize=7)
    return _save(fig, path)


def collinear_plot(study: dict, path: str | Path) -> Path:
    """cond(M), agreement with dolfinx and the exact moment balance against the angle θ off collinearity."""
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    floor = 1e-17
    for bk, mk in (("sparse", "o"), ("spectral", "s")):
        rows = [r for r in study["rows"] if "cond" in r.get(bk, {}) and r["angle"] > 0]
        th = [r["angle"] for r in rows]
        axes[0].loglog(th, [r[bk]["cond"] for r in rows], marker=mk, label=f"{bk} backend", fillstyle="none")
        axes[1].loglog(th, [max(r[bk].get("f_vs_dolfinx", np.nan), floor) for r in rows], marker=mk, ls="--",
                       label=f"{bk}: forces vs dolfinx", fillstyle="none")
        axes[1].loglog(th, [max(r[bk]["axis_moment"], floor) for r in rows], marker=mk,
                       label=f"{bk}: moment residual", fillstyle="full", ms=4)
    rows = [r for r in study["rows"] if "dolfinx_axis_moment" in r and r["angle"] > 0]
    axes[1].loglog([r["angle"] for r in rows], [max(r["dolfinx_axis_moment"], floor) for r in rows], "k^-",
                   label="dolfinx: moment residual", ms=4)
    th0 = study.get("first_error_angle")
    for ax in axes:
        if th0:
            ax.axvline(th0, color="r", ls="--", lw=0.8, label=f"CollinearContactError from θ = {th0:g}")
        ax.invert_xaxis()
        ax.set_xlabel("angle θ off the line (rad)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    axes[0].set_ylabel("cond₂(M)")
    axes[0].set_title("Bordered matrix M of eq. (3)")
    axes[1].set_ylabel("relative error")
    axes[1].set_title("vs dolfinx, and exact moment balance")
    return _save(fig, path)


def plots(part: dict[str, Any], out_dir: Path) -> dict[str, str]:
    """The study's figures, written to ``out_dir``; their names by key."""
    images: dict[str, str] = {}
    stab = part.get("stability", {})
    if "convergence" in part:
        images["convergence"] = convergence_plot(part["convergence"], out_dir / "convergence.png").name
        images["error_time"] = error_time_plot(part["convergence"], out_dir / "error_time.png").name
    if "locking" in stab:
        images["locking"] = locking_plot(stab["locking"], stab.get("beam"), out_dir / "locking.png").name
    if "collinear" in stab:
        images["collinear"] = collinear_plot(stab["collinear"], out_dir / "collinear.png").name
    return images


# ----------------------------------------------------------------- report sections
def crosscheck_rows(results: list[dict]) -> list[list[Any]]:
    rows = []
    for r in results:
        def worst(key, bk):
            vals = [c[bk][key] for c in r.get("contact", []) if bk in c]
            return max(vals) if vals else None

        rows.append([r["label"], r["n_vertices"], r["n_tets"], r["K_rel_diff"], r["G_rel_diff"], r["energy_rel_diff"],
                     r["null_fem_grasp"], r["null_dolfinx"], r.get("eig6_max_fem_grasp"), r.get("eig7_rel_diff"),
                     worst("u_rel_diff", "sparse"), worst("f_rel_diff", "sparse"),
                     worst("u_rel_diff", "spectral"), worst("f_rel_diff", "spectral"),
                     max([worst("equilibrium_force", bk) or 0.0 for bk in ("sparse", "spectral")]
                         + [worst("equilibrium_torque", bk) or 0.0 for bk in ("sparse", "spectral")])])
    return rows


CROSS_HEADERS = ["mesh", "vertices", "tets", "K rel diff", "G rel diff", "energy rel diff", "‖K r‖ fem_grasp",
                 "‖K r‖ dolfinx", "6 smallest |λ|/‖K‖", "λ7,8 rel diff (two matrices)", "u sparse", "f sparse", "u spectral",
                 "f spectral", "equilibrium"]


def section(s: dict[str, Any], images: dict[str, str]) -> str:
    """The report's sections of this study: fem_grasp against dolfinx entry by entry, the manufactured solution's
    convergence, stability."""
    parts: list[str] = []
    cross = s.get("crosscheck", {})
    parts.append("<h2>fem_grasp against dolfinx, entry by entry</h2>")
    parts.append("<p class='note'>Relative differences: K and G as max |Δ| / max |entry|; energies of five random "
                 "fields (fem_grasp ½ΔᵀKΔ against dolfinx's integral of eq. (2)); rigid modes as "
                 "‖K r‖ / (‖K‖₂ ‖r‖) (worst of the six); the six smallest eigenvalues of fem_grasp's K (shift-invert "
                 "Lanczos) relative to ‖K‖₂, and the 7th and 8th eigenvalues of the two matrices compared; contact "
                 "problems (gravity plus held nodes: a grasp-like set and a random set) as max |Δ| / max |·| of the "
                 "displacement field (u) and the contact forces (f) for each fem_grasp backend against a dolfinx/PETSc "
                 "Dirichlet solve; equilibrium = worst relative force/torque imbalance of fem_grasp's solutions. "
                 "A dash means not run at that size.</p>")
    if cross.get("small"):
        parts.append("<h3>Small meshes (the test-suite's)</h3>" + table(CROSS_HEADERS, crosscheck_rows(cross["small"])))
    if cross.get("paper"):
        parts.append("<h3>The four paper objects (Table I material and weight)</h3>")
        parts.append(table(CROSS_HEADERS, crosscheck_rows(cross["paper"])))
        parts.append("<p class='note'>Mesh sources: " + "; ".join(
            f"{html.escape(r['label'])}: {html.escape(str(r.get('source')))}" for r in cross["paper"]) + "</p>")
    if cross.get("refinement"):
        parts.append(f"<h3>Refinement series ({html.escape(cross.get('refinement_object', ''))})</h3>")
        parts.append(table(CROSS_HEADERS, crosscheck_rows(cross["refinement"])))
        if cross.get("refinement_note"):
            parts.append(f"<p class='note'>{html.escape(cross['refinement_note'])}</p>")
        parts.append(table(["mesh", "fem_grasp K (s)", "dolfinx K (s)", "dolfinx set-up (s)", "dolfinx contact (s)",
                            "fem_grasp sparse contact (s)"],
                           [[r["label"], r["seconds_fem_grasp_K"], r["seconds_dolfinx_K"], r["seconds_dolfinx_setup"],
                             max([c["dolfinx_seconds"] for c in r.get("contact", [])], default=None),
                             max([c["sparse"]["seconds"] for c in r.get("contact", []) if "sparse" in c],
                                 default=None)] for r in cross["refinement"]]))

    if any(k.startswith(("mesh_", "contact_")) for k in images):
        parts.append("<h3>Pictures</h3><div class='grid'>")
        for key in sorted(k for k in images if k.startswith("mesh_")):
            parts.append(img(images[key], f"{key[5:]}: tetrahedral mesh"))
        parts.append("</div><div class='grid'>")
        for key in sorted(k for k in images if k.startswith("contact_")):
            parts.append(img(images[key], f"{key[8:]}: {s.get('render_note', '')}"))
        parts.append("</div>")

    conv = s.get("convergence")
    if conv:
        parts.append("<h2>Convergence: manufactured solution on the unit box</h2>")
        parts.append(f"<p class='note'>Exact field: a sum of three plane waves with div u ≠ 0; E = {fmt(conv['young'])} "
                     f"Pa, ν = {fmt(conv['poisson'])}; every boundary node takes the exact value; body force "
                     "−div σ(u): closed form integrated by a degree-5 rule on the fem_grasp side, UFL-derived on the "
                     "dolfinx side. Errors are relative to the exact field's norm. Times cover assembly and solve "
                     "(MUMPS for all three), not JIT compilation or error evaluation. Largest relative difference "
                     f"between fem_grasp's and dolfinx's P1 errors: {fmt(conv['p1_error_max_rel_diff'])} (the two "
                     "differ only in load quadrature).</p>")
        parts.append(table(["method", "L2 rate (fit)", "L2 rate (last pair)", "energy rate (fit)",
                            "energy rate (last pair)", "expected L2 / energy"],
                           [[m, r["l2"], r["l2_last"], r["energy"], r["energy_last"],
                             "3 / 2" if "P2" in m else "2 / 1"] for m, r in conv["rates"].items()]))
        rows = []
        for m, runs in conv["runs"].items():
            for r in runs:
                rows.append([m, r["N"], r["n_dofs"], r["l2_error"] / r["l2_norm"], r["energy_error"] / r["energy_norm"],
                             r["seconds"]])
        parts.append(table(["method", "N", "DOFs", "rel L2 error", "rel energy error", "seconds"], rows))
        parts.append(img(images.get("convergence"), "errors against cell size"))
        parts.append(img(images.get("error_time"), "errors against wall time"))

    st = s.get("stability", {})
    if st:
        parts.append("<h2>Stability: locking, Young's modulus, near-collinear contacts, slivers</h2>")
        lk, bm = st.get("locking"), st.get("beam")
        if lk or bm:
            parts.append("<h3>Poisson's ratio and volumetric locking</h3>")
        if bm:
            parts.append(
                f"<p class='note'>Cantilever {fmt(bm['length'])} × {fmt(bm['width'])} × {fmt(bm['width'])} m clamped "
                f"at x = 0, sagging under its weight (E = {fmt(bm['young'])} Pa, ρ = {fmt(bm['density'])} kg/m³). "
                f"Vertical deflection at the centre of the free end, relative to dolfinx P2 on a "
                f"{'×'.join(map(str, bm['reference_divisions']))} mesh; the P1 runs and the P2 comparison use the "
                f"{'×'.join(map(str, bm['divisions']))} mesh (two elements through the thickness). Euler–Bernoulli "
                f"(no shear, no ν): {fmt(bm['euler_bernoulli_tip'])} m. fem_grasp P1 and dolfinx P1 agree to "
                f"{fmt(bm['max_fem_grasp_vs_dolfinx_p1'])} at every ν: fem_grasp locks exactly like standard P1, "
                "which is the expected behaviour of the element the paper uses, not a bug.</p>")
            parts.append(table(["ν", "reference tip (m)", "fem_grasp P1 / ref", "dolfinx P1 / ref", "dolfinx P2 / ref",
                                "fem_grasp P1 work / ref"],
                               [[r["poisson"], r["reference_tip"], r["fem_grasp P1"]["tip_ratio"],
                                 r["dolfinx P1"]["tip_ratio"], r["dolfinx P2"]["tip_ratio"],
                                 r["fem_grasp P1"]["work_ratio"]] for r in bm["rows"]]))
        if lk:
            parts.append("<p class='note'>Divergence-free manufactured field (its load does not depend on ν), fully "
                         f"Dirichlet unit box, N = {lk['divisions']} (P1) and N = {lk['p2_divisions']} (P2). With the "
                         "whole boundary prescribed the L2 error hardly moves, but the energy-norm error — dominated "
                         "by the spurious λ (div u_h)² term — grows like λ for P1 and far less for P2. Growth of the "
                         "L2 error from ν = 0 to the last ν: " + ", ".join(
                             f"{k} ×{fmt(v)}" for k, v in lk["l2_growth"].items()) + ".</p>")
            parts.append(table(["ν"] + [f"{m} {k}" for m in ("fem_grasp P1", "dolfinx P1", "dolfinx P2")
                                        for k in ("L2", "energy")],
                               [[r["poisson"]] + [r[m][k] for m in ("fem_grasp P1", "dolfinx P1", "dolfinx P2")
                                                  for k in ("l2_rel", "energy_rel")] for r in lk["rows"]]))
        parts.append(img(images.get("locking"), "locking against ν"))
        pt = st.get("poisson_operators")
        if pt:
            parts.append("<p class='note'>K and a grasp-like contact solve against dolfinx for each ν (small box):</p>")
            parts.append(table(["ν", "K rel diff", "f sparse", "u sparse", "f spectral", "u spectral"],
                               [[r["poisson"], r["K_rel_diff"], r["sparse"]["f_vs_dolfinx"], r["sparse"]["u_vs_dolfinx"],
                                 r["spectral"]["f_vs_dolfinx"], r["spectral"]["u_vs_dolfinx"]] for r in pt]))
        ys = st.get("young")
        if ys:
            parts.append("<h3>Young's modulus from 10² to 10¹² Pa</h3>")
            parts.append(f"<p class='note'>{html.escape(ys.get('label', ''))}: deviations from exact scaling, relative "
                         f"to E = {fmt(ys['reference_young'])} Pa: F̄(Δ̄) − F̄(0) ∝ E, F̄(0) independent of E, the "
                         "gravity-only displacement ∝ 1/E; and agreement with dolfinx at each E.</p>")
            rows = []
            for r in ys["rows"]:
                for bk in ("sparse", "spectral"):
                    v = r[bk]
                    rows.append([r["young"], bk, v["C_scaling"], v["F0_invariance"], v["u_gravity_scaling"],
                                 v["f_vs_dolfinx"], v["u_vs_dolfinx"]])
            parts.append(table(["E (Pa)", "backend", "C Δ̄ ∝ E", "F̄(0) const", "u_g ∝ 1/E", "f vs dolfinx",
                                "u vs dolfinx"], rows))
        co = st.get("collinear")
        if co:
            parts.append("<h3>Near-collinear contact sets</h3>")
            parts.append("<p class='note'>Three held nodes on a cube edge, the middle one turned off the line by θ; "
                         "the body hangs from them under gravity. Both fem_grasp and dolfinx become ill-conditioned "
                         "(cond(M) ∝ θ⁻²), so their agreement degrades like cond · 10⁻¹⁶. "
                         f"CollinearContactError is first raised at θ = {fmt(co.get('first_error_angle'))}.</p>")
            rows = []
            for r in co["rows"]:
                row = [r["angle"], r.get("dolfinx_max_force", r.get("dolfinx_error")), r.get("dolfinx_axis_moment")]
                for bk in ("sparse", "spectral"):
                    v = r[bk]
                    row += [v.get("cond", "raised"), v.get("max_force"), v.get("f_vs_dolfinx"), v.get("axis_moment")]
                rows.append(row)
            parts.append(table(["θ (rad)", "dolfinx max |f|", "dolfinx moment residual", "cond(M) sparse",
                                "max |f| sparse", "f vs dolfinx", "moment residual", "cond(M) spectral",
                                "max |f| spectral", "f vs dolfinx", "moment residual"], rows))
            parts.append("<p class='note'>Moment residual: balance of moments about the line through the two end "
                         "nodes, relative to gravity's moment. Only the middle node has a lever arm (∝ θ) about that "
                         "line, so this statics identity fixes the large middle force exactly; it shows which solver "
                         "still gets the physics right as the conditioning degrades.</p>")
            parts.append(img(images.get("collinear"), "conditioning against angle"))
        sl = st.get("sliver")
        if sl:
            parts.append("<h3>Sliver tetrahedra</h3>")
            parts.append(f"<p class='note'>Delaunay tetrahedralisation of a cube grid jittered by "
                         f"{fmt(sl['jitter'])} of the spacing: minimum quality {fmt(sl['min_quality'])} (1 = regular), "
                         f"median {fmt(sl['median_quality'])}, {sl['n_below_0.01']} of {sl['n_tets']} tetrahedra below "
                         "0.01. ‖K‖₂ is inflated by the slivers; agreement with dolfinx:</p>")
            parts.append(table(CROSS_HEADERS, crosscheck_rows([dict(sl, label="sliver cube")])))

    return "\n".join(parts)


# ----------------------------------------------------------------- headline checks
def checks(s: dict[str, Any]) -> list[dict[str, Any]]:
    """The pass/fail rows of this study: operators to 1e-12 and contact solves to 1e-9 against dolfinx on every
    mesh of the run, the expected convergence rates, exact scaling in E, the same locking as dolfinx's P1."""
    out: list[dict[str, Any]] = []

    def add(name: str, value: float, threshold: str, ok: bool) -> None:
        out.append(check(name, value, threshold, ok))

    cross = s.get("crosscheck", {})
    meshes = [r for key in ("small", "paper", "refinement") for r in cross.get(key, [])]
    st = s.get("stability", {})
    if st.get("sliver"):
        meshes = meshes + [st["sliver"]]
    if meshes:
        for key, label in (("K_rel_diff", "K: max |ΔK_ij| / max |K_ij|"), ("G_rel_diff", "G: max relative difference"),
                           ("energy_rel_diff", "strain energy of random fields")):
            v = finite_max(r[key] for r in meshes)
            add(f"{label} (all {len(meshes)} meshes)", v, "≤ 1e-12", v <= 1e-12)
        v = finite_max([r["null_dolfinx"] for r in meshes] + [r["null_fem_grasp"] for r in meshes])
        add("rigid modes: ‖K r‖ / (‖K‖₂‖r‖), both matrices", v, "≤ 1e-12", v <= 1e-12)
        v = finite_max(r.get("eig6_max_fem_grasp") for r in meshes)
        add("six smallest eigenvalues of K / ‖K‖₂ (meshes where computed)", v, "≤ 1e-12", v <= 1e-12)
        v = finite_max(r.get("eig7_diff_over_norm") for r in meshes)
        add("λ7, λ8 of fem_grasp's K vs dolfinx's, |Δλ| / ‖K‖₂", v, "≤ 1e-12", v <= 1e-12)
        for key, label in (("u_rel_diff", "contact displacement fields"), ("f_rel_diff", "contact forces")):
            v = finite_max(worst(r, key) for r in meshes)
            add(f"{label}, both backends vs dolfinx", v, "≤ 1e-9", v <= 1e-9)
        v = finite_max(max(worst(r, "equilibrium_force"), worst(r, "equilibrium_torque")) for r in meshes)
        add("equilibrium of contact forces + gravity (relative)", v, "≤ 1e-10", v <= 1e-10)
        top = finite_max(r["n_vertices"] for r in cross.get("refinement", []))
        add("largest mesh in the refinement series (vertices)", top, "≥ 50,000 (full run)",
            s.get("config", {}).get("refinement_min_top", 0) == 0 or top >= 5e4)
    conv = s.get("convergence")
    if conv:
        expected = {"fem_grasp P1": (2, 1), "dolfinx P1": (2, 1), "dolfinx P2": (3, 2)}
        for m, (l2, en) in expected.items():
            r = conv["rates"][m]
            add(f"{m} L2 rate (last pair)", r["l2_last"], f"{l2} ± 0.15", abs(r["l2_last"] - l2) <= 0.15)
            add(f"{m} energy rate (last pair)", r["energy_last"], f"{en} ± 0.15", abs(r["energy_last"] - en) <= 0.15)
        add("fem_grasp P1 vs dolfinx P1 errors, relative difference", conv["p1_error_max_rel_diff"], "≤ 1e-3",
            conv["p1_error_max_rel_diff"] <= 1e-3)
    if st.get("young"):
        add("E from 1e2 to 1e12: deviation from exact scaling", st["young"]["max_deviation"], "≤ 1e-10",
            st["young"]["max_deviation"] <= 1e-10)
    if st.get("locking"):
        g = st["locking"]["l2_growth"]
        add("locking: P1 L2 error growth ν 0 → 0.4999 (fem_grasp / dolfinx)", g["fem_grasp P1"] / g["dolfinx P1"],
            "= 1 ± 0.01 (same locking)", abs(g["fem_grasp P1"] / g["dolfinx P1"] - 1) <= 0.01)
    if st.get("beam"):
        v = st["beam"]["max_fem_grasp_vs_dolfinx_p1"]
        add("cantilever tip deflection, fem_grasp P1 vs dolfinx P1, all ν", v, "≤ 1e-9", v <= 1e-9)
    if st.get("poisson_operators"):
        v = finite_max(r["K_rel_diff"] for r in st["poisson_operators"])
        add("K vs dolfinx for ν up to 0.4999", v, "≤ 1e-12", v <= 1e-12)
    return out


__all__ = ["CROSS_HEADERS", "checks", "collinear_plot", "convergence_plot", "crosscheck_rows", "error_time_plot",
           "locking_plot", "plots", "section"]
