"""Same answer on every machine: pickups under round-off perturbations.

Floating-point results of vectorised code differ in the last bits between
CPUs (another OpenBLAS kernel, another numpy SIMD path), between one and two
BLAS threads, and between the numba-compiled and the plain-Python kernels.  A
verdict that flips, or a run that crashes, when the last bit of a float
changes cannot be trusted.  This harness runs the same pickups under such
perturbations and compares each with an unperturbed reference run:

=====================  ======================================================
variant                what changes
=====================  ======================================================
``reference``          nothing (compiled kernels, the BLAS's default threads)
``jitter-<seed>``      every mesh coordinate moved by a random ~1e-12 × the
                       mesh diameter (seeded), before anything is computed
``plain-python``       ``FEM_GRASP_NO_JIT=1``: the kernels run as Python
``blas-1-thread``      ``OPENBLAS_NUM_THREADS=1``
``blas-2-threads``     ``OPENBLAS_NUM_THREADS=2``
``openblas-<core>``    ``OPENBLAS_CORETYPE=<core>`` (with ``OPENBLAS_L2_SIZE``):
                       another CPU's BLAS kernels, where this CPU runs them
``numpy-<features>``   ``NPY_DISABLE_CPU_FEATURES``: numpy's ufunc loops
                       without the widest SIMD this CPU offers
=====================  ======================================================

Every variant runs in its own process (the environment variables are read at
import), all of its cases one after the other.  What is promised, for each
case and variant against the reference (:func:`compare`):

* the same verdict (picked up or not), and the same kind of failure;
* the squeeze depth at lift (or where the squeeze stopped) within one squeeze
  increment (:data:`DEPTH_TOLERANCE_STEPS`);
* the finger forces at the end within :data:`FORCE_TOLERANCE` of the weight:
  Σ f·n̂ and each finger's resultant;
* ``check()`` passing on every snapshot (equilibrium, non-penetration,
  Coulomb's law).

A case that sits exactly on a branch point, where round-off legitimately
decides between two physical outcomes, is listed in :data:`BRANCH_POINTS`
with the reason; its verdict may then differ and is reported, not failed.

``python -m verification roundoff [--quick] [--json PATH]`` runs the
sweep and prints the spread table (docs/limits.md quotes it); it is a stage
of the full report too (headline check and section: :mod:`.report`).
``tests/test_perturbation.py`` runs the quick part inside ``make test``.
"""

from __future__ import annotations

import json
import logging
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .report import checks, section

log = logging.getLogger(__name__)

ROOT = Path(__file__).resolve().parents[2]

#: Relative size of the coordinate jitter (× mesh diameter): far below any geometric tolerance of the
#: tracking (1e-10 × diameter), far above the last bit (1e-16).
JITTER = 1e-12
#: The squeeze depth at lift may differ by up to this many squeeze increments: a perturbation may move an
#: event (a zero-force touch released or kept) by up to one increment of the lift test's schedule.
DEPTH_TOLERANCE_STEPS = 1.0
#: Final finger forces (Σ f·n̂, each finger's resultant) may differ by this fraction of the weight.  When
#: the same branch is taken they agree to ~1e-9; a lift test passing one increment earlier or later moves
#: them by the force one squeeze increment adds (measured: see docs/limits.md).
FORCE_TOLERANCE = 0.05
#: Worker processes at a time (each runs one variant's cases; BLAS threads as the variant says).
WORKERS = 2
#: Cases known to sit on a branch point, with the reason (the verdict may flip; reported, not failed).
BRANCH_POINTS: dict[str, str] = {}

#: OpenBLAS core types tried where the CPU has the instructions their kernels need.
OPENBLAS_CORES: dict[str, tuple[str, ...]] = {
    "Prescott": ("pni",),  # SSE3 ("pni" in /proc/cpuinfo)
    "Nehalem": ("sse4_2",),
    "Sandybridge": ("avx",),
    "Haswell": ("avx2", "fma"),
    "SkylakeX": ("avx512f", "avx512bw", "avx512vl", "avx512dq"),
}
#: numpy SIMD features that can be switched off at start-up (NPY_DISABLE_CPU_FEATURES), widest first.
NUMPY_FEATURES = ("AVX512_ICL", "AVX512_CNL", "AVX512_CLX", "AVX512_SKX", "AVX512CD", "AVX512F", "AVX2", "FMA3")


# ------------------------------------------------------------------ variants
@dataclass(frozen=True)
class Variant:
    """A perturbation: environment variables for the worker process and a coordinate-jitter seed."""

    name: str
    env: tuple[tuple[str, str], ...] = ()
    jitter_seed: int | None = None


def _cpu_flags() -> set[str]:
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return set()
    for line in text.splitlines():
        if line.startswith("flags"):
            return set(line.split(":", 1)[1].split())
    return set()


