"""Algorithm 1 end to end: two-finger pickup of a soft 3D object (paper §III).

:func:`pickup` runs

* step 1, the force-closure test of the initial placement (:mod:`fem_grasp.grasp.closure`);
* step 2, the resting configuration on the table (:func:`fem_grasp.grasp.rest.rest`, §III-A);
* steps 3–4, the squeeze with the lift test after every increment
  (:mod:`fem_grasp.grasp.squeeze`, :mod:`fem_grasp.grasp.lift_test`, §III-B/C);
* step 5, the lift (:mod:`fem_grasp.grasp.lift`);
* step 6, failure when the squeeze reaches its maximum depth,

and returns a :class:`PickupResult` with the whole story: events, snapshots
at every event, liftable-weight history, forces, timings, and the rigid-body
comparison of Table III (:mod:`fem_grasp.grasp.rigid`).  Failures (no force
closure, gross slip, too little friction, …) are results, not exceptions.

Default scene (the paper's §IV, where it is silent our choice)
--------------------------------------------------------------
* squeeze directions d̂₁ = (0, 0.974, −0.227), d̂₂ = (0, −0.974, −0.227),
  ratio s = 1; fingertip radius :data:`fem_grasp.contact.obstacles.DEFAULT_RADIUS`;
* μ_ℱ = μ_𝒫 = :data:`DEFAULT_FRICTION` unless given (``mu_table`` defaults to
  ``mu_finger``, the paper has one μ per object);
* finger contacts p_i, p_j (:func:`default_finger_contacts`): among the
  pairs of surface nodes extreme along ∓ĥ (ĥ the horizontal part of d̂₁) at
  heights stepped by 2.5 % of the object's height, those whose tangent
  fingertips clear the table by max(R/10, |d̂₁·ẑ| × maximum squeeze), start
  outside the object and are force closure, by the rule
  ``placement_rule="centre-of-mass-height"`` (:data:`~fem_grasp.grasp.placement.DEFAULT_PLACEMENT_RULE`,
  the rule of the paper scenes and of a scene that names none, so that
  ``pickup()`` and ``fem-grasp run`` agree): the first valid pair from the
  centre of mass's height outwards whose rigid grasp is feasible — the
  fingers alone could hold a rigid body of the resting shape; where a dome's
  side leans further than the friction angle, the fingers move to where it is
  steeper — or the first valid pair if none is.  (``placement_rule="least-force"``:
  the pair whose rigid grasp needs the least total normal force, Table III's
  measure; contacts where the surface faces a little upward let the normal
  forces carry part of the weight, but a deep squeeze there can push a soft
  body up out of the grasp.)
* maximum squeeze depth: 40 % of the object's width along ĥ;
* squeeze increment: 1/20 of the depth ρ* = mg / (μ_ℱ k₀) at which a
  finger of the initial (point) contact stiffness k₀ would press hard enough
  to hold the weight by friction — so the increments adapt to E — kept
  between 0.1 % and 2 % of the maximum depth (the contact patch grows with
  the geometry, whatever E);
* a lift that fails (all contacts of a finger slide, or no quasi-static
  stick/slip state exists: the grip is lost) sends the run back to the
  squeeze from the lift-start state (Algorithm 1 step 6, "otherwise go back
  to step 3"): the lift test, path-independent, can pass where the real lift,
  which unloads the table gradually, slips; up to ``max_lift_attempts`` = 4
  lifts, each recorded in ``result.lift_attempts``; the squeeze resumes with
  its first lift test at the next end of a sub-increment
  (``PickupOptions.step_divisions``);
* lift-test step h = mg/20; lift increment equal to the squeeze increment,
  maximum lift height equal to the object's height (a soft object stays on
  the table while its contacts with the fingers stretch: at E = 1e4 Pa the
  paper's objects need centimetres of lift to let go).

The records a pickup returns, each snapshot held to the contact laws, are :mod:`~fem_grasp.grasp.results`;
the default placement (p_i, p_j and the maximum squeeze) is :mod:`~fem_grasp.grasp.default_contacts`.
"""

from __future__ import annotations

import contextlib
import logging
import time
from dataclasses import replace
from typing import Any, Sequence

import numpy as np

