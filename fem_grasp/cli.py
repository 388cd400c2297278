"""The ``fem-grasp`` command line (also ``python -m fem_grasp``).

Subcommands::

    fem-grasp run SCENE [--quick] [--out DIR] [--report] [--accuracy A]   squeeze and lift (Algorithm 1)
    fem-grasp rest SCENE [--quick] [--out DIR]              the resting state only (§III-A)
    fem-grasp mesh INPUT -o OUTPUT [--vertices N | --size H] closed surface scan → tetrahedral mesh
    fem-grasp info PATH                                     figures of a mesh, a surface or a scene
    fem-grasp report DIR                                    report.html + pictures from a run's output
    fem-grasp scenes                                        the scenes shipped with fem_grasp

SCENE is a TOML file (:mod:`fem_grasp.scene`) or the name of a shipped
scene (``tomato``, ``orange``, ``steam_bun``, ``football``, ``foam_block``,
``slippery_soap``).  Exit status: 0 success, 1 the grasp failed (a valid
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

__all__ = ["main", "EXIT_OK", "EXIT_FAILED", "EXIT_BAD_INPUT", "EXIT_INTERNAL"]

log = logging.getLogger(__name__)

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_INTERNAL = 0, 1, 2, 3


class _BadInput(Exception):
    """Raised inside a command for input problems: exit status 2."""


# ------------------------------------------------------------------ progress
class Progress:
    """A phase-by-phase progress bar (tqdm) on a terminal; silent otherwise or when quiet.

    ``pickup()`` reports no progress from inside, so the bar advances by
    phase (mesh, rest, pickup, write, report) and shows the elapsed time.
    """

    def __init__(self, phases: Sequence[str], enabled: bool) -> None:
        self.bar = None
        if enabled:
            try:
                from tqdm import tqdm
            except ImportError:
                tqdm = None
            if tqdm is not None:
                self.bar = tqdm(total=len(phases), unit="phase", file=sys.stderr, leave=False, mininterval=0,
                                bar_format="{desc:<28} {bar:20} {n_fmt}/{total_fmt} [{elapsed}]")

    @contextlib.contextmanager
    def phase(self, name: str) -> Iterator[None]:
        if self.bar is not None:
            self.bar.set_description_str(name, refresh=True)
        yield
        if self.bar is not None:
            self.bar.update(1)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _progress_enabled(args: argparse.Namespace) -> bool:
    return not args.quiet and sys.stderr.isatty()


# ------------------------------------------------------------------ helpers
def _out(args: argparse.Namespace, text: str = "") -> None:
    if not args.quiet:
        print(text)


def _cache_dir(args: argparse.Namespace) -> Path | None:
    from .scene import default_cache_dir

    if args.no_cache:
        return None
    return Path(args.cache) if args.cache else default_cache_dir()


def _load_scene(args: argparse.Namespace) -> Any:
    from .scene import load_scene, resolve_scene, with_overrides

    scene = load_scene(resolve_scene(args.scene), quick=args.quick)
    young = getattr(args, "young", None)
    if young is not None:
        from .scene import _positive, parse_quantity

        young = parse_quantity(young, "pressure", "--young")
        _positive("--young", young, "Pa")
    scene = with_overrides(scene, backend=getattr(args, "backend", None), young=young,
                           lift=False if getattr(args, "no_lift", False) else None)
    accuracy = getattr(args, "accuracy", None)
    if accuracy is not None:
        from dataclasses import replace

        scene = replace(scene, accuracy=_parse_accuracy(accuracy))
    return scene


def _parse_accuracy(text: str) -> float | None:
    """``--accuracy``: a relative error (0.05), a percentage (5%), or off (one run on the scene's mesh)."""
    t = str(text).strip().lower()
    if t in ("off", "none", "no"):
        return None
    try:
        value = float(t[:-1]) / 100.0 if t.endswith("%") else float(t)
    except ValueError:
        raise _BadInput(f"--accuracy: expected a relative error such as 0.05, a percentage such as 5%, or off; "
                        f"got {text!r}") from None
    if not 0.0 < value < 1.0:
        raise _BadInput(f"--accuracy: a relative error in (0, 1) (e.g. 0.05 or 5%), got {text!r}")
    return value


def _check_contacts(scene: Any, mesh: Any) -> None:
    if scene.contacts is None:
        return
    src = scene.path or "<scene>"
    surface = set(mesh.surface_nodes.tolist())
    for k in scene.contacts:
        if k >= mesh.n_points:
            raise _BadInput(f"{src}: fingers.contacts: node {k} does not exist (the mesh has {mesh.n_points} nodes, "
                            f"0 … {mesh.n_points - 1}); with --quick the mesh differs, use contacts = \"auto\"")
        if k not in surface:
            raise _BadInput(f"{src}: fingers.contacts: node {k} is not on the surface of the mesh")


def _fmt(x: float | None, unit: str = "", scale: float = 1.0, digits: int = 4) -> str:
    if x is None or not np.isfinite(x):
        return "—"
    return f"{x * scale:.{digits}g}{(' ' + unit) if unit else ''}"


def _summary_lines(scene: Any, result: Any, rest_cached: bool) -> list[str]:
    counts = result.event_counts()
    rigid = result.rigid
    wmax = max((w for _, w in result.liftable), default=0.0)
    lines = [
        f"scene      {scene.name}{' (quick)' if scene.quick else ''}: {result.body.n_nodes} nodes, "
        f"{result.body.mesh.n_tets} tets, weight {result.body.weight:.4g} N, E {scene.young:.4g} Pa, "
        f"nu {scene.poisson:g}, mu finger {scene.mu_finger:g}, mu table {scene.mu_table:g}",
        f"rest       {result.rest.n_contacts} table contacts ({int(result.rest.sliding.sum())} sliding), "
        f"max sag {_fmt(result.rest.max_sag, 'mm', 1e3)}{' [cached]' if rest_cached else ''}",
        f"result     {'PICKED UP' if result.success else 'NOT PICKED UP'}"
        + ("" if result.success else f": {result.reason}"),
        f"squeeze    rho = {_fmt(result.squeeze_depth, 'mm', 1e3)} (max {_fmt(result.max_squeeze, 'mm', 1e3)}), "
        f"liftable weight up to {wmax:.4g} N",
        f"contacts   {result.n_final_contacts} in the final configuration; finger normal force "
        f"{result.finger_normal_force:.4g} N (rigid object: "
        f"{_fmt(rigid.total_normal_force if rigid is not None and rigid.feasible else None, 'N')})",
        f"events     {len(result.events)}: " + ", ".join(f"{k} {v}" for k, v in counts.items())
        + "  (A contact, B break, C stick→slip, D slip→stick)",
        "time       " + ", ".join(f"{k} {v:.2f} s" for k, v in result.timings.items()),
    ]
    acc = getattr(result, "accuracy", None)
    if acc:
        if not acc["converged"]:
            lines[2] += "  [NOT CONVERGED: see accuracy]"
        lines[3:3] = _accuracy_lines(acc, scene.quick)
    return lines


def _accuracy_lines(acc: dict[str, Any], quick: bool) -> list[str]:
    """The estimated error of the answer, and one line per level (:func:`fem_grasp.accuracy.converged_pickup`)."""
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
        how = ("its verdict may differ from the converged one" if stated and not np.isfinite(bound) else
               f"it may be off by about {pct(bound)} in rho* and the finger force (as measured by the convergence "
               "study for this scene)" if stated else "how far it is off is not known")
        head = (f"accuracy   NOT CONVERGED: {acc.get('note', '')}; {how}"
                + (f"; run without --quick for the answer to {100 * acc['target']:g} %"
                   if quick and acc.get("target") is not None and np.isfinite(acc["target"]) else ""))
    elif not all(np.isfinite(v) for v in (e["squeeze_depth"], e["finger_force"])):
        head = (f"accuracy   NOT CONVERGED to {100 * acc['target']:g} %: {acc.get('note', '')}, so not even the verdict "
                "is settled at this resolution" + ("; run without --quick for the converged answer" if quick else ""))
    else:
        head = (f"accuracy   NOT CONVERGED to {100 * acc['target']:g} %: the answer may be off by about "
                f"{pct(e['squeeze_depth'])} in rho* and {pct(e['finger_force'])} in the finger force "
                f"({acc.get('note', '')})" + ("; run without --quick for the converged answer" if quick else ""))
    lines = [head]
    for lv in acc["levels"]:
        lines.append(f"  level {lv['level']}  {lv['vertices']:,} vertices, spacing {1e3 * lv['inner_size']:.3g} mm at "
                     f"the patches, increment {1e3 * lv['step']:.3g} mm: "
                     f"{'picked up' if lv['success'] else 'not picked up'}, rho {1e3 * lv['squeeze_depth']:.4g} mm, "
                     f"finger force {lv['finger_force']:.4g} N, {lv['seconds'] + lv['mesh_seconds']:.1f} s")
    return lines


# ------------------------------------------------------------------ commands
def cmd_run(args: argparse.Namespace) -> int:
    from .output import prepare_out_dir, write_run
    from .pickup import pickup
    from .scene import cached_rest

    scene = _load_scene(args)
    out = Path(args.out) if args.out else None
    if args.report and out is None:
        raise _BadInput("--report needs --out DIR (the report is written there)")
    if out is not None:
        prepare_out_dir(out, args.force)
    cache = _cache_dir(args)
    phases = ["mesh", "rest", "pickup"] + (["write"] if out else []) + (["report"] if args.report else [])
    bar = Progress(phases, _progress_enabled(args))
    try:
        with bar.phase("meshing the object"):
            body = scene.body(cache)
            _check_contacts(scene, body.mesh)
        with bar.phase("resting on the table"):
            rs, cached = cached_rest(body, scene.mu_table, backend=scene.backend, down=scene.object.down,
                                     cache_dir=cache)
        with bar.phase("squeeze, lift test, lift" if scene.accuracy is None else "squeeze and lift, refining"):
            if scene.accuracy is None or scene.quick:
                result = pickup(body, rest_state=rs, **scene.pickup_kwargs())
                if scene.quick or scene.expected_error is not None:
                    from .accuracy import single_run_report

                    # One coarse run: not converged; the scene states how far such a run is from the converged
                    # answer (its [quick] solver.expected_error, measured by the convergence study).
                    result.accuracy = single_run_report(
                        result, scene.accuracy, scene.expected_error,
                        "--quick: one run on the coarse mesh, no refinement" if scene.quick else
                        "one run on the scene's mesh (accuracy off)")
            else:
                from .accuracy import converged_pickup

                result = converged_pickup(body, accuracy=scene.accuracy, geometry=scene.geometry(), rest_state=rs,
                                          **scene.pickup_kwargs())
        code = EXIT_OK if result.success else EXIT_FAILED
        if out is not None:
            with bar.phase("writing results"):
                write_run(out, result, scene, force=True,
                          extra={"exit_code": code, "rest_from_cache": cached, "command": list(args.argv)})
        if args.report:
            from .report import write_report

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
                   f"finger2.pvd, table.vtu)")
        if args.report:
            _out(args, f"report     {out}/report.html")
    return code


