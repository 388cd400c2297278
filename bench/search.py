"""The ``search`` section of ``make bench``: a placement search per paper scene, serially and on Dask.

For each shipped paper scene the same ``--search-candidates`` candidates (seed 0) are evaluated three ways:

* ``serial`` — the plain loop in this process (``workers=0``);
* ``dask 1`` and ``dask 2`` — a ``LocalCluster`` of one and of two worker processes (one thread each),
  started once for all scenes (its start-up is reported apart).

Each run's time splits into the **shared set-up** — the resting state and the candidates (in this process,
once per search), and per worker process the factorisation, every surface node's compliance columns, the
restored resting state and the compiled kernels (``setup_time`` of the row that built them) — and the
**per-candidate work**: the pickup of each candidate (``time`` of its row).  Dask's overhead per candidate is
the wall time of the one-worker run, less that worker's set-up, over that of the plain loop, less its set-up,
minus one.  Candidates per minute on two cores: the two-worker run's candidates over its wall time from the
first submission (set-up included), and over its wall time less a worker's set-up (steady state).  The rows of
every engine are checked against the serial ones (same verdicts, numbers to 1e-9).
"""

from __future__ import annotations

import logging
import os
import tempfile
import time
from typing import Any

import numpy as np

log = logging.getLogger("bench")

__all__ = ["SCENES", "print_search", "section_search"]

#: The paper's four objects, each with its shipped scene.
SCENES = ("tomato", "orange", "steam_bun", "football")
RUN_COLUMNS = ("time", "cpu_time", "setup_time", "worker")


def _same(a: Any, b: Any) -> bool:
    if list(a["key"]) != list(b["key"]):
        return False
    for c in a.columns:
        if c in RUN_COLUMNS:
            continue
        x, y = a[c].to_numpy(), b[c].to_numpy()
        if x.dtype.kind == "f":
            if not np.allclose(x, y, rtol=1e-9, atol=1e-15, equal_nan=True):
                return False
        elif list(x) != list(y):
            return False
    return True


def _run(name: str, count: int, cache: str, client: Any = None) -> dict[str, Any]:
    from fem_grasp import search

    t0 = time.perf_counter()
    r = search(name, None, candidates=count, workers=0 if client is None else None, client=client, report=False,
               best=0, cache_dir=cache)
    wall = time.perf_counter() - t0
    t = r.table
    setup = t["setup_time"].to_numpy(float)
    built = setup[setup > 0]
    work = float(t["time"].sum())
    return {"table": t, "wall_s": wall, "evaluate_s": r.timings["evaluate"], "rest_s": r.timings["rest"],
            "candidates_s": r.timings["candidates"], "worker_setup_s": [float(x) for x in built],
            "work_s": work, "cpu_s": float(t["cpu_time"].sum()), "n": len(t), "grasped": r.n_grasped,
            "errors": r.n_errors, "vertices": int(len(r.setup.points))}


def _engine_overhead(d: dict[str, Any], workers: int) -> float:
    """Seconds per candidate that the engine's wall time spends outside the pickups and the workers' set-up."""
    outside = d["evaluate_s"] * workers - d["work_s"] - sum(d["worker_setup_s"])
    return outside / d["n"]


