"""Benchmarks of fem_grasp: ``make bench`` (``python -m bench.bench``; sections and tools in bench/README.md).

Sections (``--only NAME``, repeatable; default all):

``solve``
    One contact-displacement solve (three low support nodes and two finger
    nodes squeezed 1 mm, under gravity) on the orange at ~10k and ~50k
    vertices: fem_grasp from a fresh :class:`~fem_grasp.Body` (assembly,
    grounding, factorisation, compliance columns, forces and field) against
    dolfinx 0.5.2 (assembly with the Dirichlet conditions, lifting, PETSc/MUMPS
    Cholesky solve, reactions from the unconstrained K; JIT excluded by a
    warm-up on the same mesh).  Every available sparse solver is timed.
``scaling``
    Time and peak memory (ru_maxrss, one subprocess per size) of assembly,
    factorisation, ``rest()`` and ``pickup()`` from 1k to 100k vertices
    (uniform orange meshes at the orange scene's 20 kPa, fingers placed by
    the paper scenes' centre-of-mass-height rule); a size whose run exceeds
    ``--pickup-cap`` seconds is recorded as ``"timeout"``.
``objects``
    Per-object pickup medians for the four paper objects, each with its
    shipped scene (``fem-grasp run NAME``: graded mesh, placement rule,
    modulus); each repetition on a fresh body, so assembly and factorisation
    are included; import time and first-call time measured separately in a
    fresh interpreter.
``spectral``
    One pickup of the football scene with the sparse and the spectral (paper)
    backends: time ratio and the largest difference of the results.
``columns``
    Compliance columns solved k at a time (k = 3, 30, 90, 300) on the uniform
    orange of about 31k vertices, with BLAS on all its threads and on one:
    seconds per column, the reason new contacts' columns are solved in
    batches (``compliance.PREFETCH_NODES``) on all threads, also inside the
    tracking's one-thread limit (:mod:`fem_grasp.threads`).
``jit``
    One tomato pickup with the Gauss–Seidel sweeps compiled by numba and one
    with them as plain Python (``FEM_GRASP_NO_JIT=1``), each in a fresh
    process after a warm-up pickup: time ratio, same events; and the warm-up
    pickup's time, which compiles the sweeps (an empty numba cache).
``floor``
    What the method must compute at each size of the scaling section, in
    floating-point operations, against the fastest this machine computes
    (a dense matrix product): the CHOLMOD factorisation (Σ c_j² over the
    column counts of L) and one compliance column (4 nnz(L): a forward and
    a back substitution), their measured rates, and, with the scaling
    section's count of the nodes that touched (three columns each), the
    least time of factorisation and columns together (the 100k-vertex
    target).  One subprocess per size (L is converted to a simplicial copy
    to count it; about 10 GiB at 100k).  Needs CHOLMOD.

``search``
    A placement search (``fem-grasp search``) of ``--search-candidates`` candidates per paper scene, as a
    plain loop and on a Dask LocalCluster of one and of two worker processes: candidates per minute, Dask's
    overhead per candidate, and the time per candidate split into the shared set-up and the per-candidate
    work (:mod:`bench.search`).
``converge``
    Wall time to a 10 %, 5 % and 2 % answer (ρ* and the finger
    force both within the target of the converged reference) for each paper
    object and the foam block: uniform refinement, grading at the fingertips
    (the cheapest level from which every finer one is within the target) and
    the adaptive loop (``pickup(..., accuracy=target)``: its time, its error
    against the reference and whether its own estimate covered it).  The runs
    are those of ``python -m verification converge`` (``make converge``), one
    subprocess each, read from its cache (and computed into it when missing:
    hours from an empty cache).
``tracker``
    Each shipped paper scene's pickup (and the foam block's) with
    a baseline commit's fem_grasp and with this checkout's, in two worker
    processes taking turns: medians after the first call, their ratio, and
    whether the answers are the same (events, ρ* to 1e-9, forces to 1e-9 mg);
    then the uniform orange at 10k and 100k vertices (up to
    ``--max-vertices``), and the convergence study's cheapest converged
    routes (the tomato and the football graded to R/4 at fingertips and
    table: the time to a converged answer) (:mod:`bench.tracker`;
    ``--baseline REV``).
``accuracy``
    Per shipped object (the four paper scenes and the foam block), the wall
    time and the actual error against the convergence study's reference
    (ρ* and Σ f·n̂ relative to it, the verdict against its verdict) of the
    paper's method run once on the shipped mesh (accuracy off), of the scene
    as shipped (``Scene.run()``: the adaptive loop at the scene's accuracy,
    5 % unless it says otherwise), and of the adaptive loop at 5 %
    (``pickup(..., accuracy=0.05)``, needs gmsh; not run again where it is
    the scene's default, whose row it repeats: its levels nested, each
    bisecting the one before at the patches, :mod:`fem_grasp.mesh.bisection`),
    and of that loop with remeshed levels (``refinement="remesh"``: each
    level a new gmsh mesh graded at the patches); with the error each run
    states (the scene's ``expected_error``, the loop's estimate, or
    "unknown") and whether it covers the actual one.  One subprocess per run
    (``--accuracy-cap`` seconds, beyond which the row says "not run").
    Each run is measured against the object's pinned reference where it
    has one (the answer at the placement rule's own grasp points, on uniform
    meshes with those points as nodes: ``scripts/pinned_reference.py``),
    with its error against the study's beside it; else against the study's
    reference, read from its cache (``--converge-quick``: its quick study),
    else from the full study's committed references
    (``verification/converge/references.json``); an object with neither is
    skipped (``--accuracy-compute`` computes the study's: hours, minutes for
    the quick study).  The default is run again on ``--accuracy-draws``
    other draws of its meshes: each rounds the points and lengths gmsh is
    given to another grid (``POINT_QUANTUM`` times 2, 4, ...: a move of at
    most a millionth of a spacing, which gives gmsh's mesh of the same level
    other tetrahedra, as another CPU's round-off would do to them
    unrounded); the row gives how often the loop converges, the spread of
    its time, its answer's error and its stated error, and how often that
    covers the error (for nested levels the draw is level 0's mesh, which
    they refine).  The remeshed levels are run again on the same draws.
``divisions``
    Per shipped scene, the pickup at its squeeze increment s, at s with the
    increment in which the lift test passes divided in four
    (``PickupOptions.step_divisions``) and at s/4 throughout: ρ*, Σ f·n̂, each
    finger's resultant against the s/4 run, lift tests and time
    (:mod:`bench.divisions`).

Medians over ``--reps`` repetitions.  Prints tables and writes
``bench/out/bench.json`` (sections run earlier are kept when ``--only`` runs
some again).  Meshes are generated once with gmsh and cached in
``bench/out/meshes``.
"""

from __future__ import annotations

import argparse
import gc
import json
import logging
import math
import os
import platform
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

log = logging.getLogger("bench")

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "bench" / "out" / "bench.json"
SECTIONS = ("solve", "scaling", "objects", "spectral", "jit", "columns", "floor", "search", "converge", "tracker",
            "accuracy", "divisions")
SOLVE_SIZES = (10000, 50000)
#: The uniform oranges of the tracker section (10k: the target is ≥ 5× faster than the baseline; 100k reported).
TRACKER_LARGE = (10000, 100000)
SCALING_SIZES = (1000, 3000, 10000, 30000, 50000, 100000)
#: SuperLU above this many vertices takes minutes and gigabytes: not timed.
SUPERLU_MAX_VERTICES = 20000
YOUNG = 1e4
#: The orange scene's modulus and placement rule for the scaling pickups (at 10 kPa its uniform meshes are
#: not picked up: the squeeze runs to its limit, which measures the limit, not a pickup).
SCALING_YOUNG = 2e4


# ----------------------------------------------------------------- helpers
def median(values: list[float]) -> float:
    return float(statistics.median(values))


def timed(fn: Callable[[], Any]) -> tuple[float, Any]:
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, out


