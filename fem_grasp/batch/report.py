"""``report.html`` of a placement search: where on the object the grasps work, and the best of them.

Beside report.html in the search folder:

* ``candidates.png`` and ``candidates_top.png`` — the resting object with each candidate's two contact points
  (joined by a line), coloured by ρ* for the grasps that pick it up, grey for the others (pyvista, off-screen,
  in a freshly spawned process as :mod:`fem_grasp.io.report` does);
* ``search_plots.png`` — ρ* and the fingers' grip at lift-off against height and azimuth (matplotlib);
* an inline map of azimuth × height whose points tell, on hover, each candidate's verdict and reason;
* the best grasps (``best/01`` …), each with the pickup report of :func:`fem_grasp.io.report.write_report`;
* the ranked table of every candidate, failures with their reason.
"""

from __future__ import annotations

import html
import logging
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from ..io.output import MARKER, add_to_marker, atomic_write_bytes, atomic_write_text

__all__ = ["PICTURES", "write_search_report"]

log = logging.getLogger(__name__)

#: The pictures of a search report.
PICTURES = ("candidates.png", "candidates_top.png", "search_plots.png")
_GREY = "#9a9a9a"
_ERROR = "#222222"


def _word(lifts: bool) -> str:
    return "picked up" if lifts else "lift test passed (the lift is not simulated)"


def _colours(values: np.ndarray, lo: float, hi: float) -> list[str]:
    from matplotlib import colormaps
    from matplotlib.colors import to_hex

    cmap = colormaps["viridis"]
    span = hi - lo if hi > lo else 1.0
    return [to_hex(cmap(min(max((v - lo) / span, 0.0), 1.0))) for v in values]


def _rho_range(table: Any) -> tuple[float, float]:
    ok = table["grasped"].to_numpy()
    rho = 1e3 * table["rho_star"].to_numpy()[ok]
    return (float(rho.min()), float(rho.max())) if len(rho) else (0.0, 1.0)


def _point_colours(table: Any) -> list[str]:
    lo, hi = _rho_range(table)
    out = []
    for ok, status, rho in zip(table["grasped"], table["status"], table["rho_star"]):
        out.append(_colours(np.array([1e3 * rho]), lo, hi)[0] if ok else (_GREY if status == "ok" else _ERROR))
    return out


# ------------------------------------------------------------------ pictures of the object
def render_candidates(out: Path, result: Any, size: tuple[int, int] = (900, 700), pool: Any = None) -> list[Path]:
    """candidates.png and candidates_top.png (pyvista in a spawned process: ``pool``, a
    :func:`fem_grasp.io.report.render_process`, or a new one)."""
    table = result.table
    pts = np.asarray(result.rest_positions if result.rest_positions is not None else result.setup.points, float)
    lo, hi = _rho_range(table)
    job = {"points": pts, "tets": np.asarray(result.setup.tets), "table_z": float(result.setup.table_z),
           "pi": table[["xi", "yi", "zi"]].to_numpy(float), "pj": table[["xj", "yj", "zj"]].to_numpy(float),
           "colours": _point_colours(table), "size": tuple(size), "rho_range": (lo, hi),
           "any_ok": bool(table["grasped"].any()), "title": f"{result.setup.name}: {len(table)} candidates, "
           f"{int(table['grasped'].sum())} {_word(result.setup.options.lift)} (coloured by rho* in mm), grey: not"}
    jobs = [{**job, "path": str(out / "candidates.png"), "view": "oblique"},
            {**job, "path": str(out / "candidates_top.png"), "view": "top"}]
    if pool is not None:
        return [Path(p) for p in pool.map(_draw_candidates, jobs)]
    from ..io.report import render_process

    with render_process() as own:
        return [Path(p) for p in own.map(_draw_candidates, jobs)]