def section_search(candidates: int = 16, scenes: tuple[str, ...] = SCENES) -> dict[str, Any]:
    """Per scene, back to back (the machine's load drifts): the plain loop, one worker, two workers."""
    from dask.distributed import Client, LocalCluster

    rows = []
    load0 = os.getloadavg()
    clusters, starts = {}, {}
    try:
        for n in (1, 2):
            t0 = time.perf_counter()
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                                   dashboard_address=None, silence_logs=logging.ERROR)
            client = Client(cluster)
            client.wait_for_workers(n)
            starts[n] = time.perf_counter() - t0
            clusters[n] = (cluster, client)
        with tempfile.TemporaryDirectory() as cache:
            for name in scenes:
                _run(name, 1, cache)  # the rest cached and the kernels loaded: every engine starts alike
                s = _run(name, candidates, cache)
                runs = {n: _run(name, candidates, cache, clusters[n][1]) for n in (1, 2)}
                log.info("search %s: serial %.1f s, dask 1 %.1f s, dask 2 %.1f s", name, s["evaluate_s"],
                         runs[1]["evaluate_s"], runs[2]["evaluate_s"])
                per = s["work_s"] / s["n"]
                row: dict[str, Any] = {
                    "scene": name, "vertices": s["vertices"], "candidates": s["n"], "grasped": s["grasped"],
                    "errors": s["errors"], "rest_s": s["rest_s"], "candidates_s": s["candidates_s"],
                    # a fresh worker process's set-up (the loop's was done by the warm-up run)
                    "worker_setup_s": runs[1]["worker_setup_s"][0] if runs[1]["worker_setup_s"] else 0.0,
                    "per_candidate_s": per, "per_candidate_cpu_s": s["cpu_s"] / s["n"],
                    "serial_evaluate_s": s["evaluate_s"], "serial_per_minute": 60.0 * s["n"] / s["evaluate_s"],
                    "serial_overhead_s": _engine_overhead(s, 1)}
                for n, d in runs.items():
                    setup = max(d["worker_setup_s"], default=0.0)
                    row.update({
                        f"dask{n}_evaluate_s": d["evaluate_s"], f"dask{n}_worker_setup_s": d["worker_setup_s"],
                        f"dask{n}_same": _same(d["table"], s["table"]), f"dask{n}_start_s": starts[n],
                        f"dask{n}_per_candidate_s": d["work_s"] / d["n"],
                        f"dask{n}_per_minute": 60.0 * d["n"] / d["evaluate_s"],
                        f"dask{n}_per_minute_steady": 60.0 * d["n"] / max(d["evaluate_s"] - setup, 1e-9),
                        f"dask{n}_overhead_s": _engine_overhead(d, n)})
                # Dask's overhead over the plain loop, per candidate: the one-worker run's wall time less its
                # set-up, against the loop's; and the engine time outside the pickups against their work
                loop = (s["evaluate_s"] - sum(s["worker_setup_s"])) / s["n"]
                one = (runs[1]["evaluate_s"] - sum(runs[1]["worker_setup_s"])) / runs[1]["n"]
                row["dask_overhead_wall"] = one / loop - 1.0
                row["dask_overhead"] = (row["dask1_overhead_s"] - row["serial_overhead_s"]) / per
                rows.append(row)
    finally:
        for cluster, client in clusters.values():
            client.close()
            cluster.close()
    return {"rows": rows, "candidates": candidates, "load_average_before": load0,
            "load_average_after": os.getloadavg(), "cluster_start_s": starts,
            "note": "the same candidates (seed 0) per scene for every engine, run back to back; shared set-up: "
                    "rest + candidates in the client, factorisation + columns + rest + kernels once per worker "
                    "process; overhead: engine wall time outside the pickups and set-up, per candidate, over the "
                    "pickups' own time (dask_overhead_wall: the one-worker run's wall time over the loop's)"}


def print_search(sec: dict[str, Any]) -> None:
    print(f"\n(h) placement search, {sec['candidates']} candidates per paper scene (load average "
          f"{sec['load_average_before'][0]:.1f} before, {sec['load_average_after'][0]:.1f} after; a local cluster "
          f"starts in {sec['cluster_start_s'].get('1', sec['cluster_start_s'].get(1, float('nan'))):.1f} s with one "
          f"worker, {sec['cluster_start_s'].get('2', sec['cluster_start_s'].get(2, float('nan'))):.1f} s with two)")
    print(f"{'scene':>10s} {'vertices':>8s} {'grasped':>7s} | {'set-up s: rest':>14s} {'cand.':>6s} {'worker':>7s} | "
          f"{'per cand. s':>11s} {'cpu s':>6s} | {'candidates/min: serial':>22s} {'dask 1':>7s} {'dask 2':>7s} "
          f"{'steady':>7s} | {'overhead':>8s} {'wall':>7s} {'same':>5s}")
    for r in sec["rows"]:
        print(f"{r['scene']:>10s} {r['vertices']:8d} {r['grasped']:4d}/{r['candidates']:<2d} | {r['rest_s']:14.2f} "
              f"{r['candidates_s']:6.2f} {r['worker_setup_s']:7.2f} | {r['per_candidate_s']:11.2f} "
              f"{r['per_candidate_cpu_s']:6.2f} | {r['serial_per_minute']:22.1f} {r['dask1_per_minute']:7.1f} "
              f"{r['dask2_per_minute']:7.1f} {r['dask2_per_minute_steady']:7.1f} | {100 * r['dask_overhead']:7.1f}% "
              f"{100 * r['dask_overhead_wall']:6.1f}% {str(r['dask1_same'] and r['dask2_same']):>5s}")