def maxrss_mib() -> float:
    """Peak resident memory of this process so far, MiB (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def machine() -> dict[str, Any]:
    from verification._common.run import cpu_model

    cpu = cpu_model()
    try:
        mem = next(int(line.split()[1]) for line in Path("/proc/meminfo").read_text().splitlines()
                   if line.startswith("MemTotal")) / 2**20
    except (OSError, StopIteration):
        mem = float("nan")
    import scipy

    from fem_grasp.contact.kernels import jit
    from fem_grasp.elastic import sparse_solvers

    return {"cpu": cpu, "cores": os.cpu_count(), "memory_gib": round(mem, 1), "python": platform.python_version(),
            "numpy": np.__version__, "scipy": scipy.__version__, "default_solver": sparse_solvers.choose_solver(),
            "cholmod": sparse_solvers.cholmod_available(), "inner_loops": jit.backend_name(),
            "date": time.strftime("%Y-%m-%d")}


def orange_body(mesh, young: float = YOUNG):
    from fem_grasp import Body
    from fem_grasp.grasp import objects

    row = objects.paper_object("orange")
    return Body(mesh, young, row.poisson, weight=row.weight)


def demo_contacts(body) -> tuple[np.ndarray, np.ndarray]:
    """Three low support nodes and two finger nodes at the centre-of-mass height, squeezed 1 mm along d̂1, d̂2."""
    from fem_grasp.grasp import placement

    support = placement.spread_triple(body.mesh.points, placement.lowest_nodes(body.mesh))
    fingers = placement.finger_contact_nodes(body.mesh, body.center_of_mass[2])
    nodes = np.concatenate([support, fingers]).astype(np.int64)
    disp = np.zeros((5, 3))
    disp[3:] = 1e-3 * np.array(placement.PAPER_SQUEEZE_DIRECTIONS)
    return nodes, disp


def available_solvers() -> list[str]:
    from fem_grasp.elastic import sparse_solvers

    out = ["cholmod"] if sparse_solvers.cholmod_available() else []
    out.append("superlu")
    try:
        import petsc4py  # noqa: F401
        out.append("mumps")
    except ImportError:
        pass
    return out


# ------------------------------------------------------------ (a) solve
def fem_grasp_solve(mesh, nodes, disp, solver: str) -> dict[str, Any]:
    """One contact solve from a fresh body, with its phases timed."""
    from fem_grasp import solve_contact
    from fem_grasp.elastic.compliance import Compliance

    os.environ["FEM_GRASP_SOLVER"] = solver
    gc.collect()
    t0 = time.perf_counter()
    body = orange_body(mesh)
    t_asm, _ = timed(lambda: body.stiffness)
    t_fac, comp = timed(lambda: body.compliance)
    assert isinstance(comp, Compliance) and comp.solver == solver
    t_sol, sol = timed(lambda: solve_contact(body, nodes, disp))
    total = time.perf_counter() - t0
    return {"total_s": total, "assembly_s": t_asm, "factorisation_s": t_fac, "solve_s": t_sol,
            "forces": sol.forces, "displacements": sol.displacements}


def dolfinx_solve(model, body, nodes, disp) -> dict[str, Any]:
    sol = model.solve_contact(body.young, body.poisson, body.density, body.gravity, nodes, disp)
    return {"total_s": sol.seconds, "forces": sol.forces, "displacements": sol.displacements}


def section_solve(sizes: list[int], reps: int) -> dict[str, Any]:
    from bench.meshes import cached_mesh

    rows = []
    for size in sizes:
        mesh = cached_mesh("orange", size)
        body = orange_body(mesh)
        nodes, disp = demo_contacts(body)
        row: dict[str, Any] = {"target": size, "vertices": mesh.n_points, "tets": mesh.n_tets,
                               "dofs": 3 * mesh.n_points, "contacts": len(nodes), "fem_grasp": {}}
        ref = None
        for solver in available_solvers():
            if solver == "superlu" and mesh.n_points > SUPERLU_MAX_VERTICES:
                row["fem_grasp"][solver] = "skipped (minutes and GBs at this size)"
                continue
            runs = [fem_grasp_solve(mesh, nodes, disp, solver) for _ in range(reps)]
            ref = ref or runs[0]
            row["fem_grasp"][solver] = {k: median([r[k] for r in runs])
                                        for k in ("total_s", "assembly_s", "factorisation_s", "solve_s")}
            log.info("solve %d vertices, %s: %.3f s", mesh.n_points, solver, row["fem_grasp"][solver]["total_s"])
        os.environ.pop("FEM_GRASP_SOLVER", None)
        try:
            from verification.dolfinx.reference import DolfinxModel
        except ImportError as exc:  # pragma: no cover - dolfinx is in the venv
            row["dolfinx"] = f"unavailable: {exc}"
        else:
            model = DolfinxModel(mesh)
            dolfinx_solve(model, body, nodes, disp)  # JIT and first-call costs, not timed
            runs = [dolfinx_solve(model, body, nodes, disp) for _ in range(reps)]
            row["dolfinx"] = {"total_s": median([r["total_s"] for r in runs]), "solver": "PETSc MUMPS Cholesky"}
            f_ref = runs[0]["forces"]
            row["force_rel_diff"] = float(np.abs(ref["forces"] - f_ref).max() / np.abs(f_ref).max())
            row["field_rel_diff"] = float(np.abs(ref["displacements"] - runs[0]["displacements"]).max()
                                          / np.abs(runs[0]["displacements"]).max())
            best = min(v["total_s"] for v in row["fem_grasp"].values() if isinstance(v, dict))
            row["best_fem_grasp_s"] = best
            row["ratio_fem_grasp_over_dolfinx"] = best / row["dolfinx"]["total_s"]
            del model
        rows.append(row)
    return {"rows": rows, "reps": reps}


def print_solve(sec: dict[str, Any]) -> None:
    print("\n(a) one contact solve, assembly included (orange, 5 contacts, medians of", sec["reps"], "runs)")
    print(f"{'vertices':>9s} {'DOFs':>8s} {'solver':>8s} {'assembly':>9s} {'factor':>8s} {'solve':>7s} "
          f"{'total s':>8s} {'dolfinx s':>9s} {'ratio':>6s} {'|dF|/|F|':>9s}")
    for r in sec["rows"]:
        dol = r.get("dolfinx")
        dol_s = dol["total_s"] if isinstance(dol, dict) else float("nan")
        for solver, v in r["fem_grasp"].items():
            if not isinstance(v, dict):
                print(f"{r['vertices']:9d} {r['dofs']:8d} {solver:>8s}  {v}")
                continue
            print(f"{r['vertices']:9d} {r['dofs']:8d} {solver:>8s} {v['assembly_s']:9.3f} {v['factorisation_s']:8.3f} "
                  f"{v['solve_s']:7.3f} {v['total_s']:8.3f} {dol_s:9.3f} {v['total_s'] / dol_s:6.2f} "
                  f"{r.get('force_rel_diff', float('nan')):9.1e}")


# ---------------------------------------------------------- (b) scaling
def scaling_worker(size: int) -> None:
    """Run in a subprocess: one JSON line per finished phase on stdout."""
    from bench.meshes import cached_mesh
    from fem_grasp import pickup, rest
    from fem_grasp.grasp.objects import PAPER_PLACEMENT_RULE
    from fem_grasp.grasp.pickup import DEFAULT_FRICTION

    def emit(**kw: Any) -> None:
        print(json.dumps(kw), flush=True)

    mesh = cached_mesh("orange", size)
    emit(phase="mesh", vertices=mesh.n_points, tets=mesh.n_tets, surface=len(mesh.surface_nodes),
         maxrss_mib=maxrss_mib())
    body = orange_body(mesh, SCALING_YOUNG)
    t, k = timed(lambda: body.stiffness)
    emit(phase="assembly", seconds=t, nnz=int(k.nnz), maxrss_mib=maxrss_mib())
    t, comp = timed(lambda: body.compliance)
    emit(phase="factorisation", seconds=t, solver=comp.solver, maxrss_mib=maxrss_mib())
    mu = DEFAULT_FRICTION  # pickup()'s default for finger and table
    t, rs = timed(lambda: rest(body, mu))
    emit(phase="rest", seconds=t, contacts=len(rs.contact_nodes), maxrss_mib=maxrss_mib())
    t, res = timed(lambda: pickup(body, mu_finger=mu, mu_table=mu, rest_state=rs, placement_rule=PAPER_PLACEMENT_RULE))
    emit(phase="pickup", seconds=t, success=bool(res.success), reason=res.reason, events=len(res.events),
         cached_columns=res.body.compliance.cached_nodes, touched_nodes=len(touched_nodes(rs, res)),
         maxrss_mib=maxrss_mib())


def touched_nodes(rest_state, result) -> np.ndarray:
    """The nodes in contact at rest or in any snapshot of a pickup (each needs its compliance columns)."""
    sets = [np.asarray(rest_state.contact_nodes, dtype=np.int64)]
    sets += [np.asarray(v, dtype=np.int64) for s in result.snapshots for v in s.contact_nodes.values()]
    return np.unique(np.concatenate(sets))


def section_scaling(sizes: list[int], cap: float) -> dict[str, Any]:
    rows = []
    for size in sizes:
        cmd = [sys.executable, "-m", "bench.bench", "--worker-scaling", str(size)]
        row: dict[str, Any] = {"target": size}
        lines: list[str] = []
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, text=True)
        try:
            out, _ = proc.communicate(timeout=cap)
            lines = out.splitlines()
            row["status"] = "ok" if proc.returncode == 0 else f"exit {proc.returncode}"
        except subprocess.TimeoutExpired:
            proc.kill()
            out, _ = proc.communicate()
            lines = out.splitlines()
            row["status"] = "timeout"
        row["wall_s"] = time.perf_counter() - t0
        for line in lines:
            try:
                rec = json.loads(line)
            except json.JSONDecodeError:
                continue
            row[rec.pop("phase")] = rec
        for phase in ("assembly", "factorisation", "rest", "pickup"):
            if phase not in row:
                row[phase] = "timeout" if row["status"] == "timeout" else "not reached"
        rows.append(row)
        log.info("scaling %d: %s", size, row["status"])
    return {"rows": rows, "cap_s": cap, "young": SCALING_YOUNG,
            "note": "one subprocess per size (cap on the whole run: mesh load, assembly, factorisation, rest, "
                    "pickup); memory is the process's peak RSS after each phase"}


def print_scaling(sec: dict[str, Any]) -> None:
    print(f"\n(b) cost against vertex count (orange, E = {sec.get('young', YOUNG):g} Pa, uniform meshes; one process per "
          f"size, cap {sec['cap_s']:.0f} s)")
    print(f"{'vertices':>9s} {'assembly s':>10s} {'factor s':>9s} {'rest s':>8s} {'pickup s':>9s} {'lifted':>7s} "
          f"{'peak MiB':>9s} {'after':>14s}")

    def s(v: Any) -> str:
        return f"{v['seconds']:.3f}" if isinstance(v, dict) else str(v)

    for r in sec["rows"]:
        mem, where = 0.0, "-"
        for phase in ("mesh", "assembly", "factorisation", "rest", "pickup"):
            if isinstance(r.get(phase), dict):
                mem, where = r[phase]["maxrss_mib"], phase
        verts = r["mesh"]["vertices"] if isinstance(r.get("mesh"), dict) else r["target"]
        lifted = str(r["pickup"]["success"]) if isinstance(r.get("pickup"), dict) else "-"
        print(f"{verts:9d} {s(r['assembly']):>10s} {s(r['factorisation']):>9s} {s(r['rest']):>8s} "
              f"{s(r['pickup']):>9s} {lifted:>7s} {mem:9.0f} {where:>14s}")


# ---------------------------------------------------------- (c) objects
IMPORT_SNIPPET = """
import json, time
t0 = time.perf_counter()
import fem_grasp
from fem_grasp.grasp.pickup import pickup
from fem_grasp.io.scene import load_scene, resolve_scene
t1 = time.perf_counter()
scene = load_scene(resolve_scene({name!r}))
res = pickup(scene.body(), **scene.pickup_kwargs())
t2 = time.perf_counter()
print(json.dumps({{"import_s": t1 - t0, "first_call_s": t2 - t1}}))
"""


def one_pickup(name: str, backend: str = "sparse"):
    """The shipped scene ``name`` (``fem-grasp run NAME``), on a fresh body, with the given backend."""
    from fem_grasp.grasp.pickup import pickup
    from fem_grasp.io.scene import load_scene, resolve_scene

    scene = load_scene(resolve_scene(name))
    kw = scene.pickup_kwargs()
    kw["backend"] = backend
    return pickup(scene.body(), **kw)


def section_objects(reps: int, budget: float) -> dict[str, Any]:
    from fem_grasp.grasp import objects

    rows = []
    for name in objects.NAMES:
        proc = subprocess.run([sys.executable, "-c", IMPORT_SNIPPET.format(name=name)], cwd=ROOT,
                              capture_output=True, text=True, check=True)
        first = json.loads(proc.stdout.strip().splitlines()[-1])
        times, res = [], None
        start = time.perf_counter()
        for _ in range(reps):
            t, res = timed(lambda: one_pickup(name))
            times.append(t)
            if time.perf_counter() - start > budget:
                break
        rows.append({"object": name, "vertices": res.body.n_nodes, "young": res.body.young,
                     "success": bool(res.success), "events": len(res.events), "median_s": median(times),
                     "min_s": min(times), "runs": len(times), "import_s": first["import_s"],
                     "first_call_s": first["first_call_s"],
                     "phases_s": {k: float(v) for k, v in res.timings.items()}})
        log.info("pickup %s: %.3f s", name, rows[-1]["median_s"])
    return {"rows": rows, "scenes": "the shipped paper scenes (fem-grasp run NAME)",
            "note": "median over fresh bodies (assembly and factorisation included), in-process after import"}


def print_objects(sec: dict[str, Any]) -> None:
    print("\n(c) full pickup per paper object, the shipped scenes (fresh body each run)")
    print(f"{'object':>10s} {'vertices':>8s} {'E Pa':>7s} {'lifted':>6s} {'events':>6s} {'median s':>9s} "
          f"{'runs':>4s} {'import s':>8s} {'1st call s':>10s}  largest phases")
    for r in sec["rows"]:
        ph = sorted(((v, k) for k, v in r["phases_s"].items() if k != "total"), reverse=True)[:2]
        print(f"{r['object']:>10s} {r['vertices']:8d} {r.get('young', float('nan')):7.0e} {str(r['success']):>6s} "
              f"{r['events']:6d} {r['median_s']:9.3f} {r['runs']:4d} {r['import_s']:8.3f} {r['first_call_s']:10.3f}"
              f"  {', '.join(f'{k} {v:.1f} s' for v, k in ph)}")


# --------------------------------------------------------- spectral ratio
def snapshot_difference(a, b) -> dict[str, float]:
    """Largest differences between two pickups of the same body (forces relative to the weight)."""
    out = {"same_events": [(e.kind, e.node) for e in a.events] == [(e.kind, e.node) for e in b.events],
           "squeeze_depth_rel": abs(a.squeeze_depth - b.squeeze_depth) / max(abs(b.squeeze_depth), 1e-300)}
    if a.final is not None and b.final is not None:
        w = a.body.weight
        fa, fb = np.asarray(a.final.all_forces), np.asarray(b.final.all_forces)
        out["final_forces_over_weight"] = float(np.abs(fa - fb).max() / w) if fa.shape == fb.shape else float("inf")
        out["final_positions_over_diameter"] = float(np.abs(a.final.positions - b.final.positions).max()
                                                     / a.body.mesh.diameter)
    return out


def section_spectral(name: str = "football") -> dict[str, Any]:
    t_sparse, a = timed(lambda: one_pickup(name, "sparse"))
    t_spec, b = timed(lambda: one_pickup(name, "spectral"))
    return {"object": name, "vertices": a.body.n_nodes, "sparse_s": t_sparse, "spectral_s": t_spec,
            "ratio": t_spec / t_sparse, "difference": snapshot_difference(a, b)}


def print_spectral(sec: dict[str, Any]) -> None:
    d = sec["difference"]
    print(f"\n(d) one pickup, sparse against spectral (paper), {sec['object']} ({sec['vertices']} vertices): "
          f"sparse {sec['sparse_s']:.3f} s, spectral {sec['spectral_s']:.2f} s, ratio {sec['ratio']:.0f}; "
          f"same events {d['same_events']}, squeeze depth rel. diff. {d['squeeze_depth_rel']:.1e}, "
          f"final forces / mg {d.get('final_forces_over_weight', float('nan')):.1e}, "
          f"positions / diameter {d.get('final_positions_over_diameter', float('nan')):.1e}")


# ------------------------------------------------- compiled or plain Python
JIT_SNIPPET = """
import json, time
from fem_grasp.contact.kernels import jit
from bench.bench import one_pickup
t = time.perf_counter()
one_pickup({name!r})  # compiles the kernels (an empty numba cache), warms the caches
first = time.perf_counter() - t
t = time.perf_counter()
res = one_pickup({name!r})
print(json.dumps({{"seconds": time.perf_counter() - t, "first_s": first, "inner_loops": jit.backend_name(),
                  "events": [[e.kind, int(e.node)] for e in res.events], "squeeze_depth": res.squeeze_depth}}))