def _draw_candidates(job: dict[str, Any]) -> str:
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    pv.OFF_SCREEN = True
    pts, tets = job["points"], job["tets"]
    cells = np.hstack([np.full((len(tets), 1), 4), tets]).ravel()
    grid = pv.UnstructuredGrid(cells, np.full(len(tets), pv.CellType.TETRA, dtype=np.uint8), pts)
    try:
        surf = grid.extract_surface(algorithm="dataset_surface")
    except TypeError:  # older pyvista
        surf = grid.extract_surface()
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    diam = float(np.linalg.norm(hi - lo))
    p = pv.Plotter(off_screen=True, window_size=list(job["size"]))
    p.set_background("white")
    p.add_mesh(surf, color="#e8dcc8", opacity=0.55, show_edges=True, edge_color="#b0a890", line_width=0.3)
    c = 0.5 * (lo + hi)
    span = 1.4 * float(max(hi[0] - lo[0], hi[1] - lo[1]))
    p.add_mesh(pv.Plane(center=(c[0], c[1], job["table_z"]), direction=(0, 0, 1), i_size=span, j_size=span),
               color="#c8b89a", opacity=0.3)
    # failures first, so that the grasps that work are drawn over them
    order = sorted(range(len(job["colours"])), key=lambda k: job["colours"][k] not in (_GREY, _ERROR))
    for k in order:
        colour = job["colours"][k]
        a, b = job["pi"][k], job["pj"][k]
        p.add_mesh(pv.Line(a, b), color=colour, line_width=1.5 if colour in (_GREY, _ERROR) else 2.5)
        for q in (a, b):
            p.add_mesh(pv.Sphere(radius=0.012 * diam, center=q), color=colour)
    if job["any_ok"]:
        lo_r, hi_r = job["rho_range"]
        bar = pv.PolyData(np.zeros((2, 3)))
        bar["rho* (mm)"] = np.array([lo_r, hi_r if hi_r > lo_r else lo_r + 1e-6])
        p.add_mesh(bar, scalars="rho* (mm)", cmap="viridis", point_size=0.0, opacity=0.0,
                   scalar_bar_args={"color": "black", "title": "rho* (mm)", "vertical": False, "position_x": 0.3,
                                    "position_y": 0.03, "height": 0.07, "width": 0.4})
        from ..io.report import bar_title_above

        bar_title_above(p, "rho* (mm)", 0.3, 0.03 + 0.07, job["size"])
    p.add_text(job["title"], font_size=10, color="black", position="upper_left")
    focal = c.copy()
    if job["view"] == "top":
        p.camera_position = [tuple(focal + [0.0, 0.0, 2.2 * diam]), tuple(focal), (0.0, 1.0, 0.0)]
    else:
        view = np.array([1.0, 0.12, 0.55])
        view /= np.linalg.norm(view)
        p.camera_position = [tuple(focal + 2.0 * diam * view), tuple(focal), (0.0, 0.0, 1.0)]
    p.camera.view_angle = 30.0
    final = Path(job["path"])
    tmp = final.with_name(f".{final.stem}.{os.getpid()}.tmp.png")
    try:
        p.screenshot(str(tmp))
        os.replace(tmp, final)
    finally:
        p.close()
        tmp.unlink(missing_ok=True)
    return str(final)


# ------------------------------------------------------------------ plots
def plot_search(table: Any, path: Path, lifts: bool = True) -> Path:
    """ρ* and the fingers' grip at lift-off (or where the lift test passed, when the lift is not simulated)
    against height and azimuth; grey marks: not grasped."""
    import io

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10.0, 7.0), dpi=100)
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 2, sharex="col")
    ok = table["grasped"].to_numpy()
    h = 1e3 * table["height"].to_numpy()
    az = table["azimuth_deg"].to_numpy()
    rho = 1e3 * table["rho_star"].to_numpy()
    squeeze = 1e3 * table["squeeze_depth"].to_numpy()
    for col, (x, label) in enumerate(((h, "height of the contacts above the table (mm)"),
                                      (az, "azimuth of the squeeze axis (degrees)"))):
        ax = axes[0, col]
        ax.scatter(x[ok], rho[ok], c="#1f77b4", s=22, label=f"{_word(lifts)}: ρ*")
        ax.scatter(x[~ok], squeeze[~ok], c=_GREY, marker="x", s=18, label="not: where the squeeze stopped")
        ax.set_ylabel("squeeze depth (mm)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best")
        ax = axes[1, col]
        for k, (mark, colour) in enumerate((("o", "#d62728"), ("^", "#9467bd")), start=1):
            ax.scatter(x[ok], table[f"grip{k}"].to_numpy()[ok], c=colour, marker=mark, s=20,
                       label=f"finger {k}: grip along its squeeze direction")
        ax.scatter(x[ok], table["finger_normal_force"].to_numpy()[ok], facecolors="none", edgecolors="k", s=28,
                   label="Σ f·n̂, both fingers (Table III's measure)")
        ax.set_ylabel("force at lift-off (N)" if lifts else "force when the lift test passes (N)")
        ax.set_xlabel(label)
        ax.ticklabel_format(axis="x", useOffset=False)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    fig.suptitle(f"{int(ok.sum())} of {len(ok)} candidates: {_word(lifts)}")
    buf = io.BytesIO()
    fig.savefig(buf, format="png", bbox_inches="tight")
    atomic_write_bytes(path, buf.getvalue())
    return path


