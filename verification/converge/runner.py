"""Running the study's cases: one subprocess per case (its own memory cap and time limit), records cached as JSON."""

from __future__ import annotations

import json
import logging
import os
import resource
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from .slow_lift import diagnose
from .specs import (
    RECORD_FORMAT,
    ROOT,
    body_of,
    build_mesh,
    case_key,
    code_digest,
    geometry_of,
    pickup_kwargs,
    scene_digest,
    scene_of,
)


def _bracket(liftable: list) -> list[float] | None:
    """(ρ of the last lift test that did not pass, ρ* ) — ρ* is known to within this interval."""
    if len(liftable) < 2:
        return None
    return [float(liftable[-2][0]), float(liftable[-1][0])]


def run_case(spec: dict[str, Any], record_path: Path | None = None) -> dict[str, Any]:
    """Build the mesh and run the pickup of one case; its record (module notes)."""
    from fem_grasp.grasp import accuracy
    from fem_grasp.grasp.answer import answer_of
    from fem_grasp.grasp.pickup import pickup
    from fem_grasp.mesh import remesh

    scene = scene_of(spec["object"], quick=spec["series"] == "quick")
    rec: dict[str, Any] = {"spec": spec, "format": RECORD_FORMAT, "code": code_digest(),
                           "scene": scene_digest(spec["object"])}
    if spec["series"] == "adaptive":
        t0 = time.perf_counter()
        body = scene.body()

        def partial(report) -> None:  # a record after every level: a timed-out loop keeps its levels
            if record_path is not None:
                from fem_grasp.io.output import json_safe

                part = dict(rec, partial=True, accuracy=report.to_dict(), seconds=time.perf_counter() - t0)
                record_path.with_suffix(".partial").write_text(json.dumps(json_safe(part), indent=1))

        res = accuracy.converged_pickup(body, solve=pickup, accuracy=spec["target"], geometry=geometry_of(scene),
                                        max_levels=spec.get("max_levels", accuracy.MAX_LEVELS), on_level=partial,
                                        **scene.pickup_kwargs())
        rec["seconds"] = time.perf_counter() - t0
        rec["answer"] = answer_of(res, rec["seconds"]).to_dict()
        rec["accuracy"] = res.accuracy
        rec["vertices"] = res.body.n_nodes
        rec["peak_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
        return rec
    t0 = time.perf_counter()
    mesh, info = build_mesh(spec, scene)
    rec["mesh_seconds"] = time.perf_counter() - t0
    rec.update(info)
    kw = pickup_kwargs(spec, scene, mesh)
    t0 = time.perf_counter()
    body = body_of(scene, mesh)
    if spec.get("diagnose"):
        rec["diagnosis"] = diagnose(body, kw, scene)
    res = pickup(body, **kw)
    rec["pickup_seconds"] = time.perf_counter() - t0
    rec["seconds"] = rec["mesh_seconds"] + rec["pickup_seconds"]
    ans = answer_of(res, rec["pickup_seconds"])
    rec["answer"] = ans.to_dict()
    rec["vertices"] = mesh.n_points
    rec["tets"] = mesh.n_tets
    rec["spacing"] = remesh.spacing(mesh)
    fin = res.final
    fn = np.concatenate([fin.contact_nodes["finger1"], fin.contact_nodes["finger2"]]) if fin is not None else []
    rec["patch_spacing"] = remesh.spacing(mesh, fn if len(fn) else list(res.finger_nodes))
    rec["bracket"] = _bracket(res.liftable) if res.success else None
    rec["finger_nodes"] = [int(k) for k in res.finger_nodes]
    rec["finger_points"] = mesh.points[[k for k in res.finger_nodes if k >= 0]].tolist()
    rec["lift_attempts"] = [a.to_dict() for a in res.lift_attempts]
    rec["events"] = len(res.events)
    rec["timings"] = dict(res.timings)
    rec["peak_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return rec


def load_records(cache: Path) -> dict[str, dict]:
    """The cached records, less those made for a shipped scene that has changed since (:func:`scene_digest`)."""
    out = {}
    scenes: dict[str, str] = {}
    for f in sorted(cache.glob("*.json")):
        try:
            rec = json.loads(f.read_text())
        except (OSError, ValueError):
            continue
        name = rec["spec"]["object"]
        if name not in scenes:
            scenes[name] = scene_digest(name)
        if rec.get("scene", scenes[name]) != scenes[name]:
            continue
        out[f.stem] = rec
    return out


def _worker_env() -> dict[str, str]:
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", PYTHONPATH=str(ROOT))
    return env


def run_series(series: list[dict[str, Any]], cache: Path, records: dict[str, dict], cfg: dict[str, Any],
               stale: bool) -> None:
    """Run the cases of one series in order (coarse to fine), stopping after the first that times out."""
    run_rounds([series], cache, records, cfg, stale)


def run_rounds(all_series: list[list[dict[str, Any]]], cache: Path, records: dict[str, dict], cfg: dict[str, Any],
               stale: bool, levels: int | None = None) -> None:
    """Run many series level by level: the first case of every series, then the second, … (up to ``levels``
    levels); a series stops after its first case that times out (its finer levels would too)."""
    stopped: set[int] = set()
    for i, series in enumerate(all_series):  # a series that timed out before stays stopped
        if any(records.get(case_key(sp), {}).get("timeout") for sp in series):
            stopped.add(i)
    top = max((len(s) for s in all_series), default=0)
    for level in range(top if levels is None else min(levels, top)):
        for i, series in enumerate(all_series):
            if i in stopped or level >= len(series):
                continue
            if not _run_one(series[level], cache, records, cfg, stale):
                stopped.add(i)


def _run_one(spec: dict[str, Any], cache: Path, records: dict[str, dict], cfg: dict[str, Any], stale: bool) -> bool:
    """Run one case unless cached; False when it timed out."""
    digest = code_digest()
    key = case_key(spec)
    rec = records.get(key)
    if rec is not None and not (stale and rec.get("code") != digest):
        return not rec.get("timeout")
    path = cache / f"{key}.json"
    timeout = cfg["adaptive_timeout"] if spec["series"] == "adaptive" else cfg["case_timeout"]
    t0 = time.perf_counter()
    print(f"  {spec}", flush=True)
    cmd = [sys.executable, "-m", "verification.converge", "--worker", json.dumps(spec), "--record", str(path),
           "--memory-gib", str(cfg["memory_gib"])]
    try:
        proc = subprocess.run(cmd, cwd=ROOT, env=_worker_env(), timeout=timeout, capture_output=True, text=True)
        if proc.returncode != 0 or not path.exists():
            rec = {"spec": spec, "format": RECORD_FORMAT, "code": digest, "scene": scene_digest(spec["object"]),
                   "error": proc.stderr[-2000:],
                   "seconds": time.perf_counter() - t0}
            path.write_text(json.dumps(rec, indent=1))
    except subprocess.TimeoutExpired:
        rec = {"spec": spec, "format": RECORD_FORMAT, "code": digest, "scene": scene_digest(spec["object"]),
               "timeout": True, "seconds": timeout}
        part = path.with_suffix(".partial")
        if part.exists():  # the adaptive loop's levels so far
            rec.update({k: v for k, v in json.loads(part.read_text()).items() if k in ("accuracy",)})
        path.write_text(json.dumps(rec, indent=1))
    rec = json.loads(path.read_text())
    records[key] = rec
    if "answer" in rec:
        a = rec["answer"]
        print(f"    {rec.get('vertices')} vertices: {'picked up' if a['success'] else 'NOT picked up'} "
              f"rho {1e3 * a['squeeze_depth']:.3f} mm, finger force {a['finger_force']:.3f} N, "
              f"{rec['seconds']:.1f} s", flush=True)
    else:
        print(f"    {'timeout' if rec.get('timeout') else 'error'} after {rec['seconds']:.0f} s", flush=True)
    return not rec.get("timeout")


def worker(spec_json: str, record: Path, memory_gib: float) -> int:
    limit = int(memory_gib * 2**30)
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    logging.basicConfig(level=logging.WARNING)
    spec = json.loads(spec_json)
    rec = run_case(spec, record)
    from fem_grasp.io.output import json_safe

    tmp = record.with_suffix(".tmp")
    tmp.write_text(json.dumps(json_safe(rec), indent=1))
    tmp.replace(record)
    return 0