"""


def section_jit(name: str = "tomato") -> dict[str, Any]:
    """One pickup with the kernels (Gauss–Seidel sweeps, slip-system Newton) compiled by numba, one with them
    run by Python and numpy (FEM_GRASP_NO_JIT=1), each in its own process after a warm-up pickup."""
    import tempfile

    runs = {}
    for label, extra in (("compiled", {}), ("python", {"FEM_GRASP_NO_JIT": "1"})):
        env = {k: v for k, v in os.environ.items() if k != "FEM_GRASP_NO_JIT"}
        with tempfile.TemporaryDirectory() as cache:  # an empty numba cache: the first pickup compiles
            proc = subprocess.run([sys.executable, "-c", JIT_SNIPPET.format(name=name)], cwd=ROOT,
                                  env=dict(env, NUMBA_CACHE_DIR=cache, **extra), capture_output=True, text=True,
                                  check=True)
        runs[label] = json.loads(proc.stdout.strip().splitlines()[-1])
        log.info("pickup %s, %s: %.3f s", name, runs[label]["inner_loops"], runs[label]["seconds"])
    a, b = runs["compiled"], runs["python"]
    return {"object": name, "compiled": a["inner_loops"], "compiled_s": a["seconds"], "python_s": b["seconds"],
            "ratio": b["seconds"] / a["seconds"], "same_events": a["events"] == b["events"],
            "compiled_first_s": a["first_s"], "python_first_s": b["first_s"],
            "squeeze_depth_rel": abs(a["squeeze_depth"] - b["squeeze_depth"]) / abs(b["squeeze_depth"])}


def print_jit(sec: dict[str, Any]) -> None:
    print(f"\n(e) one pickup, {sec['object']}, kernels (Gauss–Seidel sweeps, slip-system Newton) compiled "
          f"({sec['compiled']}) against plain Python: "
          f"{sec['compiled_s']:.3f} s against {sec['python_s']:.3f} s, ratio {sec['ratio']:.1f}; "
          f"same events {sec['same_events']}, squeeze depth rel. diff. {sec['squeeze_depth_rel']:.1e}; the first pickup "
          f"in a fresh process with an empty numba cache (compiling): {sec.get('compiled_first_s', float('nan')):.3f} s "
          f"against {sec.get('python_first_s', float('nan')):.3f} s")


# ------------------------------------------------------- compliance columns
def section_columns(size: int = 30000, reps: int = 3) -> dict[str, Any]:
    """Seconds per compliance column when k columns are solved at once (unit loads on k DOFs), with BLAS on
    all its threads and on one (as the tracking has it, ``threads.one_blas_thread``)."""
    from threadpoolctl import threadpool_limits

    from bench.meshes import cached_mesh

    body = orange_body(cached_mesh("orange", size), SCALING_YOUNG)
    comp = body.compliance
    rows = []
    for threads in (None, 1):
        for k in (3, 30, 90, 300):
            rhs = np.zeros((comp.n_dofs, k))
            rhs[(np.arange(k) * 7) % comp.n_dofs, np.arange(k)] = 1.0
            with threadpool_limits(limits=threads, user_api="blas"):  # not one_blas_thread: apply lifts that
                t = median([timed(lambda: comp.apply(rhs))[0] for _ in range(reps)])
            rows.append({"columns": k, "blas_threads": threads or os.cpu_count(), "seconds": t,
                         "per_column_ms": 1e3 * t / k, "reps": reps})
            log.info("%d columns at once (%s BLAS threads): %.3f s", k, threads or "all", t)
    return {"vertices": body.n_nodes, "solver": comp.solver, "rows": rows}


def print_columns(sec: dict[str, Any]) -> None:
    print(f"\n(f) compliance columns solved k at a time, orange of {sec['vertices']} vertices ({sec['solver']}), "
          f"ms per column (median of {sec['rows'][0].get('reps', 1)}):")
    for threads in sorted({r.get("blas_threads", 0) for r in sec["rows"]}, reverse=True):
        print(f"    {threads} BLAS thread(s): " + ", ".join(f"k = {r['columns']}: {r['per_column_ms']:.1f}"
                                                       for r in sec["rows"] if r.get("blas_threads", 0) == threads))


# ------------------------------------------------- floor of the method
def cholesky_counts(factor) -> tuple[int, float, float]:
    """nnz(L) and the flops of the numeric factorisation, Σ_j c_j² over L's column counts c_j (diagonal
    included), of a CHOLMOD factor; and the flops with the supernodal padding.

    ``factor.L()`` carries the supernodes' explicit zeros: the padded count is what CHOLMOD computes, the
    count without them what any Cholesky factorisation in this order must.
    """
    lower = factor.L()
    padded = np.diff(lower.indptr).astype(float)
    lower.eliminate_zeros()
    counts = np.diff(lower.indptr).astype(float)
    return int(lower.nnz), float((counts ** 2).sum()), float((padded ** 2).sum())


def dense_peak_gflops(n: int = 4000, reps: int = 3) -> float:
    """GFlop/s of an n×n matrix product on all BLAS threads (2n³ flops; median of ``reps``)."""
    rng = np.random.default_rng(0)
    a, b = rng.standard_normal((n, n)), rng.standard_normal((n, n))
    return 2.0 * n ** 3 / median([timed(lambda: a @ b)[0] for _ in range(reps)]) / 1e9


def floor_worker(size: int, reps: int) -> None:
    """Run in a subprocess: one JSON line with the factorisation's and one column's flops and rates."""
    from bench.meshes import cached_mesh
    from fem_grasp.elastic import compliance, sparse_solvers

    mesh = cached_mesh("orange", size)
    body = orange_body(mesh, SCALING_YOUNG)
    k = body.stiffness
    free = np.setdiff1d(np.arange(k.shape[0]), compliance.grounding_dofs(mesh.points, body.rigid_modes))
    kff = k[free][:, free]
    t_factor, solve = timed(lambda: sparse_solvers.factorize(kff, "cholmod"))
    width = 3 * compliance.PREFETCH_NODES  # one batch of the tracking's column solves
    rhs = np.zeros((len(free), width))
    rhs[(np.arange(width) * 7) % len(free), np.arange(width)] = 1.0
    t_column = median([timed(lambda: solve(rhs))[0] for _ in range(reps)]) / width
    from sksparse.cholmod import cholesky  # the factor's L (section_floor checks that scikit-sparse imports)

    nnz_l, flops, padded_flops = cholesky_counts(cholesky(kff))
    print(json.dumps({"vertices": mesh.n_points, "dofs": len(free), "nnz_k": int(kff.nnz), "nnz_l": nnz_l,
                      "factor_flops": flops, "supernodal_flops": padded_flops, "factor_s": t_factor,
                      "column_flops": 4.0 * nnz_l, "column_s": t_column, "batch_columns": width,
                      "peak_gflops": dense_peak_gflops(), "maxrss_mib": maxrss_mib()}), flush=True)


def section_floor(sizes: list[int], reps: int, scaling: dict[str, Any] | None) -> dict[str, Any]:
    """The flops the method needs per size and the least time they take at the dense peak; with the scaling
    section's touched nodes (same bench.json), the floor of factorisation and columns for its pickups."""
    try:
        import sksparse.cholmod  # noqa: F401  (the factor's column counts)
    except ImportError:
        log.warning("floor: needs scikit-sparse (the factor's L); skipped")
        return {"rows": [], "note": "scikit-sparse not installed"}
    touched = {}
    for r in (scaling or {}).get("rows", []):
        if isinstance(r.get("pickup"), dict) and "touched_nodes" in r["pickup"]:
            touched[r["mesh"]["vertices"]] = r
    rows = []
    for size in sizes:
        proc = subprocess.run([sys.executable, "-m", "bench.bench", "--worker-floor", str(size),
                               "--reps", str(reps)], cwd=ROOT, capture_output=True, text=True, check=True)
        row = json.loads(proc.stdout.strip().splitlines()[-1])
        peak = row["peak_gflops"] * 1e9
        row["factor_floor_s"] = row["factor_flops"] / peak
        row["column_floor_s"] = row["column_flops"] / peak
        run = touched.get(row["vertices"])
        if run is not None:
            columns = 3 * run["pickup"]["touched_nodes"]
            row["touched_nodes"] = run["pickup"]["touched_nodes"]
            row["floor_s"] = row["factor_floor_s"] + columns * row["column_floor_s"]
            # A forward substitution restricted to the elimination tree above a unit load (sparse right-hand
            # sides, not in scikit-sparse 0.4) would leave at least the back substitution, half the flops.
            row["floor_sparse_rhs_s"] = row["factor_floor_s"] + columns * row["column_floor_s"] / 2
            row["at_measured_rates_s"] = row["factor_s"] + columns * row["column_s"]
            row["scaling_s"] = run["factorisation"]["seconds"] + run["rest"]["seconds"] + run["pickup"]["seconds"]
        rows.append(row)
        log.info("floor %d: factor %.2f TFlop in %.1f s, column %.2f GFlop in %.1f ms", row["vertices"],
                 row["factor_flops"] / 1e12, row["factor_s"], row["column_flops"] / 1e9, 1e3 * row["column_s"])
    return {"rows": rows, "reps": reps,
            "note": "flops from the simplicial L (lower bounds); peak = dense matrix product on all threads; "
                    "floor = (factor flops + 3 touched nodes x column flops) / peak"}


