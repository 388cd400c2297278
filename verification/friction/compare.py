"""fem_grasp's contact evolution against an independent frictional-contact reference.

``python -m verification friction compare SCENE [--increments N] [--json PATH]``

fem_grasp tracks the squeeze, the lift test and the lift of *Picking up Soft
3D Objects with Two Fingers* event by event (events A–D, §III-C).  The
reference (:mod:`verification.friction.reference.pickup`, :mod:`verification.friction.reference.contact`,
:mod:`verification.friction.reference.body`; formulation in ``verification/friction/README.md``)
solves the same model — P1 linear elasticity assembled by dolfinx, exact
sphere and plane gaps, Coulomb cones μ_ℱ and μ_𝒫, gravity with a load factor —
as a sequence of static contact problems, one per increment, by a semismooth
Newton method on the Alart–Curnier equations, sharing no code with fem_grasp's
friction, relaxation, Gauss–Seidel, tracking, slip, lift-test, homotopy or rest
modules.  It takes from fem_grasp's result only the placement: the posed mesh,
the finger nodes and fingertip centres at ρ = 0, the squeeze directions and
ratio, the lift-test step h and the depths at which the lift test runs.

What is compared
----------------
* **Rest.**  The reference ramps gravity in (λ: 0 → 1 in n increments) from the
  posed, undeformed body and compares contact set, sliding set and forces with
  ``result.rest`` (:func:`compare_rest`).
* **Squeeze, lift test, lift.**  From fem_grasp's resting state (so that the
  squeeze comparison measures the squeeze alone), the reference runs
  Algorithm 1 with M increments per lift-test interval, for M in ``levels``.
  At every fem_grasp snapshot (each event, the lift start, the lift-off) the
  reference solves a side state at the same ρ or lift height from its
  preceding increment and the contact forces are compared
  (:func:`force_difference`: max over nodes of |Δf| / F_s, F_s = mg + max |f|);
  at every reference increment the contact sets and stick/slip states are
  compared with fem_grasp's (constant between its snapshots), each mismatch
  classified as *near an event* when either solver has an event of that node
  within ``EVENT_WINDOW`` reference increments (or one fem_grasp increment
  where fem_grasp took the increment implicitly), else *marginal* when the
  deciding quantity is within ``MARGINAL_FACTOR`` times the local force
  difference of its threshold, else *unexplained*; w(ρ) at every
  lift test; ρ*, the lift-off height and the verdict.
* **Own chain.**  At the finest M, the reference also runs from its own
  resting state (fingertip centres shifted with the touched nodes) and its
  verdict and ρ* are reported.
* **Self-check.**  Every reference state is checked against the contact laws
  (:func:`self_check`).

Exit status: 0 agreement, 1 the verdicts differ or the force difference at the
finest increment exceeds ``FORCE_TOL``, 2 bad input.
"""

from __future__ import annotations

import argparse
import functools
import json
import logging
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._common.run import json_safe
from .reference.contact import FINGER1, FINGER2, NAMES, SLIP, STICK, TABLE, TOL_NEWTON, StaticState
from .reference.pickup import ReferencePickup, Scenario

log = logging.getLogger(__name__)

#: Increments per lift-test interval of the convergence study (the finest one is the agreement figure).
DEFAULT_LEVELS = (1, 2, 4, 8)
#: Gravity-ramp increments of the resting-state comparison.
REST_LEVELS = (4, 16, 64)
#: Exit 1 when the finest level's max |Δf| / F_s exceeds this: the reference's own O(Δρ) error at M = 8
#: plus fem_grasp's implicit increments (where it takes them) stay well below it on every listed scene, while a
#: wrong friction direction, cone or gap shows up as an O(1) difference (verification/friction/README.md, "Tolerances").
FORCE_TOL = 0.05
#: A set or state mismatch within this many reference increments of a fem_grasp event of the same node is
#: "near an event": an incremental solution crosses a threshold O(Δρ) away from the exact crossing.
EVENT_WINDOW = 2.0
#: A mismatch away from events is "marginal" when the deciding quantity — the force of a contact present on one
#: side only, or the distance (μ f·n̂ − |f_t|) of the sticking side from its cone — is within this many times the
#: local force difference of the two paths (relative to F_s): the two paths are that far apart anyway.
MARGINAL_FACTOR = 2.0
#: Contacts of fem_grasp with more than this many contacts in a snapshot are taken implicitly (its module
#: notes, "Large contact sets"): events then land on its increments, so the window widens to one increment.
FG_IMPLICIT_CONTACTS = 40


# ====================================================================== set-up
@dataclass
class Case:
    """A scene, fem_grasp's result on it, and the reference's scenario and solver."""

    name: str
    scene: Any
    result: Any
    scenario: Scenario
    ref: ReferencePickup
    fem_seconds: float


