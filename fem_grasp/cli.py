"""The ``fem-grasp`` command line (also ``python -m fem_grasp``).

Subcommands::

    fem-grasp run SCENE [--quick] [--out DIR] [--report] [--young E] [--no-lift] [--accuracy A]   squeeze and lift (Algorithm 1)
    fem-grasp rest SCENE [--quick] [--out DIR]              the resting state only (§III-A)
    fem-grasp mesh INPUT -o OUTPUT [--vertices N | --size H] [--units mm]   closed surface scan → tetrahedra
    fem-grasp info PATH                                     a mesh, a surface, a scene, a result.json or a .pvd
    fem-grasp report DIR [--colour von_mises]               report.html + pictures from a run's output
    fem-grasp search SCENE --out DIR [--workers N | --scheduler tcp://HOST:PORT]
                                                            where to grasp: Algorithm 1 for many placements
    fem-grasp scenes                                        the scenes shipped with fem_grasp

Every command takes -v/-vv (the library's log on stderr), --log-file FILE and -q; a progress bar is
drawn on a terminal only (:mod:`fem_grasp.progress`).  SCENE is a TOML file (:mod:`fem_grasp.io.scene`)
or the name of a shipped scene (``tomato``, ``orange``, ``steam_bun``, ``football``, ``foam_block``,
``slippery_ball``); ``run`` takes the same path as :func:`fem_grasp.run_scene`.  Exit status: 0 success, 1 the grasp failed (a valid
answer: the object cannot be picked up so), 2 bad input (the message names
it), 3 an internal error (a bug: please report it).

:func:`main` takes ``argv`` and returns the exit status, so tests call it
in-process.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import sys
import time
from pathlib import Path
from typing import Any, Iterator, Sequence

import numpy as np

from .progress import PhaseBar, progress_enabled

__all__ = ["main", "EXIT_OK", "EXIT_FAILED", "EXIT_BAD_INPUT", "EXIT_INTERNAL"]

log = logging.getLogger(__name__)

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_INTERNAL = 0, 1, 2, 3


class _BadInput(Exception):
    """Raised inside a command for input problems: exit status 2."""


# ------------------------------------------------------------------ progress
#: The phase bar of a command (tqdm on a terminal, silent in CI or a pipe: :mod:`fem_grasp.progress`).
Progress = PhaseBar


def _progress_enabled(args: argparse.Namespace) -> bool:
    return progress_enabled(quiet=args.quiet)


# ------------------------------------------------------------------ helpers
def _out(args: argparse.Namespace, text: str = "") -> None:
    if not args.quiet:
        print(text)


def _cache_dir(args: argparse.Namespace) -> Path | None:
    from .io.cache import default_cache_dir

    if args.no_cache:
        return None
    return Path(args.cache) if args.cache else default_cache_dir()


def _load_scene(args: argparse.Namespace) -> Any:
    from .io.scene import load_scene, resolve_scene, with_overrides

    scene = load_scene(resolve_scene(args.scene), quick=args.quick)
    young = getattr(args, "young", None)
    if young is not None:
        from .io.scene import check_quantity, parse_quantity

        young = parse_quantity(young, "pressure", "--young")
        check_quantity("--young", young, "Pa")
    scene = with_overrides(scene, backend=getattr(args, "backend", None), young=young,
                           lift=False if getattr(args, "no_lift", False) else None)
    if getattr(args, "allow_implausible_units", False):
        if scene.object.kind != "mesh":
            raise _BadInput("--allow-implausible-units: only a mesh file's size and density are checked for their "
                            f"unit; the scene's object is a {scene.object.kind}")
        scene = scene.with_(allow_implausible_units=True)
    accuracy = getattr(args, "accuracy", None)
    if accuracy is not None:
        from dataclasses import replace

        from .io.scene import parse_accuracy

        scene = replace(scene, accuracy=parse_accuracy(accuracy, "--accuracy"))
    return scene


def _fmt(x: float | None, unit: str = "", scale: float = 1.0, digits: int = 4) -> str:
    if x is None or not np.isfinite(x):
        return "—"
    return f"{x * scale:.{digits}g}{(' ' + unit) if unit else ''}"


def _mm(x: float | None) -> str:
    return _fmt(x, "mm", 1e3)


def _verdict(result: Any) -> str:
    if result.success:
        return f"PICKED UP at rho = {_mm(result.squeeze_depth)}"
    if result.outcome == "lift not run":
        return (f"lift test passed at rho = {_mm(result.squeeze_depth)}; lift not simulated (--no-lift: is it "
                "liftable? yes)")
    return f"NOT PICKED UP: {result.reason}"


def _force_lines(result: Any) -> list[str]:
    """Each finger's force on the object, four ways, and which one Table III compares (grasp.forces)."""

    forces = result.finger_forces
    if forces is None:
        return []
    when = ("at lift-off" if result.success else "when the lift test passed" if result.outcome == "lift not run"
            else "at the end")
    lines = [f"fingers    force on the object {when} (N): resultant (x, y, z), |resultant|, grip (along the finger's "
             "squeeze direction), vertical (weight carried), normal sum Σ f·n̂"]
    for k, f in enumerate(forces, start=1):
        r = ", ".join(f"{x:.4g}" for x in f.resultant)
        lines.append(f"  finger {k} ({r}), |{f.magnitude:.4g}|, grip {f.grip:.4g}, vertical {f.vertical:.4g}, "
                     f"normal sum {f.normal_sum:.4g} ({f.contacts} contact{'s' if f.contacts != 1 else ''})")
    rigid = result.rigid
    rigid_n = _fmt(rigid.total_normal_force if rigid is not None and rigid.feasible else None, "N")
    lines.append(f"table III  compares Σ f·n̂ over both fingers: {result.finger_normal_force:.4g} N here, {rigid_n} "
                 "for a rigid object at the same contacts")
    return lines