def print_floor(sec: dict[str, Any]) -> None:
    if not sec["rows"]:
        print(f"\n(g) floor of the method: {sec.get('note', 'no rows')}")
        return
    print("\n(g) floor of the method: flops of the factorisation (supernodal padding in brackets) and of one "
          "compliance column (4 nnz(L)),\n    the rates measured (the factor's on its padded flops, columns in "
          "batches of 90) against the dense peak; for the\n    scaling pickups (touched nodes, three columns "
          "each) the least time of factorisation + columns at that peak, at it\n    with half the column flops "
          "(sparse right-hand sides), at the measured rates, and the scaling run's factorisation + rest + pickup")
    print(f"{'vertices':>9s} {'nnz(L)':>8s} {'factor GFlop':>16s} {'s':>6s} {'GF/s':>5s} {'col MFlop':>9s} "
          f"{'ms':>6s} {'GF/s':>5s} {'peak':>5s} {'touched':>7s} {'floor s':>8s} {'sparse-rhs':>10s} "
          f"{'at rates':>8s} {'measured':>8s}")
    for r in sec["rows"]:
        tail = (f"{r['touched_nodes']:7d} {r['floor_s']:8.3g} {r['floor_sparse_rhs_s']:10.3g} "
                f"{r['at_measured_rates_s']:8.3g} {r['scaling_s']:8.3g}") if "floor_s" in r else ""
        padded = r.get("supernodal_flops", r["factor_flops"])
        print(f"{r['vertices']:9d} {r['nnz_l'] / 1e6:7.1f}M {r['factor_flops'] / 1e9:7.4g} ({padded / 1e9:6.4g}) "
              f"{r['factor_s']:6.2f} {padded / r['factor_s'] / 1e9:5.0f} {r['column_flops'] / 1e6:7.4g} "
              f"{1e3 * r['column_s']:6.1f} {r['column_flops'] / r['column_s'] / 1e9:5.0f} "
              f"{r['peak_gflops']:5.0f} {tail}")