def cmd_rest(args: argparse.Namespace) -> int:
    from .output import prepare_out_dir, write_rest
    from .scene import cached_rest

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
    from .output import atomic_write_mesh
    from .scan import DENSE_SCAN_VERTICES, SURFACE_SUFFIXES, check_surface, mesh_surface, read_surface

    src, dst = Path(args.input), Path(args.output)
    if src.suffix.lower() not in SURFACE_SUFFIXES:
        raise _BadInput(f"{src}: expected a surface file ({', '.join(SURFACE_SUFFIXES)}), got {src.suffix or 'no suffix'}")
    if dst.exists() and not args.force:
        raise _BadInput(f"{dst} exists; pass --force to overwrite it")
    surf = check_surface(read_surface(src))
    if args.vertices is None and args.size is None and len(surf.points) > DENSE_SCAN_VERTICES:
        log.warning("%s has %d surface vertices; the mesh keeps them all. Pass --vertices N to simplify",
                    src, len(surf.points))
    t0 = time.perf_counter()
    mesh = mesh_surface(surf, target_vertices=args.vertices, size=args.size, check=False)
    atomic_write_mesh(dst, mesh.to_meshio(), file_format=_meshio_format(dst))
    q = mesh.quality
    _out(args, f"{src}: {len(surf.points)} surface vertices, {len(surf.faces)} triangles, closed and manifold")
    _out(args, f"{dst}: {mesh.n_points} vertices, {mesh.n_tets} tets, volume {mesh.volume * 1e6:.4g} cm^3 "
               f"(surface encloses {surf.volume * 1e6:.4g}), min quality {q.min():.3g}, "
               f"{time.perf_counter() - t0:.2f} s")
    return EXIT_OK


