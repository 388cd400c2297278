"""One object of the coverage study: the answer at the target accuracy, then the reference on a finer mesh.

The reference is one level beyond the answer's last (:func:`reference_plan`) meshed by gmsh on
``config["reference_draws"]`` draws — its spacings scaled by 1, 0.98, 1.02, 0.96, … (:func:`draw_factor`), which
gives other tetrahedra of about the same spacing — and is their mean, with their largest deviation from it as its
own uncertainty (:func:`combine_draws`): meshes of one spacing differ by a few per cent, as much as two levels do,
so a single draw cannot confirm a statement of a few per cent.  (Rounding gmsh's inputs to another grid, as the
benchmark draws the paper shapes' levels, left these objects' reference meshes unchanged.)  A saved study's
references (``config["references"]``, by seed) are used again where they are finer than the answer's last level
and squeezed as deep (:func:`reusable`), so that two loops are judged against the same reference.

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
    loop's levels do), the lift-test step h half the last level's and the deepest squeeze the answer's (the loop
    keeps level 0's on every level) — and whether it is too large to run
    (its predicted contacts per fingertip, the last level's times four, above ``max_contacts``)."""
    from fem_grasp.grasp.accuracy import LEVEL_RATIO, PATCH_RADIUS, outer_spacing

    levels = accuracy["levels"]
    last = levels[-1]
    inner = last["inner_size"] / LEVEL_RATIO
    predicted = max(last["finger_nodes"]) * LEVEL_RATIO**2
    return {"inner_size": inner, "radius": PATCH_RADIUS * last["inner_size"],
            "outer_size": outer_spacing(levels[0]["outer_size"], last["level"] + 1, inner),
            "step": last.get("resolution", last["step"]), "step_divisions": 4,
            "lift_test_step": last["lift_test_step"] / 2.0 if last["lift_test_step"] else None,
            "max_squeeze": _deepest_squeeze(accuracy),
            "predicted_contacts": predicted, "too_large": predicted > max_contacts}


def _deepest_squeeze(accuracy: dict[str, Any]) -> float | None:
    """The deepest squeeze every level of the answer stopped at (level 0's: the loop keeps it), metres; None where
    level 0 did not squeeze."""
    value = accuracy["levels"][0].get("max_squeeze")
    return float(value) if value is not None and math.isfinite(float(value)) and float(value) > 0 else None


#: The change of the spacings from one draw of the reference's mesh to the next (:func:`draw_factor`): enough to
#: give gmsh other tetrahedra, a change of the discretisation error of order this share of it.
DRAW_STEP = 0.02


def draw_factor(k: int) -> float:
    """The spacings of draw ``k`` of the reference's mesh relative to its plan: 1, 1 − s, 1 + s, 1 − 2s, …
    (s = :data:`DRAW_STEP`), about the plan's on average."""
    return 1.0 + DRAW_STEP * (-1) ** k * math.ceil(k / 2)


def combine_draws(draws: list[dict[str, Any]]) -> dict[str, Any]:
    """The reference from its draws (rows as the answer's): where every draw that ran gives one verdict, the mean
    of ρ*, Σ f·n̂ and the largest weight held, with ``spread`` per quantity (the largest |draw − mean| / |mean|,
    the reference's own uncertainty; 0 for one draw); ``status`` "draws disagree" where the verdicts differ (no
    reference: a finer mesh decides either way), "failed" where none ran.  A draw that stopped before the squeeze
    (its mesh's nodes at the grasp points not in force closure: a random capsule's third draw) answers no
    question about the lift and is left out, as one that raised."""
    ok = [d for d in draws if d.get("status") == "ok" and (d.get("success") or float(d.get("step") or 0.0) > 0)]
    seconds = sum(float(d.get("seconds") or 0.0) for d in draws)
    if not ok:
        first = draws[0] if draws else {}
        if first.get("status") == "ok":
            return {"status": "no squeeze", "seconds": seconds}
        return {"status": "failed", "error": first.get("error", "no draw ran"), "seconds": seconds}
    if len({bool(d["success"]) for d in ok}) > 1:
        return {"status": "draws disagree", "seconds": seconds, "draws_ok": len(ok)}
    out: dict[str, Any] = {"status": "ok", "success": bool(ok[0]["success"]), "reason": ok[0]["reason"],
                           "weight": ok[0]["weight"], "vertices": int(np.mean([d["vertices"] for d in ok])),
                           "seconds": seconds, "draws_ok": len(ok), "spread": {}}
    for q in QUANTITIES + ("max_liftable",):
        values = np.array([float(d[q]) for d in ok])
        mean = float(values.mean())
        out[q] = mean
        if q in QUANTITIES:
            out["spread"][q] = float(np.max(np.abs(values - mean)) / abs(mean)) if mean != 0 else 0.0
    return out