def load_case(scene: str | Path, *, quick: bool = False, step: float | None = None) -> Case:
    """Run fem_grasp on a scene (shipped name or path) and set up the reference.

    Cached per (resolved path, file contents, quick, step) within a process: fem_grasp's pickup is the dear
    part, and the step study, the tests and the command may ask for the same scene twice.

    Raises
    ------
    fem_grasp.errors.SceneError (a ValueError)
        A missing or invalid scene.
    """
    from fem_grasp.io.scene import resolve_scene

    path = Path(resolve_scene(str(scene))).resolve()
    text = path.read_text(encoding="utf-8") if path.exists() else ""
    return _load_case(str(path), text, bool(quick), None if step is None else float(step))


@functools.lru_cache(maxsize=8)
def _load_case(path_str: str, text: str, quick: bool, step: float | None) -> Case:
    from dataclasses import replace

    from fem_grasp import pickup
    from fem_grasp.io.scene import load_scene

    path = Path(path_str)
    sc = load_scene(path, quick=quick)
    if step is not None:
        sc = replace(sc, step=float(step))
    body = sc.body()
    t0 = time.perf_counter()
    res = pickup(body, **sc.pickup_kwargs())
    fem_seconds = time.perf_counter() - t0
    scen = scenario_from(res, sc)
    return Case(sc.name, sc, res, scen, ReferencePickup(scen), fem_seconds)


def scenario_from(result: Any, scene: Any | None = None) -> Scenario:
    """The reference's :class:`Scenario` from a fem_grasp ``PickupResult`` (the placement only)."""
    posed = result.body
    if not result.snapshots:
        raise ValueError(f"fem_grasp's result has no squeeze to compare with: {result.reason}")
    d1, d2 = (np.asarray(d, float) / np.linalg.norm(d) for d in result.directions)
    h = getattr(scene, "lift_test_step", None) or 0.05 * posed.weight  # fem_grasp's documented default, mg/20
    max_lift = getattr(scene, "max_lift", None) or float(np.ptp(result.rest.positions[:, 2]))
    return Scenario(points=np.asarray(posed.mesh.points, float), tets=np.asarray(posed.mesh.tets),
                    young=posed.young, poisson=posed.poisson, density=posed.density, gravity=posed.gravity,
                    table_z=float(result.rest.table_z), radius=float(result.finger_radius),
                    mu_finger=float(result.mu_finger), mu_table=float(result.mu_table),
                    centers0=np.asarray(result.snapshots[0].finger_centers, float).copy(),
                    velocities=np.stack([d1, result.ratio * d2]), finger_nodes=tuple(result.finger_nodes),
                    weight=float(posed.weight), lift_test_step=float(h), max_squeeze=float(result.max_squeeze),
                    step=float(result.step), max_lift=max_lift,
                    test_depths=tuple(float(r) for r, _ in result.liftable))


def start_from_fem_rest(case: Case) -> tuple[StaticState, float]:
    """The squeeze start (ρ = 0) from fem_grasp's resting state; returns it and the misfit of its field."""
    rs = case.result.rest
    ref = case.ref
    st, misfit = ref.from_state(rs.contact_nodes, np.full(rs.n_contacts, TABLE), rs.contact_forces, rs.sliding,
                                rs.displacements, 1.0, ref.obstacles(0.0, 0.0, fingers=False))
    return ref.with_fingers(st), misfit


def start_from_own_rest(case: Case, rest: StaticState) -> StaticState:
    """The squeeze start from the reference's own resting state: fingertip centres shifted with p_i, p_j."""
    ref = case.ref
    body = ref.body
    i, j = case.scenario.finger_nodes
    fg_pos = case.result.rest.positions
    own = rest.positions(body)
    shift = np.stack([own[body.slot[i]] - fg_pos[i], own[body.slot[j]] - fg_pos[j]])
    sc2 = Scenario(**{**case.scenario.__dict__, "centers0": case.scenario.centers0 + shift})
    ref2 = ReferencePickup(sc2, body)
    case_ref = ref2
    return case_ref.with_fingers(rest), case_ref


# ============================================================ fem_grasp's path
def fem_snapshots(result: Any) -> list[dict]:
    """fem_grasp's snapshots as plain records: phase, ρ, lift height, contacts {(node, owner): (force, sliding)}."""
    table = result.table
    out = []
    for s in result.snapshots:
        nrm = s.normals(table)
        contacts = {}
        for o, name in enumerate(NAMES):
            for k, f, sl, n in zip(s.contact_nodes[name], s.contact_forces[name], s.sliding[name], nrm[name]):
                contacts[(int(k), o)] = (np.asarray(f, float), bool(sl), np.asarray(n, float))
        out.append({"label": s.label, "phase": s.phase, "rho": float(s.squeeze_depth),
                    "lift": float(s.lift_height), "contacts": contacts})
    return out


def ref_contacts(state: StaticState, body) -> dict:
    nrm = state.normals(body)
    return {(int(k), int(o)): (f, int(st) == SLIP, n)
            for k, o, f, st, n in zip(state.nodes, state.owner, state.forces, state.status, nrm)}


