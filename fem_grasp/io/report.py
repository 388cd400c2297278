"""``report.html`` and its pictures, from an output folder written by :func:`fem_grasp.io.output.write_run`.

Pictures (PNG, beside report.html):

* ``rest.png``, ``lift_start.png``, ``lifted.png`` — the object at rest, when
  the lift starts, and at the end.  The deformed shape (true scale) is
  coloured per tetrahedron by the von Mises stress (kPa; or the strain energy
  density, J/m³, or the displacement less its rigid motion, mm:
  :data:`COLOURINGS`), one colour scale for the three pictures.  Contact
  forces on the object are arrows pointing at their nodes from outside the
  object (one length scale; red on the fingers, blue on the table); every
  contact node is a dot, green when it sticks and orange when it slides, with
  a legend.  The fingertips are drawn translucent, so that the arrows and
  dots on their patches show through them.  The camera looks across the
  squeeze axis from 30° above (:func:`view_direction`), the same for the
  three pictures, so that neither fingertip is behind the object.  After a
  successful pickup
  ``lifted.png`` shows the object and the fingers raised a further
  :data:`LIFTED_CLEARANCE` × the object's height above the lift-off state, off
  the table: once the table lets go, raising the fingers moves the hanging
  object rigidly (its shape and forces do not change), so the picture is the
  computed state, translated.
* ``patches.png`` — a close-up of each finger's contact patch when the lift
  starts and at the end, seen along the finger's squeeze direction: the
  contact nodes (stick / slip), their normal forces (mN, written beside each
  node and as the dot's size) and their tangential forces (arrows).
* ``liftable.png`` — the liftable weight w(ρ) of the lift test against the
  object's weight (matplotlib, no pyplot state).
* ``timeline.png`` — every event (A contact, B break, C stick→slip, D
  slip→stick) along the finger path (squeeze depth ρ, then ρ + lift height),
  coloured by the body it concerns, and the number of contacts per body.

The 3D views are rendered off-screen with pyvista in a freshly *spawned*
process (VTK aborts in a process that has loaded dolfinx; see
``verification/_common/render.py``), from plain arrays read back from the time series.
Nothing here runs unless a report is asked for (``fem-grasp run --report``
or ``fem-grasp report DIR``).
"""

from __future__ import annotations

import contextlib
import html
import logging
import multiprocessing
import os
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from .output import MARKER, add_to_marker, atomic_write_text, read_result

__all__ = ["COLOURINGS", "LIFTED_CLEARANCE", "PICTURES", "VIEW_ELEVATION", "bar_title_above", "plot_liftable", "plot_patches",
           "plot_timeline", "render_frames", "render_process", "render_views", "view_direction", "write_report"]

log = logging.getLogger(__name__)

#: The pictures of a report, in the order shown.
PICTURES = ("rest.png", "lift_start.png", "lifted.png", "patches.png", "liftable.png", "timeline.png")
#: What the 3D views can be coloured by: (field in the time series, label with its unit, factor from SI).
COLOURINGS = {
    "von_mises": ("von_mises", "von Mises stress (kPa)", 1e-3),
    "energy": ("strain_energy_density", "strain energy density (J/m^3)", 1.0),
    "elastic": ("elastic_displacement", "|displacement less its rigid motion| (mm)", 1e3),
    "displacement": ("displacement", "|displacement| (mm)", 1e3),
}
#: ``lifted.png`` shows a picked-up object this far (× its height) above its lift-off state.
LIFTED_CLEARANCE = 0.25
#: Stick and slip dots.
_STICK, _SLIP = "#2ca02c", "#ff7f0e"

_BODY_COLOURS = {"finger1": "#d62728", "finger2": "#9467bd", "table": "#1f77b4"}


