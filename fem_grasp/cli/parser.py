"""The ``fem-grasp`` argument parser: the options every command takes, those of the commands that take a scene,
and each subcommand's own (the command-line reference of the documentation is generated from it).
"""

from __future__ import annotations

import argparse

from .._version import version as fem_grasp_version
from ..grasp.options import REFINEMENTS
from .info import cmd_info, cmd_scenes
from .mesh import cmd_mesh
from .run import cmd_report, cmd_rest, cmd_run
from .search import cmd_search

__all__ = ["build_parser"]


def build_parser() -> argparse.ArgumentParser:
    """The parser of ``fem-grasp`` and of each of its subcommands."""
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
                                 epilog="Exit status: 0 success, 1 the grasp failed, 2 bad input or a missing "
                                        "optional dependency (the message names the extra to install), 3 internal "
                                        "error. Units are SI (m, N, Pa) unless a scene string says otherwise.")
    ap.add_argument("--version", action="version", version=f"%(prog)s {fem_grasp_version()}")
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
                        "status is then 1, as the object has not been lifted. Refined, its levels compare the finger "
                        "force on the table at rho* and are meshed without the lift's patches: they settle more "
                        "slowly than a full run's (not quicker, e.g. the foam block: four levels, not converged)")
    p.add_argument("--young", metavar="E",
                   help="override the scene's Young's modulus: pascals, or a string with a unit, e.g. '20 kPa'")
    p.add_argument("--accuracy", metavar="A",
                   help="the accuracy of the answer, a relative error of rho* and the finger force (default: the "
                        "scene's [solver] accuracy, 5%% unless it says otherwise): refine at the contact patches until "
                        "the estimated error is within it; 'off' runs once on the scene's mesh, the paper's Algorithm "
                        "1 as printed (--quick always runs once, on its coarse mesh, and says that its answer is not "
                        "converged)")
    p.add_argument("--max-finger-contacts", metavar="N", type=int,
                   help="when refining: do not run a level predicted to put more than N contacts on one fingertip "
                        "(default 300; each level has about four times the contacts of the one before, and costs "
                        "several times as much)")
    p.add_argument("--refinement", choices=REFINEMENTS,
                   help="when refining: 'nested' (default) bisects the level before at the contact patches, so "
                        "that the levels differ only in resolution; 'remesh' meshes the object afresh at each level")
    p.add_argument("--max-seconds", metavar="S", type=float,
                   help="when refining: a time budget; no level is started that would carry the loop past S "
                        "seconds (predicted from the levels so far), and the answer is the last level's with its "
                        "estimated error (default: the scene's [solver] max_seconds, or none)")
    p.add_argument("--step-divisions", metavar="D", type=int,
                   help="squeeze the increment in which the lift test first passes again in D parts, testing after "
                        "each: rho* to within the scene's step / D for at most D - 1 more lift tests (default: the "
                        "scene's [solver] step_divisions, 1: the paper's Algorithm 1 as printed)")
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
    p.add_argument("--accuracy", metavar="A",
                   help="an accuracy target for every candidate's answer: a relative error of rho* and the finger force "
                        "(0.05 or 5%%, as for `fem-grasp run`): each candidate runs the accuracy loop (refined at its "
                        "contact patches until two successive answers agree within A), its row carries its own "
                        "estimated errors, and ≈ marks the grasps within their and the best one's errors; several "
                        "times the cost per candidate (default: one run per candidate on the scene's mesh, within the "
                        "scene's stated error)")
    p.add_argument("--max-seconds", metavar="S", type=float,
                   help="with --accuracy: each candidate's time budget, as for `fem-grasp run --max-seconds` (the "
                        "levels a budget allows depend on the machine)")
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