def measures(contacts: dict, directions: np.ndarray) -> dict[str, float]:
    """Force measures of a contact set: per finger Σ f·n̂, the grip Σ f·d̂_f and |Σ f|; the table's Σ f_z."""
    out: dict[str, float] = {}
    for f in (FINGER1, FINGER2):
        fv = [v[0] for (k, o), v in contacts.items() if o == f]
        nv = [v[2] for (k, o), v in contacts.items() if o == f]
        F = np.sum(fv, axis=0) if fv else np.zeros(3)
        out[f"normal{f + 1}"] = float(sum(a @ b for a, b in zip(fv, nv)))
        out[f"grip{f + 1}"] = float(F @ directions[f])
        out[f"resultant{f + 1}"] = float(np.linalg.norm(F))
    tv = [v[0] for (k, o), v in contacts.items() if o == TABLE]
    out["table_fz"] = float(np.sum(tv, axis=0)[2]) if tv else 0.0
    return out


def force_difference(a: dict, b: dict, weight: float) -> dict[str, float]:
    """max |f_a − f_b| / F_s over the union of contacts (absent = zero force), F_s = mg + max |f_b|."""
    keys = set(a) | set(b)
    fs = weight + max([float(np.linalg.norm(v[0])) for v in b.values()], default=0.0)
    worst, node = 0.0, None
    for key in keys:
        fa = a[key][0] if key in a else np.zeros(3)
        fb = b[key][0] if key in b else np.zeros(3)
        d = float(np.linalg.norm(fa - fb)) / fs
        if d > worst:
            worst, node = d, key
    return {"max": worst, "node": None if node is None else [int(node[0]), NAMES[node[1]]], "scale": fs}


# ================================================================= comparison
def _events(result: Any) -> list[tuple[str, float, float, str, int, int]]:
    return [(e.phase, float(e.squeeze_depth), float(e.lift_height), e.kind, int(e.node), NAMES.index(e.contact))
            for e in result.events]


def _fem_state_at(snaps: list[dict], phase: str, rho: float, lift: float) -> dict | None:
    """fem_grasp's contacts at a reference grid point: the last snapshot at or before it on the same segment."""
    best = None
    tol = 1e-12
    for s in snaps:
        if phase == "squeeze":
            if s["phase"] == "squeeze" and s["rho"] <= rho * (1 + tol) + 1e-18:
                best = s
        else:
            if abs(s["rho"] - rho) <= tol * max(rho, 1e-9):
                if s["phase"] == "squeeze" and s["label"].startswith("lift start"):
                    best = s if best is None or best["phase"] == "squeeze" else best
                elif s["phase"] == "lift" and s["lift"] <= lift * (1 + tol) + 1e-18 and not s["label"].startswith(
                        "lift failed"):
                    best = s
    return best