def reusable(reference: dict[str, Any] | None, obj: dict[str, Any], accuracy: dict[str, Any]) -> bool:
    """Whether a saved reference (a row's ``reference``) checks this answer: the same object, a reference that
    ran — its draws agreeing on the verdict, or not (then the verdict is not settled at its resolution, which
    running the same draws again finds again) —, finer at the patches than the answer's last level, and squeezed
    at most as deep as the answer (one saved before its plan recorded that depth: where it lifted the object
    short of the answer's deepest squeeze)."""
    if not reference or reference.get("status") not in ("ok", "draws disagree") or "plan" not in reference:
        return False
    if reference.get("object") not in (None, obj):
        return False
    deepest, have = _deepest_squeeze(accuracy), reference["plan"].get("max_squeeze")
    if have is None:  # saved before references squeezed as deep as the answer: its own 40 %, which only a
        # reference lifted short of the answer's deepest squeeze did not reach
        same = bool(reference.get("success")) and deepest is not None and reference["squeeze_depth"] < deepest
    else:
        same = deepest is not None and abs(float(have) - deepest) <= 1e-9 * deepest
    return same and float(reference["plan"]["inner_size"]) < float(accuracy["levels"][-1]["inner_size"]) * (1 - 1e-9)


def run_object(seed: int, config: dict[str, Any], send: Callable[[tuple[str, Any]], None] | None = None
               ) -> dict[str, Any]:
    """Object ``seed``: its answer at ``config["accuracy"]`` and its reference (module notes); the row.

    ``send(("answer", row))`` is called between the two, so that a supervisor keeps the answer when the reference
    runs out of time, ``send(("level", report))`` after each level of the answer (the loop's
    :class:`~fem_grasp.grasp.accuracy.AccuracyReport` as a dict), so that it keeps the levels run when the answer
    does, and ``send(("reference_draw", draw))`` after each draw of the reference.
    """
    from fem_grasp import Body
    from fem_grasp.grasp.accuracy import _level_meshes, converged_pickup
    from fem_grasp.grasp.answer import patch_points
    from fem_grasp.grasp.options import PickupOptions
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
                               refinement=config.get("refinement", PickupOptions.refinement), **kw)
        row["answer"] = _answer_row(res, time.perf_counter() - t0)
        row["answer"]["accuracy"] = res.accuracy
    except Exception as exc:  # noqa: BLE001 - recorded: the object has no answer, the study goes on
        row["answer"] = {"status": "failed", "error": f"{type(exc).__name__}: {exc}",
                         "traceback": traceback.format_exc(), "seconds": time.perf_counter() - t0}
        return row
    if send is not None:
        send(("answer", row))

    saved = (config.get("references") or {}).get(seed)
    if reusable(saved, row["object"], res.accuracy):
        row["reference"] = dict(saved, reused=True)
        return row
    plan = reference_plan(res.accuracy, config["max_reference_contacts"])
    row["reference"] = {"plan": plan, "object": row["object"], "draws": []}
    if not plan["step"] > 0:  # the answer stopped before the squeeze (no placement): nothing finer to compare
        row["reference"]["status"] = "no squeeze"
        return row
    if plan["too_large"]:
        row["reference"]["status"] = "too large"
        return row
    fingers, table = patch_points(res)
    # the points every level of the answer grasped at (given, or chosen by the placement rule on level 0)
    points = res.accuracy.get("contact_points")
    embed = None if points is None else np.asarray(points, dtype=float)
    for k in range(int(config.get("reference_draws", 1))):
        t0 = time.perf_counter()
        try:
            f = draw_factor(k)
            ref_mesh = _level_meshes(geometry, fingers, table, f * plan["inner_size"], plan["radius"],
                                     f * plan["outer_size"], embed)
            ref_body = Body(ref_mesh, body.young, body.poisson, weight=body.weight, gravity=body.gravity)
            ref_kw = dict(kw, step=plan["step"], step_divisions=plan["step_divisions"])
            if plan.get("max_squeeze"):  # as deep as the answer's levels squeezed
                ref_kw["max_squeeze"] = plan["max_squeeze"]
            if embed is not None:  # the finger contacts mapped as the loop maps them
                ref_kw["contacts"] = tuple(int(i) for i in nearest_surface_nodes(ref_mesh, embed))
            if plan["lift_test_step"]:
                ref_kw["lift_test_step"] = plan["lift_test_step"]
            mesh_seconds = time.perf_counter() - t0
            draw = _answer_row(pickup(ref_body, **ref_kw), time.perf_counter() - t0)
            draw["mesh_seconds"] = mesh_seconds
        except Exception as exc:  # noqa: BLE001 - recorded: the draw has no answer
            draw = {"status": "failed", "error": f"{type(exc).__name__}: {exc}", "traceback": traceback.format_exc(),
                    "seconds": time.perf_counter() - t0}
        draw["draw"] = k
        row["reference"]["draws"].append(draw)
        if send is not None:
            send(("reference_draw", draw))
    row["reference"].update(combine_draws(row["reference"]["draws"]))
    return row