def _summary_lines(scene: Any, result: Any, rest_cached: bool) -> list[str]:
    counts = result.event_counts()
    wmax = max((w for _, w in result.liftable), default=0.0)
    times = dict(result.timings)
    rest_time = times.pop("rest", None)
    time_parts = ([f"rest {rest_time:.2f} s ({'checked from the cache' if rest_cached else 'solved'})"]
                  if rest_time is not None else []) + [f"{k} {v:.2f} s" for k, v in times.items()]
    lines = [
        f"scene      {scene.name}{' (quick)' if scene.quick else ''}: {result.body.n_nodes} nodes, "
        f"{result.body.mesh.n_tets} tets, weight {result.body.weight:.4g} N, E {scene.young:.4g} Pa, "
        f"nu {scene.poisson:g}, mu finger {scene.mu_finger:g}, mu table {scene.mu_table:g}",
        f"rest       {result.rest.n_contacts} table contacts ({int(result.rest.sliding.sum())} sliding), "
        f"max sag {_mm(result.rest.max_sag)}{' [cached]' if rest_cached else ''}",
        f"result     {_verdict(result)}",
        f"squeeze    rho = {_mm(result.squeeze_depth)} (max {_mm(result.max_squeeze)}), "
        f"liftable weight up to {wmax:.4g} N (weight {result.body.weight:.4g} N)",
        f"contacts   {result.n_final_contacts} in the final configuration",
        *_force_lines(result),
        f"events     {len(result.events)}: " + ", ".join(f"{k} {v}" for k, v in counts.items())
        + "  (A contact, B break, C stick→slip, D slip→stick)",
        "time       " + ", ".join(time_parts),
    ]
    acc = getattr(result, "accuracy", None)
    if acc:
        if not acc["converged"]:
            lines[2] += ("  (one run on this mesh: see accuracy)" if len(acc["levels"]) == 1 else
                         "  (less accurate than requested: see accuracy)")
        lines[3:3] = _accuracy_lines(acc, scene.quick)
    return lines


def _accuracy_lines(acc: dict[str, Any], quick: bool) -> list[str]:
    """The estimated error of the answer, and one line per level (:func:`fem_grasp.grasp.accuracy.converged_pickup`)."""
    e = acc["estimated_error"]

    def pct(x: Any) -> str:
        if x is None or not np.isfinite(x):
            return "unknown"
        return f"{100 * x:.0f} %" if x >= 0.1 else f"{100 * x:.2g} %"

    if acc["converged"]:
        head = (f"accuracy   target {100 * acc['target']:g} %: estimated error rho* {pct(e['squeeze_depth'])}, "
                f"finger force {pct(e['finger_force'])} ({len(acc['levels'])} levels, {acc.get('seconds', 0):.0f} s)")
    elif len(acc["levels"]) == 1:
        stated = acc.get("expected_error_stated")
        bound = e["squeeze_depth"]
        how = ("the convergence study found that such a run can even reach another verdict than a finer mesh"
               if stated and not np.isfinite(bound) else
               f"the convergence study for this scene puts such a run within about {pct(bound)} of the converged "
               "rho* and finger force" if stated else "how far it is from the converged answer is not known")
        head = (f"accuracy   {acc.get('note', '')}; {how}"
                + (f"; run without --quick for the answer to {100 * acc['target']:g} %"
                   if quick and acc.get("target") is not None and np.isfinite(acc["target"]) else ""))
    elif not all(np.isfinite(v) for v in (e["squeeze_depth"], e["finger_force"])):
        head = (f"accuracy   the requested {100 * acc['target']:g} % was not reached ({acc.get('note', '')}): the "
                "last two meshes give different verdicts, so the verdict itself is not settled at this resolution"
                + ("; run without --quick for the refined answer" if quick else ""))
    else:
        head = (f"accuracy   the error estimate ({pct(e['squeeze_depth'])} in rho*, {pct(e['finger_force'])} in the "
                f"finger force) is above the requested {100 * acc['target']:g} % ({acc.get('note', '')})"
                + ("; run without --quick for the refined answer" if quick else ""))
    lines = [head]
    for lv in acc["levels"]:
        lines.append(f"  level {lv['level']}  {lv['vertices']:,} vertices, spacing {1e3 * lv['inner_size']:.3g} mm at "
                     f"the patches, increment {1e3 * lv['step']:.3g} mm: "
                     f"{'picked up' if lv['success'] else 'not picked up'}, rho {1e3 * lv['squeeze_depth']:.4g} mm, "
                     f"finger force {lv['finger_force']:.4g} N, {lv['seconds'] + lv['mesh_seconds']:.1f} s")
    return lines