def _svg_map(table: Any, lifts: bool = True, width: int = 760, height: int = 360) -> str:
    """Azimuth × height, one circle per candidate, its verdict on hover (an SVG ``<title>``)."""
    if not len(table):
        return ""
    pad = 48
    az = table["azimuth_deg"].to_numpy(float)
    h = 1e3 * table["height"].to_numpy(float)
    a0, a1 = float(az.min()) - 5, float(az.max()) + 5
    h0, h1 = float(h.min()) - 1, float(h.max()) + 1

    def sx(a: float) -> float:
        return pad + (a - a0) / (a1 - a0) * (width - 2 * pad)

    def sy(z: float) -> float:
        return height - pad - (z - h0) / (h1 - h0) * (height - 2 * pad)

    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
             f'style="background:#fafafa;border:1px solid #ddd">']
    for k in range(5):
        a = a0 + (a1 - a0) * k / 4
        z = h0 + (h1 - h0) * k / 4
        parts.append(f'<text x="{sx(a):.1f}" y="{height - pad + 16}" font-size="11" text-anchor="middle">{a:.0f}°</text>')
        parts.append(f'<text x="{pad - 6}" y="{sy(z) + 4:.1f}" font-size="11" text-anchor="end">{z:.0f}</text>')
    parts.append(f'<text x="{width / 2}" y="{height - 8}" font-size="12" text-anchor="middle">azimuth of the squeeze '
                 f'axis</text><text x="12" y="{height / 2}" font-size="12" transform="rotate(-90 12 {height / 2})" '
                 'text-anchor="middle">height (mm)</text>')
    colours = _point_colours(table)
    for (_, r), colour in zip(table.iterrows(), colours):
        if r["grasped"]:
            what = (f"{_word(lifts)} at ρ* = {1e3 * r['rho_star']:.3g} mm; Σ f·n̂ {r['finger_normal_force']:.3g} N, grip "
                    f"{r['grip1']:.3g} / {r['grip2']:.3g} N; w/mg {r['margin']:.3g}")
        else:
            what = f"{r['outcome']}: {r['reason']}"
        tip = (f"candidate {int(r['candidate'])}: nodes {int(r['node_i'])}, {int(r['node_j'])}; azimuth "
               f"{r['azimuth_deg']:.1f}°, tilt {r['tilt_deg']:.1f}°, s = {r['ratio']:g}; {what}")
        radius = 6 if r["grasped"] else 4.5
        parts.append(f'<circle cx="{sx(r["azimuth_deg"]):.1f}" cy="{sy(1e3 * r["height"]):.1f}" r="{radius}" '
                     f'fill="{colour}" stroke="#333" stroke-width="0.5"><title>{html.escape(tip)}</title></circle>')
    parts.append("</svg>")
    return "".join(parts)


# ------------------------------------------------------------------ html
def _g(x: Any, scale: float = 1.0, fmt: str = ".3g") -> str:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return html.escape(str(x))
    return "—" if not math.isfinite(v) else format(v * scale, fmt)