def compare_level(case: Case, m: int, start: StaticState) -> dict[str, Any]:
    """Run the reference at M = ``m`` increments per lift-test interval from ``start`` and compare (module notes)."""
    res = case.result
    body = case.ref.body
    sc = case.scenario
    weight = sc.weight
    dirs = np.stack([v / np.linalg.norm(v) if np.linalg.norm(v) > 0 else v for v in sc.velocities])
    snaps = fem_snapshots(res)
    sq = sorted({s["rho"] for s in snaps if s["phase"] == "squeeze" and s["rho"] > 0})
    lifts: dict[float, list[float]] = {}
    for s in snaps:
        if s["phase"] == "lift" and s["lift"] > 0:
            lifts.setdefault(s["rho"], []).append(s["lift"])
    case.ref.solves = case.ref.splits = case.ref.continued = 0
    t0 = time.perf_counter()
    lift_heights = {k: sorted(set(v)) for k, v in lifts.items()}
    out = case.ref.run(start, m, samples={"squeeze": sq, "lift": lift_heights})
    # Where fem_grasp lifted and the reference did not (their lift tests passed at different ρ), the reference
    # also lifts from its own squeeze state there: the lift mechanics are compared whatever the lift test said.
    forced = {}
    for att in res.lift_attempts:
        rho_l = float(att.squeeze_depth)
        if any(abs(rho_l - a[0]) <= 1e-12 * rho_l for a in out.lift_attempts):
            continue
        got = case.ref.forced_lift(out, rho_l, m, lift_heights.get(rho_l, []))
        if got is not None:
            forced[rho_l] = {"success": got[0], "reason": got[1], "height": got[2], "final": got[3]}
    seconds = time.perf_counter() - t0

    # Forces at fem_grasp's snapshots (the last one at each parameter value).
    last: dict[tuple, dict] = {}
    for s in snaps:
        key = ("squeeze", s["rho"]) if s["phase"] == "squeeze" else ("lift", s["rho"], s["lift"])
        if s["label"].startswith("lift failed") or (s["phase"] == "squeeze" and s["rho"] == 0.0):
            continue
        last[key] = s
    rows, worst = [], {"max": 0.0}
    for key, s in last.items():
        rec = out.samples.get(key)
        if rec is None:
            continue
        rc = ref_contacts(rec.state, body)
        d = force_difference(rc, s["contacts"], weight)
        mf, mr = measures(s["contacts"], dirs), measures(rc, dirs)
        row = {"phase": key[0], "rho": key[1], "lift": key[2] if len(key) > 2 else 0.0, "force": d["max"],
               "node": d["node"],
               "resultant": max(abs(mr[f"resultant{f}"] - mf[f"resultant{f}"]) for f in (1, 2)) / d["scale"],
               "normal_sum": abs(mr["normal1"] + mr["normal2"] - mf["normal1"] - mf["normal2"]) / d["scale"]}
        rows.append(row)
        if d["max"] >= worst["max"]:
            worst = dict(row, max=d["max"])
    compared = len(rows)

    # Contact sets and stick/slip states at every reference increment.
    events = _events(res)
    intervals = np.diff([0.0] + sorted(set(sc.test_depths)))
    drho = float(intervals.max() / m) if len(intervals) else sc.step / m
    dh = sc.step / m
    # The reference's own events: changes between consecutive increments of one segment.
    ref_events: list[tuple[str, float, float, int, int]] = []
    prev_rec = None
    for rec in out.path:
        if rec.sample:
            continue
        if prev_rec is not None and prev_rec.phase == rec.phase and (rec.phase == "squeeze" or rec.rho == prev_rec.rho):
            pa = {(int(k), int(o)): int(st) for k, o, st in zip(prev_rec.state.nodes, prev_rec.state.owner,
                                                                prev_rec.state.status)}
            pb = {(int(k), int(o)): int(st) for k, o, st in zip(rec.state.nodes, rec.state.owner, rec.state.status)}
            for key in set(pa) | set(pb):
                if pa.get(key) != pb.get(key):
                    ref_events.append((rec.phase, rec.rho, rec.lift, key[0], key[1]))
        prev_rec = rec
    # Local force difference at the fem_grasp snapshots, by phase and parameter, for the "marginal" test.
    local = {"squeeze": sorted((r["rho"], r["force"]) for r in rows if r["phase"] == "squeeze")}
    for r in rows:
        if r["phase"] == "lift":
            local.setdefault(("lift", r["rho"]), []).append((r["lift"], r["force"]))

    def local_diff(phase: str, rho: float, lift: float) -> float:
        seq = local["squeeze"] if phase == "squeeze" else sorted(local.get(("lift", rho), []))
        par = rho if phase == "squeeze" else lift
        if not seq:
            return worst["max"]
        xs = np.array([x for x, _ in seq])
        j = int(np.searchsorted(xs, par))
        return max(v for _, v in seq[max(j - 1, 0):j + 1])

    set_mis, state_mis, n_points = [], [], 0
    for rec in out.path:
        if rec.sample or (rec.phase == "squeeze" and rec.rho == 0.0):
            continue
        fs = _fem_state_at(snaps, rec.phase, rec.rho, rec.lift)
        if fs is None:
            continue
        n_points += 1
        rc = ref_contacts(rec.state, body)
        a, b = set(rc), set(fs["contacts"])
        inc = drho if rec.phase == "squeeze" else dh
        implicit = len(fs["contacts"]) > FG_IMPLICIT_CONTACTS
        window = max(EVENT_WINDOW * inc, sc.step if implicit else 0.0)
        par = rec.rho if rec.phase == "squeeze" else rec.lift
        scale = weight + max([float(np.linalg.norm(v[0])) for v in fs["contacts"].values()], default=0.0)
        tol_local = MARGINAL_FACTOR * local_diff(rec.phase, rec.rho, rec.lift)

        def near(node: int, o: int) -> float:
            on_seg = lambda e_rho: rec.phase == "squeeze" or abs(e_rho - rec.rho) < 1e-12  # noqa: E731
            ds = [abs((e[1] if rec.phase == "squeeze" else e[2]) - par) for e in events
                  if e[4] == node and e[0] == rec.phase and on_seg(e[1])]
            ds += [abs((e[1] if rec.phase == "squeeze" else e[2]) - par) for e in ref_events
                   if e[3] == node and e[0] == rec.phase and on_seg(e[1])]
            return min(ds) if ds else math.inf

        def classify(dist: float, margin: float) -> str:
            return "near event" if dist <= window else "marginal" if margin <= tol_local else "unexplained"

        for key in a ^ b:
            dist = near(*key)
            f = rc[key][0] if key in rc else fs["contacts"][key][0]
            margin = float(np.linalg.norm(f)) / scale
            set_mis.append({"phase": rec.phase, "rho": rec.rho, "lift": rec.lift, "node": key[0],
                            "contact": NAMES[key[1]], "in": "reference" if key in a else "fem_grasp",
                            "margin": margin, "event_distance": dist, "class": classify(dist, margin),
                            "length": inc})
        for key in a & b:
            if rc[key][1] != fs["contacts"][key][1]:
                dist = near(*key)
                f, _, n = rc[key] if not rc[key][1] else fs["contacts"][key]  # the sticking side
                mu = sc.mu_table if key[1] == TABLE else sc.mu_finger
                fn = float(f @ n)
                margin = max(0.0, mu * fn - float(np.linalg.norm(f - fn * n))) / scale
                state_mis.append({"phase": rec.phase, "rho": rec.rho, "lift": rec.lift, "node": key[0],
                                  "contact": NAMES[key[1]], "reference": "slip" if rc[key][1] else "stick",
                                  "margin": margin, "event_distance": dist, "class": classify(dist, margin),
                                  "length": inc})

    # Lift test, verdict, lift-off.
    fw = dict(res.liftable)
    w_rows = [(r, fw.get(r), w) for r, w in out.liftable]
    w_mis = [{"rho": r, "fem_grasp": a, "reference": b} for r, a, b in w_rows
             if a is not None and abs(a - b) > 1e-9 * weight]
    lift_off = {}
    same_start = abs(out.squeeze_depth - res.squeeze_depth) <= 1e-12 * res.squeeze_depth
    fz = forced.get(float(res.squeeze_depth))
    if res.success and ((out.success and same_start) or (fz is not None and fz["success"])):
        fin_f = {(int(k), o): v for (k, o), v in fem_snapshots(res)[-1]["contacts"].items()}
        final, height = (out.final, out.lift_off_height) if same_start else (fz["final"], fz["height"])
        fin_r = ref_contacts(final, body)
        mf, mr = measures(fin_f, dirs), measures(fin_r, dirs)
        lift_off = {"fem_grasp": mf, "reference": mr, "source": "own lift" if same_start else "forced lift",
                    "force": force_difference(fin_r, fin_f, weight)["max"],
                    "height_fem_grasp": float(res.final.lift_height), "height_reference": height}
    return {
        "increments": m, "drho": drho, "dh": dh, "seconds": seconds, "solves": out.solves, "splits": out.splits,
        "continued": out.continued,
        "verdict_reference": out.success, "reason_reference": out.reason,
        "rho_star_reference": out.squeeze_depth, "lift_attempts_reference": len(out.lift_attempts),
        "force_max": worst["max"], "force_worst": worst, "force_rows": rows, "compared_snapshots": compared,
        "fem_snapshots": len(last),
        "set_mismatches": len(set_mis), "set_mismatches_away": sum(x["class"] != "near event" for x in set_mis),
        "set_mismatches_unexplained": sum(x["class"] == "unexplained" for x in set_mis),
        "state_mismatches": len(state_mis),
        "state_mismatches_away": sum(x["class"] != "near event" for x in state_mis),
        "state_mismatches_unexplained": sum(x["class"] == "unexplained" for x in state_mis),
        # Node-metres of parameter over which a node's set or state differs (each mismatch × its increment): the
        # measure of the disagreement, which converges as M grows while the counts grow with the grid.
        "set_mismatch_length": float(sum(x["length"] for x in set_mis)),
        "state_mismatch_length": float(sum(x["length"] for x in state_mis)),
        "set_mismatch_list": set_mis, "state_mismatch_list": state_mis, "grid_points": n_points,
        "liftable_reference": out.liftable, "liftable_mismatches": w_mis, "lift_off": lift_off,
        "forced_lifts": {str(k): {"success": v["success"], "reason": v["reason"], "height": v["height"]}
                         for k, v in forced.items()},
        "self_check": self_check(case.ref, [r.state for r in out.path] + [r.state for r in out.samples.values()]),
        "_outcome": out,
    }