def _child(seed: int, config: dict[str, Any], conn: Any) -> None:
    try:
        row = run_object(seed, config, conn.send)
        conn.send(("done", row))
    finally:
        conn.close()


def supervised(seed: int, config: dict[str, Any], poll: float = 2.0) -> dict[str, Any]:
    """:func:`run_object` in a spawned process: the answer may take ``config["answer_cap"]`` seconds, the
    reference ``config["reference_seconds"]`` per draw after it; a phase that overruns is recorded as ``timed
    out`` and its process terminated (a timed-out answer keeps the loop's levels so far as ``levels_so_far``; a
    reference that timed out or whose process died is the mean of the draws that finished, if any, with
    ``ended_early`` saying how it ended, and keeps its ``plan``, so that ``--references`` can use it again)."""
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
                row, phase, started = value, "reference", time.monotonic()
                cap = config["reference_seconds"] * int(config.get("reference_draws", 1))
                # the plan run_object makes, kept here too: a reference that ends early is reusable by it
                row["reference"] = {"plan": reference_plan(row["answer"]["accuracy"],
                                                           config["max_reference_contacts"])}
            elif kind == "reference_draw":
                row["reference"].setdefault("draws", []).append(value)
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
    if phase == "reference":
        from fem_grasp.grasp.accuracy import LEVEL_RATIO

        last = row["answer"]["accuracy"]["levels"][-1]
        row["reference"]["predicted_contacts"] = max(last["finger_nodes"]) * LEVEL_RATIO**2
        draws = row["reference"].get("draws") or []
        if any(d.get("status") == "ok" for d in draws):  # the draws that finished before it ended
            ended = row["reference"]["status"]
            row["reference"].update(combine_draws(draws), ended_early=ended, seconds=row["reference"]["seconds"])
    return row


def relative_error(value: float, reference: float) -> float:
    """|value − reference| / |reference| (0 when equal, inf when the reference is 0 and the value not)."""
    if value == reference:
        return 0.0
    return abs(value - reference) / abs(reference) if reference != 0 else math.inf
