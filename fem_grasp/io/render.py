"""The 3-D pictures of a report: ``rest.png``, ``lift_start.png`` and ``lifted.png`` (what they show:
:mod:`fem_grasp.io.report`), drawn from one camera across the squeeze axis (:func:`view_direction`).

They are rendered off-screen with pyvista in a freshly *spawned* process (VTK aborts in a process that has
loaded dolfinx; see ``verification/_common/render.py``), from plain arrays read back from the time series
(:mod:`fem_grasp.io.frames`); :func:`render_process` shares one such process among several reports.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from .frames import SLIP, STICK, finger_centres, pick_frames, read_frame

__all__ = ["COLOURINGS", "LIFTED_CLEARANCE", "VIEW_ELEVATION", "bar_title_above", "render_frames", "render_process",
           "render_views", "start_views", "view_direction", "warm_renderer"]

#: What the 3D views can be coloured by: (field in the time series, label with its unit, factor from SI).
COLOURINGS = {
    "von_mises": ("von_mises", "von Mises stress (kPa)", 1e-3),
    "energy": ("strain_energy_density", "strain energy density (J/m^3)", 1.0),
    "elastic": ("elastic_displacement", "|displacement less its rigid motion| (mm)", 1e3),
    "displacement": ("displacement", "|displacement| (mm)", 1e3),
}
#: ``lifted.png`` shows a picked-up object this far (× its height) above its lift-off state.
LIFTED_CLEARANCE = 0.25


@contextlib.contextmanager
def render_process(warm: bool = False) -> Iterator[Any]:
    """One spawned process for several reports' 3-D pictures (module notes): pass it as ``pool`` to
    :func:`write_report` (a placement search draws its best grasps and its candidates in one), saving each
    report the start of a process and of VTK's renderer (about 1.5 s).  ``warm``: start the renderer at once
    (:func:`warm_renderer`), so that it starts while the caller computes what it will draw."""
    from ..spawn import check_main_guard

    check_main_guard("rendering a report's pictures (pyvista, in a spawned process)")
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(1) as pool:
        if warm:
            pool.apply_async(warm_renderer)
        yield pool


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
    if pool is None:
        with render_process() as own:
            return start_views(out, doc, own, size, colour).get()
    return start_views(out, doc, pool, size, colour).get()


def start_views(out: Path, doc: dict[str, Any], pool: Any, size: tuple[int, int] = (1000, 760),
                colour: str = "von_mises") -> Any:
    """:func:`render_views` without waiting: the pictures are drawn in ``pool`` (a :func:`render_process`) while
    the caller goes on; the returned handle's ``get()`` waits and gives what :func:`render_views` returns."""
    if colour not in COLOURINGS:
        raise ValueError(f"colour must be one of {', '.join(COLOURINGS)}, got {colour!r}")
    picks = pick_frames(doc)
    data = [read_frame(out, f, doc) for _, _, f in picks]
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
    centres = [finger_centres(doc, f) for _, _, f in picks]
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
    return pool.map_async(_draw_frame, jobs)


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


def warm_renderer() -> None:
    """Load pyvista and VTK's off-screen renderer in this process by drawing one small picture (to nowhere)."""
    pv = _pyvista()
    p = pv.Plotter(off_screen=True, window_size=(64, 64))
    p.add_mesh(pv.Sphere())
    p.screenshot(None, return_img=True)
    p.close()


def bar_title_above(p: Any, title: str, x: float, top: float, size: Any) -> None:
    """Move a horizontal scalar bar's title above its tick labels (VTK centres it over the bar, where it overlaps
    the middle label): the bar's own title is blanked and the same words written a line higher, left-aligned."""
    bar = p.scalar_bars[title]
    bar.SetTitle("")
    width, height = (int(v) for v in size)
    p.add_text(title, position=(int(x * width), int(top * height) + 6), font_size=10, color="black")


def _draw_frame(job: dict[str, Any]) -> dict[str, Any]:
    from .series import fingertip_surface

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
    for code, colour, name in ((1, STICK, "contact sticks"), (2, SLIP, "contact slides")):
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