def compare_rest(case: Case, levels: tuple[int, ...] = REST_LEVELS) -> dict[str, Any]:
    """The reference's gravity ramp against fem_grasp's resting state (module notes)."""
    rs = case.result.rest
    weight = case.scenario.weight
    body = case.ref.body
    fem = {(int(k), TABLE): (f, bool(sl), np.array([0.0, 0.0, 1.0]))
           for k, f, sl in zip(rs.contact_nodes, rs.contact_forces, rs.sliding)}
    rows, states = [], {}
    for n in levels:
        t0 = time.perf_counter()
        st = case.ref.rest(n)
        rc = ref_contacts(st, body)
        d = force_difference(rc, fem, weight)
        sag_ref = float(max(0.0, -st.surface_disp[:, 2].min()))
        sag_fem = float(max(0.0, -rs.displacements[body.surface, 2].min()))
        rows.append({"increments": n, "seconds": time.perf_counter() - t0, "force": d["max"],
                     "contacts_reference": len(rc), "contacts_fem_grasp": len(fem),
                     "set_mismatches": len(set(rc) ^ set(fem)),
                     "sliding_reference": int(sum(v[1] for v in rc.values())),
                     "sliding_fem_grasp": int(rs.sliding.sum()),
                     "sag_reference": sag_ref, "sag_fem_grasp": sag_fem,
                     "self_check": self_check(case.ref, [st])})
        states[n] = st
    return {"rows": rows, "_states": states}


#: The slip direction is checked only on slips this many times the Newton tolerance (× diameter): Newton stops
#: with the contact equations met to TOL_NEWTON × diameter, so a slip of size |s| has its direction only to an
#: angle of about TOL_NEWTON × diameter / |s| (1 + cos of half its square): at 1e4 × the tolerance that is
#: 5e-9, below the check's 1e-7.  Smaller slips (the lift test's small load steps make slips of 1e-14 to 1e-13
#: diameters) have no resolved direction.
SLIP_DIRECTION_RESOLVED = 1e4 * TOL_NEWTON