# ------------------------------------------------------------------ frames
def _read_frame(out: Path, frame: dict[str, Any], doc: dict[str, Any] | None = None) -> dict[str, Any]:
    import meshio

    m = meshio.read(out / frame["file"])
    tets = next(c.data for c in m.cells if c.type == "tetra")
    pd = m.point_data
    cd = {k: np.asarray(v[0], float) for k, v in m.cell_data.items()}
    points = np.asarray(m.points, float)
    disp = np.asarray(pd["displacement"], float)
    if "von_mises" not in cd or "elastic_displacement" not in pd:  # a series written before these fields
        from .output import mechanics_fields

        scene = (doc or {}).get("scene") or {}
        extra_pd, extra_cd = mechanics_fields(points - disp, np.asarray(tets, np.int64), disp,
                                              float(scene.get("young") or 1.0), float(scene.get("poisson") or 0.3))
        pd = {**extra_pd, **pd}
        cd = {**extra_cd, **cd}
    return {"points": points, "tets": np.asarray(tets, np.int64), "displacement": disp,
            "elastic_displacement": np.asarray(pd["elastic_displacement"], float),
            "von_mises": cd["von_mises"], "strain_energy_density": cd["strain_energy_density"],
            "force": np.asarray(pd["contact_force"], float),
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


@contextlib.contextmanager
def render_process() -> Iterator[Any]:
    """One spawned process for several reports' 3-D pictures (module notes): pass it as ``pool`` to
    :func:`write_report` (a placement search draws its best grasps and its candidates in one), saving each
    report the start of a process and of VTK's renderer (about 3 s)."""
    from ..spawn import check_main_guard

    check_main_guard("rendering a report's pictures (pyvista, in a spawned process)")
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(1) as pool:
        yield pool


def _map(pool: Any, fn: Any, jobs: list[dict[str, Any]]) -> list[Any]:
    """``fn`` over ``jobs`` in ``pool``, or in a freshly spawned process when ``pool`` is None."""
    if pool is not None:
        return pool.map(fn, jobs)
    with render_process() as own:
        return own.map(fn, jobs)


#: How far (degrees) the 3D views look down from the horizontal.
VIEW_ELEVATION = 30.0


def view_direction(centres: Any, elevation: float = VIEW_ELEVATION) -> np.ndarray:
    """The unit vector from the object towards the camera of the 3D views: perpendicular to the line between
    the two fingertip centres (so that neither fingertip nor its contact patch is behind the object: they are
    seen left and right of it), tilted ``elevation`` degrees up from the horizontal (the camera looks down on
    the object).  Without centres (no fingers placed) an oblique view from +x, +y."""
    up = np.array([0.0, 0.0, 1.0])
    if centres is None:
        v = np.array([1.0, 0.3, 0.4])
        return v / np.linalg.norm(v)
    c = np.asarray(centres, float)
    axis = c[1] - c[0]
    n = float(np.linalg.norm(axis))
    if not n > 0:
        axis, n = np.array([0.0, 1.0, 0.0]), 1.0
    u = axis / n
    vertical = up - (up @ u) * u  # "up" within the plane perpendicular to the axis
    if np.linalg.norm(vertical) < 1e-6:  # fingers one above the other: any horizontal view will do
        vertical = np.array([1.0, 0.0, 0.0]) - u[0] * u
    vertical /= np.linalg.norm(vertical)
    side = np.cross(u, vertical)  # horizontal-ish, perpendicular to the axis
    if side @ np.array([1.0, 0.3, 0.0]) < 0:  # of the two sides, the one nearer the usual oblique view
        side = -side
    t = np.radians(elevation)
    v = np.cos(t) * side + np.sin(t) * vertical
    return v / np.linalg.norm(v)


def render_views(out: Path, doc: dict[str, Any], size: tuple[int, int] = (1000, 760),
                 colour: str = "von_mises", pool: Any = None) -> list[dict[str, Any]]:
    """Render rest.png, lift_start.png and lifted.png into ``out`` (in a spawned process, module notes).

    ``colour`` is a key of :data:`COLOURINGS`.  Returns, per picture, what was drawn: ``path``, ``lift_offset``
    (m, how far ``lifted.png`` is drawn above the computed lift-off state), ``table_gap`` (m, the drawn object's
    lowest point above the table), ``arrows`` (per finger-force arrow: its node, tip and tail in 3D,
    ``head_px`` and ``shaft_px``, the middle of its head and a point of its shaft in pixels from the top left, and
    ``length`` in metres), ``fingertips`` (centre and radius), ``legend`` (its labels), ``n_stick`` and
    ``n_slip`` (contact dots of each colour), ``colour`` (the scalar bar's title), ``clim``, ``camera`` and
    ``focal`` (the camera's position and focal point, :func:`view_direction`), ``title`` and ``note`` (the
    picture's heading and its small print).  ``pool``: a
    :func:`render_process` to draw in (default: a new one).
    """
    if colour not in COLOURINGS:
        raise ValueError(f"colour must be one of {', '.join(COLOURINGS)}, got {colour!r}")
    picks = _pick_frames(doc)
    data = [_read_frame(out, f, doc) for _, _, f in picks]
    res = doc["result"]
    table_z = float(doc["rest"]["table_z"]) if doc.get("rest") else 0.0
    height = float(np.ptp(data[0]["points"][:, 2]))
    field, label, factor = COLOURINGS[colour]
    values = []
    for d in data:
        v = d[field]
        values.append(factor * (np.linalg.norm(v, axis=1) if v.ndim == 2 else v))
    # Point contacts concentrate stress in a few elements, and the resting state is ten times less loaded than
    # the squeezed one: stresses and energies get a logarithmic scale from the 2nd to the 99.5th percentile
    # (the few elements outside it take the end colours), so that the rest of the body is not one colour.
    log_scale = colour in ("von_mises", "energy")
    every = np.concatenate(values)
    if log_scale:
        positive = every[every > 0]
        lo_v, top = ((float(np.percentile(positive, 2.0)), float(np.percentile(positive, 99.5)))
                     if len(positive) else (1e-12, 1.0))
        lo_v = min(lo_v, top / 10.0)
        label = label.replace(")", ", log scale)")
        values = [np.clip(v, lo_v, None) for v in values]
    else:
        lo_v, top = 0.0, float(every.max())
    offsets = []
    for (name, _, frame), d in zip(picks, data):
        lifted = name == "lifted.png" and doc["summary"]["success"]
        offsets.append(LIFTED_CLEARANCE * height if lifted else 0.0)
    allp = np.vstack([d["points"] + [0.0, 0.0, o] for d, o in zip(data, offsets)])
    fmax = max(float(np.linalg.norm(d["force"], axis=1).max()) for d in data)
    # One camera for the three pictures, perpendicular to the squeeze axis (the lift start's fingertips, or the
    # first placed ones), so that the pictures compare and both fingertips are seen.
    centres = [_centres(doc, f) for _, _, f in picks]
    axis_centres = next((c for c in (centres[1], centres[0], centres[2]) if c is not None), None)
    view = view_direction(axis_centres)
    jobs = []
    name_of = doc["scene"]["name"] if doc.get("scene") else "object"
    for (name, title, frame), d, v, off, cen in zip(picks, data, values, offsets, centres):
        rho, lift = 1e3 * frame["squeeze_depth"], 1e3 * frame["lift_height"]
        if off:  # the lifted picture: the computed lift-off state, raised further (a rigid move) to be seen
            head = f"{name_of}: {title}   rho = {rho:.3g} mm, fingers raised {lift + 1e3 * off:.3g} mm"
            note = (f"the table let go at {lift:.3g} mm; drawn {1e3 * off:.3g} mm higher to show the gap (the "
                    "hanging object moves rigidly)")
        else:
            head = (f"{name_of}: {title}   rho = {rho:.3g} mm" + (f", fingers raised {lift:.3g} mm" if lift > 0
                                                                 else ""))
            note = ""
        jobs.append({
            **d, "values": v, "label": label, "clim": (lo_v, max(top, 1e-12)), "log_scale": log_scale,
            "offset": off, "note": note, "view": view,
            "path": str(out / name), "size": tuple(size),
            "title": head,
            "centers": cen, "radius": float(res["finger_radius"]),
            "directions": np.asarray(res["directions"], float), "table_z": table_z,
            "lo": allp.min(axis=0), "hi": allp.max(axis=0), "fmax": fmax})
    return _map(pool, _draw_frame, jobs)


def render_frames(out: Path, doc: dict[str, Any], size: tuple[int, int] = (1000, 760),
                  colour: str = "von_mises", pool: Any = None) -> list[Path]:
    """Render rest.png, lift_start.png, lifted.png into ``out``; their paths (:func:`render_views`)."""
    return [Path(v["path"]) for v in render_views(out, doc, size, colour, pool)]


# ------------------------------------------------------------------ child side
def _pyvista() -> Any:
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    pv.OFF_SCREEN = True
    return pv


def bar_title_above(p: Any, title: str, x: float, top: float, size: Any) -> None:
    """Move a horizontal scalar bar's title above its tick labels (VTK centres it over the bar, where it overlaps
    the middle label): the bar's own title is blanked and the same words written a line higher, left-aligned."""
    bar = p.scalar_bars[title]
    bar.SetTitle("")
    width, height = (int(v) for v in size)
    p.add_text(title, position=(int(x * width), int(top * height) + 6), font_size=10, color="black")


def _draw_frame(job: dict[str, Any]) -> dict[str, Any]:
    from .output import fingertip_surface

    pv = _pyvista()
    lift = np.array([0.0, 0.0, job["offset"]])
    pts, tets = job["points"] + lift, job["tets"]
    lo, hi = job["lo"], job["hi"]
    diam = float(np.linalg.norm(hi - lo))
    cells = np.hstack([np.full((len(tets), 1), 4), tets]).ravel()
    grid = pv.UnstructuredGrid(cells, np.full(len(tets), pv.CellType.TETRA, dtype=np.uint8), pts)
    label = job["label"]
    if len(job["values"]) == len(tets):
        grid.cell_data[label] = job["values"]
    else:
        grid.point_data[label] = job["values"]
    try:
        surf = grid.extract_surface(algorithm="dataset_surface")
    except TypeError:  # older pyvista
        surf = grid.extract_surface()
    p = pv.Plotter(off_screen=True, window_size=list(job["size"]))
    p.set_background("white")
    p.add_mesh(surf, scalars=label, cmap="viridis", clim=list(job["clim"]), show_edges=True, log_scale=job["log_scale"],
               edge_color="#555555", line_width=0.3,
               scalar_bar_args={"color": "black", "title": label, "vertical": False, "position_x": 0.06,
                                "position_y": 0.03, "height": 0.07, "width": 0.5, "fmt": "%.3g",
                                "title_font_size": 14, "label_font_size": 12})
    bar_title_above(p, label, 0.06, 0.03 + 0.07, job["size"])
    # Table, and the object's shadow straight below it (so that a lifted object is seen off the table).
    c = 0.5 * (lo + hi)
    span = 1.4 * float(max(hi[0] - lo[0], hi[1] - lo[1]))
    p.add_mesh(pv.Plane(center=(c[0], c[1], job["table_z"]), direction=(0, 0, 1), i_size=span, j_size=span),
               color="#c8b89a", opacity=0.35)
    from scipy.spatial import ConvexHull

    ring = pts[ConvexHull(pts[:, :2]).vertices]
    ring[:, 2] = job["table_z"] + 1e-4 * diam
    shadow = pv.PolyData(ring, np.hstack([[len(ring)], np.arange(len(ring))]))
    p.add_mesh(shadow.triangulate(), color="#3a3a3a", opacity=0.25, lighting=False)
    # Fingertips: translucent, so that the arrows and contact dots on their patches show through.
    fingertips = []
    if job["centers"] is not None:
        for f in range(2):
            centre = np.asarray(job["centers"][f], float) + lift
            hp, tri = fingertip_surface(centre, job["radius"], job["directions"][f], 14, 36)
            poly = pv.PolyData(hp, np.hstack([np.full((len(tri), 1), 3), tri]).ravel())
            p.add_mesh(poly, color="#9a9a9a", opacity=0.3, smooth_shading=True,
                       silhouette={"color": "#555555", "line_width": 1.5})
            fingertips.append({"center": centre.tolist(), "radius": float(job["radius"])})
    # Contact forces on the object: arrows from outside the object pointing at their nodes.
    force, body, state = job["force"], job["body"], job["state"]
    arrows: list[dict[str, Any]] = []
    legend = []
    if job["fmax"] > 0:
        # the longest arrow spans 1.2 fingertip radii: it ends at its node inside the translucent fingertip
        scale = min(0.3 * diam, 1.2 * float(job["radius"])) / job["fmax"]
        for codes, colour, name in (((1, 2), "#d62728", "finger force on the object"),
                                    ((3,), "#1f77b4", "table force on the object")):
            k = np.flatnonzero(np.isin(body, codes) & (np.linalg.norm(force, axis=1) > 1e-6 * job["fmax"]))
            if not len(k):
                continue
            tails = pts[k] - force[k] * scale
            cloud = pv.PolyData(tails)
            cloud["v"] = force[k] * scale
            p.add_mesh(cloud.glyph(orient="v", scale="v", factor=1.0,
                                   geom=pv.Arrow(tip_length=0.3, tip_radius=0.12, shaft_radius=0.04)), color=colour)
            legend.append((name, colour))
            if codes == (1, 2):
                arrows += [{"node": int(n), "tip": pts[n].tolist(), "tail": t.tolist(),
                            "length": float(np.linalg.norm(pts[n] - t))} for n, t in zip(k, tails)]
    # Stick and slip, node by node.
    counts = {}
    for code, colour, name in ((1, _STICK, "contact sticks"), (2, _SLIP, "contact slides")):
        k = np.flatnonzero(state == code)
        counts[code] = len(k)
        if len(k):
            p.add_points(pts[k], color=colour, point_size=12, render_points_as_spheres=True)
            legend.append((f"{name} ({len(k)})", colour))
    # The legend, one coloured line per entry at the lower right (text actors: VTK's legend box clips long labels).
    width, height_px = (int(x) for x in job["size"])
    for i, (name, colour) in enumerate(reversed(legend)):
        p.add_text(name, position=(int(0.66 * width), 18 + 22 * i), font_size=10, color=colour)
    p.add_text(job["title"], font_size=11, color="black", position="upper_left")
    lines = [f"arrows: contact forces on the object, pointing at their nodes (longest {job['fmax']:.3g} N); "
             "fingertips translucent; shape at true scale"]
    if job["note"]:
        lines.append(job["note"])
    p.add_text("\n".join(lines), font_size=8, color="#333333", position=(12, int(job["size"][1]) - 70))
    # One camera for every picture (view_direction): perpendicular to the squeeze axis, looking down.
    focal = c.copy()
    view = np.asarray(job["view"], float)
    camera = focal + 2.6 * diam * view
    p.camera_position = [tuple(camera), tuple(focal), (0.0, 0.0, 1.0)]
    p.camera.view_angle = 30.0
    final = Path(job["path"])
    tmp = final.with_name(f".{final.stem}.{os.getpid()}.tmp.png")
    try:
        p.screenshot(str(tmp))
        ren = p.renderer
        for a in arrows:  # where each arrowhead (its middle, 20 % of the arrow behind the tip) and shaft (40 % from
            tip, tail = np.asarray(a["tip"]), np.asarray(a["tail"])  # the tail) are on the picture
            for key, q in (("head_px", tip - 0.2 * (tip - tail)), ("shaft_px", tail + 0.4 * (tip - tail))):
                ren.SetWorldPoint(*q, 1.0)
                ren.WorldToDisplay()
                x, y, _ = ren.GetDisplayPoint()
                a[key] = [float(x), float(height_px - y)]
        os.replace(tmp, final)
    finally:
        p.close()
        tmp.unlink(missing_ok=True)
    return {"path": str(final), "lift_offset": float(job["offset"]),
            "table_gap": float(pts[:, 2].min() - job["table_z"]), "arrows": arrows, "fingertips": fingertips,
            "legend": [n for n, _ in legend], "n_stick": counts[1], "n_slip": counts[2], "colour": label,
            "clim": [float(x) for x in job["clim"]], "camera": camera.tolist(), "focal": focal.tolist(),
            "title": job["title"], "note": job["note"]}


# ------------------------------------------------------------------ plots
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


def plot_patches(out: Path, doc: dict[str, Any], path: Path) -> Path:
    """Close-ups of the two contact patches when the lift starts and at the end (module notes)."""
    picks = [(title, frame) for name, title, frame in _pick_frames(doc) if name != "rest.png"]
    res = doc["result"]
    radius = float(res["finger_radius"])
    directions = np.asarray(res["directions"], float)
    fig, subplots = _figure((9.6, 4.6 * len(picks)))
    axes = np.atleast_2d(subplots(len(picks), 2))
    for row, (title, frame) in enumerate(picks):
        d = _read_frame(out, frame, doc)
        centres = _centres(doc, frame)
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
            size = 30 + 250 * np.clip(fn, 0, None) / max(float(fn.max()), 1e-300)
            for mask, colour, name in ((~slide, _STICK, "sticks"), (slide, _SLIP, "slides")):
                if mask.any():
                    ax.scatter(u[mask], v[mask], s=size[mask], color=colour, edgecolor="black", lw=0.5, zorder=3,
                               label=f"contact node {name} ({int(mask.sum())})")
            tmax = max(float(np.linalg.norm(ft, axis=1).max()), 1e-300)
            ax.quiver(u, v, ft @ eu, ft @ ev, color="#d62728", zorder=4, angles="xy", scale_units="xy",
                      scale=tmax / (0.35e3 * radius), width=0.006, label="tangential force (longest: 0.35 R)")
            ax.text(0.02, 0.02, f"longest tangential force {1e3 * tmax:.3g} mN", transform=ax.transAxes, fontsize=7)
            for x, y, val in zip(u, v, fn):
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
                 "numbers and dot sizes: normal force f·n̂ on the object (mN); arrows: tangential force", fontsize=10)
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


