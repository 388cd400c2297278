"""``report.html`` and its pictures, from an output folder written by :func:`fem_grasp.output.write_run`.

Pictures (PNG, beside report.html):

* ``rest.png``, ``lift_start.png``, ``lifted.png`` — the object at rest, when
  the lift starts, and at the end (lifted, or where the pickup stopped):
  deformed shape (true scale) coloured by displacement magnitude |δ| (mm, one
  colour scale for the three), contact forces on the object as arrows (one
  length scale; red on the fingers, blue on the table), sliding contacts as
  orange dots, the two fingertips (whole spheres) and the table.  Rendered
  off-screen with pyvista in a freshly *spawned* process (VTK aborts in a
  process that has loaded dolfinx; see ``verification/render.py``), from
  plain arrays read back from the time series.
* ``liftable.png`` — the liftable weight w(ρ) of the lift test against the
  object's weight (matplotlib, no pyplot state).
* ``timeline.png`` — every event (A contact, B break, C stick→slip, D
  slip→stick) along the finger path (squeeze depth ρ, then ρ + lift height),
  coloured by the body it concerns, and the number of contacts per body.

Nothing here runs unless a report is asked for (``fem-grasp run --report``
or ``fem-grasp report DIR``).
"""

from __future__ import annotations

import html
import logging
import multiprocessing
import os
from pathlib import Path
from typing import Any

import numpy as np

from .output import MARKER, _add_to_marker, atomic_write_text, read_result

__all__ = ["write_report", "render_frames", "plot_liftable", "plot_timeline", "PICTURES"]

log = logging.getLogger(__name__)

#: The pictures of a report, in the order shown.
PICTURES = ("rest.png", "lift_start.png", "lifted.png", "liftable.png", "timeline.png")

_BODY_COLOURS = {"finger1": "#d62728", "finger2": "#9467bd", "table": "#1f77b4"}


# ------------------------------------------------------------------ frames
def _read_frame(out: Path, frame: dict[str, Any]) -> dict[str, Any]:
    import meshio

    m = meshio.read(out / frame["file"])
    tets = next(c.data for c in m.cells if c.type == "tetra")
    pd = m.point_data
    return {"points": np.asarray(m.points, float), "tets": np.asarray(tets, np.int64),
            "displacement": np.asarray(pd["displacement"], float), "force": np.asarray(pd["contact_force"], float),
            "state": np.asarray(pd["contact_state"]).astype(int), "body": np.asarray(pd["contact_body"]).astype(int)}


def _pick_frames(doc: dict[str, Any]) -> list[tuple[str, str, dict[str, Any]]]:
    frames = doc["series"]["frames"]
    rest = frames[0]
    start = next((f for f in frames if f["label"] == "lift start"), None)
    if start is None:  # no lift: the last squeeze frame
        squeeze = [f for f in frames if f["phase"] in ("squeeze", "rest")]
        start = squeeze[-1]
    final = frames[-1]
    return [("rest.png", "at rest", rest), ("lift_start.png", "lift start" if start["label"] == "lift start"
                                            else "end of the squeeze (no lift)", start),
            ("lifted.png", "lifted" if doc["summary"]["success"] else "where the pickup stopped", final)]


def _centres(doc: dict[str, Any], frame: dict[str, Any]) -> np.ndarray | None:
    res = doc["result"]
    k = frame["snapshot"]
    if k is not None:
        return np.asarray(res["snapshots"][k]["finger_centers"], float)
    if frame["label"] == "rest" and res["snapshots"]:
        return np.asarray(res["snapshots"][0]["finger_centers"], float)
    if res.get("final"):
        return np.asarray(res["final"]["finger_centers"], float)
    return None