def self_check(ref: ReferencePickup, states: list[StaticState]) -> dict[str, float]:
    """The contact laws on the reference's own states (each figure is a worst case over all states).

    gap : max |g| / diameter over contacts; penetration : max(−g)/diameter over the other surface nodes;
    tensile : max(−f·n̂)/F_s; stick_excess : max (|f_t| − μ f·n̂)/F_s over sticking contacts;
    slip_cone : max ||f_t| − μ f·n̂|/F_s over sliding ones; slip_direction : max (1 + f_t·ŝ/(|f_t||ŝ|)) over
    sliding ones whose slip the solve resolves (|ŝ| > :data:`SLIP_DIRECTION_RESOLVED` × diameter; 0 when friction
    opposes the slip exactly); equilibrium : max |Qᵀ(f + λg)|/mg.
    """
    body = ref.body
    mg = ref.mg
    diam = body.diameter
    worst = {k: 0.0 for k in ("gap", "penetration", "tensile", "stick_excess", "slip_cone", "slip_direction",
                              "equilibrium")}
    for st in states:
        pos = st.positions(body)
        fs = mg + float(np.abs(st.forces).max(initial=0.0))
        obst = st.obstacles
        x = pos[body.slot[st.nodes]]
        for o in obst.present():
            g_all = obst.gaps(pos, o)
            mine = np.zeros(len(pos), bool)
            mine[body.slot[st.nodes[st.owner == o]]] = True
            if (~mine).any():
                worst["penetration"] = max(worst["penetration"], float(max(0.0, -g_all[~mine].min())) / diam)
            if mine.any():
                worst["gap"] = max(worst["gap"], float(np.abs(g_all[mine]).max()) / diam)
        if len(st.nodes):
            n = st.normals(body)
            fn = np.einsum("ki,ki->k", st.forces, n)
            ft = st.forces - fn[:, None] * n
            ftn = np.linalg.norm(ft, axis=1)
            mu = obst.mu(st.owner)
            worst["tensile"] = max(worst["tensile"], float(max(0.0, (-fn).max())) / fs)
            stick, slip = st.status == STICK, st.status == SLIP
            if stick.any():
                worst["stick_excess"] = max(worst["stick_excess"], float(max(0.0, (ftn - mu * fn)[stick].max())) / fs)
            if slip.any():
                worst["slip_cone"] = max(worst["slip_cone"], float(np.abs(ftn - mu * fn)[slip].max()) / fs)
                sn = np.linalg.norm(st.slips, axis=1)
                ok = slip & (sn > SLIP_DIRECTION_RESOLVED * diam) & (ftn > 0)
                if ok.any():
                    cos = np.einsum("ki,ki->k", ft[ok], st.slips[ok]) / (ftn[ok] * sn[ok])
                    worst["slip_direction"] = max(worst["slip_direction"], float((1 + cos).max()))
        slots = body.slot[st.nodes]
        dofs = (3 * slots[:, None] + np.arange(3)).ravel()
        eq = body.Q[dofs].T @ st.forces.reshape(-1) + st.load * body.qg
        worst["equilibrium"] = max(worst["equilibrium"], float(np.abs(eq).max()) / mg)
        del x
    return worst


# ===================================================================== driver
def fit_order(h: list[float], e: list[float]) -> float:
    """Least-squares slope of log e against log h (nan with fewer than two positive points)."""
    pts = [(math.log(a), math.log(b)) for a, b in zip(h, e) if a > 0 and b > 0]
    if len(pts) < 2:
        return float("nan")
    x, y = np.array(pts).T
    return float(np.polyfit(x, y, 1)[0])