def _meshio_format(path: Path) -> str:
    import meshio

    try:
        return meshio._helpers._filetypes_from_path(path)[0]  # type: ignore[attr-defined]
    except Exception:
        raise _BadInput(f"{path}: meshio cannot write files ending in {''.join(path.suffixes) or '(none)'}; "
                        "use .vtu, .msh, .xdmf, .mesh, …") from None


def cmd_info(args: argparse.Namespace) -> int:
    from .scan import SURFACE_SUFFIXES, surface_report

    p = Path(args.path)
    if p.suffix == ".toml" or (not p.exists() and p.suffix == ""):
        from .scene import load_scene, resolve_scene

        scene = load_scene(resolve_scene(args.path), quick=args.quick)
        for k, v in scene.to_dict().items():
            _out(args, f"{k:15s}{v}")
        return EXIT_OK
    if not p.exists():
        raise _BadInput(f"{p} does not exist")
    if p.suffix.lower() in SURFACE_SUFFIXES:
        r = surface_report(p)
        _out(args, f"{p}: surface, {r['vertices']} vertices, {r['triangles']} triangles, diameter "
                   f"{r['diameter']:.4g} m, area {r['area']:.4g} m^2")
        if r["ok"]:
            _out(args, f"closed, manifold, not self-intersecting; encloses {r['volume']:.4g} m^3")
            return EXIT_OK
        _out(args, r["problem"])
        return EXIT_BAD_INPUT
    from .mesh import TetMesh

    m = TetMesh.from_file(p)
    lo, hi = m.bounds
    q = m.quality
    _out(args, f"{p}: {m.n_points} vertices ({len(m.surface_nodes)} on the surface), {m.n_tets} tets, "
               f"{len(m.surface_faces)} surface triangles")
    _out(args, f"volume {m.volume:.6g} m^3, bounds {np.round(lo, 6).tolist()} … {np.round(hi, 6).tolist()} m, "
               f"diameter {m.diameter:.4g} m")
    _out(args, f"quality (1 = regular tet): min {q.min():.3g}, median {np.median(q):.3g}; "
               f"{m.n_reoriented} tets reoriented on reading")
    return EXIT_OK


