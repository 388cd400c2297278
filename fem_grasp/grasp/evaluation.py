"""Algorithm 1 for many candidate placements of one object, sharing what does not change between them.

Every candidate of a placement search (:mod:`fem_grasp.grasp.candidates`) runs :func:`~fem_grasp.grasp.pickup`
on the same object at the same resting state; only the fingers differ.  What they share is built once per
process and kept:

* the **posed body** and its sparse factorisation (the compliance X of
  :mod:`fem_grasp.elastic.compliance`);
* its **compliance columns**: those of every surface node, solved up front in fixed batches, so that no
  pickup computes a column and every pickup sees the same cache whatever ran before it in the process —
  a candidate's answer does not depend on which worker evaluated it, or after which other candidate
  (above :data:`SHARED_COLUMNS_BYTES` of columns, each pickup starts instead from an empty column cache
  on the shared factor: the same independence, less sharing);
* the **resting state** (Algorithm 1 step 2), rebuilt from its contact set and prescribed contact
  displacements by one solve, and checked to reproduce the forces it was shipped with;
* the compiled contact kernels (:func:`~fem_grasp.contact.warm_up`).

A factorised body does not pickle (the factor is a CHOLMOD or SuperLU object), so what travels between
processes is a :class:`SearchSetup`: plain arrays (the posed mesh, the material, the resting contact set)
and the grasp's shared options (:class:`~fem_grasp.grasp.options.PickupOptions`), a few hundred kilobytes for the paper's objects.  :func:`evaluator_for` builds the
:class:`Evaluator` of a setup the first time a process needs it and keeps it (a process keeps the last
:data:`KEEP_EVALUATORS`).  Everything runs on one BLAS thread, in every process, so that a search gives
the same numbers serially and on a cluster.

:func:`evaluate` turns one candidate into a result row (:data:`ROW_COLUMNS`); a candidate whose pickup raises
becomes a row with ``status = "error"`` and the error, and the search goes on.
"""

from __future__ import annotations

import contextlib
import hashlib
import math
import os
import socket
import time
import traceback
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any, Iterator

import numpy as np

from ..contact.warm_up import warm_up
from ..elastic.body import FULL_COLUMNS_MAX_NODES, Body
from ..elastic.response import ContactResponse
from ..mesh.tetmesh import TetMesh
from ..settings import DEFAULT_SETTINGS
from .candidates import Candidate
from .options import PickupOptions
from .pickup import PickupResult, pickup
from .pose import RestingPose
from .rest import RestState

__all__ = ["ACCURACY_OPTIONS", "COLUMN_BATCH", "Evaluator", "KEEP_EVALUATORS", "REST_RTOL", "ROW_COLUMNS",
           "SEARCH_SETTINGS", "SHARED_COLUMNS_BYTES", "SHARED_OPTIONS", "SearchSetup", "error_row", "evaluate",
           "evaluator_for", "one_thread", "result_row"]

#: Above this many bytes of compliance columns (every surface node's three, all kept rows) the columns are not
#: shared: each pickup starts from an empty column cache on the shared factorisation.
SHARED_COLUMNS_BYTES = 512 * 2**20
#: Surface nodes whose columns are solved together when they are computed up front (fixed batches: the same
#: round-off in every process).
COLUMN_BATCH = 200
#: Evaluators a process keeps (one per object searched; the oldest is dropped first).
KEEP_EVALUATORS = 2
#: The rebuilt resting state must reproduce the shipped contact forces to this, relative to mg + Σ|f|.
REST_RTOL = 1e-8
#: The engine's settings of a search's pickups: one thread each, as their BLAS (:func:`one_thread`): the workers
#: fill the cores, so the accuracy loop's second lift test at a level runs after the first rather than beside it
#: (``parallel_lift_tests``, the same numbers either way).  Beside it, an 8-candidate search of the tomato at 5 %
#: on two workers took 1.16 times as long (243 and 211 s against 205 and 185 s, on the 2-core AMD EPYC).
SEARCH_SETTINGS = DEFAULT_SETTINGS.replace(parallel_lift_tests=False, solve_ahead=False)