# -------------------------------------------------------------------- converge
CONVERGE_TARGETS = ("0.1", "0.05", "0.02")


def section_converge(quick: bool = False) -> dict[str, Any]:
    """Time to a converged answer per object and target (module notes), from verification.converge's study."""
    import math

    from verification import converge

    analysis = converge.study(quick=quick)
    out: dict[str, Any] = {"quick": quick, "objects": {}, "note": "times: meshing + pickup of one run (uniform, "
                           "graded: the cheapest qualifying level; adaptive: every level of the loop)"}
    for name, obj in analysis["objects"].items():
        row: dict[str, Any] = {"reference": obj.get("reference")}
        for series in ("uniform", "graded", "graded_table"):
            row[series] = {t: obj["resolution"].get(series, {}).get(t) for t in CONVERGE_TARGETS}
        adaptive = {}
        ref = obj.get("reference")
        for r in obj["series"].get("adaptive", []):
            for t, v in (r.get("targets") or {}).items():
                if v is None:
                    # the loop ran (or was cut) without its estimate meeting this target
                    adaptive[t] = {"reached": False, "timeout": bool(r.get("timeout")), "seconds": r.get("seconds")}
                    continue
                est = v["estimated_error"]
                err = {"squeeze_depth": v["rho_error"], "finger_force": v["force_error"]}
                covered = all(math.isfinite(e) and e <= est[k] for k, e in err.items()) if ref else None
                adaptive[t] = {"seconds": v["seconds"], "vertices": v["vertices"], "levels": v["level"] + 1,
                               "converged": True, "estimated_error": est, "error": err, "estimate_covers": covered,
                               "success": v["success"]}
        row["adaptive"] = adaptive
        out["objects"][name] = row
    return out


def print_converge(sec: dict[str, Any]) -> None:
    print("\n== converge: wall time to a 10 % / 5 % / 2 % answer (rho* and finger force within the target of the "
          "reference)" + (" [quick study]" if sec.get("quick") else ""))

    def cell(v: Any) -> str:
        if not v:
            return "not reached"
        if v.get("reached") is False:
            return f"not reached, {'cut at ' if v.get('timeout') else ''}{v['seconds']:.0f} s"
        if v.get("timeout"):
            return "timeout"
        extra = f" ({v['vertices']:,} v)" if v.get("vertices") else ""
        return f"{v['seconds']:.0f} s{extra}"

    print(f"{'object':<11} {'target':>6} | {'uniform':>20} | {'graded':>20} | {'graded+table':>20} | "
          f"{'adaptive':>20} | adaptive error (rho*, force) vs its estimate")
    for name, row in sec["objects"].items():
        for t in CONVERGE_TARGETS:
            a = row["adaptive"].get(t)
            ae = ""
            if a and "error" in a:
                e, est = a["error"], a["estimated_error"]
                pct = lambda x: "–" if x is None else ("wrong verdict" if x == float("inf") else f"{100 * x:.2g} %")  # noqa: E731
                ae = (f"{pct(e['squeeze_depth'])}, {pct(e['finger_force'])} vs {pct(est.get('squeeze_depth'))}, "
                      f"{pct(est.get('finger_force'))}" + ("" if a.get("converged") else " (not converged)"))
            print(f"{name:<11} {100 * float(t):>5g}% | {cell(row['uniform'][t]):>20} | {cell(row['graded'][t]):>20} | "
                  f"{cell(row['graded_table'][t]):>20} | {cell(a):>20} | {ae}")


# -------------------------------------------------------------------- accuracy
#: The objects of the accuracy section: the shipped scenes the convergence study has a reference for.
ACCURACY_OBJECTS = ("tomato", "orange", "steam_bun", "football", "foam_block")
#: The target of the adaptive row (``pickup(..., accuracy=ACCURACY_TARGET)``).
ACCURACY_TARGET = 0.05
#: The runs of each object: the paper's method once on the shipped mesh (the loop off), the scene as shipped
#: (``Scene.run()``: whatever its default is), the adaptive loop at :data:`ACCURACY_TARGET`, and that loop with
#: remeshed levels (the default's are nested).
ACCURACY_RUNS = (("one_level", "one level (accuracy off)"), ("default", "Scene.run() as shipped"),
                 ("adaptive", f"adaptive, accuracy = {100 * ACCURACY_TARGET:g} %"),
                 ("remesh", f"remeshed levels, {100 * ACCURACY_TARGET:g} %"))
#: The quantities compared, as named in the answer and in the loop's estimate.
ACCURACY_QUANTITIES = ("squeeze_depth", "finger_force")
#: Other draws of the default's and the remeshed levels' meshes (``--accuracy-draws``): draw k rounds gmsh's inputs to
#: a grid 2**k times :data:`fem_grasp.mesh.gmsh_session.POINT_QUANTUM`.
ACCURACY_DRAWS = 4