def _accuracy_state(acc: dict[str, Any]) -> str:
    """The accuracy of an answer in plain words: converged to its target, one run on its mesh, or an error
    estimate above the target."""
    target = acc.get("target")
    goal = "" if target is None or not np.isfinite(target) else f"{100 * target:g} %"
    if acc["converged"]:
        return f"converged to {goal}" if goal else "converged"
    if len(acc["levels"]) == 1:
        e = (acc.get("estimated_error") or {}).get("squeeze_depth")
        if not acc.get("expected_error_stated", True) or e is None:
            return "one run on this mesh, its error not known"
        if not np.isfinite(e):
            return "one run on this mesh, whose verdict may differ from a finer mesh's"
        return f"one run on this mesh, within about {100 * e:.2g} % (the scene's convergence study)"
    return f"the error estimate is above the requested {goal}" if goal else "the error estimate is above the target"


def _accuracy_html(acc: dict[str, Any] | None) -> str:
    """The levels of ``pickup(..., accuracy=...)`` (:func:`fem_grasp.grasp.accuracy.converged_pickup`), as a table."""
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
    return (f"<h2>Accuracy: {html.escape(_accuracy_state(acc))}</h2>"
            f"<p>{html.escape(acc.get('note', ''))}. Each level remeshes "
            f"{html.escape(acc.get('geometry', '') or 'the object')} with half the spacing at the contact patches and "
            "halves the squeeze increment and the lift-test step h; the estimated error is the difference of the last "
            "two levels.</p>"
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
        _row("verdict", verdict + ("" if ok else f": {s['reason']}")
             if s.get("outcome") != "lift not run" else
             f"lift test passed at ρ = {g(s['squeeze_depth'], 1e3)} mm; lift not simulated"),
        _row("squeeze depth ρ", f"{g(s['squeeze_depth'], 1e3)} mm (maximum {g(res['max_squeeze'], 1e3)} mm, "
                                f"increment {g(res['step'], 1e3)} mm)"),
        _row("liftable weight", f"up to {g(s['max_liftable_weight'])} N against weight {g(s['weight'])} N"),
        _row("final contacts", s["n_final_contacts"]),
        _row("Table III", f"Σ f·n̂ over both fingers {g(s['finger_normal_force'])} N (deformable); rigid object, "
                          f"same contacts: {g(s['rigid_total_normal_force'])} N (the measure Table III compares)"),
        _row("events", ", ".join(f"{k}: {v}" for k, v in s["event_counts"].items())),
        _row("resting state", "—" if not doc.get("rest") else
             f"{doc['rest']['n_contacts']} table contacts ({doc['rest']['n_sliding']} sliding), max sag "
             f"{g(doc['rest']['max_sag'], 1e3)} mm" + (" (from cache)" if doc.get("rest_from_cache") else "")),
        _row("time", ", ".join(f"{k} {v:.2f} s" for k, v in s["timings"].items())),
    ]
    acc_html = _accuracy_html(doc.get("accuracy"))
    if doc.get("accuracy"):
        acc = doc["accuracy"]
        e = acc["estimated_error"]
        pct = lambda x: "unknown" if x is None or not np.isfinite(x) else f"{100 * x:.2g} %"  # noqa: E731
        rows.insert(5, _row("accuracy", f"{_accuracy_state(acc)}: estimated error of ρ* "
                                        f"{pct(e.get('squeeze_depth'))}, of the finger force "
                                        f"{pct(e.get('finger_force'))}"))
    lifted = ("At the end: lifted off the table, drawn a little above the lift-off state (raising the fingers "
              "further moves the hanging object rigidly)." if ok else "At the end: where the pickup stopped.")
    pics = {
        "rest.png": "At rest on the table (fingertips drawn where they first touch). Colour: per tetrahedron "
                    "(scale below the picture); arrows: contact forces on the object; dots: contact nodes, green "
                    "sticking, orange sliding.",
        "lift_start.png": "When the lift test passes and the fingers start to lift (or where the squeeze stopped).",
        "lifted.png": lifted,
        "patches.png": "Each finger's contact patch seen along its squeeze direction: contact nodes sticking or "
                       "sliding, normal forces (mN) and tangential forces.",
        "liftable.png": "Liftable weight w(ρ) of the lift test against the object's weight.",
        "timeline.png": "Events along the finger path and contact nodes per body.",
    }
    forces = s.get("finger_forces") or {}
    force_rows = "".join(
        f"<tr><td>{html.escape(name.replace('finger', 'finger '))}</td>"
        f"<td>({', '.join(format(x, '.4g') for x in f['resultant'])})</td><td>{f['magnitude']:.4g}</td>"
        f"<td>{f['grip']:.4g}</td><td>{f['vertical']:.4g}</td><td>{f['normal_sum']:.4g}</td><td>{f['contacts']}</td></tr>"
        for name, f in forces.items())
    when = "at lift-off" if ok else ("when the lift test passed" if s.get("outcome") == "lift not run" else "at the end")
    force_table = "" if not forces else f"""<h2>Finger forces {when} (N)</h2>
<table><tr><th>finger</th><th>resultant (x, y, z)</th><th>|resultant|</th><th>grip (along its squeeze direction)</th>
<th>vertical (weight carried)</th><th>normal sum Σ f·n̂</th><th>contacts</th></tr>{force_rows}</table>
<p>Table III of the paper compares {html.escape(s.get('table_iii_measure') or 'the normal sums')}.</p>"""
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
{force_table}
<p>Data: <a href="result.json">result.json</a> (schema {doc['schema']} v{doc['schema_version']}).
ParaView: open <code>object.pvd</code>, <code>finger1.pvd</code>, <code>finger2.pvd</code> and <code>table.vtu</code>;
the time value is the finger path (m: ρ, then ρ + lift height); colour by <code>von_mises</code> (Pa),
<code>strain_energy_density</code> (J/m³), <code>contact_state</code> (0 none, 1 stick, 2 slip) or
<code>elastic_displacement</code>; glyph <code>contact_force</code>; field data <code>phase</code>,
<code>squeeze_depth</code>, <code>lift_height</code>, <code>liftable_weight</code> on every frame.
<code>object.xdmf</code> holds the same series as XDMF/HDF5.</p>
{acc_html}
{figs}
<h2>Events</h2>
<table><tr><th>#</th><th>phase</th><th>kind</th><th>body</th><th>node</th><th>ρ (mm)</th><th>lift (mm)</th></tr>
{ev_rows}</table>{more}
<p style="color:#777">fem_grasp {html.escape(str(doc.get('fem_grasp_version')))}, {html.escape(str(doc.get('created')))}</p>
</body></html>
"""


def write_report(out: str | Path, colour: str = "von_mises", pool: Any = None) -> Path:
    """Render the pictures and ``report.html`` into the output folder ``out``; return the HTML path.

    ``colour``: what the 3D views are coloured by, a key of :data:`COLOURINGS`; ``pool``: a
    :func:`render_process` to draw the 3D views in (default: a new one).

    Raises
    ------
    fem_grasp.io.output.OutputError
        No (readable) result.json in ``out``.
    """
    out = Path(out)
    doc = read_result(out)
    if not doc.get("series") or not doc["series"].get("frames"):
        from ..errors import OutputError

        raise OutputError(f"{out}/result.json has no time series to draw")
    if colour not in COLOURINGS:
        raise ValueError(f"colour must be one of {', '.join(COLOURINGS)}, got {colour!r}")
    render_frames(out, doc, colour=colour, pool=pool)
    plot_patches(out, doc, out / "patches.png")
    plot_liftable(doc, out / "liftable.png")
    plot_timeline(doc, out / "timeline.png")
    path = atomic_write_text(out / "report.html", _html(doc))
    if (out / MARKER).exists():
        add_to_marker(out, list(PICTURES) + ["report.html"])
    log.info("wrote %s", path)
    return path