#: The ranked table: (column, header with its unit and the result files' column name, factor from SI or None).
_TABLE = (("rank", "rank", None), ("within_error", "≈ best", None), ("candidate", "#", None),
          ("node_i", "p_i", None), ("node_j", "p_j", None),
          ("azimuth_deg", "azimuth (°)", 1.0), ("tilt_deg", "tilt (°)", 1.0), ("ratio", "s", 1.0),
          ("height", "height (mm)", 1e3), ("outcome", "verdict", None), ("rho_star", "ρ* (mm)", 1e3),
          ("margin", "w/mg", 1.0), ("liftable_max", "w max (N)", 1.0), ("grip1", "grip 1 (N)", 1.0),
          ("grip2", "grip 2 (N)", 1.0), ("finger_normal_force", "Σ f·n̂ (N)", 1.0), ("contacts", "contacts", None),
          ("events", "events", None), ("time", "time (s)", 1.0), ("reason", "reason", None))


#: With an accuracy target, each answer's estimated errors (in %) and the meshes it ran on, after Σ f·n̂.
_ACCURACY_TABLE = (("error_rho_star", "± ρ* (%)", 100.0), ("error_finger_force", "± Σ f·n̂ (%)", 100.0),
                   ("levels", "levels", None))


def _table_html(ranked: Any, accuracy: float | None = None) -> str:
    from .store import FILE_COLUMNS

    columns = _TABLE
    if accuracy is not None:
        at = [c for c, _, _ in _TABLE].index("finger_normal_force") + 1
        columns = _TABLE[:at] + _ACCURACY_TABLE + _TABLE[at:]
    head = "".join(f'<th title="{html.escape(FILE_COLUMNS[c][0]) if c in FILE_COLUMNS else ""}">{html.escape(t)}</th>'
                   for c, t, _ in columns)
    rows = []
    for _, r in ranked.iterrows():
        cells = []
        for col, _, scale in columns:
            v = r.get(col, "")
            if col == "within_error":
                cells.append("<td>≈</td>" if v is True or v == 1 else "<td></td>")
                continue
            if col == "levels":
                cells.append(f"<td>{int(v)}{'' if r.get('converged', False) else ' (not converged)'}</td>"
                             if r["status"] == "ok" else "<td></td>")
                continue
            cells.append(f"<td>{_g(v, scale) if scale is not None else html.escape(str(v))}</td>")
        cls = ("ok near" if r.get("within_error", False) else "ok") if r["grasped"] else \
            ("err" if r["status"] != "ok" else "no")
        rows.append(f'<tr class="{cls}">{"".join(cells)}</tr>')
    return f"<table class=\"ranked\"><tr>{head}</tr>{''.join(rows)}</table>"


def _error_note(result: Any) -> str:
    """What the ≈ marks mean for this search (each answer's own estimated error, or the scene's stated error), in a
    sentence."""
    target = getattr(result, "accuracy", None)
    if target is not None:
        each = (f"Each answer was refined to {100 * target:g} % by the accuracy loop (levels: the meshes it ran on) "
                "and carries its own estimated relative errors of ρ* and Σ f·n̂ (± columns; — when not known, e.g. "
                "when its verdict is not settled: its last two meshes disagree, or it failed with the weight within "
                "the estimated error of what the fingers held).")
        if result.rank_by not in ("force", "squeeze"):
            return each + " The errors cover ρ* and the finger force, not w/mg: no grasp is marked ≈."
        return each + (" ≈ within error of the best: a grasp whose ranking quantity q and the best one's q₁ could be "
                       "equal given each one's own error e and e₁, |q − q₁| ≤ e·|q| + e₁·|q₁|, or whose error is not "
                       "known: it could be the best.")
    e = getattr(result, "expected_error", None)
    if e is None:
        return ("No error is stated for this scene (<code>solver.expected_error</code>), so which grasps are as good "
                "as the best one within the accuracy of this mesh is not known.")
    if result.rank_by not in ("force", "squeeze"):
        return "The stated error covers ρ* and the finger force, not w/mg: no grasp is marked ≈."
    if not math.isfinite(e):
        return ("≈ within error of the best: the scene states that one run on this mesh may even give the wrong "
                "verdict, so every grasp is marked: any of them may be the best.")
    return (f"≈ within error of the best: grasps whose ranking quantity lies within the combined error of the best "
            f"one's (the scene states ±{100 * e:.3g} % for ρ* and the finger force of one run on this mesh): "
            "as good as the best as far as this mesh can tell.")