def study_references(quick: bool = False, compute: bool = False,
                     objects: tuple[str, ...] = ACCURACY_OBJECTS) -> dict[str, dict[str, Any] | None]:
    """Each object's reference answer: the analysis's ``reference`` from the cache of ``python -m verification
    converge`` (``quick``: its quick study), or — for the full study, where the cache holds none — the committed
    one (:mod:`verification.converge.references`, written by the study on the machine that ran it); None where
    neither has one.  An object's committed pinned reference (the answer at the placement rule's own grasp
    points, ``references.PINNED``) is kept under that key beside either.  Each carries ``source``: "cache", or
    the committed entry's study, date and machine.  Its verdict is ``success``; on a pickup ``rho`` and ``force``
    are each a ``{"value", "error", "method"}``.

    Reading analyses the cached records without computing any (as ``--report-only``, which also rewrites the
    study's converge.json and plots).  ``compute``: first run the cases a missing reference needs (the uniform
    levels, then the finest one's increments halved), which takes from minutes (quick) to hours.
    """
    from verification import converge
    from verification.converge import references

    if compute:
        converge.study(quick=quick, objects=objects, series_filter={"uniform", "reference"})
    analysis = converge.study(quick=quick, compute=False)
    committed = {} if quick else references.load()
    out: dict[str, dict[str, Any] | None] = {}
    for name in objects:
        ref = (analysis["objects"].get(name) or {}).get("reference")
        pinned = (committed.get(name) or {}).get(references.PINNED)
        if ref:
            out[name] = dict(ref, source="cache", **({references.PINNED: pinned} if pinned else {}))
        elif name in committed and "rho" in committed[name]:
            out[name] = committed[name]
        else:
            out[name] = {references.PINNED: pinned} if pinned else None
    return out


def _source(ref: dict[str, Any]) -> str:
    """Where a reference comes from, in words."""
    src = ref.get("source")
    if not isinstance(src, dict):
        return "this machine's study cache"
    made = f"`{src['command']}`" if src.get("command") else "the study"
    return f"verification/converge/references.json: {made} of {src.get('date')} on {src.get('machine')}"


def accuracy_worker(name: str, run: str, draw: int = 0, outer_exponent: float | None = None) -> None:
    """Run in a subprocess: one of :data:`ACCURACY_RUNS` of a shipped scene, one JSON line with its answer, its
    wall time (``Scene.run()`` with no mesh or rest cache: loading the mesh, the rest, the pickup; the numba
    kernels loaded before) and the error it states.  The run is made twice: the first call of the process
    (``seconds``: what a command pays) and a later one (``later_seconds``: a session that runs several, its
    imports and the allocator's pages paid already), with ``later_same``, whether it gave the same answer.
    ``draw`` k > 0: gmsh's inputs rounded to a grid 2**k times as coarse (another draw of the same levels'
    meshes), the first call only.  ``outer_exponent``: the levels' refinement of the bulk instead of
    :data:`~fem_grasp.grasp.accuracy.OUTER_EXPONENT` (a study of the rule; ``--accuracy-outer-exponent``)."""
    from fem_grasp.grasp import accuracy as accuracy_loop
    from fem_grasp.grasp.answer import answer_of
    from fem_grasp.io.scene import Scene
    from fem_grasp.mesh import gmsh_session

    if run not in dict(ACCURACY_RUNS):
        raise SystemExit(f"unknown run {run!r}; expected one of {', '.join(k for k, _ in ACCURACY_RUNS)}")
    gmsh_session.POINT_QUANTUM *= 2.0 ** draw
    if outer_exponent is not None:
        accuracy_loop.OUTER_EXPONENT = float(outer_exponent)

    def scene() -> Scene:
        shipped = Scene.load(name)
        if run == "one_level":
            return shipped.with_(accuracy=None)
        if run == "remesh":
            return shipped.with_(accuracy=ACCURACY_TARGET, refinement="remesh")
        return shipped.with_(accuracy=ACCURACY_TARGET) if run == "adaptive" else shipped

    from fem_grasp.contact.warm_up import prepare_kernels

    kernels_s, _ = timed(prepare_kernels)  # numba's kernels loaded (or compiled: a cold cache) before the clock
    first = scene()
    seconds, result = timed(lambda: first.run(cache_dir=None))
    answer = answer_of(result, seconds).to_dict()
    later_seconds = later_same = None
    if not draw:
        again = scene()
        later_seconds, later = timed(lambda: again.run(cache_dir=None))
        later_answer = answer_of(later, later_seconds).to_dict()
        later_same = all(later_answer[k] == answer[k] for k in ("success", "squeeze_depth", "finger_force"))
    acc = result.accuracy or {}
    est = acc.get("estimated_error") or {}
    # A single run states the scene's expected_error, or nothing (single_run_report then puts inf there).
    stated_any = acc.get("expected_error_stated", True) and est
    stated = {q: float(est[q]) for q in ACCURACY_QUANTITIES if stated_any and q in est}
    print(json.dumps({"seconds": seconds, "later_seconds": later_seconds, "later_same": later_same,
                      "kernels_s": kernels_s, "vertices": answer["n_vertices"],
                      "answer": {k: answer[k] for k in ("success", "reason", "squeeze_depth", "finger_force",
                                                        "max_liftable", "weight")},
                      "stated": stated, "converged": acc.get("converged"), "levels": len(acc.get("levels", [])),
                      "level_answers": [[lv["vertices"], lv["squeeze_depth"], lv["finger_force"], lv["success"]]
                                        for lv in acc.get("levels", [])],
                      "note": acc.get("note", "")}, default=float), flush=True)


def accuracy_errors(raw: dict[str, Any], reference: dict[str, Any]) -> dict[str, Any]:
    """One row of the accuracy section: a run's answer (as :func:`accuracy_worker` prints it) against the study's
    reference.

    The actual error of ρ* and of Σ f·n̂ is |run − reference| / |reference|; inf when the verdict differs from
    the reference's (the run answers another question), NaN when neither picks the object up (no ρ* to
    compare: ``w_error`` then compares the largest weight held, in units of mg).  The stated error is the run's
    own per quantity (None: unknown, or infinite: the run claims nothing).  ``covers``: the stated error is at
    least the actual one for every quantity that has both (False on a wrong verdict; None when nothing is
    stated).
    """
    from fem_grasp.grasp.estimates import relative_change

    ans = raw["answer"]
    verdict_ok = bool(ans["success"]) == bool(reference["success"])
    error: dict[str, float] = {}
    for q, key in (("squeeze_depth", "rho"), ("finger_force", "force")):
        if not verdict_ok:
            error[q] = math.inf
        elif not ans["success"]:
            error[q] = math.nan
        else:
            error[q] = relative_change(float(ans[q]), float(reference[key]["value"]))
    stated = {q: float(v) for q, v in (raw.get("stated") or {}).items() if math.isfinite(float(v))}
    if len(stated) < len(ACCURACY_QUANTITIES):
        stated = {}
    band = {q: float((reference.get(key) or {}).get("error") or 0.0) for q, key in (("squeeze_depth", "rho"),
                                                                                    ("finger_force", "force"))}
    if not stated:
        covers = covers_with_reference = None
    elif not verdict_ok:
        covers = covers_with_reference = False
    else:
        covers = all(stated[q] >= e for q, e in error.items() if math.isfinite(e))
        # the reference is itself uncertain: the run and it agree within their two errors
        covers_with_reference = all(stated[q] + band[q] >= e for q, e in error.items() if math.isfinite(e))
    row = {"status": "ok", "seconds": raw["seconds"], "later_seconds": raw.get("later_seconds"),
           "later_same": raw.get("later_same"), "vertices": raw.get("vertices"), "success": bool(ans["success"]),
           "verdict_ok": verdict_ok, "rho": ans["squeeze_depth"], "force": ans["finger_force"], "error": error,
           "stated": stated or None, "covers": covers, "covers_with_reference": covers_with_reference,
           "converged": raw.get("converged"),
           "levels": raw.get("levels"), "level_answers": raw.get("level_answers"), "note": raw.get("note", "")}
    if not ans["success"] and not reference["success"] and reference.get("weight"):
        row["w_error"] = abs(ans["max_liftable"] - reference["max_liftable"]) / reference["weight"]
    return row


def run_accuracy_worker(name: str, run: str, cap: float, draw: int = 0,
                        outer_exponent: float | None = None) -> dict[str, Any]:
    """:func:`accuracy_worker` in a subprocess of at most ``cap`` seconds: its JSON line, or a ``status`` that says
    why there is none ("cap" or the error, with the last lines of its stderr as ``stderr_tail``: with Python's
    fault handler on, a crash in native code leaves every thread's Python stack there)."""
    spec = f"{name}:{run}:{int(draw)}" + ("" if outer_exponent is None else f":{float(outer_exponent)!r}")
    cmd = [sys.executable, "-X", "faulthandler", "-m", "bench.bench", "--worker-accuracy", spec]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        out, err = proc.communicate(timeout=cap)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        return {"status": "cap", "cap_s": cap}
    if proc.returncode != 0:
        lines = err.strip().splitlines()
        log.warning("accuracy %s, %s, draw %d: exit %d; its stderr ends:\n%s", name, run, draw, proc.returncode,
                    "\n".join(lines[-STDERR_TAIL:]))
        return {"status": "error", "error": lines[-1] if lines else f"exit {proc.returncode}",
                "stderr_tail": lines[-STDERR_TAIL:]}
    return json.loads(out.strip().splitlines()[-1])