def render_frames(out: Path, doc: dict[str, Any], size: tuple[int, int] = (900, 700)) -> list[Path]:
    """Render rest.png, lift_start.png, lifted.png into ``out`` (in a spawned process)."""
    picks = _pick_frames(doc)
    data = [_read_frame(out, f) for _, _, f in picks]
    allp = np.vstack([d["points"] for d in data])
    umax = max(float(np.linalg.norm(d["displacement"], axis=1).max()) for d in data)
    fmax = max(float(np.linalg.norm(d["force"], axis=1).max()) for d in data)
    res = doc["result"]
    jobs = []
    for (name, title, frame), d in zip(picks, data):
        jobs.append({
            **d, "path": str(out / name), "size": tuple(size),
            "title": (f"{doc['scene']['name'] if doc.get('scene') else 'object'}: {title}   "
                      f"rho = {1e3 * frame['squeeze_depth']:.3g} mm, lift = {1e3 * frame['lift_height']:.3g} mm"),
            "centers": _centres(doc, frame), "radius": float(res["finger_radius"]),
            "directions": np.asarray(res["directions"], float), "table_z": float(doc["rest"]["table_z"])
            if doc.get("rest") else 0.0, "lo": allp.min(axis=0), "hi": allp.max(axis=0),
            "umax_mm": 1e3 * umax, "fmax": fmax})
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(1) as pool:
        paths = pool.map(_draw_frame, jobs)
    return [Path(p) for p in paths]


# ------------------------------------------------------------------ child side
def _pyvista() -> Any:
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    pv.OFF_SCREEN = True
    return pv


def _draw_frame(job: dict[str, Any]) -> str:
    from .output import fingertip_surface

    pv = _pyvista()
    pts, tets = job["points"], job["tets"]
    lo, hi = job["lo"], job["hi"]
    diam = float(np.linalg.norm(hi - lo))
    cells = np.hstack([np.full((len(tets), 1), 4), tets]).ravel()
    grid = pv.UnstructuredGrid(cells, np.full(len(tets), pv.CellType.TETRA, dtype=np.uint8), pts)
    label = "|displacement| (mm)"
    grid.point_data[label] = 1e3 * np.linalg.norm(job["displacement"], axis=1)
    try:
        surf = grid.extract_surface(algorithm="dataset_surface")
    except TypeError:  # older pyvista
        surf = grid.extract_surface()
    p = pv.Plotter(off_screen=True, window_size=list(job["size"]))
    p.set_background("white")
    p.add_mesh(surf, scalars=label, cmap="viridis", clim=[0.0, max(job["umax_mm"], 1e-9)], show_edges=True,
               edge_color="#444444", line_width=0.3,
               scalar_bar_args={"color": "black", "title": label, "vertical": False, "position_x": 0.3,
                                "position_y": 0.03, "height": 0.07, "width": 0.4})
    # Table.
    c = 0.5 * (lo + hi)
    span = 1.4 * float(max(hi[0] - lo[0], hi[1] - lo[1]))
    p.add_mesh(pv.Plane(center=(c[0], c[1], job["table_z"]), direction=(0, 0, 1), i_size=span, j_size=span),
               color="#c8b89a", opacity=0.35)
    # Fingertips.
    if job["centers"] is not None:
        for f in range(2):
            hp, tri = fingertip_surface(job["centers"][f], job["radius"], job["directions"][f], 14, 36)
            poly = pv.PolyData(hp, np.hstack([np.full((len(tri), 1), 3), tri]).ravel())
            p.add_mesh(poly, color="#c0c0c0", smooth_shading=True, specular=0.4)
    # Contact forces: arrows ending at the node (the force pushes the object there).
    force, body, state = job["force"], job["body"], job["state"]
    if job["fmax"] > 0:
        scale = 0.3 * diam / job["fmax"]
        for codes, colour in (((1, 2), "#d62728"), ((3,), "#1f77b4")):
            k = np.flatnonzero(np.isin(body, codes) & (np.linalg.norm(force, axis=1) > 1e-6 * job["fmax"]))
            if not len(k):
                continue
            cloud = pv.PolyData(pts[k] - force[k] * scale)
            cloud["v"] = force[k] * scale
            p.add_mesh(cloud.glyph(orient="v", scale="v", factor=1.0, geom=pv.Arrow()), color=colour)
    slide = np.flatnonzero(state == 2)
    if len(slide):
        p.add_points(pts[slide], color="orange", point_size=11, render_points_as_spheres=True)
    p.add_text(job["title"], font_size=11, color="black", position="upper_left")
    p.add_text(f"arrows: forces on the object (red fingers, blue table; longest {job['fmax']:.3g} N); "
               "orange: sliding; true scale", font_size=8, color="#333333",
               position=(12, int(job["size"][1]) - 58))
    # One camera for every picture: oblique, fingers left and right.
    focal = c.copy()
    view = np.array([1.0, 0.12, 0.55])
    view /= np.linalg.norm(view)
    p.camera_position = [tuple(focal + 2.6 * diam * view), tuple(focal), (0.0, 0.0, 1.0)]
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
def _figure(size: tuple[float, float]) -> tuple[Any, Any]:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, dpi=110)
    FigureCanvasAgg(fig)
    return fig, fig.subplots


