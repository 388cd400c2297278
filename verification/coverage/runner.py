"""One object of the coverage study: the answer at the target accuracy, then the reference on a finer mesh.

:func:`run_object` is a pure function of the seed and the configuration (same arguments, same row);
:func:`supervised` runs it in a fresh interpreter (spawned, not forked: the full report's process has loaded
dolfinx and MPI, which a fork inherits and hangs on) that is abandoned when the answer or the reference
overruns its time cap.
"""

from __future__ import annotations

import logging
import math
import multiprocessing
import time
import traceback
from typing import Any, Callable

import numpy as np

from .scene import CoverageObject

log = logging.getLogger(__name__)

#: Quantities compared: the key in the answer/reference rows and in ``estimated_error``.
QUANTITIES = ("squeeze_depth", "finger_force")


def _answer_row(res: Any, seconds: float) -> dict[str, Any]:
    from fem_grasp.grasp.answer import answer_of

    ans = answer_of(res, seconds)
    return {"status": "ok", "success": ans.success, "outcome": getattr(res, "outcome", ""), "reason": ans.reason,
            "squeeze_depth": ans.squeeze_depth, "finger_force": ans.finger_force, "max_liftable": ans.max_liftable,
            "weight": ans.weight, "finger_nodes": [f["nodes"] for f in ans.fingers], "vertices": ans.n_vertices,
            "step": ans.step, "lift_test_step": ans.lift_test_step, "seconds": seconds}


def reference_plan(accuracy: dict[str, Any], max_contacts: float) -> dict[str, Any]:
    """The reference's resolution from the answer's levels (``result.accuracy``): one level beyond the last, as
    the loop would make it — the patch spacing halved, the outer spacing the loop's next one, ρ* resolved to a
    quarter of the last level's resolution (its increment divided in four where the lift test passes, as the
    loop's levels do) and the lift-test step h half the last level's — and whether it is too large to run
    (its predicted contacts per fingertip, the last level's times four, above ``max_contacts``)."""
    from fem_grasp.grasp.accuracy import LEVEL_RATIO, PATCH_RADIUS

    levels = accuracy["levels"]
    last = levels[-1]
    inner = last["inner_size"] / LEVEL_RATIO
    predicted = max(last["finger_nodes"]) * LEVEL_RATIO**2
    return {"inner_size": inner, "radius": PATCH_RADIUS * last["inner_size"],
            "outer_size": max(levels[0]["outer_size"] / LEVEL_RATIO ** (0.5 * (last["level"] + 1)), inner),
            "step": last.get("resolution", last["step"]), "step_divisions": 4,
            "lift_test_step": last["lift_test_step"] / 2.0 if last["lift_test_step"] else None,
            "predicted_contacts": predicted, "too_large": predicted > max_contacts}