def _l2_size() -> str:
    """The L2 cache size in bytes as OpenBLAS wants it with a forced core type (read from sysfs, else 512 KiB)."""
    try:
        text = Path("/sys/devices/system/cpu/cpu0/cache/index2/size").read_text().strip()
        units = {"K": 1024, "M": 1024**2}
        return str(int(text[:-1]) * units[text[-1]]) if text[-1] in units else str(int(text))
    except (OSError, ValueError, IndexError):
        return str(512 * 1024)


def openblas_cores(flags: set[str] | None = None) -> list[str]:
    """The core types of :data:`OPENBLAS_CORES` whose instructions this CPU has."""
    flags = _cpu_flags() if flags is None else flags
    return [core for core, need in OPENBLAS_CORES.items() if all(f in flags for f in need)]


def numpy_features_to_disable() -> list[str]:
    """The dispatchable numpy SIMD features this CPU offers down to AVX2/FMA3 (switching off a feature it
    does not have is an error)."""
    try:
        from numpy.core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    except ImportError:  # another numpy layout: no such variant
        return []
    return [f for f in NUMPY_FEATURES if f in __cpu_dispatch__ and __cpu_features__.get(f)]


def variants(quick: bool) -> list[Variant]:
    """The variants of the sweep (module notes); ``quick`` keeps one jitter and one other BLAS core."""
    out = [Variant("reference")]
    seeds = (1,) if quick else (1, 2, 3, 4, 5)
    out += [Variant(f"jitter-{s}", jitter_seed=s) for s in seeds]
    out += [Variant("plain-python", (("FEM_GRASP_NO_JIT", "1"),)),
            Variant("blas-1-thread", (("OPENBLAS_NUM_THREADS", "1"),)),
            Variant("blas-2-threads", (("OPENBLAS_NUM_THREADS", "2"),))]
    cores = openblas_cores()
    if quick:  # the SSE3 kernels differ most from any x86-64 CPU's own
        cores = cores[:1]
    l2 = _l2_size()
    out += [Variant(f"openblas-{c}", (("OPENBLAS_CORETYPE", c), ("OPENBLAS_L2_SIZE", l2))) for c in cores]
    off = numpy_features_to_disable()
    if off:
        out.append(Variant("numpy-no-" + off[-1].lower(), (("NPY_DISABLE_CPU_FEATURES", " ".join(off)),)))
    return out


# --------------------------------------------------------------------- cases
def _scene_case(name: str, quick: bool) -> Callable[[], tuple[Any, dict]]:
    def build():
        from fem_grasp.io.scene import load_scene, resolve_scene

        scene = load_scene(resolve_scene(name), quick=quick)
        return scene.body(), scene.pickup_kwargs()

    return build


def _box_case(mu: float) -> Callable[[], tuple[Any, dict]]:
    """The test suite's box (tests/test_pickup.py): 3×4×3 cm, 64 nodes, 2 cm fingertips at its y-faces."""

    def build():
        from fem_grasp import Body, box_mesh

        body = Body(box_mesh((-0.015, -0.02, 0.0), (0.015, 0.02, 0.03), (3, 3, 3)), 2e4, 0.3, weight=0.3)
        return body, {"mu_finger": mu, "finger_radius": 0.02, "contacts": "faces"}

    return build


def _ellipsoid_case() -> tuple[Any, dict]:
    """A small gmsh ellipsoid with the default placement (the random-scene test's kind of body)."""
    from fem_grasp import Body, TetMesh
    from fem_grasp.mesh.shapes import ellipsoid

    mesh = TetMesh(*ellipsoid((0.03, 0.025, 0.02), 0.008))
    return Body(mesh, 2e4, 0.35, weight=0.5), {"mu_finger": 0.5, "finger_radius": 0.01}


SCENES = ("tomato", "orange", "steam_bun", "football", "foam_block", "slippery_ball")


def cases(quick: bool) -> dict[str, Callable[[], tuple[Any, dict]]]:
    """Every case of the sweep: the shipped scenes (their quick variants when ``quick``) and small bodies."""
    out: dict[str, Callable[[], tuple[Any, dict]]] = {
        f"{s}{' (quick)' if quick else ''}": _scene_case(s, quick) for s in SCENES}
    out["box μ=0.5"] = _box_case(0.5)
    if not quick:
        out["box μ=0.3"] = _box_case(0.3)
    out["ellipsoid"] = _ellipsoid_case
    return out


def _face_centres(rest_state) -> tuple[int, int]:
    """The nodes at x = −5 mm, z = 2 cm of the box's y-faces, as tests/test_pickup.py places its fingers (its
    grid has no node at a face centre: the offset keeps round-off from breaking a tie)."""
    p = rest_state.body.mesh.points
    c = rest_state.body.center_of_mass + [-1e-3, 0.0, 1e-3]
    half = 0.5 * float(np.ptp(p[:, 1]))
    return (int(np.argmin(np.linalg.norm(p - (c - [0, half, 0]), axis=1))),
            int(np.argmin(np.linalg.norm(p - (c + [0, half, 0]), axis=1))))