def run_case(scene: str | Path | Case, *, levels: tuple[int, ...] = DEFAULT_LEVELS,
             rest_levels: tuple[int, ...] = REST_LEVELS, quick: bool = False, own_chain: bool = True,
             step: float | None = None) -> dict[str, Any]:
    """The whole comparison on one scene (a name, a path, or a :class:`Case` already loaded); a JSON-ready dict."""
    t0 = time.perf_counter()
    case = scene if isinstance(scene, Case) else load_case(scene, quick=quick, step=step)
    quick = bool(getattr(case.scene, "quick", quick))
    res = case.result
    start, misfit = start_from_fem_rest(case)
    lv, samples = [], []
    for m in sorted(set(int(x) for x in levels)):
        r = compare_level(case, m, start)
        out = r.pop("_outcome")
        samples.append({k: ref_contacts(v.state, case.ref.body) for k, v in out.samples.items()})
        lv.append(r)
        log.info("%s M=%d: force %.3g, sets %d (%d away), states %d (%d away), %.1f s", case.name, m, r["force_max"],
                 r["set_mismatches"], r["set_mismatches_away"], r["state_mismatches"], r["state_mismatches_away"],
                 r["seconds"])
    # The reference against its own finest level at fem_grasp's snapshots: its O(Δρ) self-convergence.
    for r, smp in zip(lv, samples):
        diffs = [force_difference(smp[k], samples[-1][k], case.scenario.weight)["max"]
                 for k in smp if k in samples[-1]]
        r["self_difference"] = max(diffs, default=float("nan"))
    rest = compare_rest(case, rest_levels)
    own = None
    if own_chain and lv:
        rest_state = rest["_states"][max(rest_levels)]
        st, ref2 = start_from_own_rest(case, rest_state)
        o = ref2.run(st, lv[-1]["increments"])
        own = {"verdict": o.success, "reason": o.reason, "rho_star": o.squeeze_depth,
               "lift_off_height": o.lift_off_height, "liftable": o.liftable, "rest_increments": max(rest_levels)}
    rest.pop("_states")
    fine = lv[-1]
    fem_verdict = bool(res.success)
    summary = {
        "scene": case.name, "path": str(case.scene.path) if case.scene.path else None, "quick": quick,
        "vertices": int(len(case.scenario.points)), "surface_nodes": int(case.ref.body.n_surface),
        "young": case.scenario.young, "weight": case.scenario.weight, "mu_finger": case.scenario.mu_finger,
        "mu_table": case.scenario.mu_table, "step": case.scenario.step, "lift_test_step": case.scenario.lift_test_step,
        "verdict_fem_grasp": fem_verdict, "reason_fem_grasp": res.reason,
        "rho_star_fem_grasp": float(res.squeeze_depth), "lift_attempts_fem_grasp": len(res.lift_attempts),
        "fem_seconds": case.fem_seconds, "condense_seconds": case.ref.body.seconds, "start_misfit": misfit,
        "levels": lv, "rest": rest, "own_chain": own,
        "verdict_reference": fine["verdict_reference"],
        "rho_star_difference": abs(fine["rho_star_reference"] - float(res.squeeze_depth)),
        "force_max_finest": fine["force_max"],
        "order_force": fit_order([r["drho"] for r in lv], [r["force_max"] for r in lv]),
        "order_self": fit_order([r["drho"] for r in lv[:-1]], [r["self_difference"] for r in lv[:-1]]),
        "force_tol": FORCE_TOL,
    }
    summary["verdicts_agree"] = summary["verdict_reference"] == fem_verdict
    summary["agree"] = bool(summary["verdicts_agree"] and fine["force_max"] <= FORCE_TOL)
    summary["seconds"] = time.perf_counter() - t0
    return summary


def step_study(scene: str | Path, *, divisors: tuple[float, ...] = (1.0, 4.0, 16.0), increments: tuple[int, ...] = (1, 4),
               quick: bool = False) -> dict[str, Any]:
    """fem_grasp's own increment against the plateau of the force difference.

    fem_grasp advances the squeeze and the lift in increments of its ``step`` (events split them); between
    events a sliding contact's slip is solved once per increment, along the direction of the increment's
    held force.  Its path is therefore first order in ``step``, and the difference to the reference levels
    off at that error as the reference's increment shrinks.  This runs fem_grasp at its step / each divisor
    and the reference at each M; the plateau should fall in proportion to fem_grasp's step.
    """
    base = load_case(scene, quick=quick)
    rows = []
    for div in divisors:
        case = base if div == 1.0 else load_case(scene, quick=quick, step=base.result.step / div)
        start, _ = start_from_fem_rest(case)
        for m in increments:
            r = compare_level(case, m, start)
            r.pop("_outcome")
            rows.append({"divisor": div, "fem_step": case.result.step, "increments": m, "drho": r["drho"],
                         "force_max": r["force_max"], "set_mismatch_length": r["set_mismatch_length"],
                         "state_mismatch_length": r["state_mismatch_length"],
                         "liftable_mismatches": len(r["liftable_mismatches"]), "tests": len(case.result.liftable),
                         "verdict_fem_grasp": bool(case.result.success), "verdict_reference": r["verdict_reference"],
                         "rho_star_fem_grasp": float(case.result.squeeze_depth),
                         "rho_star_reference": r["rho_star_reference"], "fem_seconds": case.fem_seconds,
                         "seconds": r["seconds"]})
            log.info("step study %s: fem step %.3g, M=%d: force %.3g", scene, case.result.step, m, r["force_max"])
    plateau = {}
    for div in divisors:
        vals = [x["force_max"] for x in rows if x["divisor"] == div]
        plateau[div] = min(vals) if vals else float("nan")
    steps = [next(x["fem_step"] for x in rows if x["divisor"] == d) for d in divisors]
    return {"scene": str(scene), "quick": quick, "rows": rows,
            "order_in_fem_step": fit_order(steps, [plateau[d] for d in divisors])}