def _best_html(out: Path, result: Any) -> str:
    if not result.best:
        return "<p>No candidate grasps the object.</p>" if not result.n_grasped else ""
    ranked = result.ranked
    parts = []
    for folder in result.best:
        rank = int(folder.name)
        r = ranked[ranked["rank"] == rank].iloc[0]
        rel = folder.relative_to(out).as_posix()
        pic = f'<img src="{rel}/lifted.png" alt="grasp {rank} lifted">' if (folder / "lifted.png").exists() else ""
        link = (f'<a href="{rel}/report.html">its pickup report</a>' if (folder / "report.html").exists()
                else f'<a href="{rel}/result.json">result.json</a>')
        near = " (≈ within error of the best)" if rank > 1 and r.get("within_error", False) else ""
        acc = ""
        if getattr(result, "accuracy", None) is not None:
            acc = (f" Estimated error (accuracy loop, {int(r['levels'])} meshes, "
                   f"{'converged' if r['converged'] else 'not converged'} to {100 * result.accuracy:g} %): ρ* ±"
                   f"{_g(r['error_rho_star'], 100, '.2g')} %, Σ f·n̂ ±{_g(r['error_finger_force'], 100, '.2g')} %.")
        parts.append(
            f"<figure>{pic}<figcaption><b>Grasp {rank}</b>{near} (candidate {int(r['candidate'])}): nodes "
            f"{int(r['node_i'])} and {int(r['node_j'])}, azimuth {r['azimuth_deg']:.1f}°, tilt {r['tilt_deg']:.1f}°, "
            f"s = {r['ratio']:g}, {1e3 * r['height']:.3g} mm above the table. {_word(result.setup.options.lift).capitalize()} at ρ* = "
            f"{1e3 * r['rho_star']:.3g} mm; grip {r['grip1']:.3g} and {r['grip2']:.3g} N, Σ f·n̂ "
            f"{r['finger_normal_force']:.3g} N (rigid object: {_g(r['rigid_normal_force'])} N), {int(r['contacts'])} "
            f"contact nodes, {int(r['events'])} events.{acc} Full results: {link} (ParaView: "
            f"<code>{rel}/object.pvd</code>).</figcaption></figure>")
    return "\n".join(parts)