def cmd_report(args: argparse.Namespace) -> int:
    from .report import write_report

    path = write_report(Path(args.dir))
    _out(args, f"report     {path}")
    return EXIT_OK


def cmd_scenes(args: argparse.Namespace) -> int:
    from .scene import load_scene, shipped_scenes

    for name, path in shipped_scenes().items():
        try:
            desc = load_scene(path).description
        except Exception as exc:  # noqa: BLE001 - list broken scenes too
            desc = f"(cannot be read: {exc})"
        _out(args, f"{name:16s} {desc}")
    return EXIT_OK


# ------------------------------------------------------------------ parser
def build_parser() -> argparse.ArgumentParser:
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors; no progress bar")
    common.add_argument("-v", "--verbose", action="count", default=0, help="log progress (-vv: debug)")

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

    ap = argparse.ArgumentParser(prog="fem-grasp", description=__doc__.split("\n\n")[0],
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
    p.add_argument("input", help="surface file: .stl, .obj, .ply or .off, in metres")
    p.add_argument("-o", "--output", required=True, help="volume mesh to write (.vtu, .msh, .xdmf, …)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--vertices", type=int, help="remesh to about this many vertices (±10 %%)")
    g.add_argument("--size", type=float, help="remesh at this target edge length, metres")
    p.add_argument("--force", action="store_true", help="overwrite OUTPUT if it exists")
    p.set_defaults(func=cmd_mesh)

    p = sub.add_parser("info", parents=[common], help="figures of a volume mesh, a surface, or a scene",
                       description="Volume mesh: counts, volume (m^3), bounds (m), quality. Surface: counts and "
                                   "whether it can be meshed. Scene: its parsed values in SI units.")
    p.add_argument("path", help="mesh file, surface file, scene file or shipped scene name")
    p.add_argument("--quick", action="store_true", help="for a scene: apply its [quick] overrides")
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("report", parents=[common], help="render report.html from a run's output folder",
                       description="Render the pictures (pyvista, off-screen) and report.html from DIR/result.json "
                                   "and the time series written by `fem-grasp run --out DIR`.")
    p.add_argument("dir", help="output folder of `fem-grasp run`")
    p.set_defaults(func=cmd_report)

    p = sub.add_parser("scenes", parents=[common], help="list the scenes shipped with fem_grasp")
    p.set_defaults(func=cmd_scenes)
    return ap


@contextlib.contextmanager
def _logging(args: argparse.Namespace) -> Iterator[None]:
    """Route fem_grasp's log records to stderr at the chosen level for one command; restore afterwards.

    ``main`` runs in-process (tests, notebooks), so the level and handler it sets must not outlive it.
    """
    level = logging.ERROR if args.quiet else [logging.WARNING, logging.INFO, logging.DEBUG][min(args.verbose, 2)]
    root = logging.getLogger("fem_grasp")
    old_level, old_propagate = root.level, root.propagate
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("%(levelname)s: %(message)s"))
    root.setLevel(level)
    root.addHandler(handler)
    root.propagate = False
    try:
        yield
    finally:
        root.removeHandler(handler)
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
    with _logging(args):
        return _dispatch(args)


def _dispatch(args: argparse.Namespace) -> int:
    from .mesh import MeshError
    from .output import OutputError
    from .friction import FrictionError
    from .rest import RestConvergenceError
    from .scan import SurfaceError
    from .scene import SceneError

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