# ------------------------------------------------------------------ commands
def cmd_run(args: argparse.Namespace) -> int:
    from .io.output import check_out_path, prepare_out_dir, write_run
    from .io.scene import pickup_scene

    scene = _load_scene(args)
    out = Path(args.out) if args.out else None
    if args.report and out is None:
        raise _BadInput("--report needs --out DIR (the report is written there)")
    if out is not None:
        check_out_path(out)
        prepare_out_dir(out, args.force)
    cache = _cache_dir(args)
    phases = ["mesh", "rest", "pickup"] + (["write"] if out else []) + (["report"] if args.report else [])
    bar = Progress(phases, _progress_enabled(args))
    try:
        result, cached = pickup_scene(scene, cache, phase=bar.phase)
        code = EXIT_OK if result.success else EXIT_FAILED
        if out is not None:
            with bar.phase("writing results"):
                write_run(out, result, scene, force=True,
                          extra={"exit_code": code, "rest_from_cache": cached, "command": list(args.argv)})
        if args.report:
            from .io.report import write_report

            with bar.phase("rendering the report"):
                write_report(out)
    finally:
        bar.close()
    for line in _summary_lines(scene, result, cached):
        _out(args, line)
    if scene.expect is not None and (scene.expect == "success") != result.success:
        log.warning("scene %s expects %s but the pickup %s", scene.name, scene.expect,
                    "succeeded" if result.success else "failed")
    if out is not None:
        _out(args, f"output     {out}/result.json, {out}/object.pvd (ParaView: open object.pvd, finger1.pvd, "
                   f"finger2.pvd, table.vtu; time = the finger path in metres)")
        if args.report:
            _out(args, f"report     {out}/report.html")
    return code


def cmd_rest(args: argparse.Namespace) -> int:
    from .io.cache import cached_rest
    from .io.output import prepare_out_dir, write_rest

    scene = _load_scene(args)
    out = Path(args.out) if args.out else None
    if out is not None:
        prepare_out_dir(out, args.force)
    cache = _cache_dir(args)
    body = scene.body(cache)
    rs, cached = cached_rest(body, scene.mu_table, backend=scene.backend, down=scene.object.down, cache_dir=cache)
    fig = rs.check(raise_on_failure=False)
    _out(args, f"scene      {scene.name}{' (quick)' if scene.quick else ''}: {body.n_nodes} nodes, weight "
               f"{body.weight:.4g} N, E {scene.young:.4g} Pa, mu table {scene.mu_table:g}")
    _out(args, f"rest       {rs.n_contacts} table contacts ({int(rs.sliding.sum())} sliding), max sag "
               f"{_fmt(rs.max_sag, 'mm', 1e3)}, {rs.iterations} iterations{' [cached]' if cached else ''}")
    _out(args, f"checks     {'pass' if fig['ok'] else 'FAIL: ' + '; '.join(fig['failures'])} (equilibrium "
               f"{fig['force_residual']:.1e} force, {fig['torque_residual']:.1e} torque)")
    if out is not None:
        write_rest(out, rs, scene, force=True, extra={"rest_from_cache": cached})
        _out(args, f"output     {out}/rest.json, {out}/rest.vtu")
    return EXIT_OK if fig["ok"] else EXIT_INTERNAL


def cmd_mesh(args: argparse.Namespace) -> int:
    from ._files import atomic_write_mesh
    from .mesh.scan import DENSE_SCAN_VERTICES, SURFACE_SUFFIXES, Surface, check_surface, mesh_surface, read_surface
    from .mesh.units import LENGTH_UNITS, size_warning

    src, dst = Path(args.input), Path(args.output)
    if src.suffix.lower() not in SURFACE_SUFFIXES:
        raise _BadInput(f"{src}: expected a surface file ({', '.join(SURFACE_SUFFIXES)}), got {src.suffix or 'no suffix'}")
    if dst.exists() and not args.force:
        raise _BadInput(f"{dst} exists; pass --force to overwrite it")
    surf = read_surface(src)
    scale = LENGTH_UNITS[args.units]
    if scale != 1.0:
        surf = Surface(surf.points * scale, surf.faces, surf.source)
    warning = size_warning(surf.diameter, args.units, str(src), hint="--units")
    if warning:
        log.warning("%s", warning)
    surf = check_surface(surf)
    if args.vertices is None and args.size is None and len(surf.points) > DENSE_SCAN_VERTICES:
        log.warning("%s has %d surface vertices; the mesh keeps them all. Pass --vertices N to simplify",
                    src, len(surf.points))
    t0 = time.perf_counter()
    mesh = mesh_surface(surf, target_vertices=args.vertices, size=args.size, check=False)
    atomic_write_mesh(dst, mesh.to_meshio(), file_format=_meshio_format(dst))
    q = mesh.quality
    unit = "" if args.units == "m" else f", read in {args.units} and written in metres"
    _out(args, f"{src}: {len(surf.points)} surface vertices, {len(surf.faces)} triangles, closed and manifold{unit}")
    _out(args, f"{dst}: {mesh.n_points} vertices, {mesh.n_tets} tets, volume {mesh.volume * 1e6:.4g} cm^3 "
               f"(surface encloses {surf.volume * 1e6:.4g}), diameter {mesh.diameter * 1e3:.4g} mm, min quality "
               f"{q.min():.3g}, {time.perf_counter() - t0:.2f} s")
    return EXIT_OK


def _meshio_format(path: Path) -> str:
    import meshio

    try:
        return meshio._helpers._filetypes_from_path(path)[0]  # type: ignore[attr-defined]
    except Exception:
        raise _BadInput(f"{path}: meshio cannot write files ending in {''.join(path.suffixes) or '(none)'}; "
                        "use .vtu, .msh, .xdmf, .mesh, …") from None


