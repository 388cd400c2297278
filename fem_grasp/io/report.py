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
  contact nodes (stick / slip), their normal forces (mN, as the dot's size,
  and written beside each node on patches of up to 30 contacts) and their
  tangential forces (arrows).
* ``liftable.png`` — the liftable weight w(ρ) of the lift test against the
  object's weight, with every level's w(ρ) when the answer was refined
  (matplotlib, no pyplot state).
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
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import require
from ..grasp.accuracy import percent_error
from .output import MARKER, add_to_marker, atomic_write_text, read_result
from .plots import plot_liftable, plot_patches, plot_timeline
from .render import (
    COLOURINGS,
    LIFTED_CLEARANCE,
    VIEW_ELEVATION,
    bar_title_above,
    render_frames,
    render_process,
    render_views,
    start_views,
    view_direction,
)

__all__ = ["COLOURINGS", "LIFTED_CLEARANCE", "PICTURES", "VIEW_ELEVATION", "bar_title_above", "plot_liftable",
           "plot_patches", "plot_timeline", "render_frames", "render_process", "render_views", "require_report_extra",
           "view_direction", "write_report"]

log = logging.getLogger(__name__)

#: The pictures of a report, in the order shown.
PICTURES = ("rest.png", "lift_start.png", "lifted.png", "patches.png", "liftable.png", "timeline.png")


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
        return f"one run on this mesh, within about {percent_error(e)} (the scene's convergence study)"
    return f"the error estimate is above the requested {goal}" if goal else "the error estimate is above the target"


def _accuracy_html(acc: dict[str, Any] | None) -> str:
    """The levels of ``pickup(..., accuracy=...)`` (:func:`fem_grasp.grasp.accuracy.converged_pickup`), as a table."""
    if not acc:
        return ""

    def change(lv: dict[str, Any]) -> str:
        c = lv.get("change")
        return "—" if not c else f"{percent_error(c['squeeze_depth'])} / {percent_error(c['finger_force'])}"

    rows = "".join(
        f"<tr><td>{lv['level']}</td><td>{lv['vertices']:,}</td><td>{1e3 * lv['inner_size']:.3g}</td>"
        f"<td>{1e3 * lv['outer_size']:.3g}</td><td>{1e3 * lv['step']:.3g}</td><td>{lv['lift_test_step']:.3g}</td>"
        f"<td>{'picked up' if lv['success'] else 'not picked up'}</td><td>{1e3 * lv['squeeze_depth']:.4g}</td>"
        f"<td>{lv['finger_force']:.4g}</td>"
        f"<td>{lv['finger_nodes'][0]} / {lv['finger_nodes'][1]} / {lv['table_nodes']}</td>"
        f"<td>{change(lv)}</td><td>{lv['seconds'] + lv['mesh_seconds']:.1f}</td></tr>" for lv in acc["levels"])
    made = ("bisects the level before (nested levels) on" if acc.get("refinement") == "nested"
            else "remeshes")
    return (f"<h2>Accuracy: {html.escape(_accuracy_state(acc))}</h2>"
            f"<p>{html.escape(acc.get('note', ''))}. Each level {made} "
            f"{html.escape(acc.get('geometry', '') or 'the object')} with half the spacing at the contact patches, "
            "grasps at the same two points and resolves ρ* to a share of the target; the estimated error is three "
            "times the change of the last two levels or, from three levels on, the larger of that and their "
            "uncertainty (Eça and Hoekstra), plus the resolution of ρ*.</p>"
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
        rows.insert(5, _row("accuracy", f"{_accuracy_state(acc)}: estimated error of ρ* "
                                        f"{percent_error(e.get('squeeze_depth'))}, of the finger force "
                                        f"{percent_error(e.get('finger_force'))}"))
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
        "liftable.png": "Liftable weight w(ρ) of the lift test against the object's weight (and of each level of the "
                        "refinement: a finer level tests from the coarser level's ρ* on).",
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


def require_report_extra(purpose: str = "report.html") -> None:
    """Check that the ``report`` extra (matplotlib, pyvista) is installed, without importing either.

    ``fem-grasp run --report`` calls it before the pickup, so that a missing extra is said at once, not
    after minutes of simulation.

    Raises
    ------
    fem_grasp.errors.MissingExtraError
        matplotlib or pyvista is not installed (an ImportError naming the extra).
    """
    for module in ("matplotlib", "pyvista"):  # pyvista is imported only in the spawned renderer (module notes)
        require(module, "report", purpose, load=False)


def write_report(out: str | Path, colour: str = "von_mises", pool: Any = None) -> Path:
    """Render the pictures and ``report.html`` into the output folder ``out``; return the HTML path.

    ``colour``: what the 3D views are coloured by, a key of :data:`COLOURINGS`; ``pool``: a
    :func:`render_process` to draw the 3D views in (default: a new one).

    Raises
    ------
    fem_grasp.io.output.OutputError
        No (readable) result.json in ``out``.
    fem_grasp.errors.MissingExtraError
        The ``report`` extra (matplotlib, pyvista) is not installed.
    """
    out = Path(out)
    doc = read_result(out)
    if not doc.get("series") or not doc["series"].get("frames"):
        from ..errors import OutputError

        raise OutputError(f"{out}/result.json has no time series to draw")
    if colour not in COLOURINGS:
        raise ValueError(f"colour must be one of {', '.join(COLOURINGS)}, got {colour!r}")
    require_report_extra("report.html")
    with contextlib.ExitStack() as stack:
        if pool is None:
            pool = stack.enter_context(render_process(warm=True))
        views = start_views(out, doc, pool, colour=colour)  # drawn in the render process while the plots are here
        plot_patches(out, doc, out / "patches.png")
        plot_liftable(doc, out / "liftable.png")
        plot_timeline(doc, out / "timeline.png")
        views.get()
    path = atomic_write_text(out / "report.html", _html(doc))
    if (out / MARKER).exists():
        add_to_marker(out, list(PICTURES) + ["report.html"])
    log.info("wrote %s", path)
    return path