#: Lines of a failed worker's stderr kept in its row (:func:`run_accuracy_worker`).
STDERR_TAIL = 60


def default_accuracy(name: str) -> float | None:
    """The accuracy a shipped scene is run to by default (``Scene.run()``; None: one run on its mesh)."""
    from fem_grasp.io.scene import Scene

    return Scene.load(name).accuracy


def section_accuracy(cap: float = 600.0, quick: bool = False, compute: bool = False,
                     objects: tuple[str, ...] = ACCURACY_OBJECTS, draws: int = ACCURACY_DRAWS,
                     outer_exponent: float | None = None) -> dict[str, Any]:
    """Per shipped object, the wall time and the actual error of the one level run, the default and the adaptive
    loop (module notes) against the object's reference: its pinned one (the placement rule's own grasp points,
    :mod:`verification.converge.references`) where it has one, with the error against the study's (each mesh
    grasping at its own nodes) beside it as ``error_study``; else the study's.  Objects without either are
    skipped.  The default is run again on ``draws`` other draws of its meshes (``rows["draws"]``, a list of
    rows; for nested levels the draw is level 0's mesh, which they refine), and so are the remeshed levels
    (``rows["remesh_draws"]``).  ``outer_exponent``: every loop refines the bulk by that instead of the library's
    rule (the rows then measure that rule; ``out["outer_exponent"]`` says so)."""
    from verification.converge import references

    refs = study_references(quick=quick, compute=compute, objects=objects)
    out: dict[str, Any] = {"study": "quick" if quick else "full", "cap_s": cap, "target": ACCURACY_TARGET,
                           "draws": draws, "outer_exponent": outer_exponent, "objects": {}}
    for name in objects:
        ref = refs.get(name)
        if not ref:
            log.warning("accuracy: no reference for %s, neither in the convergence study's cache nor committed "
                        "(python -m verification converge%s --objects %s computes it); skipped", name, " --quick" if quick else "", name)
            out["objects"][name] = {"reference": None}
            continue
        keys = ("success", "vertices", "rho", "force", "max_liftable", "weight", "step", "source")
        pinned = ref.get(references.PINNED)
        study = {k: ref.get(k) for k in keys} if "rho" in ref else None
        reference = dict({k: pinned.get(k) for k in keys}, kind="pinned") if pinned else dict(study, kind="study")
        rows: dict[str, Any] = {}
        default_is_adaptive = default_accuracy(name) == ACCURACY_TARGET
        for run, _ in ACCURACY_RUNS:
            if run == "adaptive" and default_is_adaptive:  # the same run as the default: its row, not a rerun
                rows[run] = dict(rows["default"], same_as="default")
                continue
            raw = run_accuracy_worker(name, run, cap, 0, outer_exponent)
            rows[run] = accuracy_errors(raw, reference) if "answer" in raw else raw
            if "answer" in raw and pinned and study:
                rows[run]["error_study"] = accuracy_errors(raw, study)["error"]
            log.info("accuracy %s, %s: %s", name, run, rows[run].get("status"))
        for run, key in (("default", "draws"), ("remesh", "remesh_draws")):
            rows[key] = []
            for draw in range(1, draws + 1):
                raw = run_accuracy_worker(name, run, cap, draw, outer_exponent)
                rows[key].append(accuracy_errors(raw, reference) if "answer" in raw else raw)
                log.info("accuracy %s, %s, mesh draw %d: %s", name, run, draw, rows[key][-1].get("status"))
        out["objects"][name] = {"reference": reference, "study_reference": study if pinned else None, "rows": rows}
    return out


def _pct(x: float | None) -> str:
    if x is None:
        return "–"
    if math.isinf(x):
        return "wrong verdict"
    if math.isnan(x):
        return "n/a"
    return f"{100 * x:.0f} %" if x >= 1 else f"{100 * x:.2g} %"


def print_accuracy(sec: dict[str, Any]) -> None:
    print(f"\n== accuracy: each shipped scene's answer against its reference (at the placement rule's grasp points "
          f"where it has one, else the convergence study's, {sec['study']} study); adaptive at "
          f"{100 * sec['target']:g} %, cap {sec['cap_s']:g} s per run")
    print("    error: relative to the reference (or 'wrong verdict'); stated: the run's own estimate of its error in "
          "rho* / force\n    (the scene's expected_error, or the adaptive loop's); covers: stated >= actual for both "
          "('NO, ref' where only\n    the stated error plus the reference's own uncertainty covers the difference)")
    print("    seconds: the first call of a process (a command's) / a later call in it (a session's)")
    if sec.get("outer_exponent") is not None:
        print(f"    every level refines the bulk by 2**{sec['outer_exponent']:g} (--accuracy-outer-exponent), "
              "not by the library's rule: these rows measure that rule, not the library's answers")
    print(f"{'object':<11} {'run':<28} {'seconds':>11} {'vertices':>8} {'verdict':<22} {'rho* mm':>8} "
          f"{'error':>15} {'force N':>8} {'error':>15} {'stated':>15} {'covers':>7}")
    for name, obj in sec["objects"].items():
        ref = obj.get("reference")
        if not ref:
            print(f"{name:<11} no reference (the study's cache, the committed references): skipped")
            continue
        verdict = "picked up" if ref["success"] else "NOT picked up"
        if ref["success"]:
            rho, force = ref["rho"], ref["force"]

            def band(q: dict[str, Any]) -> str:  # the reference's own uncertainty (inf: a single level, none known)
                return f"±{_pct(q['error'])} {q['method']}" if math.isfinite(q["error"]) else q["method"]

            label = "reference, rule's grasp" if ref.get("kind") == "pinned" else "reference"
            print(f"{name:<11} {label:<28} {'':>11} {ref['vertices']:8d} {verdict:<22} "
                  f"{1e3 * rho['value']:8.3f} {band(rho):>15} {force['value']:8.3f} {band(force):>15}"
                  f"  ({_source(ref)})")
        else:
            print(f"{name:<11} {'reference':<28} {'':>11} {ref['vertices']:8d} {verdict:<22}  ({_source(ref)})")
        study = obj.get("study_reference")
        if study and study.get("success"):
            print(f"{'':<11} {'study, grasps at own nodes':<28} {'':>11} {study['vertices']:8d} {'':<22} "
                  f"{1e3 * study['rho']['value']:8.3f} {'':>15} {study['force']['value']:8.3f} {'':>15}"
                  f"  ({_source(study)})")
        for run, label in ACCURACY_RUNS:
            r = obj["rows"][run]
            if r.get("same_as"):
                print(f"{'':<11} {label:<28} the same run as {dict(ACCURACY_RUNS)[r['same_as']]}")
                continue
            _print_accuracy_row(label, r)
        for run, key, name_of in (("default", "draws", "Scene.run()"), ("remesh", "remesh_draws", "remeshed levels")):
            draws = obj["rows"].get(key) or []
            for k, r in enumerate(draws, 1):
                _print_accuracy_row(f"{name_of}, mesh draw {k}", r)
            _print_draws_summary(f"{name_of}, all {len(draws) + 1} draws", [obj["rows"][run]] + draws)


def _print_draws_summary(label: str, runs: list[dict[str, Any]]) -> None:
    """The line of :func:`print_accuracy` that sums up a run over the draws of its meshes (none for one run)."""
    ok = [r for r in runs if r.get("status") == "ok"]
    if len(runs) < 2 or not ok:
        return
    secs = sorted(r["seconds"] for r in ok)
    # NaN where neither the run nor the reference picks it up: no ρ* to compare
    worst = {q: max((r["error"][q] for r in ok if not math.isnan(r["error"][q])), default=math.nan)
             for q in ACCURACY_QUANTITIES}
    print(f"{'':<11} {label:<28} converged {sum(bool(r['converged']) for r in ok)}/{len(runs)}, median "
          f"{statistics.median(secs):.1f} s ({secs[0]:.1f}-{secs[-1]:.1f}), verdict "
          f"{sum(r['verdict_ok'] for r in ok)}/{len(runs)}, largest error {_pct(worst['squeeze_depth'])} / "
          f"{_pct(worst['finger_force'])}, stated error covers it {sum(bool(r['covers']) for r in ok)}"
          f"/{len(runs)}")