def cmd_info(args: argparse.Namespace) -> int:
    from .errors import MeshError
    from .mesh.scan import SURFACE_SUFFIXES, surface_report

    p = Path(args.path)
    if p.suffix.lower() == ".json" or (p.is_dir() and (p / "result.json").exists()):
        return _info_result(args, p / "result.json" if p.is_dir() else p)
    if p.suffix.lower() == ".pvd":
        return _info_pvd(args, p)
    if p.suffix == ".toml" or (not p.exists() and p.suffix == ""):
        from .io.scene import load_scene, resolve_scene

        scene = load_scene(resolve_scene(args.path), quick=args.quick)
        for line in _scene_lines(scene):
            _out(args, line)
        return EXIT_OK
    if not p.exists():
        raise _BadInput(f"{p} does not exist")
    if p.suffix.lower() in SURFACE_SUFFIXES:
        from .mesh.units import size_warning

        r = surface_report(p)
        _out(args, f"{p}: surface, {r['vertices']} vertices, {r['triangles']} triangles, diameter "
                   f"{r['diameter']:.4g} m, area {r['area']:.4g} m^2 (read as metres)")
        warning = size_warning(r["diameter"], "m", str(p), hint="--units")
        if warning:
            log.warning("%s (fem-grasp mesh takes --units)", warning)
        if r["ok"]:
            _out(args, f"closed, manifold, not self-intersecting; encloses {r['volume']:.4g} m^3")
            return EXIT_OK
        _out(args, r["problem"])
        return EXIT_BAD_INPUT
    from .mesh.tetmesh import TetMesh

    try:
        m = TetMesh.from_file(p)
    except MeshError:
        raise
    except Exception as exc:  # meshio raises many types for what it cannot read
        raise _BadInput(f"{p}: cannot read it as a volume mesh ({type(exc).__name__}: {exc}); info reads volume "
                        f"meshes (.vtu, .msh, .xdmf, …), surfaces ({', '.join(SURFACE_SUFFIXES)}), scenes (.toml), "
                        "result.json and .pvd time series") from None
    lo, hi = m.bounds
    q = m.quality
    _out(args, f"{p}: {m.n_points} vertices ({len(m.surface_nodes)} on the surface), {m.n_tets} tets, "
               f"{len(m.surface_faces)} surface triangles")
    _out(args, f"volume {m.volume:.6g} m^3, bounds {np.round(lo, 6).tolist()} … {np.round(hi, 6).tolist()} m, "
               f"diameter {m.diameter:.4g} m")
    _out(args, f"quality (1 = regular tet): min {q.min():.3g}, median {np.median(q):.3g}; "
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
               + (f", remeshed at spacing {_mm(o.size)}" if o.size else "")
               + ("; implausible units allowed" if o.allow_implausible_units else ""))
    else:
        obj = (f"box {' x '.join(_fmt(x, '', 1e3) for x in o.box)} mm, {' x '.join(str(d) for d in o.divisions)} "
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
        return default if x is None else (_mm(x) if unit == "mm" else _fmt(x, unit))

    if scene.quick:
        acc = "one run on the quick variant's coarse mesh (--quick does not refine)"
    elif scene.accuracy is not None:
        acc = f"refine at the contact patches until rho* and the finger force agree to {100 * scene.accuracy:g} %"
    else:
        acc = "one run on the scene's mesh"
    if scene.expected_error is not None:
        acc += ("; such a run may even reach another verdict than a finer mesh (solver.expected_error = inf)"
                if not np.isfinite(scene.expected_error) else
                f"; such a run is within about {100 * scene.expected_error:g} % of the converged answer "
                "(solver.expected_error)")
    lines = [
        f"scene      {scene.name}{' (quick)' if scene.quick else ''}: {scene.description or '(no description)'}",
        f"file       {scene.path}" if scene.path is not None else "file       (not from a file)",
        f"object     {obj}",
        f"material   Young's modulus E {_pressure(scene.young)}, Poisson's ratio {scene.poisson:g}, {load}, "
        f"gravity {scene.gravity:g} m/s^2",
        f"friction   fingers mu_F {scene.mu_finger:g}, table mu_P {scene.mu_table:g}",
        f"fingers    radius {_mm(scene.finger_radius)}; initial contacts {contacts}; squeeze directions "
        f"({', '.join(f'{x:.3g}' for x in d1)}) and ({', '.join(f'{x:.3g}' for x in d2)}), {tilt:.3g} deg below "
        f"the horizontal; ratio s {scene.ratio:g}",
        f"solver     {scene.backend}; max squeeze {opt(scene.max_squeeze, 'mm', '40 % of the width (default)')}, "
        f"increment {opt(scene.step, 'mm', 'adapted to E (default)')}, lift-test step "
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
    from .io.output import read_result

    doc = read_result(path.parent) if path.name == "result.json" else None
    if doc is None:
        raise _BadInput(f"{path}: info reads a run's result.json (or its folder); this file is not one")
    s, scene = doc["summary"], doc.get("scene") or {}
    verdict = ("picked up" if s["success"] else "lift test passed, lift not simulated"
               if s.get("outcome") == "lift not run" else f"not picked up: {s['reason']}")
    _out(args, f"{path}: {doc['schema']} v{doc['schema_version']}, fem_grasp {doc.get('fem_grasp_version')}, "
               f"{doc.get('created')}")
    _out(args, f"scene      {scene.get('name', '?')}{' (quick)' if scene.get('quick') else ''}: {s['n_nodes']} nodes, "
               f"{s['n_tets']} tets, weight {s['weight']:.4g} N, E {scene.get('young', float('nan')):.4g} Pa")
    _out(args, f"result     {verdict}")
    _out(args, f"squeeze    rho = {_mm(s['squeeze_depth'])}, liftable weight up to {s['max_liftable_weight']:.4g} N; "
               f"{s['n_final_contacts']} contacts in the final configuration")
    for name, f in (s.get("finger_forces") or {}).items():
        _out(args, f"  {name.replace('finger', 'finger ')} resultant ({', '.join(f'{x:.4g}' for x in f['resultant'])}) N, "
                   f"|{f['magnitude']:.4g}|, grip {f['grip']:.4g}, vertical {f['vertical']:.4g}, normal sum "
                   f"{f['normal_sum']:.4g}")
    _out(args, f"table III  Σ f·n̂ {s['finger_normal_force']:.4g} N; rigid object "
               f"{_fmt(s.get('rigid_total_normal_force'), 'N')}")
    _out(args, f"events     {s['n_events']}: " + ", ".join(f"{k} {v}" for k, v in s["event_counts"].items()))
    series = doc.get("series") or {}
    frames = series.get("frames") or []
    if frames:
        _out(args, f"series     {len(frames)} frames in {series.get('object', 'object.pvd')}"
                   + (f" and {series['xdmf']}" if series.get("xdmf") else "")
                   + f"; time = finger path, 0 … {_mm(frames[-1].get('time', frames[-1].get('finger_path')))}")
    return EXIT_OK


def _info_pvd(args: argparse.Namespace, path: Path) -> int:
    """``fem-grasp info object.pvd``: the frames of a time series and their time values."""
    import meshio

    from .io.output import read_pvd

    if not path.exists():
        raise _BadInput(f"{path} does not exist")
    entries = read_pvd(path)
    _out(args, f"{path}: ParaView time series, {len(entries)} frames, time {entries[0][0]:.6g} … {entries[-1][0]:.6g}"
         if entries else f"{path}: ParaView time series with no frames")
    for t, f in entries[:1] + entries[-1:] if len(entries) > 1 else entries:
        m = meshio.read(path.parent / f)
        fd = {k: np.asarray(v).ravel()[0] for k, v in m.field_data.items()}
        extra = ", ".join(f"{k} {v:.6g}" for k, v in fd.items())
        _out(args, f"  t = {t:.6g}: {f}, {len(m.points)} points; point data {', '.join(m.point_data)}; "
                   f"cell data {', '.join(m.cell_data) or '—'}" + (f"; field data {extra}" if extra else ""))
    return EXIT_OK


def cmd_report(args: argparse.Namespace) -> int:
    from .io.report import write_report

    path = write_report(Path(args.dir), colour=args.colour)
    _out(args, f"report     {path}")
    return EXIT_OK


def cmd_scenes(args: argparse.Namespace) -> int:
    from .io.scene import load_scene, shipped_scenes

    for name, path in shipped_scenes().items():
        try:
            desc = load_scene(path).description
        except Exception as exc:  # noqa: BLE001 - list broken scenes too
            desc = f"(cannot be read: {exc})"
        _out(args, f"{name:16s} {desc}")
    return EXIT_OK


def _grid_option(text: str | None, option: str) -> Any:
    """``N`` (a count), ``LO:HI:N`` (N values from LO to HI) or ``A,B,C`` (these values)."""
    if text is None:
        return None
    t = text.strip()
    try:
        if ":" in t:
            lo, hi, n = t.split(":")
            return (float(lo), float(hi), int(n))
        if "," in t or "." in t:
            return [float(v) for v in t.split(",") if v.strip()]
        return int(t)
    except ValueError:
        raise _BadInput(f"{option} {text!r}: write a count N, a range LO:HI:N, or values A,B,C") from None


#: What each ranking of the search ranks by, in words.
_RANKED_BY = {"force": "the least finger normal force Σ f·n̂", "squeeze": "the least squeeze depth rho*",
              "margin": "the largest w/mg"}


def _best_table(best: Any, rank: str, error: float | None) -> list[str]:
    """The best grasps of a search as a table whose headers are the result files' column names (with units);
    ``≈`` marks those within the stated error of the best one (``within_error``, :func:`fem_grasp.batch.rank_table`)."""
    if not len(best):
        return []
    cols = (("rank", None, ""), ("nodes", None, ""), ("azimuth_deg", "azimuth_deg", ".0f"),
            ("tilt_deg", "tilt_deg", ".1f"), ("s", "ratio", "g"), ("height_mm", "height", ".3g"),
            ("rho_star_mm", "rho_star", ".4g"), ("grip1_N", "grip1", ".3g"), ("grip2_N", "grip2", ".3g"),
            ("finger_normal_force_N", "finger_normal_force", ".3g"))
    rows = []
    for _, r in best.iterrows():
        cells = []
        for head, col, fmt in cols:
            if head == "rank":
                cells.append(f"{int(r['rank'])}{' ≈' if r.get('within_error', False) else ''}")
            elif head == "nodes":
                cells.append(f"{int(r['node_i'])}, {int(r['node_j'])}")
            else:
                scale = 1e3 if head.endswith("_mm") else 1.0
                v = float(r[col]) * scale
                cells.append(format(v, fmt) if np.isfinite(v) else "—")
        rows.append(cells)
    widths = [max(len(h), *(len(c[k]) for c in rows)) for k, (h, _, _) in enumerate(cols)]
    line = lambda cells: "  " + "  ".join(c.ljust(w) for c, w in zip(cells, widths)).rstrip()  # noqa: E731
    if error is None or rank not in ("force", "squeeze"):
        note = ("; no error stated for this scene, so which of them are equally good is not known" if error is None
                else "")
    elif not np.isfinite(error):
        note = "; ≈: the scene states that one run may even give the wrong verdict, so any of them may be the best"
    else:
        note = (f"; ≈: within the stated error (±{100 * error:.3g} % each) of the best, so as good as it as far as "
                "this mesh can tell")
    return [f"best       ranked by {_RANKED_BY[rank]}{note}", line([h for h, _, _ in cols]), *map(line, rows)]


def cmd_search(args: argparse.Namespace) -> int:
    from .batch.engine import search

    scene = _load_scene(args)
    if args.workers is not None and args.workers < 0:
        raise _BadInput("--workers must be >= 0 (0: a plain loop in this process)")
    grid = {k: _grid_option(getattr(args, k), f"--{k}") for k in ("heights", "azimuths", "tilts", "ratios")}
    for k in ("tilts", "ratios"):  # a bare number of tilts or ratios is that value, not a count
        if isinstance(grid[k], int):
            grid[k] = [float(grid[k])]
    result = search(scene, args.out, candidates=args.candidates, seed=args.seed, cone=args.cone,
                    workers=args.workers, scheduler=args.scheduler, resume=args.resume, force=args.force,
                    rank=args.rank, best=args.best if args.out else 0, report=not args.no_report and bool(args.out),
                    cache_dir=_cache_dir(args), connect_timeout=args.connect_timeout,
                    progress=_progress_enabled(args), **grid)
    t, cs = result.table, result.candidates
    n_ok, n_err = result.n_grasped, result.n_errors
    rejected = ", ".join(f"{k} {v}" for k, v in cs.rejected.items()) or "none"
    _out(args, f"search     {scene.name}{' (quick)' if scene.quick else ''}: {len(t)} candidates of {cs.valid} valid "
               f"grid points (rejected: {rejected}); {result.engine}")
    verdict = "picked up" if result.lifts else "pass the lift test (the lift is not simulated)"
    _out(args, f"result     {n_ok} {verdict}, {len(t) - n_ok - n_err} not, {n_err} errors"
               + (f" ({result.resumed} from an earlier run)" if result.resumed else ""))
    best = result.ranked[result.ranked["rank"] > 0].head(max(args.best, 5))
    for line in _best_table(best, args.rank, result.expected_error):
        _out(args, line)
    per = t["time"].median() if len(t) else float("nan")
    _out(args, "time       " + ", ".join(f"{k} {v:.1f} s" for k, v in result.timings.items())
               + f"; median {per:.2f} s per candidate")
    if args.out:
        out = Path(args.out)
        _out(args, f"files      {out}/results.parquet, {out}/results.csv (one row per candidate), {out}/search.json")
        if result.report is not None:
            _out(args, f"report     {result.report}" + (f" (best grasps: {out}/best/01 …)" if result.best else ""))
    return EXIT_OK if n_ok else EXIT_FAILED


# ------------------------------------------------------------------ parser
def build_parser() -> argparse.ArgumentParser:
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors; no progress bar")
    common.add_argument("-v", "--verbose", action="count", default=0,
                        help="log what the library does (-v: info, -vv: debug) to stderr")
    common.add_argument("--log-file", metavar="FILE",
                        help="also write the library's log (info, or debug with -vv) to FILE, with times")

    scene_opts = argparse.ArgumentParser(add_help=False)
    scene_opts.add_argument("scene", help="scene file (TOML) or the name of a shipped scene (see `fem-grasp scenes`)")
    scene_opts.add_argument("--quick", action="store_true",
                            help="apply the scene's [quick] overrides (a coarse mesh: seconds instead of minutes)")
    scene_opts.add_argument("--out", metavar="DIR", help="write results into DIR (refused if DIR is not empty and "
                                                         "was not written by fem_grasp, unless --force)")
    scene_opts.add_argument("--force", action="store_true", help="write into a non-empty folder not written by us")
    scene_opts.add_argument("--cache", metavar="DIR", help="cache folder for meshes and resting states "
                                                           "(default: $XDG_CACHE_HOME/fem_grasp or ~/.cache/fem_grasp)")
    scene_opts.add_argument("--no-cache", action="store_true", help="neither read nor write the cache")
    scene_opts.add_argument("--allow-implausible-units", action="store_true",
                            help="compute even when the object's size (over 1 m) or density (outside 10–20,000 "
                                 "kg/m^3) says its mesh is in another unit; without it such a scene is refused "
                                 "(exit 2): set units = \"mm\" in the scene's [object] table instead")

    ap = argparse.ArgumentParser(prog="fem-grasp",
                                 description="fem-grasp (also python -m fem_grasp): will two fingers pick up a soft "
                                             "object by squeezing and lifting it? Every command takes -v, --log-file "
                                             "and -q; `fem-grasp COMMAND --help` for its options.",
                                 epilog="Exit status: 0 success, 1 the grasp failed, 2 bad input, 3 internal error. "
                                        "Units are SI (m, N, Pa) unless a scene string says otherwise.")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND", required=True)

    p = sub.add_parser("run", parents=[common, scene_opts], help="squeeze and lift the object of a scene",
                       description="Run Algorithm 1 on a scene: rest on the table, squeeze with the lift test, lift. "
                                   "Prints a summary (squeeze depth ρ in mm, forces in N). Exit status 0 when the "
                                   "object is picked up, 1 when not (a valid answer), 2 on bad input.")
    p.add_argument("--report", action="store_true", help="also render report.html and its pictures into --out")
    p.add_argument("--backend", choices=["sparse", "spectral"],
                   help="override the scene's contact solver (spectral: dense eigendecomposition, the paper's)")
    p.add_argument("--no-lift", action="store_true",
                   help="stop when the lift test passes (is it liftable?) instead of simulating the lift; the exit "
                        "status is then 1, as the object has not been lifted")
    p.add_argument("--young", metavar="E",
                   help="override the scene's Young's modulus: pascals, or a string with a unit, e.g. '20 kPa'")
    p.add_argument("--accuracy", metavar="A",
                   help="override the scene's [solver] accuracy: a relative error of rho* and the finger force "
                        "(0.05 or 5%%): refine at the contact patches until two successive answers agree within it; "
                        "'off' runs once on the scene's mesh (--quick always runs once, on its coarse mesh, and says "
                        "that its answer is not converged)")
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("rest", parents=[common, scene_opts], help="compute the resting state of a scene's object",
                       description="Rest the object on the table (paper §III-A): contacts, forces (N), sag (mm).")
    p.add_argument("--backend", choices=["sparse", "spectral"], help="override the scene's contact solver")
    p.set_defaults(func=cmd_rest)

    p = sub.add_parser("mesh", parents=[common], help="closed surface scan (STL/OBJ/PLY) → tetrahedral mesh",
                       description="Check a closed triangle surface (closed, manifold, one piece, not "
                                   "self-intersecting) and fill it with tetrahedra (gmsh). Without --vertices or "
                                   "--size the scan's triangles are kept; with them the surface is remeshed "
                                   "(simplifying a dense scan).")
    p.add_argument("input", help="surface file: .stl, .obj, .ply or .off (coordinates in metres unless --units)")
    p.add_argument("--units", choices=["m", "cm", "mm"], default="m",
                   help="the unit of the file's coordinates (scanners often write mm); the mesh is written in metres")
    p.add_argument("-o", "--output", required=True, help="volume mesh to write (.vtu, .msh, .xdmf, …)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--vertices", type=int, help="remesh to about this many vertices (±10 %%)")
    g.add_argument("--size", type=float, help="remesh at this target edge length, metres (after --units)")
    p.add_argument("--force", action="store_true", help="overwrite OUTPUT if it exists")
    p.set_defaults(func=cmd_mesh)

    p = sub.add_parser("info", parents=[common], help="figures of a mesh, a surface, a scene, a result or a series",
                       description="Volume mesh: counts, volume (m^3), bounds (m), quality. Surface: counts and "
                                   "whether it can be meshed. Scene: its parsed values in SI units. result.json (or "
                                   "its folder): the run's answer and forces. A .pvd series: its frames and times.")
    p.add_argument("path", help="mesh file, surface file, scene file or shipped scene name, result.json, or a .pvd")
    p.add_argument("--quick", action="store_true", help="for a scene: apply its [quick] overrides")
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("report", parents=[common], help="render report.html from a run's output folder",
                       description="Render the pictures (pyvista, off-screen) and report.html from DIR/result.json "
                                   "and the time series written by `fem-grasp run --out DIR`.")
    p.add_argument("dir", help="output folder of `fem-grasp run`")
    p.add_argument("--colour", choices=["von_mises", "energy", "elastic", "displacement"], default="von_mises",
                   help="colour the 3D views by the von Mises stress (default, kPa), the strain energy density "
                        "(J/m^3), the displacement less its rigid motion or the whole displacement (mm)")
    p.set_defaults(func=cmd_report)

    p = sub.add_parser("search", parents=[common, scene_opts], help="where to grasp: Algorithm 1 for many placements",
                       description="A placement search: candidate finger placements (heights, azimuths of the squeeze "
                                   "axis, tilts, ratios s; antipodal, clear of the table, force closure) each run "
                                   "through Algorithm 1 on a Dask cluster (a local one by default); results.parquet "
                                   "and results.csv written as they arrive, report.html with the best grasps. Exit "
                                   "status 0 when some candidate picks the object up, 1 when none does, 2 on bad input "
                                   "or an unreachable scheduler.")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--workers", type=int, metavar="N",
                   help="worker processes of the local Dask cluster (default: the cores; 0: a plain loop here)")
    g.add_argument("--scheduler", metavar="ADDRESS", help="run on an existing Dask cluster, e.g. tcp://HOST:8786")
    p.add_argument("--candidates", type=int, default=64, metavar="N", help="at most N candidates (default 64)")
    p.add_argument("--heights", metavar="SPEC", help="heights as fractions of the object's height above the table "
                                                     "clearance: a count N, LO:HI:N or A,B,C (one value: A,) (default: sized "
                                                     "to --candidates)")
    p.add_argument("--azimuths", metavar="SPEC", help="azimuths of the squeeze axis, degrees: a count N, LO:HI:N or "
                                                      "A,B,C (one value: A,) (default: N over [0, 180) when s = 1, "
                                                      "else [0, 360))")
    p.add_argument("--tilts", metavar="SPEC", help="downward tilts of the squeeze directions, degrees: A, A,B,C or "
                                                   "LO:HI:N (default: the paper's 13.1)")
    p.add_argument("--ratios", metavar="SPEC", help="squeeze ratios s: A, A,B,C or LO:HI:N (default 1)")
    p.add_argument("--seed", type=int, default=0, help="picks the candidates when the grid holds more (default 0)")
    p.add_argument("--cone", type=float, metavar="DEG", help="half-angle of the antipodal cone (default atan mu_F)")
    p.add_argument("--resume", action="store_true", help="skip the candidates whose results DIR already holds")
    p.add_argument("--rank", choices=["force", "squeeze", "margin"], default="force",
                   help="rank grasps by the least finger normal force (default), the least rho*, or the largest w/mg")
    p.add_argument("--best", type=int, default=3, metavar="K", help="full results and pickup reports of the best K")
    p.add_argument("--no-report", action="store_true", help="do not render report.html")
    p.add_argument("--connect-timeout", type=float, default=10.0, metavar="S",
                   help="seconds to reach --scheduler and find a worker on it (default 10)")
    p.set_defaults(func=cmd_search)

    p = sub.add_parser("scenes", parents=[common], help="list the scenes shipped with fem_grasp")
    p.set_defaults(func=cmd_scenes)
    return ap


@contextlib.contextmanager
def _logging(args: argparse.Namespace) -> Iterator[None]:
    """Route fem_grasp's log records to stderr at the chosen level for one command (and, with ``--log-file``,
    every record from INFO up — DEBUG with -vv — to that file); show fem_grasp's warnings (units, locking) as
    one line each; restore everything afterwards.

    ``main`` runs in-process (tests, notebooks), so the level and handler it sets must not outlive it.
    """
    import warnings

    level = logging.ERROR if args.quiet else [logging.WARNING, logging.INFO, logging.DEBUG][min(args.verbose, 2)]
    root = logging.getLogger("fem_grasp")
    old_level, old_propagate = root.level, root.propagate
    handlers: list[logging.Handler] = []
    console = logging.StreamHandler(sys.stderr)
    console.setFormatter(logging.Formatter("%(levelname)s: %(message)s"))
    console.setLevel(level)
    handlers.append(console)
    file_level = level
    if getattr(args, "log_file", None):
        try:
            fh = logging.FileHandler(args.log_file, encoding="utf-8")
        except OSError as exc:
            print(f"fem-grasp: error: --log-file {args.log_file}: {exc}", file=sys.stderr)
            raise SystemExit(EXIT_BAD_INPUT) from None
        file_level = logging.DEBUG if args.verbose >= 2 else logging.INFO
        fh.setLevel(file_level)
        fh.setFormatter(logging.Formatter("%(asctime)s %(name)s %(levelname)s: %(message)s"))
        handlers.append(fh)
    root.setLevel(min(level, file_level))
    for h in handlers:
        root.addHandler(h)
    root.propagate = False
    # The accuracy loop's levels are shown as they finish, even at the default level: a refinement can take
    # minutes, and silence then reads as a hang.
    levels = logging.getLogger("fem_grasp.grasp.accuracy")
    old_levels_level = levels.level
    progress = None
    if not args.quiet and level > logging.INFO:
        progress = logging.StreamHandler(sys.stderr)
        progress.setFormatter(logging.Formatter("%(message)s"))
        progress.addFilter(lambda record: record.levelno == logging.INFO and record.msg.startswith("accuracy level"))
        levels.setLevel(logging.INFO)
        levels.addHandler(progress)
    old_show = warnings.showwarning

    def show(message: Any, category: type, filename: str, lineno: int, file: Any = None, line: Any = None) -> None:
        if issubclass(category, UserWarning) and "fem_grasp" in str(filename):
            logging.getLogger("fem_grasp.warnings").warning("%s", message)
        else:
            old_show(message, category, filename, lineno, file, line)

    try:
        with warnings.catch_warnings():  # the caller's filters stay (pytest's errors, -W); only the display changes
            warnings.showwarning = show
            yield
    finally:
        warnings.showwarning = old_show
        for h in handlers:
            root.removeHandler(h)
            h.close()
        if progress is not None:
            levels.removeHandler(progress)
            progress.close()
        levels.setLevel(old_levels_level)
        root.setLevel(old_level)
        root.propagate = old_propagate


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status (0 success, 1 grasp failed, 2 bad input, 3 internal error)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help (0) or a usage error (2)
        return int(exc.code or 0)
    args.argv = argv
    try:
        with _logging(args):
            return _dispatch(args)
    except SystemExit as exc:  # --log-file cannot be opened
        return int(exc.code or 0)


def _dispatch(args: argparse.Namespace) -> int:
    from .errors import FrictionError, MeshError, OutputError, RestConvergenceError, SceneError, SurfaceError

    try:
        return int(args.func(args))
    except (_BadInput, SceneError, SurfaceError, MeshError, OutputError, FileNotFoundError) as exc:
        print(f"fem-grasp {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except ValueError as exc:  # pickup()/rest() refuse bad scene values with ValueError subclasses
        print(f"fem-grasp {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except (FrictionError, RestConvergenceError) as exc:
        # No resting state: the object slides off or never settles on the table.  An answer, not a bug.
        print(f"fem-grasp {args.command}: the object does not come to rest on the table: {exc}", file=sys.stderr)
        return EXIT_FAILED
    except KeyboardInterrupt:
        print("fem-grasp: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - report, do not dump a traceback on the user
        log.debug("internal error", exc_info=True)
        print(f"fem-grasp {args.command}: internal error ({type(exc).__name__}): {exc} — rerun with -vv for the "
              "traceback and report it", file=sys.stderr)
        return EXIT_INTERNAL


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