def run_object(seed: int, config: dict[str, Any], send: Callable[[tuple[str, Any]], None] | None = None
               ) -> dict[str, Any]:
    """Object ``seed``: its answer at ``config["accuracy"]`` and its reference (module notes); the row.

    ``send(("answer", row))`` is called between the two, so that a supervisor keeps the answer when the reference
    runs out of time, and ``send(("level", report))`` after each level of the answer (the loop's
    :class:`~fem_grasp.grasp.accuracy.AccuracyReport` as a dict), so that it keeps the levels run when the answer
    does.
    """
    from fem_grasp import Body
    from fem_grasp.grasp.accuracy import _level_meshes, converged_pickup
    from fem_grasp.grasp.answer import patch_points
    from fem_grasp.grasp.pickup import pickup
    from fem_grasp.mesh.remesh import geometry_of_mesh, nearest_surface_nodes

    obj = CoverageObject.of_seed(seed)
    row: dict[str, Any] = {"seed": seed, "object": obj.to_dict()}
    t0 = time.perf_counter()
    try:
        mesh, smallest = obj.mesh()
        geometry = geometry_of_mesh(mesh)
        body = obj.body(mesh)
        kw = obj.pickup_arguments(smallest)
        on_level = None if send is None else (lambda report: send(("level", report.to_dict())))
        res = converged_pickup(body, solve=pickup, accuracy=config["accuracy"], geometry=geometry,
                               max_seconds=config["answer_seconds"], on_level=on_level,
                               max_finger_contacts=config["answer_max_contacts"],
                               refinement=config.get("refinement", "remesh"), **kw)
        row["answer"] = _answer_row(res, time.perf_counter() - t0)
        row["answer"]["accuracy"] = res.accuracy
    except Exception as exc:  # noqa: BLE001 - recorded: the object has no answer, the study goes on
        row["answer"] = {"status": "failed", "error": f"{type(exc).__name__}: {exc}",
                         "traceback": traceback.format_exc(), "seconds": time.perf_counter() - t0}
        return row
    if send is not None:
        send(("answer", row))

    plan = reference_plan(res.accuracy, config["max_reference_contacts"])
    row["reference"] = {"plan": plan}
    if not plan["step"] > 0:  # the answer stopped before the squeeze (no placement): nothing finer to compare
        row["reference"]["status"] = "no squeeze"
        return row
    if plan["too_large"]:
        row["reference"]["status"] = "too large"
        return row
    t0 = time.perf_counter()
    try:
        fingers, table = patch_points(res)
        # the points every level of the answer grasped at (given, or chosen by the placement rule on level 0)
        points = res.accuracy.get("contact_points")
        embed = None if points is None else np.asarray(points, dtype=float)
        ref_mesh = _level_meshes(geometry, fingers, table, plan["inner_size"], plan["radius"], plan["outer_size"],
                                 embed)
        ref_body = Body(ref_mesh, body.young, body.poisson, weight=body.weight, gravity=body.gravity)
        ref_kw = dict(kw, step=plan["step"], step_divisions=plan["step_divisions"])
        if embed is not None:  # the finger contacts mapped as the loop maps them
            ref_kw["contacts"] = tuple(int(k) for k in nearest_surface_nodes(ref_mesh, embed))
        if plan["lift_test_step"]:
            ref_kw["lift_test_step"] = plan["lift_test_step"]
        mesh_seconds = time.perf_counter() - t0
        ref = pickup(ref_body, **ref_kw)
        row["reference"].update(_answer_row(ref, time.perf_counter() - t0))
        row["reference"]["mesh_seconds"] = mesh_seconds
    except Exception as exc:  # noqa: BLE001 - recorded: the object has no reference
        row["reference"].update(status="failed", error=f"{type(exc).__name__}: {exc}",
                                traceback=traceback.format_exc(), seconds=time.perf_counter() - t0)
    return row


def _child(seed: int, config: dict[str, Any], conn: Any) -> None:
    try:
        row = run_object(seed, config, conn.send)
        conn.send(("done", row))
    finally:
        conn.close()


def supervised(seed: int, config: dict[str, Any], poll: float = 2.0) -> dict[str, Any]:
    """:func:`run_object` in a spawned process: the answer may take ``config["answer_cap"]`` seconds, the
    reference ``config["reference_seconds"]`` after it; a phase that overruns is recorded as ``timed out`` and
    its process terminated (a timed-out answer keeps the loop's levels so far as ``levels_so_far``)."""
    ctx = multiprocessing.get_context("spawn")
    receive, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(seed, config, send), daemon=True)
    row: dict[str, Any] = {"seed": seed, "object": CoverageObject.of_seed(seed).to_dict()}
    phase, started = "answer", time.monotonic()
    cap = config["answer_cap"]
    proc.start()
    send.close()
    try:
        while True:
            if time.monotonic() - started > cap:
                row[phase] = dict(row.get(phase, {}), status="timed out", seconds=time.monotonic() - started)
                break
            if receive.poll(poll):
                try:
                    kind, value = receive.recv()
                except EOFError:
                    kind, value = "died", None
            elif proc.is_alive():
                continue
            else:
                kind, value = "died", None
            if kind == "level":  # the answer's levels so far: kept if the answer runs out of time
                row["answer"] = {"levels_so_far": value}
            elif kind == "answer":
                row, phase, started, cap = value, "reference", time.monotonic(), config["reference_seconds"]
                row["reference"] = {}
            elif kind == "done":
                return value
            else:
                proc.join(10)
                row[phase] = dict(row.get(phase, {}), status="failed", seconds=time.monotonic() - started,
                                  error=f"the worker process ended (exit code {proc.exitcode})")
                break
    finally:
        receive.close()
        if proc.is_alive():
            proc.terminate()
            proc.join(10)
            if proc.is_alive():
                proc.kill()
        proc.join()
    if phase == "reference" and "plan" not in row["reference"]:
        from fem_grasp.grasp.accuracy import LEVEL_RATIO

        last = row["answer"]["accuracy"]["levels"][-1]
        row["reference"]["predicted_contacts"] = max(last["finger_nodes"]) * LEVEL_RATIO**2
    return row


def relative_error(value: float, reference: float) -> float:
    """|value − reference| / |reference| (0 when equal, inf when the reference is 0 and the value not)."""
    if value == reference:
        return 0.0
    return abs(value - reference) / abs(reference) if reference != 0 else math.inf
