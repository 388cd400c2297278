"""matplotlib figures of the verification studies (Agg backend, PNG files)."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

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