def _jittered(body, seed: int):
    from fem_grasp import Body, TetMesh

    rng = np.random.default_rng(seed)
    mesh = body.mesh
    points = mesh.points + JITTER * mesh.diameter * rng.uniform(-1.0, 1.0, mesh.points.shape)
    return Body(TetMesh(points, mesh.tets), body.young, body.poisson, density=body.density, gravity=body.gravity)


def run_case(build: Callable[[], tuple[Any, dict]], jitter_seed: int | None) -> dict[str, Any]:
    """One pickup and the figures :func:`compare` reads (or the exception it raised)."""
    from fem_grasp.grasp.pickup import pickup
    from fem_grasp.grasp.rest import rest

    t0 = time.perf_counter()
    try:
        body, kwargs = build()
        if jitter_seed is not None:
            body = _jittered(body, jitter_seed)
        if kwargs.get("contacts") == "faces":
            rs = rest(body, kwargs["mu_finger"])
            kwargs = dict(kwargs, contacts=_face_centres(rs), rest_state=rs)
        res = pickup(body, **kwargs)
        figures = res.check(raise_on_failure=False)
    except Exception as exc:  # noqa: BLE001 - a crash is what the harness looks for
        return {"error": f"{type(exc).__name__}: {exc}", "seconds": time.perf_counter() - t0}
    final = res.final
    per_finger = {}
    if final is not None:
        for name in ("finger1", "finger2"):
            per_finger[name] = np.asarray(final.contact_forces[name]).sum(axis=0).tolist()
    return {
        "success": bool(res.success), "outcome": res.outcome, "reason": res.reason,
        "squeeze_depth": float(res.squeeze_depth), "step": float(res.step), "weight": float(res.body.weight),
        "finger_normal_force": float(res.finger_normal_force), "finger_resultants": per_finger,
        "events": "".join(e.kind for e in res.events), "n_final_contacts": int(res.n_final_contacts),
        "checks_ok": all(f["ok"] for f in figures), "check_failures": sorted({x for f in figures for x in f["failures"]}),
        "seconds": time.perf_counter() - t0,
    }


def _worker(variant: str, quick: bool, seed: int | None, names: list[str], out: Path) -> None:
    table = cases(quick)
    results = {name: run_case(table[name], seed) for name in names}
    out.write_text(json.dumps({"variant": variant, "results": results}), encoding="utf-8")


def run_variant(variant: Variant, quick: bool, names: list[str], work: Path) -> dict[str, dict]:
    """Run ``names`` (keys of :func:`cases`) in a fresh process with the variant's environment."""
    out = work / f"{variant.name}.json"
    env = dict(os.environ)
    for key in ("FEM_GRASP_NO_JIT", "OPENBLAS_NUM_THREADS", "OPENBLAS_CORETYPE", "OPENBLAS_L2_SIZE",
                "NPY_DISABLE_CPU_FEATURES"):
        env.pop(key, None)
    env.update(dict(variant.env))
    cmd = [sys.executable, "-m", "verification.roundoff", "--worker", variant.name,
           "--out", str(out), "--cases", json.dumps(names)]
    if quick:
        cmd.append("--quick")
    if variant.jitter_seed is not None:
        cmd += ["--seed", str(variant.jitter_seed)]
    proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-5:]
        return {name: {"error": f"worker failed (exit {proc.returncode}): " + " | ".join(tail)} for name in names}
    return json.loads(out.read_text(encoding="utf-8"))["results"]


# --------------------------------------------------------------- comparison
def compare(ref: dict, other: dict) -> dict[str, Any]:
    """What differs between a variant's run and the reference's, and whether that is within the promise."""
    row: dict[str, Any] = {"problems": []}
    for label, r in (("reference", ref), ("variant", other)):
        if "error" in r:
            row["problems"].append(f"{label} raised {r['error']}")
    if row["problems"]:
        return row
    weight, step = ref["weight"], max(ref["step"], 1e-300)
    row["same_verdict"] = ref["success"] == other["success"] and ref["outcome"] == other["outcome"]
    row["same_events"] = ref["events"] == other["events"]
    row["depth_steps"] = abs(other["squeeze_depth"] - ref["squeeze_depth"]) / step
    forces = [abs(other["finger_normal_force"] - ref["finger_normal_force"])]
    for name, f in ref["finger_resultants"].items():
        g = other["finger_resultants"].get(name)
        forces.append(np.inf if g is None else float(np.linalg.norm(np.subtract(g, f))))
    row["force_diff"] = max(forces) / weight
    if not row["same_verdict"]:
        row["problems"].append(f"verdict {ref['outcome']} → {other['outcome']}")
    if row["depth_steps"] > DEPTH_TOLERANCE_STEPS:
        row["problems"].append(f"squeeze depth differs by {row['depth_steps']:.3g} increments")
    if row["force_diff"] > FORCE_TOLERANCE:
        row["problems"].append(f"finger forces differ by {row['force_diff']:.3g} mg")
    if not other["checks_ok"]:
        row["problems"].append("check() fails: " + "; ".join(other["check_failures"]))
    return row