from ..contact import tracking as contact_tracking
from ..contact.obstacles import FINGER1, FINGER2
from ..contact.tracking import ContactEvent, ContactState, Tracker
from ..contact.warm_up import prepare_kernels
from ..elastic.body import Body
from ..errors import ContactNodeError, PickupCheckError, TrackingError
from ..settings import DEFAULT_SETTINGS, EngineSettings
from .closure import placement_closure
from .default_contacts import default_finger_contacts, default_max_squeeze
from .lift import lift as run_lift
from .lift_test import LiftTest
from .options import DEFAULT_FRICTION, PickupOptions
from .placement import check_contact_nodes, check_directions, check_finger_placement
from .rest import RestState, rest
from .results import OUTCOMES, LiftAttempt, PickupResult, Snapshot
from .rigid import rigid_grasp
from .squeeze import SqueezeOutcome, initial_state, next_passed, squeeze

__all__ = ["DEFAULT_FRICTION", "OUTCOMES", "LiftAttempt", "PickupCheckError", "PickupOptions", "PickupResult",
           "Snapshot", "default_finger_contacts", "default_max_squeeze", "pickup"]

log = logging.getLogger(__name__)

def _initial_stiffness(tracker: Tracker, placed: ContactState, velocities: np.ndarray) -> float:
    """k₀: rate of the normal force at the initial contact of finger 1 per unit ρ, N/m.

    ``placed`` is the state of :func:`~fem_grasp.grasp.squeeze.initial_state`, before it is settled: both
    fingertips touch there by construction.  (The settle may release a touch that carries no force, by
    round-off; the finger then re-establishes contact by event A as it moves in, and the increment must
    not depend on which way the round-off went.)
    """
    on = np.flatnonzero(placed.owner == FINGER1)
    if not on.size:
        raise ValueError("the initial placement has no contact on finger 1")
    resp = tracker.response(placed.nodes)
    vel = np.zeros((placed.n_contacts, 3))
    for f in (FINGER1, FINGER2):
        vel[placed.owner == f] = velocities[f]
    rate = (resp.reduced_stiffness @ vel.reshape(-1)).reshape(-1, 3)
    j = int(on[0])
    return float(max(rate[j] @ placed.normals[j], np.linalg.norm(rate[j]) * 1e-3))


