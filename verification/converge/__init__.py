"""Convergence of the pickup answer: ``python -m verification converge [--quick]`` (``make converge``).

For the four paper scenes (tomato, orange, steam bun, football) and the foam
block, each with its shipped scene's settings, the answer of Algorithm 1 of
*Picking up Soft 3D Objects with Two Fingers* — the verdict, the squeeze depth
ρ* at which the lift starts, the finger forces at lift-off (per finger: the
resultant's norm, its component along the finger's squeeze direction and its
vertical component; Σ f·n̂ over both patches), the contact-patch node counts
and the liftable weight w(ρ) — is computed under

``uniform``
    uniform refinement from the paper's resolution (Table I's vertex count;
    the foam block's 6 × 8 × 6 grid) upwards, ×2 in vertices per level
    (``fem_grasp.mesh.shapes.paper_mesh(name, N)``; the box: its grid divisions × k);
``graded``
    grading at the fingertips: spacing R/2, R/4, R/8 (and R/16 for the orange and the box) within 1.25 R of
    the two finger contact points (placed by the scene's rule on the
    paper-resolution mesh), growing at :data:`fem_grasp.mesh.remesh.DEFAULT_GRADING`
    to the paper-resolution spacing (:class:`fem_grasp.mesh.shapes.Refinement`);
``graded_table``
    the same, and the same spacing around the resting contact patch on the table;
``step`` / ``h``
    the squeeze increment, then the lift-test step h, halved repeatedly on one
    mesh (the uniform level at 4× the paper's vertex count; the box's ×2 grid);
``seed``
    five meshes of the same spacing (gmsh's ``Mesh.RandomSeed``; the box's
    grid jittered) at the paper's resolution (and at 4× for the orange; the box's ×2 grid),
    for the scatter at a fixed h;
``reference``
    the finest uniform level that ran, with the squeeze increment and h halved
    twice: the reference every other run's error is measured against;
``adaptive``
    :func:`fem_grasp.grasp.accuracy.converged_pickup` at 2 % (the answers at 10 % and 5 % are that run stopped
    earlier: the loop is deterministic);
``shipped`` / ``quick``
    the scene as shipped (its committed mesh) and its ``[quick]`` variant, one run each (their errors are what
    the scene states as ``expected_error``, printed by ``--scene-errors``).

Each run is a subprocess (its own memory, a time cap, peak memory measured)
whose record is cached as JSON under ``verification/out/converge/cache`` (a
cache hit needs the same case; records say the code digest they were made
with, and ``--stale`` recomputes those from other code).  A series stops at
its first level that exceeds the time cap.  The analysis (``converge.json``)
gives per object the tables, the converged estimates (Richardson where three
levels are monotone with an observed order, else the finest level with a
band), each run's error against the reference, the cheapest resolution for
10 %, 5 % and 2 %, the seed scatter, and a diagnosis of every verdict flip and
every non-monotone jump (a slow independent lift test: weights raised in
steps of h/8 from zero at every squeeze increment, to show whether a state
the lift test missed exists).  Plots: error against run time (log–log) for ρ*
and the finger force, and w(ρ) of the uniform levels overlaid.

The full study takes hours on two cores (``--quick``: minutes).  As a stage of the full report
(:func:`run`) it reads the cached runs (after ``make converge`` it only reads); its section and headline check
are in :mod:`.report`.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

from .analysis import analyse, attach_diagnoses, diagnosis_cases
from .report import checks, plots, section
from .runner import load_records, run_case, run_rounds, run_series
from .specs import CONFIGS, DEFAULT_OUT, OBJECTS, adaptive_cases, case_key, cases, code_digest, dependent_cases

__all__ = ["CONFIGS", "DEFAULT_OUT", "OBJECTS", "STAGES", "case_key", "checks", "code_digest", "run", "run_case",
           "section", "study"]



def study(quick: bool = False, out: Path = DEFAULT_OUT, objects: tuple[str, ...] = OBJECTS, compute: bool = True,
          stale: bool = False, series_filter: set[str] | None = None) -> dict[str, Any]:
    """Run (or, with ``compute=False``, only read) the study's cases; analyse; plot; return the analysis."""
    cfg = CONFIGS["quick" if quick else "full"]
    cache = out / "cache"
    cache.mkdir(parents=True, exist_ok=True)
    records = load_records(cache)
    t0 = time.perf_counter()

    def want(series: list[dict]) -> bool:
        return bool(series) and (series_filter is None or series[0]["series"] in series_filter)

    if compute:
        # the coarse levels of every series first, then the step, h and reference series, then the fine levels
        main_series = [s for s in cases(cfg, objects, records) if want(s)]
        run_rounds(main_series, cache, records, cfg, stale, levels=cfg["early_levels"])
        run_rounds([s for s in dependent_cases(cfg, objects, records) if want(s)], cache, records, cfg, stale)
        run_rounds(main_series, cache, records, cfg, stale)
        run_rounds([s for s in dependent_cases(cfg, objects, records) if want(s)], cache, records, cfg, stale)
        analysis = analyse(records, objects, cfg)
        for spec in diagnosis_cases(analysis, cfg):
            if series_filter is None or "diagnose" in series_filter or spec["series"] in series_filter:
                run_series([spec], cache, records, dict(cfg, case_timeout=max(cfg["case_timeout"], 1800)), stale)
        for series in adaptive_cases(cfg, objects):
            if want(series):
                run_series(series, cache, records, cfg, stale)
    wanted = {case_key(s) for group in (cases(cfg, objects, records), dependent_cases(cfg, objects, records),
                                         adaptive_cases(cfg, objects)) for series in group for s in series}
    wanted |= {k for k, r in records.items() if r["spec"].get("diagnose")}
    used = {k: r for k, r in records.items() if k in wanted and r["spec"]["object"] in objects}
    analysis = analyse(used, objects, cfg)
    attach_diagnoses(analysis, records)
    analysis["quick"] = quick
    analysis["config"] = cfg
    analysis["seconds"] = time.perf_counter() - t0
    analysis["total_case_seconds"] = float(sum(r.get("seconds") or 0.0 for r in used.values()))
    analysis["images"] = plots(analysis, out)
    from fem_grasp.io.output import json_safe

    (out / "converge.json").write_text(json.dumps(json_safe(analysis), indent=1))
    return analysis


#: Stages of :func:`run`.
STAGES = 1


def run(quick: bool, out_dir: Path, stages: Any) -> tuple[dict[str, Any], dict[str, str]]:
    """The study as a stage of the full report, in ``out_dir/converge``.  Cached runs are reused, so after ``make
    converge`` this only reads; from an empty cache it computes the whole study (hours).  ``quick`` runs the quick
    study of the foam block alone (a few minutes; the paper objects' quick study is half an hour:
    ``python -m verification converge --quick``)."""
    part: dict[str, Any] = {}
    images: dict[str, str] = {}

    def one() -> None:
        res = study(quick=quick, out=out_dir / "converge", objects=("foam_block",) if quick else OBJECTS)
        for key, name in res.pop("images", {}).items():
            images[key] = f"converge/{name}"
        part["grasp_convergence"] = res

    stages.run("grasp convergence", one)
    return part, images