def _save(fig: Any, path: Path) -> Path:
    import io

    from .output import atomic_write_bytes

    buf = io.BytesIO()
    fig.savefig(buf, format="png", bbox_inches="tight")
    atomic_write_bytes(path, buf.getvalue())
    return path


def plot_liftable(doc: dict[str, Any], path: Path) -> Path:
    """w(ρ) from the lift test against the real weight."""
    fig, subplots = _figure((6.4, 4.0))
    ax = subplots()
    res, summ = doc["result"], doc["summary"]
    lw = np.asarray(res["liftable"], float).reshape(-1, 2)
    weight = float(summ["weight"])
    if len(lw):
        ax.step(1e3 * lw[:, 0], lw[:, 1], where="post", color="#1f77b4", marker=".", ms=3,
                label="liftable weight w(ρ) (lift test)")
    ax.axhline(weight, color="#d62728", ls="--", label=f"weight mg = {weight:.3g} N")
    rho = float(summ["squeeze_depth"])
    ax.axvline(1e3 * rho, color="0.4", ls=":", label=f"squeeze stops, ρ = {1e3 * rho:.3g} mm")
    ax.set_xlim(left=0)
    ax.set_xlabel("squeeze depth ρ (mm)")
    ax.set_ylabel("weight (N)")
    ax.set_ylim(bottom=0, top=max(1.25 * weight, float(lw[:, 1].max()) * 1.05 if len(lw) else 0))
    ax.set_title("Lift test: the fingers lift once w(ρ) ≥ mg" + ("" if len(lw) else " (no lift test ran)"))
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)
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


# ------------------------------------------------------------------ html
def _row(k: str, v: Any) -> str:
    return f"<tr><th>{html.escape(k)}</th><td>{html.escape(str(v))}</td></tr>"


