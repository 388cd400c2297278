"""``fem-grasp run``, ``rest`` and ``report``: a scene's pickup (Algorithm 1) or its resting state, the summary
printed after it, and report.html from a run's output folder.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import time
from pathlib import Path
from typing import Any

import numpy as np

from .common import (
    EXIT_FAILED,
    EXIT_INTERNAL,
    EXIT_OK,
    BadInput,
    Progress,
    cache_dir_of,
    echo,
    mm,
    number,
    progress_on,
    scene_of,
)

__all__ = ["cmd_report", "cmd_rest", "cmd_run"]

log = logging.getLogger(__name__)


def _verdict(result: Any) -> str:
    if result.success:
        return f"PICKED UP at rho = {mm(result.squeeze_depth)}"
    if result.outcome == "lift not run":
        return (f"lift test passed at rho = {mm(result.squeeze_depth)}; lift not simulated (--no-lift: is it "
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
    rigid_n = number(rigid.total_normal_force if rigid is not None and rigid.feasible else None, "N")
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
        f"max sag {mm(result.rest.max_sag)}{' [cached]' if rest_cached else ''}",
        f"result     {_verdict(result)}",
        f"squeeze    rho = {mm(result.squeeze_depth)} (max {mm(result.max_squeeze)}), "
        f"liftable weight up to {wmax:.4g} N (weight {result.body.weight:.4g} N)",
        f"contacts   {result.n_final_contacts} in the final configuration",
        *_force_lines(result),
        f"events     {len(result.events)}: " + ", ".join(f"{k} {v}" for k, v in counts.items())
        + "  (A contact, B break, C stick→slip, D slip→stick)",
        "time       " + ", ".join(time_parts),
    ]
    acc = getattr(result, "accuracy", None)
    if acc and len(acc["levels"]) > 1 and "seconds" in acc:  # the timings are the last level's
        lines[-1] = (f"time       {acc['seconds']:.1f} s for {len(acc['levels'])} levels; the last: "
                     + ", ".join(time_parts))
    if acc:
        if not acc["converged"]:
            lines[2] += ("  (one run on this mesh: see accuracy)" if len(acc["levels"]) == 1 else
                         "  (less accurate than requested: see accuracy)" if _errors_known(acc) else
                         "  (the verdict is not settled at this resolution: see accuracy)")
        lines[3:3] = _accuracy_lines(acc, scene.quick)
    return lines


def _errors_known(acc: dict[str, Any]) -> bool:
    """The refined answer states finite errors of ρ* and the force (else its verdict is not settled)."""
    e = acc["estimated_error"]
    return all(np.isfinite(e[k]) for k in ("squeeze_depth", "finger_force"))


def _accuracy_lines(acc: dict[str, Any], quick: bool) -> list[str]:
    """The estimated error of the answer, and one line per level (:func:`fem_grasp.grasp.accuracy.converged_pickup`)."""
    from ..grasp.accuracy import levels_label
    from ..grasp.accuracy import percent_error as pct

    e = acc["estimated_error"]

    last = acc["levels"][-1]
    deepest = last.get("max_squeeze")
    # a failure that squeezed to the deepest squeeze answers that setting, the same on every level: no error
    rho_error = ("none (rho is the deepest squeeze, a setting)" if not last["success"] and deepest
                 and last["squeeze_depth"] >= deepest * (1 - 1e-9) else pct(e["squeeze_depth"]))
    if acc["converged"]:
        head = (f"accuracy   target {100 * acc['target']:g} %: estimated error rho* {rho_error}, "
                f"finger force {pct(e['finger_force'])} ({levels_label(len(acc['levels']), acc.get('refinement'))}, "
                f"{acc.get('seconds', 0):.0f} s)")
    elif len(acc["levels"]) == 1:
        stated = acc.get("expected_error_stated")
        bound = e["squeeze_depth"]
        hint = " (without --accuracy off the run refines it)" if acc.get("refinable") else ""
        how = ("the convergence study found that such a run can even reach another verdict than a finer mesh"
               if stated and not np.isfinite(bound) else
               f"measured against this scene's converged answer, such a run is within about {pct(bound)} of its rho* "
               f"and finger force{hint}" if stated
               else f"how far it is from the converged answer is not known{hint}")
        head = (f"accuracy   {acc.get('note', '')}; {how}"
                + (f"; run without --quick for the answer to {100 * acc['target']:g} %"
                   if quick and acc.get("target") is not None and np.isfinite(acc["target"]) else ""))
    elif not _errors_known(acc):
        why = acc.get("verdict") or "the last two meshes give different verdicts"
        head = (f"accuracy   the requested {100 * acc['target']:g} % was not reached ({acc.get('note', '')}): {why}, "
                "so the verdict itself is not settled at this resolution"
                + ("; run without --quick for the refined answer" if quick else ""))
    else:
        head = (f"accuracy   target {100 * acc['target']:g} %, not reached: estimated error rho* "
                f"{rho_error}, finger force {pct(e['finger_force'])} ({acc.get('note', '')})"
                + ("; run without --quick for the refined answer" if quick else ""))
    lines = [head]
    given = acc.get("given_mesh")
    if given:
        lines.append(f"  given    {given['vertices']:,} vertices, its finger nodes "
                     f"{1e3 * given['grasp_offset']:.2g} mm from the grasp points: "
                     f"{'picked up' if given['success'] else 'not picked up'}, rho "
                     f"{1e3 * given['squeeze_depth']:.4g} mm, finger force {given['finger_force']:.4g} N "
                     "(another grasp: level 0 is remeshed with the points as nodes)")
    for lv in acc["levels"]:
        lines.append(f"  level {lv['level']}  {lv['vertices']:,} vertices, spacing {1e3 * lv['inner_size']:.3g} mm at "
                     f"the patches, increment {1e3 * lv['step']:.3g} mm"
                     + (f" (divided by {lv['step_divisions']} where the lift test passed)"
                        if lv.get("step_divisions", 1) > 1 else "") + ": "
                     f"{'picked up' if lv['success'] else 'not picked up'}, rho {1e3 * lv['squeeze_depth']:.4g} mm, "
                     f"finger force {lv['finger_force']:.4g} N, {lv['seconds'] + lv['mesh_seconds']:.1f} s")
    return lines


# ------------------------------------------------------------------ commands
def cmd_run(args: argparse.Namespace) -> int:
    from ..io.output import check_out_path, prepare_out_dir

    scene = scene_of(args)
    out = Path(args.out) if args.out else None
    if args.report and out is None:
        raise BadInput("--report needs --out DIR (the report is written there)")
    if args.report:  # before the pickup: a missing extra is said now, not after minutes of simulation
        from ..io.report import require_report_extra

        require_report_extra("--report")
    if out is not None:
        check_out_path(out)
        prepare_out_dir(out, args.force)
    cache = cache_dir_of(args)
    phases = ["mesh", "rest", "pickup"] + (["write"] if out else []) + (["report"] if args.report else [])
    bar = Progress(phases, progress_on(args))
    with contextlib.ExitStack() as stack:
        pool = None
        if args.report:  # the renderer starts in its own process while the pickup runs
            from ..io.report import render_process

            pool = stack.enter_context(render_process(warm=True))
        result, cached, t_write = _run_and_write(args, scene, out, cache, bar, pool)
    for line in _summary_lines(scene, result, cached):
        echo(args, line)
    code = _exit_code(result)
    if scene.expect is not None and (scene.expect == "success") != result.success:
        log.warning("scene %s expects %s but the pickup %s", scene.name, scene.expect,
                    "succeeded" if result.success else "failed")
    if out is not None:
        echo(args, f"output     {out}/result.json, {out}/object.pvd (ParaView: open object.pvd, finger1.pvd, "
                   f"finger2.pvd, table.vtu; time = the finger path in metres), written in {t_write:.1f} s")
        if args.report:
            echo(args, f"report     {out}/report.html")
    return code


def _exit_code(result: Any) -> int:
    """What ``fem-grasp run`` exits with for ``result`` (and records in result.json)."""
    return EXIT_OK if result.success else EXIT_FAILED


def _run_and_write(args: argparse.Namespace, scene: Any, out: Path | None, cache: Any, bar: Progress,
                   pool: Any) -> tuple[Any, bool, float]:
    """The pickup of ``scene``, its output written into ``out`` and its report drawn (in ``pool``) when asked;
    (result, whether the rest came from the cache, seconds spent writing)."""
    from ..io.output import write_run
    from ..io.scene import pickup_scene

    t_write = 0.0
    try:
        result, cached = pickup_scene(scene, cache, phase=bar.phase)
        if out is not None:
            t0 = time.perf_counter()
            with bar.phase("writing results"):
                write_run(out, result, scene, force=True,
                          extra={"exit_code": _exit_code(result),
                                 "rest_from_cache": cached, "command": list(args.argv)})
            t_write = time.perf_counter() - t0
        if args.report:
            from ..io.report import write_report

            with bar.phase("rendering the report"):
                write_report(out, pool=pool)
    finally:
        bar.close()
    return result, cached, t_write


def cmd_rest(args: argparse.Namespace) -> int:
    from ..io.cache import cached_rest
    from ..io.output import prepare_out_dir, write_rest

    scene = scene_of(args)
    out = Path(args.out) if args.out else None
    if out is not None:
        prepare_out_dir(out, args.force)
    cache = cache_dir_of(args)
    body = scene.body(cache)
    rs, cached = cached_rest(body, scene.mu_table, backend=scene.backend, down=scene.object.down, cache_dir=cache)
    fig = rs.check(raise_on_failure=False)
    echo(args, f"scene      {scene.name}{' (quick)' if scene.quick else ''}: {body.n_nodes} nodes, weight "
               f"{body.weight:.4g} N, E {scene.young:.4g} Pa, mu table {scene.mu_table:g}")
    echo(args, f"rest       {rs.n_contacts} table contacts ({int(rs.sliding.sum())} sliding), max sag "
               f"{number(rs.max_sag, 'mm', 1e3)}, {rs.iterations} iterations{' [cached]' if cached else ''}")
    echo(args, f"checks     {'pass' if fig['ok'] else 'FAIL: ' + '; '.join(fig['failures'])} (equilibrium "
               f"{fig['force_residual']:.1e} force, {fig['torque_residual']:.1e} torque)")
    if out is not None:
        write_rest(out, rs, scene, force=True, extra={"rest_from_cache": cached})
        echo(args, f"output     {out}/rest.json, {out}/rest.vtu")
    return EXIT_OK if fig["ok"] else EXIT_INTERNAL


def cmd_report(args: argparse.Namespace) -> int:
    from ..io.report import write_report

    path = write_report(Path(args.dir), colour=args.colour)
    echo(args, f"report     {path}")
    return EXIT_OK