# =================================================================== pickup
def pickup(body: Body, options: PickupOptions | None = None, *, rest_state: RestState | None = None,
           settings: EngineSettings | None = None, **overrides: Any) -> PickupResult:
    """Run Algorithm 1: will two hemispherical fingers pick ``body`` up from the table?

    Parameters
    ----------
    body : Body
        The object, in any orientation (it is posed on the table by
        :func:`fem_grasp.grasp.rest.rest`; ``result.body`` is the posed body).
    options : PickupOptions, optional
        The grasp's options (:class:`~fem_grasp.grasp.options.PickupOptions`, which documents each with its
        unit and default: friction μ_ℱ and μ_𝒫, fingertip radius R, contacts p_i, p_j, squeeze directions and
        ratio s, maximum squeeze and its increment, lift-test step h, maximum lift, lift on or off, lift attempts,
        placement rule, backend, accuracy target and its geometry).  Default: ``PickupOptions()``.
    rest_state : RestState, optional
        A resting state of ``body`` computed before (skips step 2; with ``accuracy``, level 0 only).
    settings : EngineSettings, optional
        The engine's numerical settings for the rest, squeeze, lift test and lift trackers
        (:class:`~fem_grasp.settings.EngineSettings`; default: the engine's defaults); the same at every level of
        an ``accuracy`` refinement.
    **overrides
        Fields of ``options`` changed by name, e.g. ``pickup(body, mu_finger=0.32, lift=False)``
        (:meth:`PickupOptions.from_overrides`).  With ``accuracy`` set,
        :func:`fem_grasp.grasp.accuracy.converged_pickup` refines the mesh at the contact patches and the
        increments until two successive answers agree within it, and the result (the last level's) carries the
        estimated error in ``result.accuracy``.

    Returns
    -------
    PickupResult
        ``success`` and ``reason``; see its attributes.  Failures are results.

    Raises
    ------
    ValueError
        An unknown option (naming it and the nearest known one) or a value out of range
        (:class:`~fem_grasp.errors.SceneError` and its subclasses), before anything is solved; contact nodes
        that are not surface nodes of the posed body (:class:`~fem_grasp.errors.ContactNodeError`).
    """
    opts = PickupOptions.from_overrides(overrides, base=options)
    prepare_kernels()  # once per process: compile or load the kernels, or say they run as plain Python
    if opts.accuracy is not None:
        from .accuracy import converged_pickup

        return converged_pickup(body, solve=pickup, accuracy=opts.accuracy, geometry=opts.geometry, options=opts,
                                rest_state=rest_state, settings=settings)
    t_start = time.perf_counter()
    mu_f, mu_t = opts.mu_finger, opts.table_friction
    finger_radius, ratio, backend = opts.finger_radius, opts.ratio, opts.backend
    max_squeeze, step, max_lift = opts.max_squeeze, opts.step, opts.max_lift
    d1, d2 = check_directions(*opts.directions, ratio=ratio)
    timings: dict[str, float] = {}

    # Step 2 (computed first: step 1 needs the resting shape).
    t0 = time.perf_counter()
    rs = rest_state if rest_state is not None else rest(body, mu_t, backend=backend, settings=settings)
    timings["rest"] = time.perf_counter() - t0
    posed = rs.body
    table = rs.table
    result = PickupResult(False, "", posed, rs, (-1, -1), None, mu_f, mu_t, float(finger_radius), (d1, d2),
                          float(ratio), timings=timings)

    if max_squeeze is None:
        max_squeeze = default_max_squeeze(rs.positions, d1)

    # Step 1: force closure of p_i, p_j and the support-triangle centre.
    t0 = time.perf_counter()
    if opts.contacts is None:
        try:
            ij, closure = default_finger_contacts(rs, d1, mu_f, mu_t, finger_radius, np.stack([d1, ratio * d2]),
                                                  rule=opts.placement_rule, max_squeeze=max_squeeze)
        except ValueError as exc:
            result.reason = str(exc) if str(exc).startswith("no finger placement") else \
                f"no initial finger placement: {exc}"
            result.outcome = "no placement"
            timings["closure"] = time.perf_counter() - t0
            timings["total"] = time.perf_counter() - t_start
            return result
    else:
        ij = tuple(int(k) for k in check_contact_nodes(posed.mesh, rs.positions, opts.contacts,
                                                          what="finger contact node"))
        if len(ij) != 2:
            raise ContactNodeError(f"give two finger contact nodes (p_i, p_j), got {len(ij)}")
        out = posed.mesh.outward_normals(rs.positions)
        check_finger_placement(rs.positions, posed.mesh.surface_nodes,
                               rs.positions[list(ij)] + finger_radius * out[list(ij)], finger_radius,
                               contact_nodes=ij, normals=out, directions=np.stack([d1, ratio * d2]))
        closure = placement_closure(posed, rs.positions, ij, rs.support_triangle, mu_f, mu_t)
    result.finger_nodes = ij
    result.closure = closure
    timings["closure"] = time.perf_counter() - t0
    com = (posed.mesh.volumes @ rs.positions[posed.mesh.tets].mean(axis=1)) / posed.mesh.volume
    out = posed.mesh.outward_normals(rs.positions)
    result.rigid = rigid_grasp(rs.positions[list(ij)], -out[list(ij)], com, posed.weight, mu_f)
    if not closure.closed:
        result.reason = f"the initial placement is not force closure (Algorithm 1 step 1): {closure.reason}"
        result.outcome = "not force closure"
        timings["total"] = time.perf_counter() - t_start
        return result

    # Steps 3-5, with the columns of the next likely contacts solved on the other core meanwhile (fine meshes).
    wanted = (settings or DEFAULT_SETTINGS).solve_ahead and posed.n_nodes >= contact_tracking.AHEAD_MIN_VERTICES
    ahead = posed.compliance.solving_ahead() if backend == "sparse" and wanted else contextlib.nullcontext()
    with ahead:
        # Steps 3-4: squeeze with the lift test.
        t0 = time.perf_counter()
        tracker = Tracker(posed, radius=finger_radius, mu_finger=mu_f, mu_table=mu_t, table=table, backend=backend,
                          settings=settings)
        hanging = Tracker(posed, radius=finger_radius, mu_finger=mu_f, mu_table=mu_t, table=None, backend=backend,
                          settings=settings)
        velocities = np.stack([d1, ratio * d2])

        surface = posed.mesh.surface_nodes

        def snap(st: ContactState, label: str, events: Sequence[ContactEvent] = ()) -> None:
            result.snapshots.append(Snapshot.from_state(st, finger_radius, label, events, surface_nodes=surface))

        try:
            placed = initial_state(tracker, rs, ij)
            state, ev0 = tracker.settle(placed, velocities, phase="squeeze")
        except (TrackingError, ValueError) as exc:
            result.reason = f"the fingers cannot be placed: {exc}"
            result.outcome = "placement failed"
            timings["total"] = time.perf_counter() - t_start
            return result
        result.events.extend(ev0)
        snap(state, "initial", ev0)
        if step is None:
            k0 = _initial_stiffness(tracker, placed, velocities)
            rho_star = posed.weight / (max(mu_f, 1e-3) * k0)
            step = min(0.02 * max_squeeze, max(rho_star / 20.0, 1e-3 * max_squeeze))
        result.max_squeeze = float(max_squeeze)
        result.step = float(step)
        result.step_divisions = opts.step_divisions
        lt = LiftTest(hanging, posed.weight, opts.lift_test_step)
        result.lift_test_step = float(lt.step)
        t_squeeze = t0
        timings["squeeze"] = timings["lift_test"] = timings["lift"] = 0.0
        first_test = opts.first_lift_test or 0.0
        resumed: SqueezeOutcome | None = None
        while True:
            sq = resumed if resumed is not None else squeeze(
                tracker, state, (d1, d2), ratio, lt, max_squeeze=max_squeeze, step=step,
                divisions=opts.step_divisions, first_test=first_test, on_event=lambda st, ev: snap(st, "event", ev))
            result.events.extend(sq.events)
            result.liftable.extend(sq.liftable)
            result.squeeze_depth = sq.state.squeeze_depth
            timings["lift_test"] += sq.lift_test_time
            timings["squeeze"] += time.perf_counter() - t_squeeze - sq.lift_test_time
            if not sq.passed:
                result.outcome = "squeeze failed" if sq.failed else "not liftable"
                result.reason = sq.reason + "".join(f"; lift attempt at ρ = {1e3 * a.squeeze_depth:.4g} mm failed: "
                                                    f"{a.reason}" for a in result.lift_attempts)
                result.final = Snapshot.from_state(sq.state, finger_radius, "final", surface_nodes=surface)
                result.finger_normal_force = result.final.finger_normal_force(table)
                timings["total"] = time.perf_counter() - t_start
                return result

            # Step 5: lift.
            t0 = time.perf_counter()
            attempt = len(result.lift_attempts) + 1
            snap(sq.state, "lift start" if attempt == 1 else f"lift start (attempt {attempt})")
            if not opts.lift:
                result.reason = "the lift test passed; the lift was not run (lift=False)"
                result.outcome = "lift not run"
                result.final = result.snapshots[-1]
                result.finger_normal_force = result.final.finger_normal_force(table)
                timings["total"] = time.perf_counter() - t_start
                return result
            if max_lift is None:
                max_lift = float(np.ptp(rs.positions[:, 2]))
            lf = run_lift(tracker, sq.state, max_height=max_lift, step=step,
                          on_event=lambda st, ev: snap(st, "event", ev))
            timings["lift"] += time.perf_counter() - t0
            result.events.extend(lf.events)
            result.lift_attempts.append(LiftAttempt(sq.state.squeeze_depth, lf.success, lf.reason,
                                                    lf.state.lift_height, len(lf.events)))
            if lf.success or attempt >= opts.max_lift_attempts or sq.state.squeeze_depth >= max_squeeze * (1 - 1e-9):
                break
            # Algorithm 1 step 6, "otherwise go back to step 3": the simulated lift predicts a slip, so the
            # planner squeezes on from the lift-start state and tries again at the next passing lift test.
            log.info("lift attempt %d at ρ = %.4g m failed (%s); squeezing further", attempt,
                     sq.state.squeeze_depth, lf.reason)
            snap(lf.state, f"lift failed (attempt {attempt})")
            t_squeeze = time.perf_counter()
            # The next end of a sub-increment, where the walk down tested it already, else squeezed to and tested.
            resumed = next_passed(sq, on_event=lambda st, ev: snap(st, "event", ev))
            state = replace(sq.state, phase="squeeze")
            # on from the next end of a sub-increment: ρ* was found to one, and the next lift may start there
            first_test = state.squeeze_depth + step / opts.step_divisions
        result.success = lf.success
        result.outcome = "picked up" if lf.success else "lift failed"
        first = result.lift_attempts[0].squeeze_depth
        result.reason = lf.reason if attempt == 1 or lf.success else (
            f"{lf.reason} (after {attempt} lift attempts from ρ = {1e3 * first:.4g} mm)")
        result.final = Snapshot.from_state(lf.state, finger_radius, "lift-off" if lf.success else "final",
                                           surface_nodes=surface)
        result.snapshots.append(result.final)
        result.finger_normal_force = result.final.finger_normal_force(table)
        timings["total"] = time.perf_counter() - t_start
        log.info("pickup %s: ρ = %.4g m, %d events, %d final contacts, finger normal force %.4g N, %.2f s",
                 "succeeded" if result.success else f"failed ({result.reason})", result.squeeze_depth,
                 len(result.events), result.n_final_contacts, result.finger_normal_force, timings["total"])
        return result