def print_summary(s: dict[str, Any]) -> None:
    print(f"scene {s['scene']}: {s['vertices']} vertices, E = {s['young']:.3g} Pa, mg = {s['weight']:.4g} N, "
          f"μ_F = {s['mu_finger']:g}, μ_P = {s['mu_table']:g}")
    print(f"  verdicts: fem_grasp {'picked up' if s['verdict_fem_grasp'] else 'not picked up'}"
          f"{'' if s['verdict_fem_grasp'] else ' (' + s['reason_fem_grasp'] + ')'}; reference "
          f"{'picked up' if s['verdict_reference'] else 'not picked up'}")
    print(f"  ρ*: fem_grasp {s['rho_star_fem_grasp'] * 1e3:.4f} mm, |Δρ*| = {s['rho_star_difference'] * 1e3:.4g} mm")
    print("  M   Δρ (mm)   max |Δf|/F_s  snapshots  set mismatches       state mismatches     w mism.  s")
    print("                                         all/away/unexpl.     all/away/unexpl.")
    for r in s["levels"]:
        sets = f"{r['set_mismatches']}/{r['set_mismatches_away']}/{r['set_mismatches_unexplained']}"
        states = f"{r['state_mismatches']}/{r['state_mismatches_away']}/{r['state_mismatches_unexplained']}"
        print(f"  {r['increments']:<3d} {r['drho'] * 1e3:<9.4g} {r['force_max']:<13.3e} "
              f"{r['compared_snapshots']:>4d}/{r['fem_snapshots']:<4d}  {sets:<20s} {states:<20s} "
              f"{len(r['liftable_mismatches']):>3d}  {r['seconds']:6.1f}")
    fine = s["levels"][-1]
    away = [x for x in fine["set_mismatch_list"] + fine["state_mismatch_list"] if x["class"] == "unexplained"]
    if away:
        where = sorted({(x["phase"], round(x["rho"] * 1e3, 4), round(x["lift"] * 1e3, 4)) for x in away})
        print("  unexplained mismatches at (phase, ρ mm, lift mm): " + ", ".join(map(str, where[:12]))
              + (" …" if len(where) > 12 else ""))
    if fine["liftable_mismatches"]:
        print("  w(ρ) differs at ρ (mm) = " + ", ".join(f"{x['rho'] * 1e3:.4g} ({x['fem_grasp']:.4g} vs "
                                                        f"{x['reference']:.4g} N)" for x in fine["liftable_mismatches"]))
    if fine["lift_off"]:
        lo = fine["lift_off"]
        print(f"  lift-off: height {lo['height_fem_grasp'] * 1e3:.4f} vs {lo['height_reference'] * 1e3:.4f} mm; "
              f"Σ f·n̂ {lo['fem_grasp']['normal1'] + lo['fem_grasp']['normal2']:.5g} vs "
              f"{lo['reference']['normal1'] + lo['reference']['normal2']:.5g} N; max |Δf|/F_s {lo['force']:.3e}")
    print(f"  convergence order in Δρ: against fem_grasp {s['order_force']:.2f} (it levels off at fem_grasp's own "
          f"O(step) error), of the reference against its finest level {s['order_self']:.2f}")
    for r in s["rest"]["rows"]:
        print(f"  rest, {r['increments']} load increments: max |Δf|/F_s {r['force']:.3e}, contacts "
              f"{r['contacts_reference']} vs {r['contacts_fem_grasp']} ({r['set_mismatches']} differ), sliding "
              f"{r['sliding_reference']} vs {r['sliding_fem_grasp']}, sag {r['sag_reference'] * 1e3:.4f} vs "
              f"{r['sag_fem_grasp'] * 1e3:.4f} mm")
    if s.get("own_chain"):
        o = s["own_chain"]
        print(f"  reference from its own rest: {'picked up' if o['verdict'] else 'not picked up'}, ρ* = "
              f"{o['rho_star'] * 1e3:.4f} mm")
    sc = fine["self_check"]
    print("  reference self-check (worst): " + ", ".join(f"{k} {v:.1e}" for k, v in sc.items()))
    print(f"  {'AGREE' if s['agree'] else 'DISAGREE'} (force tolerance {s['force_tol']:g} at M = {fine['increments']}); "
          f"{s['seconds']:.1f} s")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m verification friction compare",
                                     description="fem_grasp's squeeze, lift test and lift against an independent "
                                                 "frictional-contact reference")
    parser.add_argument("scene", help="a shipped scene name (tomato, foam_block, …) or a path to a scene .toml")
    parser.add_argument("--increments", type=int, default=DEFAULT_LEVELS[-1],
                        help="finest number of reference increments per lift-test interval; the convergence study "
                             "halves it down to 1 (default %(default)s)")
    parser.add_argument("--json", type=Path, help="write every figure to this JSON file")
    parser.add_argument("--quick", action="store_true", help="the scene's [quick] overrides")
    parser.add_argument("--no-own-chain", action="store_true", help="skip the run from the reference's own rest")
    parser.add_argument("-v", "--verbose", action="store_true")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(asctime)s %(name)s %(levelname)s %(message)s")
    if args.increments < 1:
        print(f"error: --increments must be ≥ 1, got {args.increments}", file=sys.stderr)
        return 2
    levels = tuple(sorted({max(1, args.increments >> k) for k in range(0, 12)}))
    levels = levels[-4:]
    try:
        case = load_case(args.scene, quick=args.quick)
    except (ValueError, FileNotFoundError, OSError) as exc:  # SceneError, MeshError, … are ValueErrors
        print(f"error: {exc}", file=sys.stderr)
        return 2
    summary = run_case(case, levels=levels, own_chain=not args.no_own_chain)
    print_summary(summary)
    if args.json:
        args.json.write_text(json.dumps(json_safe(summary), indent=1), encoding="utf-8")
    return 0 if summary["agree"] else 1


if __name__ == "__main__":
    sys.exit(main())