def sweep(quick: bool, names: list[str] | None = None, variant_names: list[str] | None = None,
          work: Path | None = None, progress: Callable[[str], None] | None = None,
          workers: int = WORKERS) -> dict[str, Any]:
    """Run every variant on every case (``workers`` processes at a time) and compare; returns the table and
    a list of violations."""
    import tempfile
    from concurrent.futures import ThreadPoolExecutor

    table = cases(quick)
    names = list(table) if names is None else names
    vs = [v for v in variants(quick) if variant_names is None or v.name in variant_names or v.name == "reference"]
    own = tempfile.TemporaryDirectory() if work is None else None
    work = Path(own.name) if own is not None else work
    try:
        def one(v: Variant) -> dict[str, dict]:
            t0 = time.perf_counter()
            out = run_variant(v, quick, names, work)
            if progress is not None:
                progress(f"{v.name}: {time.perf_counter() - t0:.1f} s")
            return out

        with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
            runs = dict(zip((v.name for v in vs), pool.map(one, vs)))
    finally:
        if own is not None:
            own.cleanup()
    ref = runs["reference"]
    rows, violations = [], []
    for name in names:
        for v in vs:
            if v.name == "reference":
                row = {"problems": [] if "error" not in ref[name] else [f"reference raised {ref[name]['error']}"]}
                if "error" not in ref[name] and not ref[name]["checks_ok"]:
                    row["problems"].append("check() fails: " + "; ".join(ref[name]["check_failures"]))
            else:
                row = compare(ref[name], runs[v.name][name])
            row.update(case=name, variant=v.name)
            rows.append(row)
            if row["problems"] and not (name in BRANCH_POINTS and all(p.startswith("verdict") for p in row["problems"])):
                violations.append(f"{name} / {v.name}: " + "; ".join(row["problems"]))
    return {"quick": quick, "variants": [v.name for v in vs], "runs": runs, "rows": rows, "violations": violations,
            "tolerances": {"depth_steps": DEPTH_TOLERANCE_STEPS, "force_of_weight": FORCE_TOLERANCE,
                           "jitter": JITTER}, "branch_points": BRANCH_POINTS}


def spread_table(result: dict[str, Any]) -> str:
    """A Markdown table: per case, the reference's answer and the largest spread over the variants."""
    lines = ["| case | reference | variants | same events | max Δρ* (increments) | max Δforce (mg) | problems |",
             "|---|---|---|---|---|---|---|"]
    ref = result["runs"]["reference"]
    for name in ref:
        rows = [r for r in result["rows"] if r["case"] == name and r["variant"] != "reference"]
        r0 = ref[name]
        answer = (r0["error"] if "error" in r0 else
                  f"{r0['outcome']}, ρ = {1e3 * r0['squeeze_depth']:.2f} mm, {r0['finger_normal_force']:.3f} N")
        same = sum(bool(r.get("same_events")) for r in rows)
        d = max((r.get("depth_steps", np.nan) for r in rows), default=np.nan)
        f = max((r.get("force_diff", np.nan) for r in rows), default=np.nan)
        probs = "; ".join(f"{r['variant']}: {', '.join(r['problems'])}" for r in rows if r["problems"]) or "none"
        lines.append(f"| {name} | {answer} | {len(rows)} | {same}/{len(rows)} | {d:.3g} | {f:.2g} | {probs} |")
    return "\n".join(lines)


#: Stages of :func:`run`.
STAGES = 1


def run(quick: bool, out_dir: Path, stages: Any) -> tuple[dict[str, Any], dict[str, str]]:
    """The sweep as a stage of the report: its part of the summary (the spread table, not every run's record)."""
    part: dict[str, Any] = {}
    stages.run("round-off perturbations", lambda: sweep(quick=quick),
               lambda v: part.__setitem__("perturbation", {k: v[k] for k in v if k != "runs"}
                                          | {"table": spread_table(v)}))
    return part, {}


__all__ = ["BRANCH_POINTS", "DEPTH_TOLERANCE_STEPS", "FORCE_TOLERANCE", "JITTER", "STAGES", "cases", "checks",
           "compare", "run", "run_case", "section", "spread_table", "sweep", "variants"]