#: The options every candidate of a search shares (a :class:`SearchSetup`'s); the others are the candidate's
#: (``contacts``, ``directions``, ``ratio``, ``max_squeeze``), not run per candidate (the placement rule), or those
#: of the accuracy loop (:data:`ACCURACY_OPTIONS`).
SHARED_OPTIONS = ("mu_finger", "mu_table", "finger_radius", "step", "lift_test_step", "max_lift", "lift",
                  "max_lift_attempts", "backend")
#: The accuracy loop's options a search shares when it has an accuracy target (``accuracy`` set): each candidate is
#: then evaluated by :func:`fem_grasp.grasp.accuracy.converged_pickup`; without it they are not kept.
ACCURACY_OPTIONS = ("accuracy", "max_finger_contacts", "max_seconds", "geometry")

#: The columns of a result row: name → (kind, description).  Lengths in metres, forces in newtons, angles in
#: degrees.  Per-finger forces are those of the final snapshot (at lift-off when picked up), measured as in
#: :mod:`fem_grasp.grasp.forces`.
ROW_COLUMNS: dict[str, tuple[str, str]] = {
    "candidate": ("int", "index of the candidate in the search"),
    "key": ("str", "the candidate's name: nodes, azimuth, tilt, ratio (what --resume matches)"),
    "node_i": ("int", "finger 1's initial contact node p_i"),
    "node_j": ("int", "finger 2's initial contact node p_j"),
    "azimuth_deg": ("float", "azimuth φ of the squeeze axis around the vertical, degrees"),
    "tilt_deg": ("float", "downward tilt τ of the squeeze directions, degrees"),
    "ratio": ("float", "squeeze ratio s"),
    "height": ("float", "mean height of p_i, p_j above the table at rest, m"),
    "max_squeeze": ("float", "maximum squeeze depth, m"),
    "xi": ("float", "p_i at rest, x (m)"), "yi": ("float", "p_i at rest, y (m)"), "zi": ("float", "p_i at rest, z (m)"),
    "xj": ("float", "p_j at rest, x (m)"), "yj": ("float", "p_j at rest, y (m)"), "zj": ("float", "p_j at rest, z (m)"),
    "closure_quality": ("float", "Ferrari–Canny ε of the force-closure test (Algorithm 1 step 1)"),
    "status": ("str", "ok, or error: the evaluation raised (see error)"),
    "outcome": ("str", "how the pickup ended (fem_grasp.grasp.OUTCOMES), or error"),
    "success": ("bool", "the object was picked up"),
    "grasped": ("bool", "picked up; or, when the lift is not simulated (lift = false), the lift test passed"),
    "reason": ("str", "why not, in words (empty on success)"),
    "error": ("str", "the exception, when status is error"),
    "rho_star": ("float", "ρ*: the squeeze depth at which the successful lift started (or, when the lift is not "
                          "simulated, the lift test passed), m; NaN when not grasped"),
    "squeeze_depth": ("float", "the squeeze depth when the lift started or the squeeze stopped, m"),
    "step": ("float", "the squeeze increment of the lift tests' schedule, m (ρ* is resolved to it)"),
    "margin": ("float", "w(ρ)/mg at the last lift test: ≥ 1 once the lift test passes"),
    "liftable_max": ("float", "the largest liftable weight the lift test found, up to the deepest squeeze reached, N"),
    "weight": ("float", "the object's weight mg, N"),
    "grip1": ("float", "finger 1's resultant along d̂₁ (its squeeze), N"),
    "vertical1": ("float", "finger 1's resultant along ẑ (the weight it carries), N"),
    "normal1": ("float", "finger 1's normal sum Σ f·n̂ over its patch, N"),
    "force1": ("float", "|resultant| of finger 1, N"),
    "contacts1": ("int", "finger 1's contact nodes"),
    "grip2": ("float", "finger 2's resultant along d̂₂, N"),
    "vertical2": ("float", "finger 2's resultant along ẑ, N"),
    "normal2": ("float", "finger 2's normal sum, N"),
    "force2": ("float", "|resultant| of finger 2, N"),
    "contacts2": ("int", "finger 2's contact nodes"),
    "finger_normal_force": ("float", "Σ f·n̂ over both fingers (the paper's Table III measure), N"),
    "rigid_normal_force": ("float", "the rigid grasp's total normal force at the same contacts, N (NaN if none)"),
    "contacts": ("int", "contact nodes in the final configuration (Table II's first figure)"),
    "contacts_table": ("int", "table contacts in the final configuration"),
    "events": ("int", "events A–D, squeeze and lift"),
    "events_A": ("int", "contact establishment"), "events_B": ("int", "contact break"),
    "events_C": ("int", "stick to slip"), "events_D": ("int", "slip to stick"),
    "lift_attempts": ("int", "simulated lifts (more than one when a lift failed and the squeeze went on)"),
    "time": ("float", "wall time of this candidate's pickup, s"),
    "cpu_time": ("float", "CPU time of this candidate's pickup in its process, s"),
    "setup_time": ("float", "wall time this evaluation spent building the shared state, s (0 when its process "
                            "had it)"),
    "worker": ("str", "host:pid of the process that evaluated it"),
    "error_rho_star": ("float", "estimated relative error of ρ*: with an accuracy target, the accuracy loop's estimate "
                                "(the change between its last two levels, or the uncertainty of its last three where "
                                "larger, plus the resolution of ρ*; inf when not known, e.g. the verdict is not "
                                "settled); in a one-level search, the scene's stated error "
                                "(solver.expected_error), NaN when none is stated"),
    "error_finger_force": ("float", "estimated relative error of the finger force Σ f·n̂, as error_rho_star"),
    "converged": ("bool", "the accuracy loop reached its target (two successive levels agree within it); False for "
                          "one level"),
    "levels": ("int", "meshes Algorithm 1 ran on for this candidate: 1 without an accuracy target, else the accuracy "
                      "loop's levels (level 0 on the search's mesh, then refined at the contact patches; the answer "
                      "columns are then the last level's, the candidate's columns its placement on the search's "
                      "mesh)"),
}