def _accuracy_html(acc: dict[str, Any] | None) -> str:
    """The levels of ``pickup(..., accuracy=...)`` (:func:`fem_grasp.accuracy.converged_pickup`), as a table."""
    if not acc:
        return ""

    def change(lv: dict[str, Any]) -> str:
        c = lv.get("change")
        return "—" if not c else f"{100 * c['squeeze_depth']:.2g} % / {100 * c['finger_force']:.2g} %"

    rows = "".join(
        f"<tr><td>{lv['level']}</td><td>{lv['vertices']:,}</td><td>{1e3 * lv['inner_size']:.3g}</td>"
        f"<td>{1e3 * lv['outer_size']:.3g}</td><td>{1e3 * lv['step']:.3g}</td><td>{lv['lift_test_step']:.3g}</td>"
        f"<td>{'picked up' if lv['success'] else 'not picked up'}</td><td>{1e3 * lv['squeeze_depth']:.4g}</td>"
        f"<td>{lv['finger_force']:.4g}</td>"
        f"<td>{lv['finger_nodes'][0]} / {lv['finger_nodes'][1]} / {lv['table_nodes']}</td>"
        f"<td>{change(lv)}</td><td>{lv['seconds'] + lv['mesh_seconds']:.1f}</td></tr>" for lv in acc["levels"])
    return (f"<h2>Accuracy: {'converged' if acc['converged'] else 'NOT converged'} "
            f"(target {100 * acc['target']:g} %)</h2><p>{html.escape(acc.get('note', ''))}. Each level remeshes "
            f"{html.escape(acc.get('geometry', ''))} with half the spacing at the contact patches and halves the "
            "squeeze increment and the lift-test step h; the estimated error is the difference of the last two "
            "levels.</p>"
            "<table><tr><th>level</th><th>vertices</th><th>spacing at the patches (mm)</th><th>outer (mm)</th>"
            "<th>increment (mm)</th><th>h (N)</th><th>verdict</th><th>ρ* (mm)</th><th>finger force (N)</th>"
            "<th>contacts finger 1 / 2 / table</th><th>change of ρ* / force</th><th>s</th></tr>"
            f"{rows}</table>")


