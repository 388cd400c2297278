"""The ``tracker`` section of ``make bench``: the pickup engine against a baseline commit, side by side.

Two worker processes, one importing fem_grasp from this checkout and one from a baseline commit (exported with
``git archive`` into ``bench/out/baseline-<sha>``), take turns on the same scenes: for each scene a first call
(the body's assembly and factorisation included, the numba kernels already loaded by a warm-up on another scene)
and then ``reps`` pickups, alternating baseline and current so both see the same load on a shared machine.
Per scene the table gives the medians, their ratio, the first calls, and whether the answers are the same at the
level of the answer: the verdict, ρ* within :data:`SAME_RHO_STEPS` squeeze increments, each finger's resultant and
Σ f·n̂ within :data:`SAME_FORCE` of the weight; whether the event sequences are identical is reported beside it, as
an instrument (at a knife edge round-off decides them, not the model).

``--against SETTING …`` compares this checkout with itself instead: the "baseline" worker runs this checkout's
fem_grasp with each SETTING applied — ``settings.FIELD=VALUE`` (a field of
:class:`fem_grasp.settings.EngineSettings`, e.g. ``settings.implicit_contacts=0``: every tracker of the worker is
built with it, ``Tracker.default_settings``; an unknown field is refused naming it), ``module.ATTRIBUTE=VALUE``
(any other switch, such as ``fem_grasp.grasp.lift_test.DEFAULT_STEP_FRACTION=0.1``, set after import; VALUE a
Python literal) or ``ENV:NAME=VALUE`` (an environment variable of the worker, e.g. ``ENV:FEM_GRASP_NO_JIT=1``):
what one step of the engine is worth, measured in one interleaved run.  A constant that other modules import by value (``from
fem_grasp.elastic.compliance import PREFETCH_NODES``) keeps its old value there: the worker warns, naming those
modules (:func:`by_value_copies`), unless they are switched too.

``python -m bench.tracker --baseline REV`` runs it alone; ``python -m bench.bench --only tracker`` (``make bench``)
runs it as a section of the benchmark and keeps it in ``bench/out/bench.json``.  The worker protocol (one JSON
line per request on stdin, one per answer on stdout) is :func:`serve`.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import os
import statistics
import subprocess
import sys
import tarfile
import time
from pathlib import Path
from typing import Any

log = logging.getLogger("bench")

__all__ = ["PHASES", "SCENES", "SAME_FORCE", "SAME_RHO_STEPS", "SEARCH_CANDIDATES", "by_value_copies", "compare",
           "compare_search", "fingerprint", "print_tracker", "section_tracker", "serve"]

ROOT = Path(__file__).resolve().parent.parent
#: The shipped paper scenes and the foam block (the box the tests use most).
SCENES = ("tomato", "orange", "steam_bun", "football", "foam_block")
#: The default baseline: the engine before the event-tracking rewrite (the convergence study's last change).
DEFAULT_BASELINE = "8d4802882b8d0ef62be1f91ccaf5e132eca56f11"
#: The orange scene's modulus, for the uniform oranges of ``--large`` (as in the scaling section).
ORANGE_YOUNG = 2e4
#: The convergence study's cheapest routes to a converged answer (docs/convergence.md, "time to target"): the
#: tomato (2 %) and the football (10 %) meshed finer at the fingertips and the table, inner spacing R/4
#: (``--routes``; the "time to a 5 % answer").
ROUTES = (("tomato", 0.25), ("football", 0.25))
#: The phases of a pickup that ``PickupResult.timings`` reports, in Algorithm 1's order, and their sum.
PHASES = ("rest", "closure", "squeeze", "lift_test", "lift", "total")
#: Placements of ``--search`` (the placement search's default number of candidates).
SEARCH_CANDIDATES = 64
#: A placement search's rows are the same answer when these columns are equal ...
SEARCH_EXACT = ("status", "outcome", "success")
#: ... ρ* agrees to :data:`SAME_RHO_STEPS` squeeze increments and these finger forces (each finger's resultant and
#: Table III's normal sum) to :data:`SAME_FORCE` of mg.  The event counts are reported, not compared.
SEARCH_FORCES = ("force1", "force2", "finger_normal_force")
#: Event counts of a search row: an instrument (where two engines take other branches), not part of the answer.
SEARCH_EVENTS = ("events", "events_A", "events_B", "events_C", "events_D")
#: "The same answer" is judged at the level of the answer: the verdict, ρ* within this many squeeze increments ...
SAME_RHO_STEPS = 1.0
#: ... and each finger's resultant and Σ f·n̂ within this fraction of mg.  Identical event sequences are reported
#: as an instrument: at a knife edge (a zero-force node released or kept) round-off decides them, not the model.
SAME_FORCE = 0.01


# ------------------------------------------------------------------ worker side
def fingerprint(result: Any) -> dict[str, Any]:
    """What "the same answer" compares: verdict, events (kind, node, contact body, phase), ρ*, the final contact
    forces per node, the weight."""
    import numpy as np

    final = result.final
    forces = ({str(k): np.asarray(v, dtype=float).reshape(-1, 3).tolist() for k, v in final.contact_forces.items()}
              if final is not None else {})
    fingers = result.finger_forces
    return {"success": bool(result.success), "reason": result.reason, "rho": float(result.squeeze_depth),
            "events": [[e.kind, int(e.node), e.contact, e.phase] for e in result.events], "forces": forces,
            "weight": float(result.body.weight), "step": float(result.step),
            "fingers": ([[*map(float, f.resultant), float(f.normal_sum)] for f in fingers]
                        if fingers is not None else None)}


def _pickup(name: str, quick: bool = False) -> dict[str, Any]:
    from fem_grasp.io.scene import load_scene, resolve_scene

    # one run on the scene's mesh (the engine's time), whatever the scene's accuracy: a scene's default refines
    scene = dataclasses.replace(load_scene(resolve_scene(name), quick=quick), accuracy=None)
    t0 = time.perf_counter()
    result = scene.run(cache_dir=None)
    seconds = time.perf_counter() - t0
    return _answer(seconds, result)


def _scene_run(name: str, changes: dict[str, Any]) -> dict[str, Any]:
    """``fem-grasp run NAME`` as a user runs it (the scene's own accuracy target: the time to an answer with its
    stated error), with :meth:`~fem_grasp.io.scene.Scene.with_`'s ``changes``; the answer is the final level's."""
    from fem_grasp.io.scene import run_scene

    t0 = time.perf_counter()
    result = run_scene(name, cache_dir=None, **changes)
    return _answer(time.perf_counter() - t0, result)


def scene_run_request(spec: str) -> dict[str, Any]:
    """The worker's request for ``--runs SPEC``: ``NAME`` or ``NAME:key=value,key=value`` (a shipped scene and
    :meth:`~fem_grasp.io.scene.Scene.with_`'s changes; a value is a Python literal or else a string, as in a scene
    file: ``tomato:refinement=nested,max_finger_contacts=600``)."""
    import ast

    name, _, rest = spec.partition(":")
    changes: dict[str, Any] = {}
    for item in filter(None, rest.split(",")):
        key, eq, value = item.partition("=")
        if not eq or not key.strip():
            raise SystemExit(f"--runs {spec}: expected NAME:key=value[,key=value], got {item!r}")
        try:
            changes[key.strip()] = ast.literal_eval(value.strip())
        except (ValueError, SyntaxError):
            changes[key.strip()] = value.strip()
    return {"run": name, "changes": changes}


def _orange_pickup(path: str) -> dict[str, Any]:
    """The scaling section's uniform orange (a gmsh mesh saved by the parent) at the orange scene's 20 kPa, Table I
    ν and weight, pickup()'s default friction and the paper scenes' placement rule, rest included."""
    import numpy as np

    from fem_grasp import Body, pickup, rest
    from fem_grasp.grasp import objects
    from fem_grasp.grasp.pickup import DEFAULT_FRICTION
    from fem_grasp.mesh.tetmesh import TetMesh

    with np.load(path) as data:
        mesh = TetMesh(data["points"], data["tets"])
    row = objects.paper_object("orange")
    t0 = time.perf_counter()
    body = Body(mesh, ORANGE_YOUNG, row.poisson, weight=row.weight)
    resting = rest(body, DEFAULT_FRICTION)
    t_rest = time.perf_counter() - t0
    result = pickup(body, mu_finger=DEFAULT_FRICTION, mu_table=DEFAULT_FRICTION, rest_state=resting,
                    placement_rule=objects.PAPER_PLACEMENT_RULE)
    return _answer(time.perf_counter() - t0, result, rest=t_rest)


def _answer(seconds: float, result: Any, rest: float | None = None) -> dict[str, Any]:
    """A worker's answer: the pickup's wall time, its fingerprint and its phases (``PickupResult.timings``, s;
    ``rest``: the rest computed before :func:`~fem_grasp.pickup` was called, with the body's factorisation)."""
    phases = {k: float(v) for k, v in result.timings.items()}
    if rest is not None:
        phases["rest"] += rest
        phases["total"] += rest
    return {"seconds": seconds, "fingerprint": fingerprint(result), "phases": phases}


def serve() -> int:
    """Answer ``{"scene": NAME, "quick": false}`` lines with ``{"seconds": …, "fingerprint": …}`` lines until stdin closes; the
    first line out says which fem_grasp this process imported."""
    logging.basicConfig(level=logging.WARNING)
    import fem_grasp

    try:
        _apply_switches()
    except (ValueError, SyntaxError, ImportError) as exc:  # reported to the parent, which raises it
        print(json.dumps({"error": str(exc)}), flush=True)
        return 1
    print(json.dumps({"fem_grasp": str(Path(fem_grasp.__file__).resolve().parent)}), flush=True)
    for line in sys.stdin:
        request = json.loads(line)
        try:
            if "search" in request:
                answer = _search(request["search"], int(request["candidates"]), bool(request.get("quick")))
            elif "run" in request:
                answer = _scene_run(request["run"], request["changes"])
            elif "route" in request:
                answer = _route_pickup(request["mesh"], request["route"])
            elif "mesh" in request:
                answer = _orange_pickup(request["mesh"])
            else:
                answer = _pickup(request["scene"], bool(request.get("quick")))
        except Exception as exc:  # noqa: BLE001 - reported to the parent, which names the tree and the scene
            answer = {"error": f"{type(exc).__name__}: {exc}"}
        print(json.dumps(answer), flush=True)
    return 0


def _route_pickup(path: str, scene_name: str) -> dict[str, Any]:
    """A shipped scene's pickup on another mesh of its object (a graded mesh of ``--routes``, saved by the parent
    with the contact nodes nearest the scene's): the body as the convergence study builds it, the scene's settings."""
    import numpy as np

    from fem_grasp.elastic.body import Body
    from fem_grasp.grasp.pickup import pickup
    from fem_grasp.io.scene import load_scene, resolve_scene
    from fem_grasp.mesh.tetmesh import TetMesh

    scene = load_scene(resolve_scene(scene_name))
    with np.load(path) as data:
        mesh = TetMesh(data["points"], data["tets"])
        contacts = tuple(int(k) for k in data["contacts"]) if data["contacts"].size else None
    kw = scene.pickup_kwargs()
    if contacts is not None:
        kw["contacts"] = contacts
    t0 = time.perf_counter()
    body = Body(mesh, scene.young, scene.poisson, gravity=scene.gravity,
                **({"weight": scene.weight} if scene.weight is not None else {"density": scene.density}))
    result = pickup(body, **kw)
    return {**_answer(time.perf_counter() - t0, result), "vertices": int(len(mesh.points))}


def _search(scene_name: str, candidates: int, quick: bool) -> dict[str, Any]:
    """A placement search of a shipped scene (``fem-grasp search``'s defaults, in this process, no files): its wall
    time and, per placement, the columns that :func:`compare_search` compares."""
    import math

    from fem_grasp.batch.engine import search

    t0 = time.perf_counter()
    result = search(scene_name, None, candidates=candidates, workers=0, report=False, best=0, quick=quick,
                    cache_dir=None)
    seconds = time.perf_counter() - t0

    def plain(v: Any) -> Any:  # JSON: numbers and strings, NaN (no ρ*) as None
        v = v.item() if hasattr(v, "item") else v
        return None if isinstance(v, float) and math.isnan(v) else v

    columns = SEARCH_EXACT + SEARCH_EVENTS + ("rho_star", "step", "weight") + SEARCH_FORCES
    rows = {str(row["key"]): {c: plain(row[c]) if c in row else None for c in columns}
            for _, row in result.table.iterrows()}
    return {"seconds": seconds, "placements": rows}


def route_mesh(scene_name: str, inner: float, cache: Path) -> Path:
    """The convergence study's graded mesh of a scene's object (fingertips and table at ``inner`` × R), built once
    with gmsh and saved with the scene's contact nodes mapped onto it (``verification.converge.specs``)."""
    import numpy as np

    from verification.converge import specs

    path = cache / f"{scene_name}_graded_table_{inner:g}.npz"
    if not path.exists():
        spec = {"object": scene_name, "series": "graded_table", "inner": inner}
        scene = specs.scene_of(scene_name)
        mesh, _ = specs.build_mesh(spec, scene)
        contacts = specs.pickup_kwargs(spec, scene, mesh).get("contacts")
        cache.mkdir(parents=True, exist_ok=True)
        np.savez(path, points=mesh.points, tets=mesh.tets,
                 contacts=np.asarray(contacts if contacts is not None else [], dtype=np.int64))
    return path


# ------------------------------------------------------------------ parent side
def _steps_apart(rho_a: float | None, rho_b: float | None, step_a: float | None, step_b: float | None) -> float:
    """|Δρ*| in squeeze increments (the larger of the two sides'); no ρ* on both sides is no difference. A side that
    does not record its increment (an older baseline) borrows the other's."""
    if rho_a is None or rho_b is None:
        return 0.0 if rho_a is None and rho_b is None else float("inf")
    step = max(step_a or 0.0, step_b or 0.0)
    gap = abs(float(rho_a) - float(rho_b))
    return gap / step if step > 0 else (0.0 if gap == 0 else float("inf"))


def _finger_gap(base: dict[str, Any], new: dict[str, Any]) -> float:
    """The largest difference of a finger's resultant or Σ f·n̂ between two fingerprints, / mg (from the contact
    forces when a side does not record its finger forces)."""
    import numpy as np

    from fem_grasp.contact.obstacles import OBSTACLES

    def fingers(fp: dict[str, Any]) -> np.ndarray | None:
        if fp.get("fingers") is not None:
            return np.asarray(fp["fingers"], dtype=float)
        if not fp["forces"]:
            return None
        rows = [np.asarray(fp["forces"].get(f, []), dtype=float).reshape(-1, 3).sum(axis=0) for f in OBSTACLES[:2]]
        return np.array([[*r, np.nan] for r in rows])

    a, b = fingers(base), fingers(new)
    if a is None or b is None:
        return 0.0 if a is None and b is None else float("inf")
    gap = np.abs(a - b)
    return float(np.nanmax(gap)) / base["weight"]


def compare(base: dict[str, Any], new: dict[str, Any]) -> dict[str, Any]:
    """Whether two fingerprints are the same answer: the same verdict, ρ* within :data:`SAME_RHO_STEPS` squeeze
    increments, each finger's resultant and Σ f·n̂ within :data:`SAME_FORCE` × mg.  Reported beside it, as
    instruments: whether the event sequences are identical (and where they differ), |Δρ*|/ρ* and the largest
    difference of a final contact force node by node / mg (a different number of contacts: infinitely far)."""
    import numpy as np

    same_events = base["events"] == new["events"]
    rho = abs(new["rho"] - base["rho"]) / max(abs(base["rho"]), 1e-300)
    steps = _steps_apart(base["rho"], new["rho"], base.get("step"), new.get("step"))
    force = 0.0
    for obstacle in set(base["forces"]) | set(new["forces"]):
        a = np.asarray(base["forces"].get(obstacle, []), dtype=float).reshape(-1, 3)
        b = np.asarray(new["forces"].get(obstacle, []), dtype=float).reshape(-1, 3)
        if a.shape != b.shape:
            force = float("inf")
        elif a.size:
            force = max(force, float(np.abs(a - b).max()) / base["weight"])
    fingers = _finger_gap(base, new)
    same = base["success"] == new["success"] and steps <= SAME_RHO_STEPS and fingers <= SAME_FORCE
    return {"same_verdict": base["success"] == new["success"], "same_events": same_events,
            "events": [len(base["events"]), len(new["events"])], "rho_rel": rho, "rho_steps": steps,
            "force_mg": force, "fingers_mg": fingers, "same": same,
            "event_changes": event_changes(base["events"], new["events"])}


def compare_search(base: dict[str, dict[str, Any]], new: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """:func:`compare` for two placement searches, placement by placement (:data:`SEARCH_EXACT`, ρ* within
    :data:`SAME_RHO_STEPS` increments, :data:`SEARCH_FORCES` within :data:`SAME_FORCE` × mg): the same answer when
    every placement is; ``placements_differ`` names those that are not, with what differs.  Event counts are
    compared as an instrument (``same_events``)."""

    def gap(a: Any, b: Any) -> float:  # no value on both sides (no ρ*, no force) is no difference
        if a is None or b is None:
            return 0.0 if a is None and b is None else float("inf")
        return abs(float(a) - float(b))

    differ, rho_max, steps_max, force_max, same_events = [], 0.0, 0.0, 0.0, True
    for key in sorted(set(base) | set(new)):
        a, b = base.get(key), new.get(key)
        if a is None or b is None:
            differ.append({"key": key, "what": "only in the " + ("current" if a is None else "baseline") + " search"})
            continue
        unequal = [c for c in SEARCH_EXACT if a[c] != b[c]]
        same_events &= all(a.get(c) == b.get(c) for c in SEARCH_EVENTS)
        rho = gap(a["rho_star"], b["rho_star"]) / max(abs(a["rho_star"] or 0.0), 1e-300)
        steps = _steps_apart(a["rho_star"], b["rho_star"], a.get("step"), b.get("step"))
        weight = a["weight"] or b["weight"]  # none on a placement whose pickup raised (an error row)
        force = max(gap(a[c], b[c]) for c in SEARCH_FORCES) / (weight or 1.0)
        rho_max, steps_max, force_max = max(rho_max, rho), max(steps_max, steps), max(force_max, force)
        if unequal or steps > SAME_RHO_STEPS or force > SAME_FORCE:
            what = [f"{c} {a[c]} -> {b[c]}" for c in unequal]
            if steps > SAME_RHO_STEPS:
                what.append(f"rho* {1e3 * (a['rho_star'] or 0):.4g} -> {1e3 * (b['rho_star'] or 0):.4g} mm "
                            f"({steps:.3g} increments)")
            if force > SAME_FORCE:
                what.append(f"finger forces {force:.1e} mg apart")
            differ.append({"key": key, "what": "; ".join(what)})
    events = [sum(r.get("events") or 0 for r in side.values()) for side in (base, new)]
    return {"same_verdict": all(base[k]["success"] == new[k]["success"] for k in set(base) & set(new)),
            "same_events": same_events, "events": events, "rho_rel": rho_max, "rho_steps": steps_max,
            "force_mg": force_max, "fingers_mg": force_max, "same": not differ, "event_changes": [],
            "placements": len(base), "picked_up": [sum(bool(r["success"]) for r in side.values()) for side in (base, new)],
            "placements_differ": differ}


def event_changes(base: list, new: list) -> list[dict[str, Any]]:
    """Where two event sequences differ (difflib's edit script): each change's position in the baseline and the
    events it removes and adds, e.g. a node released, re-touching the table and released again at one
    parameter (a branch point: see the README's speed section)."""
    import difflib

    a, b = [tuple(e) for e in base], [tuple(e) for e in new]
    return [{"at": i1, "removed": [list(e) for e in a[i1:i2]], "added": [list(e) for e in b[j1:j2]]}
            for tag, i1, i2, j1, j2 in difflib.SequenceMatcher(None, a, b, autojunk=False).get_opcodes()
            if tag != "equal"]


def export_baseline(rev: str, into: Path | None = None) -> tuple[str, Path]:
    """The baseline's sources, exported once per commit into ``bench/out/baseline-<sha>`` (or ``into``) with
    ``git archive``."""
    proc = subprocess.run(["git", "rev-parse", "--verify", f"{rev}^{{commit}}"], cwd=ROOT, capture_output=True,
                          text=True)
    if proc.returncode != 0:
        raise SystemExit(f"bench tracker: {rev!r} is not a commit of this repository ({proc.stderr.strip()})")
    sha = proc.stdout.strip()
    tree = (into or ROOT / "bench" / "out") / f"baseline-{sha[:12]}"
    if not (tree / "fem_grasp" / "__init__.py").exists():
        tree.mkdir(parents=True, exist_ok=True)
        tar = tree.with_suffix(".tar")
        # the package and the committed paper meshes it loads (grasp.objects.MESH_DIR)
        subprocess.run(["git", "archive", "--format=tar", "-o", str(tar), sha], cwd=ROOT,  # all: meshes moved
                       check=True)
        with tarfile.open(tar) as t:
            t.extractall(tree)
        tar.unlink()
    return sha, tree


def _apply_switches() -> None:
    """Set the module attributes named in ``BENCH_SWITCHES`` (a JSON list of [module.ATTRIBUTE, value]) and the
    engine settings named ``settings.FIELD`` (the worker's ``Tracker.default_settings``); see ``--against``."""
    import ast
    import importlib

    switches = json.loads(os.environ.get("BENCH_SWITCHES", "[]"))
    overrides = {name.partition(".")[2]: ast.literal_eval(value) for name, value in switches
                 if name.startswith("settings.")}
    switches = [[name, value] for name, value in switches if not name.startswith("settings.")]
    if overrides:
        from fem_grasp.contact.tracking import Tracker
        from fem_grasp.settings import EngineSettings

        Tracker.default_settings = EngineSettings.from_overrides(overrides, base=Tracker.default_settings)
    if switches:
        # Everything a pickup imports, so that copies of a switched constant imported by value can be found.
        importlib.import_module("fem_grasp.io.scene")
        importlib.import_module("fem_grasp.grasp.pickup")
    left = {name for name, _ in switches}  # switched, or already warned about
    for name, value in switches:
        module, _, attribute = name.rpartition(".")
        mod = importlib.import_module(module)
        if not hasattr(mod, attribute):
            raise ValueError(f"--against: {module} has no attribute {attribute!r}")
        copies = [other for other in by_value_copies(mod, attribute) if f"{other}.{attribute}" not in left]
        left.update(f"{other}.{attribute}" for other in copies)
        if copies:
            log.warning("--against %s: %s keep their own %s (imported by value); switch them too if meant",
                        name, ", ".join(copies), attribute)
        setattr(mod, attribute, ast.literal_eval(value))


def by_value_copies(module: Any, attribute: str) -> list[str]:
    """The other loaded ``fem_grasp`` modules whose global ``attribute`` is the very object ``module`` binds to
    it (a ``from module import ATTRIBUTE``): setting the attribute on ``module`` does not reach them."""
    value = getattr(module, attribute)
    return sorted(name for name, other in list(sys.modules.items())
                  if other is not module and other is not None and name.split(".")[0] == "fem_grasp"
                  and vars(other).get(attribute, _MISSING) is value)


_MISSING = object()


def _against(settings: list[str]) -> tuple[dict[str, str], list[list[str]]]:
    """``--against`` settings as (environment, switches)."""
    env: dict[str, str] = {}
    switches: list[list[str]] = []
    for item in settings:
        name, eq, value = item.partition("=")
        if not eq or not name:
            raise SystemExit(f"--against {item!r}: expected settings.FIELD=VALUE, module.ATTRIBUTE=VALUE or "
                             "ENV:NAME=VALUE")
        if name.startswith("ENV:"):
            env[name[4:]] = value
        else:
            switches.append([name, value])
    return env, switches


class _Worker:
    def __init__(self, label: str, tree: Path, env: dict[str, str] | None = None,
                 switches: list[list[str]] | None = None):
        # run as a script, not with -m: -m puts the working directory first on sys.path, and this checkout's
        # fem_grasp would shadow the baseline's
        env = dict(os.environ, PYTHONPATH=str(tree), **(env or {}), BENCH_SWITCHES=json.dumps(switches or []))
        self.label = label
        self.proc = subprocess.Popen([sys.executable, str(Path(__file__).resolve()), "--serve"], cwd=tree, env=env,
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        hello = json.loads(self.proc.stdout.readline())
        if "error" in hello:
            self.close()
            raise RuntimeError(f"the {label} worker: {hello['error']}")
        if Path(hello["fem_grasp"]) != (tree / "fem_grasp").resolve():
            self.close()
            raise RuntimeError(f"the {label} worker imported fem_grasp from {hello['fem_grasp']}, not from {tree}")

    def ask(self, request: dict[str, Any]) -> dict[str, Any]:
        """One request of :func:`serve`'s protocol (a scene, a mesh, a route or a search) and its answer."""
        self.proc.stdin.write(json.dumps(request) + "\n")
        self.proc.stdin.flush()
        answer = json.loads(self.proc.stdout.readline())
        if "error" in answer:
            raise RuntimeError(f"{self.label}, {request}: {answer['error']}")
        return answer

    def close(self) -> None:
        if self.proc.stdin:
            self.proc.stdin.close()
        self.proc.wait(timeout=60)


def section_tracker(baseline: str = DEFAULT_BASELINE, reps: int = 3, scenes: tuple[str, ...] = SCENES,
                    warm_up: str | None = "foam_block", quick: bool = False,
                    export_to: Path | None = None, large: tuple[int, ...] = (),
                    mesh_cache: Path | None = None, routes: tuple[tuple[str, float], ...] = (),
                    against: tuple[str, ...] = (), searches: tuple[str, ...] = (),
                    candidates: int = SEARCH_CANDIDATES, runs: tuple[str, ...] = ()) -> dict[str, Any]:
    """Time the shipped scenes' pickups (their ``[quick]`` variants with ``quick``) with the baseline's fem_grasp
    and this checkout's, interleaved (module notes); medians of ``reps`` after the first call.  ``large``: also
    the uniform orange of about that many vertices (the scaling section's, rest included), one row each;
    ``routes``: also these (scene, inner spacing / R) graded meshes (:data:`ROUTES`).  ``searches``: also a placement
    search of ``candidates`` placements of each of these scenes, compared placement by placement
    (:func:`compare_search`; a test of "the same answer" far wider than one pickup).  ``runs``: also these scenes
    as ``fem-grasp run`` answers by default, the accuracy loop included (:func:`scene_run_request`).  ``against``:
    the baseline is this checkout with these settings instead of a commit (module notes)."""
    run_requests = [(f"{spec} (run)", scene_run_request(spec)) for spec in runs]  # a bad spec stops before any work
    if against:
        env, switches = _against(list(against))
        sha = "this checkout with " + " ".join(against)
        workers = {"baseline": _Worker("baseline", ROOT, env, switches), "current": _Worker("current", ROOT)}
    else:
        sha, tree = export_baseline(baseline, export_to)
        workers = {"baseline": _Worker("baseline", tree), "current": _Worker("current", ROOT)}
    try:
        for w in workers.values():  # numba's kernels loaded (or compiled) before any scene is timed
            if warm_up:
                w.ask({"scene": warm_up, "quick": True})
        rows = []
        # (row label, the request each worker answers)
        cases: list[tuple[str, dict[str, Any]]] = [(scene, {"scene": scene, "quick": quick}) for scene in scenes]
        if large or routes:
            from bench.meshes import CACHE, cached_mesh

            cache = mesh_cache or CACHE
            for size in large:
                cached_mesh("orange", size, cache)  # gmsh once, then both trees read the same file
                cases.append((f"orange {size / 1000:g}k", {"mesh": str(cache / f"orange_{int(size)}.npz")}))
            for name, inner in routes:
                cases.append((f"{name} R/{1 / inner:g}", {"mesh": str(route_mesh(name, inner, cache)), "route": name}))
        cases += run_requests
        cases += [(f"search {name}", {"search": name, "candidates": candidates, "quick": quick}) for name in searches]
        for scene, request in cases:
            runs: dict[str, list[dict[str, Any]]] = {"baseline": [], "current": []}
            for _ in range(reps + 1):
                for label, w in workers.items():
                    runs[label].append(w.ask(request))
            row: dict[str, Any] = {"scene": scene}
            if "route" in request:
                row["vertices"] = runs["current"][0].get("vertices")
            for label, rs in runs.items():
                row[label] = {"first": rs[0]["seconds"], "median": statistics.median(r["seconds"] for r in rs[1:]),
                              "times": [r["seconds"] for r in rs], "phases": _phase_medians(rs[1:])}
            row["ratio"] = row["baseline"]["median"] / row["current"]["median"]
            same, answer = (compare_search, "placements") if "search" in request else (compare, "fingerprint")
            row["answer"] = same(runs["baseline"][0][answer], runs["current"][0][answer])
            # every repetition of one tree gives its first answer (the engine is deterministic)
            row["repeatable"] = all(same(rs[0][answer], r[answer])["same"] for rs in runs.values() for r in rs[1:])
            rows.append(row)
            log.info("tracker %s: %.3f s -> %.3f s (x%.2f), same answer %s", scene, row["baseline"]["median"],
                     row["current"]["median"], row["ratio"], row["answer"]["same"])
    finally:
        for w in workers.values():
            w.close()
    return {"baseline": sha, "reps": reps, "quick": quick, "rows": rows, "same_rho_steps": SAME_RHO_STEPS,
            "same_force": SAME_FORCE}


def _phase_medians(runs: list[dict[str, Any]]) -> dict[str, float]:
    """Median of each phase over ``runs`` (the phases every run reports)."""
    names = set.intersection(*(set(r.get("phases", {})) for r in runs)) if runs else set()
    return {k: statistics.median(r["phases"][k] for r in runs) for k in PHASES if k in names}


def print_tracker(sec: dict[str, Any]) -> None:
    base = sec["baseline"] if sec["baseline"].startswith("this checkout") else sec["baseline"][:12]
    print(f"\n== tracker: baseline {base} against this checkout, interleaved, medians of "
          f"{sec['reps']} after the first call (s)")
    print(f"{'scene':<11} {'baseline':>9} {'current':>9} {'speed-up':>9} {'first b/c':>13}  same answer "
          f"(events, |dρ*| in increments, max finger |df|/mg)")
    for r in sec["rows"]:
        a = r["answer"]
        if r.get("vertices"):
            print(f"{r['scene']} ({r['vertices']:,} vertices):")
        print(f"{r['scene']:<11} {r['baseline']['median']:9.3f} {r['current']['median']:9.3f} {r['ratio']:8.2f}x "
              f"{r['baseline']['first']:6.2f}/{r['current']['first']:<6.2f}  {'yes' if a['same'] else 'NO '} "
              f"({'same' if a['same_events'] else 'different'} {a['events'][1]} events, {a['rho_steps']:.2g}, "
              f"{a['fingers_mg']:.1e}){'' if r['repeatable'] else '  (not repeatable)'}")
        if "placements" in a:
            print(f"{'':<11} {a['placements']} placements, picked up {a['picked_up'][0]} / {a['picked_up'][1]}; "
                  f"{len(a['placements_differ'])} differ" + (":" if a["placements_differ"] else ""))
            for d in a["placements_differ"]:
                print(f"{'':<13} {d['key']}: {d['what']}")
        for ch in a.get("event_changes", []):
            def fmt(evs):
                return ", ".join(f"{k} {n} {c}" for k, n, c, _ in evs) or "nothing"
            print(f"{'':<11} event {ch['at']}: baseline {fmt(ch['removed'])}; current {fmt(ch['added'])}")
    print("\nwhere this checkout's pickup time goes: medians of each phase (s; 'set-up' is the rest of the timed call: "
          "the scene's loading and the body's assembly)")
    print(f"{'scene':<14}" + "".join(f"{k.replace('_', ' '):>10}" for k in PHASES) + f"{'set-up':>9}")
    for r in sec["rows"]:
        ph = r["current"].get("phases", {})
        if "total" in ph:
            print(f"{r['scene']:<14}" + "".join(f"{ph.get(k, float('nan')):10.3f}" for k in PHASES)
                  + f"{r['current']['median'] - ph['total']:9.3f}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.tracker", description=__doc__.split("\n\n")[0])
    ap.add_argument("--baseline", default=DEFAULT_BASELINE,
                    help="commit to compare against (default: the engine before the event-tracking rewrite)")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--scenes", nargs="+", default=list(SCENES))
    ap.add_argument("--quick", action="store_true", help="the scenes' [quick] variants")
    ap.add_argument("--large", type=int, nargs="*", default=[],
                    help="also the uniform orange of about these many vertices (e.g. 10000 100000)")
    ap.add_argument("--routes", action="store_true",
                    help="also the convergence study's converged routes: " + ", ".join(
                        f"{n} graded to R/{1 / i:g} at fingertips and table" for n, i in ROUTES))
    ap.add_argument("--search", nargs="+", default=[], metavar="SCENE",
                    help="also a placement search of each of these scenes (fem-grasp search's candidates, in the "
                         "worker's process), compared placement by placement")
    ap.add_argument("--candidates", type=int, default=SEARCH_CANDIDATES, help="placements per --search")
    ap.add_argument("--runs", nargs="+", default=[], metavar="SCENE",
                    help="also these scenes as `fem-grasp run SCENE` answers by default (the accuracy loop: the time "
                         "to an answer with its stated error); SCENE:key=value,... adds the scene's changes, e.g. "
                         "tomato:refinement=nested,max_finger_contacts=600")
    ap.add_argument("--against", nargs="+", default=[], metavar="SETTING",
                    help="instead of a commit, this checkout with these settings: settings.FIELD=VALUE (a field "
                         "of fem_grasp.settings.EngineSettings, e.g. settings.implicit_contacts=0), "
                         "module.ATTRIBUTE=VALUE (e.g. fem_grasp.grasp.lift_test.DEFAULT_STEP_FRACTION=0.1) or "
                         "ENV:NAME=VALUE (e.g. ENV:FEM_GRASP_NO_JIT=1)")
    ap.add_argument("--serve", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.serve:
        return serve()
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    print_tracker(section_tracker(args.baseline, args.reps, tuple(args.scenes), quick=args.quick,
                                  large=tuple(args.large), routes=ROUTES if args.routes else (),
                                  against=tuple(args.against), searches=tuple(args.search),
                                  candidates=args.candidates, runs=tuple(args.runs)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