@contextlib.contextmanager
def one_thread() -> Iterator[None]:
    """BLAS on one thread (threadpoolctl, when installed): the same numbers in every process of a search."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        yield
        return
    with threadpool_limits(limits=1, user_api="blas"):
        yield


def _digest(*parts: Any) -> str:
    h = hashlib.sha256()
    for p in parts:
        if isinstance(p, np.ndarray):
            h.update(str(p.dtype).encode())
            h.update(np.ascontiguousarray(p).tobytes())
        else:
            h.update(repr(p).encode())
    return h.hexdigest()[:24]


@dataclass(frozen=True, eq=False)
class SearchSetup:
    """What every candidate of a search shares, as plain arrays (picklable; module notes).

    Attributes
    ----------
    name : the object's name (for messages)
    points, tets : the posed body's mesh (the node numbering of every candidate)
    young, poisson, density, gravity : its material
    options : the :class:`~fem_grasp.grasp.options.PickupOptions` every candidate shares (:data:`SHARED_OPTIONS`;
        ``mu_table`` is the resting state's; with an accuracy target also :data:`ACCURACY_OPTIONS`, the target and
        the geometry the loop remeshes); each candidate adds its contacts, directions, ratio and maximum squeeze
    table_z, rest_nodes, rest_forces, rest_displacements, rest_sliding, support_triangle, pose_rotation,
    pose_translation, pose_margin, rest_iterations, rest_time : the resting state
    key : a digest of what the answers depend on (not the name, nor what is re-solved from the rest; the accuracy
        target, its contact bound and the geometry's kind and parameters when there is a target)
    """

    name: str
    points: np.ndarray
    tets: np.ndarray
    young: float
    poisson: float
    density: float
    gravity: float
    options: PickupOptions
    table_z: float
    rest_nodes: np.ndarray
    rest_forces: np.ndarray
    rest_displacements: np.ndarray
    rest_sliding: np.ndarray
    support_triangle: np.ndarray
    pose_rotation: np.ndarray
    pose_translation: np.ndarray
    pose_margin: float
    rest_iterations: int
    rest_time: float
    key: str = ""

    @classmethod
    def from_rest(cls, rest_state: RestState, *, name: str = "object", options: PickupOptions | None = None,
                  **overrides: Any) -> "SearchSetup":
        """The setup of a search on the object resting in ``rest_state``, with ``options`` (default: the defaults)
        changed by ``overrides`` (:meth:`PickupOptions.from_overrides`); only :data:`SHARED_OPTIONS` are kept, and
        ``mu_table`` is the resting state's; with ``accuracy`` set, also :data:`ACCURACY_OPTIONS` (``geometry``: what
        the accuracy loop remeshes, in the frame of the body as given before it was posed on the table; None: the
        body's boundary, :func:`fem_grasp.mesh.remesh.geometry_of_mesh`)."""
        given = PickupOptions.from_overrides(overrides, base=options)
        keep = SHARED_OPTIONS + (ACCURACY_OPTIONS if given.accuracy is not None else ())
        shared = PickupOptions(**{k: getattr(given, k) for k in keep}).replace(mu_table=float(rest_state.mu_table))
        body = rest_state.body
        fields = dict(
            name=str(name), points=np.array(body.mesh.points, dtype=float), tets=np.array(body.mesh.tets, dtype=np.int64),
            young=float(body.young), poisson=float(body.poisson), density=float(body.density),
            gravity=float(body.gravity), table_z=float(rest_state.table_z),
            rest_nodes=np.array(rest_state.contact_nodes, dtype=np.int64),
            rest_forces=np.array(rest_state.contact_forces, dtype=float),
            rest_displacements=np.array(rest_state.contact_displacements, dtype=float),
            rest_sliding=np.array(rest_state.sliding, dtype=bool),
            support_triangle=np.array(rest_state.support_triangle, dtype=np.int64),
            pose_rotation=np.array(rest_state.pose.rotation, dtype=float),
            pose_translation=np.array(rest_state.pose.translation, dtype=float),
            pose_margin=float(rest_state.pose.margin), rest_iterations=int(rest_state.iterations),
            rest_time=float(rest_state.wall_time))
        # the key names what the answers depend on: not the name, the rest's timing, or what the worker re-solves
        # (the forces and the margin, equal to round-off whether the rest was computed or read from a cache); the
        # options enter by name, each as a plain value
        named = {**fields, **{k: getattr(shared, k) for k in SHARED_OPTIONS}}
        if shared.accuracy is not None:  # a one-level search keeps the key it always had
            # the geometry by its kind and parameters (a surface's by its kind: it is the body's or its scan's,
            # whose mesh is in the key), not by its description, which names the object
            named.update(accuracy=shared.accuracy, max_finger_contacts=shared.max_finger_contacts,
                         geometry=repr(shared.geometry),
                         **({} if shared.max_seconds is None else {"max_seconds": shared.max_seconds}))
        key = _digest(*(v for k, v in sorted(named.items())
                        if k not in ("name", "rest_time", "rest_iterations", "rest_forces", "pose_margin")))
        fields["options"] = shared
        return cls(**fields, key=key)

    @property
    def accuracy(self) -> float | None:
        """The accuracy target of every candidate's answer (:func:`~fem_grasp.grasp.accuracy.converged_pickup`), or
        None: one run of Algorithm 1 on this mesh."""
        return self.options.accuracy



class Evaluator:
    """The shared state of a search in one process, and Algorithm 1 on it for each candidate (module notes).

    Attributes
    ----------
    setup : the :class:`SearchSetup`
    body : the posed body, factorised
    rest : the resting state on ``body``
    shared_columns : whether every surface node's compliance columns are computed and shared
    setup_time : seconds it took to build (factorisation, columns, resting state, kernels)
    """

    def __init__(self, setup: SearchSetup) -> None:
        t0 = time.perf_counter()
        self.setup = setup
        self._given: Body | None = None
        with one_thread():
            warm_up()
            body = Body(TetMesh(setup.points, setup.tets), setup.young, setup.poisson, density=setup.density,
                        gravity=setup.gravity)
            self.body = body
            surface = body.mesh.surface_nodes
            rows = 3 * (body.n_nodes if body.n_nodes <= FULL_COLUMNS_MAX_NODES else len(surface))
            backend = setup.options.backend
            self.shared_columns = backend == "sparse" and 3 * len(surface) * rows * 8 <= SHARED_COLUMNS_BYTES
            if backend == "sparse":
                body.gravity_compliance_field  # noqa: B018 - the factorisation and X G, once
                if self.shared_columns:
                    for start in range(0, len(surface), COLUMN_BATCH):
                        body.compliance.prefetch(surface[start:start + COLUMN_BATCH])
            else:
                body.spectral  # noqa: B018 - the eigendecomposition, once
            self.rest = self._restore_rest(body) if self.shared_columns or backend != "sparse" else None
        self.setup_time = time.perf_counter() - t0

    def _restore_rest(self, body: Body) -> RestState:
        """The resting state on ``body`` from the setup's contact set (one solve), checked against the shipped forces."""
        s = self.setup
        sol = ContactResponse(body, s.rest_nodes, backend=s.options.backend).solve(s.rest_displacements)
        scale = body.weight + float(np.abs(s.rest_forces).sum())
        apart = float(np.abs(sol.forces - s.rest_forces).max()) if len(s.rest_nodes) else 0.0
        if apart > REST_RTOL * scale:
            raise ValueError(f"the resting state of {s.name} does not re-solve to its forces ({apart:.3g} N apart); "
                             "the setup and this process's fem_grasp disagree")
        pose = RestingPose(body, s.support_triangle, s.pose_rotation, s.pose_translation, s.pose_margin, None)
        state = RestState(body, s.table_z, s.options.table_friction, sol.positions, sol.displacements, s.rest_nodes, sol.forces,
                          s.rest_displacements, s.rest_sliding, s.support_triangle, [], s.rest_iterations,
                          s.rest_time, pose, sol)
        state.check()
        return state

    def pickup(self, candidate: Candidate) -> PickupResult:
        """Algorithm 1 for ``candidate`` at the shared resting state."""
        s = self.setup
        with one_thread():
            if self.rest is not None:
                body, rest_state = self.body, self.rest
            else:  # columns too large to share: a fresh column cache on the shared factor
                body = self.body.transformed()
                rest_state = self._restore_rest(body)
            options = s.options.replace(contacts=candidate.finger_nodes, directions=candidate.directions,
                                        ratio=candidate.ratio, max_squeeze=candidate.max_squeeze)
            if options.accuracy is None:
                return pickup(body, options, rest_state=rest_state, settings=SEARCH_SETTINGS)
            # The accuracy loop: level 0 on the shared rest (and factorisation), as above; the finer levels remesh
            # the geometry, which is in the frame of the body as given, and rest and solve on their own.
            return pickup(self.given_body(), options, rest_state=rest_state, settings=SEARCH_SETTINGS)

    def given_body(self) -> Body:
        """The body as it was given, before it was posed on the table (the frame of the accuracy loop's geometry),
        with the posed body's node numbering: its mesh is the posed one moved back, p = Rᵀ (q − t)."""
        if self._given is None:
            s = self.setup
            points = (s.points - s.pose_translation) @ s.pose_rotation
            self._given = Body(TetMesh(points, s.tets), s.young, s.poisson, density=s.density, gravity=s.gravity)
        return self._given

#: This process's evaluators, by setup key (oldest first).
_EVALUATORS: "OrderedDict[str, Evaluator]" = OrderedDict()


def evaluator_for(setup: SearchSetup) -> tuple[Evaluator, bool]:
    """This process's :class:`Evaluator` of ``setup``, built on first use; and whether this call built it."""
    ev = _EVALUATORS.get(setup.key)
    if ev is not None:
        _EVALUATORS.move_to_end(setup.key)
        return ev, False
    ev = Evaluator(setup)
    _EVALUATORS[setup.key] = ev
    while len(_EVALUATORS) > KEEP_EVALUATORS:
        _EVALUATORS.popitem(last=False)
    return ev, True


def _worker_name() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


def _candidate_columns(candidate: Candidate) -> dict[str, Any]:
    (xi, yi, zi), (xj, yj, zj) = candidate.points
    return {"candidate": candidate.index, "key": candidate.key, "node_i": candidate.finger_nodes[0],
            "node_j": candidate.finger_nodes[1], "azimuth_deg": candidate.azimuth, "tilt_deg": candidate.tilt,
            "ratio": candidate.ratio, "height": candidate.height, "max_squeeze": candidate.max_squeeze,
            "xi": xi, "yi": yi, "zi": zi, "xj": xj, "yj": yj, "zj": zj,
            "closure_quality": candidate.closure_quality}


def _blank_row() -> dict[str, Any]:
    blank = {"int": -1, "float": math.nan, "str": "", "bool": False}
    return {name: blank[kind] for name, (kind, _) in ROW_COLUMNS.items()}


def result_row(candidate: Candidate, result: PickupResult, seconds: float = math.nan) -> dict[str, Any]:
    """The result row (:data:`ROW_COLUMNS`) of ``candidate``'s pickup."""
    row = _blank_row()
    row.update(_candidate_columns(candidate))
    counts = result.event_counts()
    weight = float(result.body.weight)
    last_w = result.liftable[-1][1] if result.liftable else 0.0
    ff = result.finger_forces
    grasped = bool(result.success or result.outcome == "lift not run")
    row.update({
        "status": "ok", "outcome": result.outcome, "success": bool(result.success), "grasped": grasped,
        "reason": result.reason, "rho_star": float(result.squeeze_depth) if grasped else math.nan,
        "squeeze_depth": float(result.squeeze_depth), "step": float(result.step), "margin": float(last_w) / weight,
        "liftable_max": float(max((w for _, w in result.liftable), default=0.0)), "weight": weight,
        "finger_normal_force": float(result.finger_normal_force),
        "rigid_normal_force": (float(result.rigid.total_normal_force)
                               if result.rigid is not None and result.rigid.feasible else math.nan),
        "contacts": int(result.n_final_contacts),
        "contacts_table": 0 if result.final is None else int(len(result.final.contact_nodes["table"])),
        "events": len(result.events), **{f"events_{k}": int(v) for k, v in counts.items()},
        "lift_attempts": len(result.lift_attempts), "time": float(seconds),
    })
    acc = getattr(result, "accuracy", None)
    if acc:  # the accuracy loop's answer: its own estimated error
        err = acc.get("estimated_error", {})
        row.update({"error_rho_star": float(err.get("squeeze_depth", math.inf)),
                    "error_finger_force": float(err.get("finger_force", math.inf)),
                    "converged": bool(acc.get("converged", False)), "levels": len(acc.get("levels", ())) or 1})
    else:  # one run on the search's mesh: the error is the one the search states (set by the search)
        row.update({"converged": False, "levels": 1})
    if ff is not None:
        for k, f in enumerate(ff, start=1):
            row.update({f"grip{k}": f.grip, f"vertical{k}": f.vertical, f"normal{k}": f.normal_sum,
                        f"force{k}": f.magnitude, f"contacts{k}": int(f.contacts)})
    return row


def error_row(candidate: Candidate, error: str, seconds: float = math.nan) -> dict[str, Any]:
    """The row of a candidate whose evaluation raised (or whose worker died, :mod:`fem_grasp.batch`)."""
    row = _blank_row()
    row.update(_candidate_columns(candidate))
    row.update({"status": "error", "outcome": "error", "reason": error.splitlines()[0] if error else "error",
                "error": error, "time": float(seconds)})
    return row


def evaluate(setup: SearchSetup, candidate: Candidate) -> dict[str, Any]:
    """Algorithm 1 for one candidate, as a result row (:data:`ROW_COLUMNS`); an exception becomes an error row."""
    t0 = time.perf_counter()
    setup_time = 0.0
    try:
        ev, built = evaluator_for(setup)
        setup_time = ev.setup_time if built else 0.0
        t1, c1 = time.perf_counter(), time.process_time()
        result = ev.pickup(candidate)
        row = result_row(candidate, result, time.perf_counter() - t1)
        row["cpu_time"] = time.process_time() - c1
    except Exception as exc:  # noqa: BLE001 - recorded in the row, the search goes on
        tb = traceback.format_exc(limit=-3)
        row = error_row(candidate, f"{type(exc).__name__}: {exc}\n{tb}", time.perf_counter() - t0 - setup_time)
    row["setup_time"] = float(setup_time)
    row["worker"] = _worker_name()
    return row
