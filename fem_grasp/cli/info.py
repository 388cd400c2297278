"""``fem-grasp info`` and ``fem-grasp scenes``: the figures of a mesh, a surface, a scene, a result.json or a
ParaView series, each with its units; the scenes shipped with fem_grasp.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path
from typing import Any

import numpy as np

from .common import EXIT_BAD_INPUT, EXIT_OK, BadInput, echo, mm, number

__all__ = ["cmd_info", "cmd_scenes"]

log = logging.getLogger(__name__)


def cmd_info(args: argparse.Namespace) -> int:
    from ..errors import MeshError
    from ..mesh.scan import SURFACE_SUFFIXES, surface_report

    p = Path(args.path)
    if p.suffix.lower() == ".json" or (p.is_dir() and (p / "result.json").exists()):
        return _info_result(args, p / "result.json" if p.is_dir() else p)
    if p.suffix.lower() == ".pvd":
        return _info_pvd(args, p)
    if p.suffix == ".toml" or (not p.exists() and p.suffix == ""):
        from ..io.scene import load_scene, resolve_scene

        scene = load_scene(resolve_scene(args.path), quick=args.quick)
        for line in _scene_lines(scene):
            echo(args, line)
        return EXIT_OK
    if not p.exists():
        raise BadInput(f"{p} does not exist")
    if p.suffix.lower() in SURFACE_SUFFIXES:
        from ..mesh.units import size_warning

        r = surface_report(p)
        echo(args, f"{p}: surface, {r['vertices']} vertices, {r['triangles']} triangles, diameter "
                   f"{r['diameter']:.4g} m, area {r['area']:.4g} m^2 (read as metres)")
        warning = size_warning(r["diameter"], "m", str(p), hint="--units")
        if warning:
            log.warning("%s (fem-grasp mesh takes --units)", warning)
        if r["ok"]:
            echo(args, f"closed, manifold, not self-intersecting; encloses {r['volume']:.4g} m^3")
            return EXIT_OK
        echo(args, r["problem"])
        return EXIT_BAD_INPUT
    from ..mesh.tetmesh import TetMesh

    try:
        m = TetMesh.from_file(p)
    except MeshError:
        raise
    except Exception as exc:  # meshio raises many types for what it cannot read
        raise BadInput(f"{p}: cannot read it as a volume mesh ({type(exc).__name__}: {exc}); info reads volume "
                       f"meshes (.vtu, .msh, .xdmf, …), surfaces ({', '.join(SURFACE_SUFFIXES)}), scenes (.toml), "
                       "result.json and .pvd time series") from None
    lo, hi = m.bounds
    q = m.quality
    echo(args, f"{p}: {m.n_points} vertices ({len(m.surface_nodes)} on the surface), {m.n_tets} tets, "
               f"{len(m.surface_faces)} surface triangles")
    echo(args, f"volume {m.volume:.6g} m^3, bounds {np.round(lo, 6).tolist()} … {np.round(hi, 6).tolist()} m, "
               f"diameter {m.diameter:.4g} m")
    echo(args, f"quality (1 = regular tet): min {q.min():.3g}, median {np.median(q):.3g}; "
               f"{m.n_reoriented} tets reoriented on reading")
    return EXIT_OK


def _pressure(x: float) -> str:
    for unit, scale in (("GPa", 1e9), ("MPa", 1e6), ("kPa", 1e3)):
        if abs(x) >= scale:
            return f"{x / scale:.4g} {unit}"
    return f"{x:.4g} Pa"


def _scene_lines(scene: Any) -> list[str]:
    """``fem-grasp info scene.toml``: the parsed scene, one labelled line per part, with units; settings left
    to the pickup say what it chooses."""
    o = scene.object
    if o.kind == "paper":
        obj = f"paper object {o.paper!r} (Table I)" + (f", remeshed at about {o.vertices} vertices" if o.vertices
                                                      else ", its committed mesh")
    elif o.kind == "mesh":
        obj = (f"mesh file {o.mesh} (coordinates in {o.units})"
               + (f", remeshed at about {o.vertices} vertices" if o.vertices else "")
               + (f", remeshed at spacing {mm(o.size)}" if o.size else "")
               + ("; implausible units allowed" if o.allow_implausible_units else ""))
    else:
        obj = (f"box {' x '.join(number(x, '', 1e3) for x in o.box)} mm, {' x '.join(str(d) for d in o.divisions)} "
               "cells")
    if o.down is not None:
        obj += f"; down is ({', '.join(f'{x:g}' for x in o.down)}) in the mesh's frame"
    load = (f"weight {scene.weight:.4g} N (mass {1e3 * scene.weight / scene.gravity:.4g} g)" if scene.weight is not None
            else f"density {scene.density:.4g} kg/m^3 (the weight from the mesh's volume)")
    d1, d2 = (np.asarray(d, float) for d in scene.directions)
    tilt = np.degrees(np.arcsin(np.clip(-d1[2], -1.0, 1.0)))
    contacts = (f"nodes {scene.contacts[0]} and {scene.contacts[1]}" if scene.contacts is not None
                else f"chosen by the rule {scene.placement_rule!r}")

    def opt(x: float | None, unit: str, default: str) -> str:
        return default if x is None else (mm(x) if unit == "mm" else number(x, unit))

    if scene.quick:
        acc = "one run on the quick variant's coarse mesh (--quick does not refine)"
    elif scene.accuracy is not None:
        acc = (f"refine at the contact patches until the estimated error of rho* and the finger force is within "
               f"{100 * scene.accuracy:g} %")
    else:
        acc = "one run on the scene's mesh (accuracy off)"
    if scene.expected_error is not None:
        refined = scene.accuracy is not None and not scene.quick
        run = "one run on this mesh (--accuracy off)" if refined else "such a run"
        acc += (f"; {run} may even reach another verdict than a finer mesh (solver.expected_error = inf)"
                if not np.isfinite(scene.expected_error) else
                f"; {run} is within about {100 * scene.expected_error:g} % of the converged answer "
                "(solver.expected_error)")
    lines = [
        f"scene      {scene.name}{' (quick)' if scene.quick else ''}: {scene.description or '(no description)'}",
        f"file       {scene.path}" if scene.path is not None else "file       (not from a file)",
        f"object     {obj}",
        f"material   Young's modulus E {_pressure(scene.young)}, Poisson's ratio {scene.poisson:g}, {load}, "
        f"gravity {scene.gravity:g} m/s^2",
        f"friction   fingers mu_F {scene.mu_finger:g}, table mu_P {scene.mu_table:g}",
        f"fingers    radius {mm(scene.finger_radius)}; initial contacts {contacts}; squeeze directions "
        f"({', '.join(f'{x:.3g}' for x in d1)}) and ({', '.join(f'{x:.3g}' for x in d2)}), {tilt:.3g} deg below "
        f"the horizontal; ratio s {scene.ratio:g}",
        f"solver     {scene.backend}; max squeeze {opt(scene.max_squeeze, 'mm', '40 % of the width (default)')}, "
        f"increment {opt(scene.step, 'mm', 'adapted to E (default)')}"
        + (f" (divided by {scene.step_divisions} where the lift test passes)"
           if (scene.step_divisions or 1) > 1 else "") + ", lift-test step "
        f"{opt(scene.lift_test_step, 'N', 'mg/20 (default)')}, max lift "
        f"{opt(scene.max_lift, 'mm', 'the object height (default)')}; "
        + ("lift simulated" if scene.lift else "stops when the lift test passes (lift = false)"),
        f"accuracy   {acc}",
    ]
    if scene.expect is not None:
        lines.append(f"expect     {scene.expect}")
    return lines


def _info_result(args: argparse.Namespace, path: Path) -> int:
    """``fem-grasp info result.json``: what the run found, from the file alone."""
    from ..io.output import read_result

    doc = read_result(path.parent) if path.name == "result.json" else None
    if doc is None:
        raise BadInput(f"{path}: info reads a run's result.json (or its folder); this file is not one")
    s, scene = doc["summary"], doc.get("scene") or {}
    verdict = ("picked up" if s["success"] else "lift test passed, lift not simulated"
               if s.get("outcome") == "lift not run" else f"not picked up: {s['reason']}")
    echo(args, f"{path}: {doc['schema']} v{doc['schema_version']}, fem_grasp {doc.get('fem_grasp_version')}, "
               f"{doc.get('created')}")
    echo(args, f"scene      {scene.get('name', '?')}{' (quick)' if scene.get('quick') else ''}: {s['n_nodes']} nodes, "
               f"{s['n_tets']} tets, weight {s['weight']:.4g} N, E {scene.get('young', float('nan')):.4g} Pa")
    echo(args, f"result     {verdict}")
    echo(args, f"squeeze    rho = {mm(s['squeeze_depth'])}, liftable weight up to {s['max_liftable_weight']:.4g} N; "
               f"{s['n_final_contacts']} contacts in the final configuration")
    for name, f in (s.get("finger_forces") or {}).items():
        echo(args, f"  {name.replace('finger', 'finger ')} resultant ({', '.join(f'{x:.4g}' for x in f['resultant'])}) N, "
                   f"|{f['magnitude']:.4g}|, grip {f['grip']:.4g}, vertical {f['vertical']:.4g}, normal sum "
                   f"{f['normal_sum']:.4g}")
    echo(args, f"table III  Σ f·n̂ {s['finger_normal_force']:.4g} N; rigid object "
               f"{number(s.get('rigid_total_normal_force'), 'N')}")
    echo(args, f"events     {s['n_events']}: " + ", ".join(f"{k} {v}" for k, v in s["event_counts"].items()))
    series = doc.get("series") or {}
    frames = series.get("frames") or []
    if frames:
        echo(args, f"series     {len(frames)} frames in {series.get('object', 'object.pvd')}"
                   + (f" and {series['xdmf']}" if series.get("xdmf") else "")
                   + f"; time = finger path, 0 … {mm(frames[-1].get('time', frames[-1].get('finger_path')))}")
    return EXIT_OK


def _info_pvd(args: argparse.Namespace, path: Path) -> int:
    """``fem-grasp info object.pvd``: the frames of a time series and their time values."""
    import meshio

    from ..io.output import read_pvd

    if not path.exists():
        raise BadInput(f"{path} does not exist")
    entries = read_pvd(path)
    echo(args, f"{path}: ParaView time series, {len(entries)} frames, time {entries[0][0]:.6g} … {entries[-1][0]:.6g}"
         if entries else f"{path}: ParaView time series with no frames")
    for t, f in entries[:1] + entries[-1:] if len(entries) > 1 else entries:
        m = meshio.read(path.parent / f)
        fd = {k: np.asarray(v).ravel()[0] for k, v in m.field_data.items()}
        extra = ", ".join(f"{k} {v:.6g}" for k, v in fd.items())
        echo(args, f"  t = {t:.6g}: {f}, {len(m.points)} points; point data {', '.join(m.point_data)}; "
                   f"cell data {', '.join(m.cell_data) or '—'}" + (f"; field data {extra}" if extra else ""))
    return EXIT_OK


def cmd_scenes(args: argparse.Namespace) -> int:
    from ..io.scene import load_scene, shipped_scenes

    for name, path in shipped_scenes().items():
        try:
            desc = load_scene(path).description
        except Exception as exc:  # noqa: BLE001 - list broken scenes too
            desc = f"(cannot be read: {exc})"
        echo(args, f"{name:16s} {desc}")
    return EXIT_OK