def _print_accuracy_row(label: str, r: dict[str, Any]) -> None:
    """One run's row of :func:`print_accuracy` (and its levels' answers)."""
    if r["status"] == "cap":
        print(f"{'':<11} {label:<28} not run (cap: beyond {r['cap_s']:g} s)")
        return
    if r["status"] != "ok":
        print(f"{'':<11} {label:<28} failed: {r.get('error', r['status'])}")
        return
    v = ("picked up" if r["success"] else "NOT picked up") + (", ok" if r["verdict_ok"] else ", WRONG")
    st = r["stated"]
    stated = "unknown" if not st else f"{_pct(st['squeeze_depth'])}/{_pct(st['finger_force'])}"
    covers = {None: "–", True: "yes", False: "NO"}[r["covers"]]
    if r["covers"] is False and r.get("covers_with_reference"):
        covers = "NO, ref"
    e = r["error"]
    later = r.get("later_seconds")
    secs = f"{r['seconds']:.1f}" + ("" if later is None else f"/{later:.1f}")
    if r.get("later_same") is False:
        v += ", later call differs"
    print(f"{'':<11} {label:<28} {secs:>11} {r['vertices']:8d} {v:<22} {1e3 * r['rho']:8.3f} "
          f"{_pct(e['squeeze_depth']):>15} {r['force']:8.3f} {_pct(e['finger_force']):>15} {stated:>15} "
          f"{covers:>7}" + (f"  {r['levels']} levels, {'converged' if r['converged'] else 'not converged'}"
                            if (r.get("levels") or 0) > 1 else "")
          + (f"  (study's: {_pct(r['error_study']['squeeze_depth'])} / "
             f"{_pct(r['error_study']['finger_force'])})" if r.get("error_study") else ""))
    if (r.get("levels") or 0) > 1 and r.get("level_answers"):
        print(f"{'':<11} {'':<28} levels: " + "; ".join(
            f"{v:,} v {1e3 * rho:.3f} mm {f:.3f} N" + ("" if ok else " (not picked up)")
            for v, rho, f, ok in r["level_answers"]))


# -------------------------------------------------------------------- main
def _print_tracker(sec: dict[str, Any]) -> None:
    from bench.tracker import print_tracker

    print_tracker(sec)


def _print_divisions(sec: dict[str, Any]) -> None:
    from bench.divisions import print_divisions

    print_divisions(sec)


def print_search(sec: dict[str, Any]) -> None:
    from bench.search import print_search as show

    show(sec)


PRINTERS = {"solve": print_solve, "scaling": print_scaling, "objects": print_objects, "spectral": print_spectral,
            "jit": print_jit, "columns": print_columns, "floor": print_floor, "search": print_search,
            "converge": print_converge, "tracker": _print_tracker, "accuracy": print_accuracy,
            "divisions": _print_divisions}



def main(argv: list[str] | None = None) -> dict[str, Any]:
    ap = argparse.ArgumentParser(prog="python -m bench.bench", description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", action="append", choices=SECTIONS, help="run only this section (repeatable)")
    ap.add_argument("--max-vertices", type=int, default=100000, help="largest mesh (default 100000)")
    ap.add_argument("--reps", type=int, default=3, help="repetitions for medians (default 3)")
    ap.add_argument("--pickup-cap", type=float, default=300.0,
                    help="seconds allowed per size in the scaling section (default 300)")
    ap.add_argument("--object-budget", type=float, default=60.0,
                    help="stop repeating an object's pickup after this many seconds (default 60)")
    ap.add_argument("--search-candidates", type=int, default=16,
                    help="candidates per paper scene in the search section (default 16)")
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--converge-quick", action="store_true",
                    help="sections converge and accuracy: read (or compute) the quick study of verification.converge")
    ap.add_argument("--baseline", default=None,
                    help="section tracker: the commit to compare this checkout against (default: the engine before the "
                         "event-tracking rewrite)")
    ap.add_argument("--accuracy-cap", type=float, default=600.0,
                    help="section accuracy: seconds allowed per run of a scene; a longer run is reported as not run "
                         "(default 600)")
    ap.add_argument("--accuracy-objects", nargs="+", choices=ACCURACY_OBJECTS, default=list(ACCURACY_OBJECTS),
                    help="section accuracy: the shipped scenes to run (default: all five)")
    ap.add_argument("--accuracy-draws", type=int, default=ACCURACY_DRAWS,
                    help="section accuracy: run the default and the remeshed levels again on this many other draws "
                         f"of their meshes (gmsh's inputs rounded to other grids; default {ACCURACY_DRAWS}, 0: none)")
    ap.add_argument("--accuracy-compute", action="store_true",
                    help="section accuracy: compute the convergence study's missing references first (hours; "
                         "minutes with --converge-quick); by default an object without one is skipped")
    ap.add_argument("--accuracy-outer-exponent", type=float, default=None, metavar="X",
                    help="section accuracy: every level refines the bulk by 2**X instead of the library's rule "
                         "(OUTER_EXPONENT, 0.5): a study of that rule (0: the bulk at level 0's spacing)")
    ap.add_argument("--worker-scaling", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--worker-accuracy", help=argparse.SUPPRESS)
    ap.add_argument("--worker-floor", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    logging.getLogger("fem_grasp").setLevel(logging.WARNING)
    if args.worker_scaling:
        scaling_worker(args.worker_scaling)
        return {}
    if args.worker_floor:
        floor_worker(args.worker_floor, args.reps)
        return {}
    if args.worker_accuracy:
        name, run, draw, *outer = args.worker_accuracy.split(":")
        accuracy_worker(name, run, int(draw), float(outer[0]) if outer else None)
        return {}
    sections = args.only or list(SECTIONS)
    data: dict[str, Any] = {}
    if args.out.exists():
        try:
            data = json.loads(args.out.read_text())
        except json.JSONDecodeError:
            data = {}
    data["machine"] = machine()
    data["command"] = "python -m bench.bench " + " ".join(argv if argv is not None else sys.argv[1:])
    for name in sections:
        if name == "solve":
            data["solve"] = section_solve([s for s in SOLVE_SIZES if s <= args.max_vertices], args.reps)
        elif name == "scaling":
            data["scaling"] = section_scaling([s for s in SCALING_SIZES if s <= args.max_vertices], args.pickup_cap)
        elif name == "objects":
            data["objects"] = section_objects(args.reps, args.object_budget)
        elif name == "spectral":
            data["spectral"] = section_spectral()
        elif name == "jit":
            data["jit"] = section_jit()
        elif name == "columns":
            data["columns"] = section_columns(reps=args.reps)
        elif name == "search":
            from bench.search import section_search

            data["search"] = section_search(args.search_candidates)
        elif name == "converge":
            data["converge"] = section_converge(args.converge_quick)
        elif name == "tracker":
            from bench.tracker import DEFAULT_BASELINE, ROUTES, section_tracker

            data["tracker"] = section_tracker(args.baseline or DEFAULT_BASELINE, args.reps,
                                              large=tuple(s for s in TRACKER_LARGE if s <= args.max_vertices),
                                              routes=ROUTES)
        elif name == "accuracy":
            data["accuracy"] = section_accuracy(args.accuracy_cap, args.converge_quick, args.accuracy_compute,
                                                tuple(args.accuracy_objects), args.accuracy_draws,
                                                args.accuracy_outer_exponent)
        elif name == "divisions":
            from bench.divisions import measure

            data["divisions"] = measure(reps=args.reps)
        elif name == "floor":
            data["floor"] = section_floor([s for s in SCALING_SIZES if s <= args.max_vertices], args.reps,
                                          data.get("scaling"))
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(data, indent=2, default=float))
    m = data["machine"]
    print(f"\nmachine: {m['cpu']}, {m['cores']} cores, {m['memory_gib']} GiB; Python {m['python']}, numpy {m['numpy']}, "
          f"scipy {m['scipy']}; default sparse solver {m['default_solver']}; inner loops {m.get('inner_loops', '?')}")
    for name in SECTIONS:
        if name in data:
            PRINTERS[name](data[name])
    print(f"\nwrote {args.out}")
    return data


if __name__ == "__main__":
    main()