def _html(out: Path, result: Any, pictures: list[str]) -> str:
    t = result.table
    n_ok, n_err = result.n_grasped, result.n_errors
    cs = result.candidates
    rejected = ", ".join(f"{k} {v}" for k, v in cs.rejected.items()) or "none"
    s = result.setup
    times = ", ".join(f"{k} {v:.1f} s" for k, v in result.timings.items())
    per = t["time"].to_numpy(float)
    per = per[np.isfinite(per)]
    rows = [
        ("object", f"{s.name}: {len(s.points)} nodes, weight {_g(float(t['weight'].max()) if len(t) else math.nan)} N, "
                   f"E = {_g(s.young)} Pa, ν = {s.poisson:g}; μ_F = {s.options.mu_finger:g}, "
                   f"μ_P = {s.options.mu_table:g}; fingertip radius {_g(s.options.finger_radius, 1e3)} mm"),
        ("candidates", f"{len(t)} evaluated of {cs.valid} valid grid points (seed {cs.seed}); grid points rejected: "
                       f"{rejected}"),
        ("verdicts", f"{n_ok} {_word(s.options.lift)}, {len(t) - n_ok - n_err} not, {n_err} errors"),
        ("engine", f"{result.engine}; {result.resumed} candidates from an earlier run"),
        ("accuracy", "one run of Algorithm 1 per candidate on this mesh" if getattr(result, "accuracy", None) is None
         else f"each candidate refined to {100 * result.accuracy:g} % of ρ* and Σ f·n̂ (the accuracy loop); "
              f"{int(t['converged'].sum()) if len(t) else 0} of {len(t)} converged"),
        ("time", f"{times}; per candidate: median {_g(np.median(per) if len(per) else math.nan)} s"),
    ]
    info = "".join(f"<tr><th>{html.escape(k)}</th><td>{html.escape(v)}</td></tr>" for k, v in rows)
    caps = {"candidates.png": "Each candidate's two initial contacts on the resting object, joined, coloured by ρ* "
                              "when the grasp picks the object up; grey when not (hover the map below for why).",
            "candidates_top.png": "The same from above.",
            "search_plots.png": "ρ* (top) and the fingers' forces at lift-off (bottom) against the height of the "
                                "contacts and the azimuth of the squeeze axis."}
    figs = "\n".join(f'<figure><img src="{n}" alt="{html.escape(caps[n])}"><figcaption>{html.escape(caps[n])}'
                     f"</figcaption></figure>" for n in pictures)
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>fem_grasp search: {html.escape(s.name)}</title>
<style>
body {{ font-family: system-ui, sans-serif; max-width: 1200px; margin: 2em auto; color: #222; }}
table {{ border-collapse: collapse; margin: 1em 0; font-size: 13px; }} th, td {{ border: 1px solid #ccc; padding: 2px 6px; text-align: left; }}
th {{ background: #f4f4f4; }} figure {{ margin: 1.5em 0; }} img {{ max-width: 100%; border: 1px solid #ddd; }}
tr.no td {{ color: #777; }} tr.err td {{ color: #a00; }} tr.near td {{ background: #eef6ee; }} code {{ background: #f4f4f4; padding: 1px 4px; }}
</style></head><body>
<h1>Where to grasp the {html.escape(s.name)}</h1>
<p>Algorithm 1 of <i>Picking up Soft 3D Objects with Two Fingers</i> for every candidate placement: two fingertips
squeeze along (d̂₁, s d̂₂) from the initial contacts p_i, p_j, with the lift test after every increment, then lift.</p>
<table>{info}</table>
<p>Data: <a href="results.parquet">results.parquet</a>, <a href="results.csv">results.csv</a> (one row per candidate),
<a href="search.json">search.json</a> (the scene, the grid, the candidates, the engine).</p>
{figs}
<h2>Map: azimuth × height (hover a point)</h2>
{_svg_map(t, s.options.lift)}
<h2>The best grasps</h2>
{_best_html(out, result)}
<h2>Every candidate, ranked</h2>
<p>Grasps ({html.escape(_word(s.options.lift))}) first, ranked by {html.escape(result.rank_by)}; then the others by how close the
lift test came (w/mg), with their reason; errors last. {_error_note(result)} Lengths in mm, forces in N (the result
files name each column with its unit: <code>height_mm</code>, <code>rho_star_mm</code>, <code>grip1_N</code>, …).</p>
{_table_html(result.ranked, getattr(result, "accuracy", None))}
</body></html>
"""


def write_search_report(out: str | Path, result: Any, pool: Any = None) -> Path:
    """Render the pictures and ``report.html`` of a search (a :class:`~fem_grasp.batch.engine.SearchResult`) into
    its folder ``out``; return the HTML path.  Without pyvista the pictures of the object are left out, without
    matplotlib the report has no plots and no colours.  ``pool``: a :func:`fem_grasp.io.report.render_process`
    to draw in (default: a new one)."""
    out = Path(out)
    pictures: list[str] = []
    if len(result.table):
        try:
            import pyvista  # noqa: F401

            render_candidates(out, result, pool=pool)
            pictures += ["candidates.png", "candidates_top.png"]
        except ImportError:
            log.warning("pyvista is not installed (the 'report' extra: pip install \"fem_grasp[report]\"): the search "
                        "report has no pictures of the object")
        plot_search(result.table, out / "search_plots.png", result.setup.options.lift)
        pictures.append("search_plots.png")
    path = atomic_write_text(out / "report.html", _html(out, result, pictures))
    if (out / MARKER).exists():
        add_to_marker(out, pictures + ["report.html"])
    log.info("wrote %s", path)
    return path
