"""The 2-D pictures of a report (matplotlib, no pyplot state): ``patches.png`` (each finger's contact patch),
``liftable.png`` (the lift test's w(ρ)) and ``timeline.png`` (the events along the finger path); what they
show: :mod:`fem_grasp.io.report`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .frames import SLIP, STICK, finger_centres, pick_frames, read_frame

__all__ = ["plot_liftable", "plot_patches", "plot_timeline"]

_BODY_COLOURS = {"finger1": "#d62728", "finger2": "#9467bd", "table": "#1f77b4"}
#: A patch of more contacts than this has no force printed at its nodes, and smaller dots: on the accuracy loop's
#: finest level (about 130 contacts on a fingertip, 1 mm apart) the numbers and dots covered one another.
LABELLED_CONTACTS = 30


def _figure(size: tuple[float, float]) -> tuple[Any, Any]:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    return fig, fig.subplots


def _save(fig: Any, path: Path) -> Path:
    import io

    from .._files import atomic_write_bytes

    buf = io.BytesIO()
    fig.savefig(buf, format="png", bbox_inches="tight")
    atomic_write_bytes(path, buf.getvalue())
    return path


def plot_liftable(doc: dict[str, Any], path: Path) -> Path:
    """w(ρ) from the lift test against the real weight; with the accuracy loop, every level's w(ρ) (a finer level
    tests only from the coarser level's ρ*, so the coarser levels show the curve's way up)."""
    fig, subplots = _figure((6.4, 4.0))
    ax = subplots()
    res, summ = doc["result"], doc["summary"]
    lw = np.asarray(res["liftable"], float).reshape(-1, 2)
    weight = float(summ["weight"])
    levels = (doc.get("accuracy") or {}).get("levels") or []  # the last is the answer's (``lw``)
    coarser = [lv for lv in levels[:-1] if lv.get("liftable")]
    top = [float(lw[:, 1].max())] if len(lw) else []
    for n, lv in enumerate(coarser):
        w = np.asarray(lv["liftable"], float).reshape(-1, 2)
        grey = str(round(0.75 - 0.3 * n / max(len(coarser) - 1, 1), 2))
        ax.step(1e3 * w[:, 0], w[:, 1], where="post", color=grey, marker=".", ms=2, lw=1,
                label=f"w(ρ), level {lv['level']} ({lv['vertices']:,} vertices)")
        top.append(float(w[:, 1].max()))
    if len(lw):
        last = f", level {levels[-1]['level']} (the answer's)" if len(levels) > 1 else " (lift test)"
        ax.step(1e3 * lw[:, 0], lw[:, 1], where="post", color="#1f77b4", marker=".", ms=4, lw=1.8,
                label=f"liftable weight w(ρ){last}")
    ax.axhline(weight, color="#d62728", ls="--", label=f"weight mg = {weight:.3g} N")
    rho = float(summ["squeeze_depth"])
    ax.axvline(1e3 * rho, color="0.4", ls=":", label=f"squeeze stops, ρ = {1e3 * rho:.3g} mm")
    ax.set_xlim(left=0)
    ax.set_xlabel("squeeze depth ρ (mm)")
    ax.set_ylabel("weight (N)")
    ax.set_ylim(bottom=0, top=max([1.25 * weight] + [1.05 * t for t in top]))
    ax.set_title("Lift test: the fingers lift once w(ρ) ≥ mg" + ("" if len(lw) else " (no lift test ran)"))
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)
    return _save(fig, path)


def plot_patches(out: Path, doc: dict[str, Any], path: Path) -> Path:
    """Close-ups of the two contact patches when the lift starts and at the end (:mod:`fem_grasp.io.report`)."""
    picks = [(title, frame) for name, title, frame in pick_frames(doc) if name != "rest.png"]
    res = doc["result"]
    radius = float(res["finger_radius"])
    directions = np.asarray(res["directions"], float)
    fig, subplots = _figure((9.6, 4.6 * len(picks)))
    axes = np.atleast_2d(subplots(len(picks), 2))
    for row, (title, frame) in enumerate(picks):
        d = read_frame(out, frame, doc)
        centres = finger_centres(doc, frame)
        for f in range(2):
            ax = axes[row, f]
            ax.set_aspect("equal")
            ax.grid(alpha=0.25)
            ax.set_xlabel("across the squeeze (mm)")
            ax.set_ylabel("up (mm)")
            if centres is None:
                ax.set_title(f"finger {f + 1}, {title}: not placed", fontsize=9)
                continue
            c = np.asarray(centres[f], float)
            dn = directions[f] / np.linalg.norm(directions[f])
            ev = np.array([0.0, 0.0, 1.0]) - dn[2] * dn
            ev /= np.linalg.norm(ev)
            eu = np.cross(ev, dn)  # seen from the finger, looking along its squeeze direction
            rel = d["points"] - c
            near = np.flatnonzero((np.linalg.norm(rel, axis=1) < 1.6 * radius) & (rel @ dn > -0.2 * radius))
            ax.scatter(1e3 * rel[near] @ eu, 1e3 * rel[near] @ ev, s=4, color="0.75", zorder=1,
                       label="object nodes near the fingertip")
            t = np.linspace(0, 2 * np.pi, 200)
            ax.plot(1e3 * radius * np.cos(t), 1e3 * radius * np.sin(t), color="0.5", lw=0.8, ls="--",
                    label=f"fingertip outline (R = {1e3 * radius:.3g} mm)")
            k = np.flatnonzero(d["body"] == f + 1)
            if not len(k):
                ax.set_title(f"finger {f + 1}, {title}: no contact", fontsize=9)
                continue
            n_hat = rel[k] / np.linalg.norm(rel[k], axis=1, keepdims=True)
            fk = d["force"][k]
            fn = np.einsum("ij,ij->i", fk, n_hat)
            ft = fk - fn[:, None] * n_hat
            u, v = 1e3 * rel[k] @ eu, 1e3 * rel[k] @ ev
            slide = d["state"][k] == 2
            size = (30 + 250 * np.clip(fn, 0, None) / max(float(fn.max()), 1e-300)) * min(1.0, LABELLED_CONTACTS / len(k))
            for mask, colour, name in ((~slide, STICK, "sticks"), (slide, SLIP, "slides")):
                if mask.any():
                    ax.scatter(u[mask], v[mask], s=size[mask], color=colour, edgecolor="black", lw=0.5, zorder=3,
                               label=f"contact node {name} ({int(mask.sum())})")
            tmax = max(float(np.linalg.norm(ft, axis=1).max()), 1e-300)
            ax.quiver(u, v, ft @ eu, ft @ ev, color="#d62728", zorder=4, angles="xy", scale_units="xy",
                      scale=tmax / (0.35e3 * radius), width=0.006, label="tangential force (longest: 0.35 R)")
            ax.text(0.02, 0.02, f"longest tangential force {1e3 * tmax:.3g} mN", transform=ax.transAxes, fontsize=7)
            for x, y, val in zip(u, v, fn) if len(k) <= LABELLED_CONTACTS else ():
                text = f"{1e3 * val:.3g}" if 1e3 * abs(val) >= 0.01 else "<0.01"
                ax.annotate(text, (x, y), xytext=(4, 4), textcoords="offset points", fontsize=6.5)
            r = fk.sum(axis=0)
            ax.set_title(f"finger {f + 1}, {title}\n{len(k)} contacts: {int((~slide).sum())} stick, "
                         f"{int(slide.sum())} slip\nΣ f·n̂ = {fn.sum():.3g} N, |resultant| = {np.linalg.norm(r):.3g} N",
                         fontsize=8.5)
            lim = 1.25e3 * radius
            ax.set_xlim(-lim, lim)
            ax.set_ylim(-lim, lim)
    handles = {}
    for ax in axes.ravel():
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab.split(" (")[0] if lab.startswith("contact node") else lab, h)
    if handles:  # one legend for the four panels, under them
        fig.legend(list(handles.values()), list(handles), loc="outside lower center", ncol=3, fontsize=7.5,
                   markerscale=0.6)
    fig.suptitle("Contact patches seen from each finger along its squeeze direction\n"
                 f"dot sizes (and numbers, on patches of up to {LABELLED_CONTACTS} contacts): normal force f·n̂ on the "
                 "object (mN); arrows: tangential force", fontsize=10)
    return _save(fig, path)


def plot_timeline(doc: dict[str, Any], path: Path) -> Path:
    """Events along the finger path and the number of contacts per body."""
    fig, subplots = _figure((8.0, 5.2))
    ax, ax2 = subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [1.3, 1]})
    res = doc["result"]
    rho_end = float(doc["summary"]["squeeze_depth"])

    def path_mm(phase: str, rho: float, h: float) -> float:
        return 1e3 * (rho + h if phase == "lift" else rho)

    kinds = ["A", "B", "C", "D"]
    names = {"A": "A contact", "B": "B break", "C": "C stick→slip", "D": "D slip→stick"}
    rng = np.random.default_rng(0)
    for body, colour in _BODY_COLOURS.items():
        ev = [e for e in res["events"] if e["contact"] == body]
        if not ev:
            continue
        x = [path_mm(e["phase"], e["squeeze_depth"], e["lift_height"]) for e in ev]
        y = np.array([kinds.index(e["kind"]) for e in ev]) + {"finger1": -0.2, "finger2": 0.0, "table": 0.2}[body]
        ax.scatter(x, y + rng.uniform(-0.06, 0.06, len(y)), s=12, color=colour, label=body, alpha=0.8)
    ax.set_yticks(range(4), [names[k] for k in kinds])
    ax.set_ylim(-0.6, 4.3)  # room for the legend above the D row
    ax.set_title(f"{len(res['events'])} events along the finger path (squeeze ρ, then ρ + lift height)")
    ax.legend(loc="upper left", fontsize=8, ncol=3)
    frames = doc["series"]["frames"]
    x = [path_mm(f["phase"], f["squeeze_depth"], f["lift_height"]) for f in frames]
    for body, colour in _BODY_COLOURS.items():
        counts = []
        for f in frames:
            if f["snapshot"] is not None:
                counts.append(len(res["snapshots"][f["snapshot"]]["contact_nodes"][body]))
            elif f["label"] == "rest":
                counts.append(doc["rest"]["n_contacts"] if body == "table" else 0)
            else:
                counts.append(len((res.get("final") or {}).get("contact_nodes", {}).get(body, [])))
        style = {"finger1": dict(lw=3.0, alpha=0.6), "finger2": dict(lw=1.5, ls="--"), "table": dict(lw=1.5)}[body]
        ax2.step(x, counts, where="post", color=colour, label=body, **style)
    ax2.set_ylabel("contact nodes")
    ax2.set_xlabel("finger path (mm): squeeze depth ρ, then ρ + lift height")
    for a in (ax, ax2):
        a.axvline(1e3 * rho_end, color="0.4", ls=":")
        a.grid(alpha=0.3)
    ax2.legend(loc="upper left", fontsize=8, ncol=3)
    return _save(fig, path)