def _html(doc: dict[str, Any]) -> str:
    s, res, scene = doc["summary"], doc["result"], doc.get("scene") or {}
    ok = s["success"]
    verdict = "picked up" if ok else "not picked up"
    g = lambda x, scale=1.0, fmt=".4g": "—" if x is None else format(x * scale, fmt)  # noqa: E731
    rows = [
        _row("object", f"{scene.get('name', '?')}{' (quick variant)' if scene.get('quick') else ''}: "
                       f"{s['n_nodes']} nodes, {s['n_tets']} tetrahedra"),
        _row("material", f"E = {g(scene.get('young'))} Pa, ν = {scene.get('poisson')}, weight {g(s['weight'])} N"),
        _row("friction", f"μ_F = {res['mu_finger']} (fingers), μ_P = {res['mu_table']} (table)"),
        _row("fingers", f"radius {g(res['finger_radius'], 1e3)} mm, initial contacts {res['finger_nodes']}, "
                        f"ratio s = {res['ratio']}"),
        _row("verdict", verdict + ("" if ok else f": {s['reason']}")),
        _row("squeeze depth ρ", f"{g(s['squeeze_depth'], 1e3)} mm (maximum {g(res['max_squeeze'], 1e3)} mm, "
                                f"increment {g(res['step'], 1e3)} mm)"),
        _row("liftable weight", f"up to {g(s['max_liftable_weight'])} N against weight {g(s['weight'])} N"),
        _row("final contacts", s["n_final_contacts"]),
        _row("finger normal force", f"{g(s['finger_normal_force'])} N (deformable); rigid object, same contacts: "
                                    f"{g(s['rigid_total_normal_force'])} N (paper, Table III)"),
        _row("events", ", ".join(f"{k}: {v}" for k, v in s["event_counts"].items())),
        _row("resting state", "—" if not doc.get("rest") else
             f"{doc['rest']['n_contacts']} table contacts ({doc['rest']['n_sliding']} sliding), max sag "
             f"{g(doc['rest']['max_sag'], 1e3)} mm" + (" (from cache)" if doc.get("rest_from_cache") else "")),
        _row("time", ", ".join(f"{k} {v:.2f} s" for k, v in s["timings"].items())),
    ]
    acc_html = _accuracy_html(doc.get("accuracy"))
    if doc.get("accuracy"):
        e = doc["accuracy"]["estimated_error"]
        pct = lambda x: "unknown" if x is None else f"{100 * x:.2g} %"  # noqa: E731
        rows.insert(5, _row("accuracy", f"target {100 * doc['accuracy']['target']:g} %: estimated error of ρ* "
                                        f"{pct(e.get('squeeze_depth'))}, of the finger force {pct(e.get('finger_force'))}"
                                        f" — {'converged' if doc['accuracy']['converged'] else 'NOT converged'}"))
    pics = {
        "rest.png": "At rest on the table (fingertips drawn where they first touch).",
        "lift_start.png": "When the lift test passes and the fingers start to lift (or where the squeeze stopped).",
        "lifted.png": "At the end: lifted off the table, or where the pickup stopped.",
        "liftable.png": "Liftable weight w(ρ) of the lift test against the object's weight.",
        "timeline.png": "Events along the finger path and contact nodes per body.",
    }
    figs = "\n".join(f'<figure><img src="{n}" alt="{html.escape(c)}"><figcaption>{html.escape(c)}</figcaption></figure>'
                     for n, c in pics.items())
    ev_rows = "".join(f"<tr><td>{i}</td><td>{e['phase']}</td><td>{e['kind']}</td><td>{e['contact']}</td>"
                      f"<td>{e['node']}</td><td>{1e3 * e['squeeze_depth']:.4g}</td><td>{1e3 * e['lift_height']:.4g}</td></tr>"
                      for i, e in enumerate(res["events"][:500]))
    more = f"<p>… and {len(res['events']) - 500} more in result.json.</p>" if len(res["events"]) > 500 else ""
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>fem_grasp: {html.escape(scene.get('name', 'result'))}</title>
<style>
body {{ font-family: system-ui, sans-serif; max-width: 1000px; margin: 2em auto; color: #222; }}
h1 .ok {{ color: #2a7d2a; }} h1 .fail {{ color: #b22222; }}
table {{ border-collapse: collapse; margin: 1em 0; }} th, td {{ border: 1px solid #ccc; padding: 3px 8px; text-align: left; }}
th {{ background: #f4f4f4; }} figure {{ margin: 1.5em 0; }} img {{ max-width: 100%; border: 1px solid #ddd; }}
code {{ background: #f4f4f4; padding: 1px 4px; }}
</style></head><body>
<h1>{html.escape(scene.get('name', 'pickup'))}: <span class="{'ok' if ok else 'fail'}">{verdict}</span></h1>
<p>{html.escape(scene.get('description', ''))}</p>
<table>{''.join(rows)}</table>
<p>Data: <a href="result.json">result.json</a> (schema {doc['schema']} v{doc['schema_version']}).
ParaView: open <code>object.pvd</code>, <code>finger1.pvd</code>, <code>finger2.pvd</code> and <code>table.vtu</code>;
colour by <code>contact_state</code> (0 none, 1 stick, 2 slip) or <code>displacement</code>, glyph <code>contact_force</code>.</p>
{acc_html}
{figs}
<h2>Events</h2>
<table><tr><th>#</th><th>phase</th><th>kind</th><th>body</th><th>node</th><th>ρ (mm)</th><th>lift (mm)</th></tr>
{ev_rows}</table>{more}
<p style="color:#777">fem_grasp {html.escape(str(doc.get('fem_grasp_version')))}, {html.escape(str(doc.get('created')))}</p>
</body></html>
"""


def write_report(out: str | Path) -> Path:
    """Render the pictures and ``report.html`` into the output folder ``out``; return the HTML path.

    Raises
    ------
    fem_grasp.output.OutputError
        No (readable) result.json in ``out``.
    """
    out = Path(out)
    doc = read_result(out)
    if not doc.get("series") or not doc["series"].get("frames"):
        from .output import OutputError

        raise OutputError(f"{out}/result.json has no time series to draw")
    render_frames(out, doc)
    plot_liftable(doc, out / "liftable.png")
    plot_timeline(doc, out / "timeline.png")
    path = atomic_write_text(out / "report.html", _html(doc))
    if (out / MARKER).exists():
        _add_to_marker(out, list(PICTURES) + ["report.html"])
    log.info("wrote %s", path)
    return path
