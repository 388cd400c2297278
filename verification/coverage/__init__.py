"""Does the stated error hold?  ``python -m verification coverage``: the accuracy loop on random objects.

``pickup(body, accuracy=A)`` (:func:`fem_grasp.grasp.accuracy.converged_pickup`) refines the mesh at the contact
patches until two successive answers agree within A, and states its estimated error of ρ* (the squeeze depth at
which the lift starts) and of the finger force Σ f·n̂.  This study measures how often that estimate is at
least the actual error, on random objects nobody tuned the loop for.

An object (:class:`~.scene.CoverageObject`, drawn from ``np.random.default_rng(seed0 + i)``) is a gmsh
ellipsoid, two fused spheres or a capsule, 2–4.5 cm in size, of E 5–100 kPa (log-uniform), ν 0.2–0.45,
density 300–1500 kg/m³, μ 0.3–1.0 at the fingers and the table, a fingertip 0.3–0.6 times its smallest radius,
squeezed 0–30° below the horizontal with ratio s 0–1; its first mesh has about 500 vertices.

* the **answer**: ``converged_pickup`` at accuracy A (5 %; 10 % with ``--quick``) with a time budget, its levels
  made as the library makes them (nested by default; ``--refinement remesh``: remeshed,
  ``PickupOptions.refinement``); its whole ``result.accuracy``
  (levels, estimated error, convergence, note) is kept;
* the **reference**: one pickup a level beyond the answer's last — the patch spacing halved at the answer's
  contact patches (the table patch four times coarser, as the loop grades it), the loop's next outer spacing,
  a quarter of the last squeeze increment and half its lift-test step h
  (:func:`~.runner.reference_plan`) — on three draws of its mesh (``--reference-draws``; its spacings scaled
  by 1, 0.98 and 1.02), their mean, with their spread as its own uncertainty; skipped as too large when it would put
  more than 400 contacts on a fingertip, and abandoned after its time cap per draw (keeping the draws done);
  ``--references FILE`` takes a saved study's references where they are finer than the answer's last level,
  so that two loops are judged against the same ones;
* per object, the actual errors |answer − reference| / |reference| of ρ* and of the finger force; a quantity is
  **covered** when its estimated error is at least the actual one and the two verdicts (lifted or not) agree,
  or when its estimate is infinite (the answer states that it does not know); the summary also counts it with
  the reference's spread added to the estimate.

Headline checks (:mod:`.report`): both quantities covered on at least 90 % of the objects with a reference,
and every verdict agreeing with its reference.  Each object runs in a spawned process, ``--workers`` at a time.
"""

from __future__ import annotations

import concurrent.futures
import json
from pathlib import Path
from typing import Any, Callable

from .report import checks, section
from .runner import QUANTITIES, combine_draws, reference_plan, run_object, supervised
from .scene import RANGES, SHAPES, TARGET_VERTICES, CoverageObject, capsule, capsule_volume
from .summary import REQUIRED_COVERAGE, evaluate, passed, reference_of, summarise

#: The full study and ``--quick``: objects, target accuracy, the answer's time budget (``max_seconds`` of the
#: loop) and hard cap, the reference's time cap (per draw), the largest reference run (contacts per fingertip),
#: and the draws of the reference's mesh (:mod:`~verification.coverage.runner`).
CONFIGS: dict[str, dict[str, Any]] = {
    "full": {"objects": 10, "accuracy": 0.05, "answer_seconds": 600.0, "answer_cap": 1800.0, "answer_max_contacts": 80,
             "reference_seconds": 900.0, "max_reference_contacts": 400, "reference_draws": 3},
    "quick": {"objects": 3, "accuracy": 0.10, "answer_seconds": 150.0, "answer_cap": 450.0, "answer_max_contacts": 80,
              "reference_seconds": 300.0, "max_reference_contacts": 400, "reference_draws": 1},
}
#: Stages of :func:`run`.
STAGES = 1


def sweep(config: dict[str, Any], seed: int = 0, workers: int = 2,
          progress: Callable[[dict[str, Any]], None] | None = None) -> dict[str, Any]:
    """Objects ``seed`` … ``seed + config["objects"] − 1``, ``workers`` at a time; ``progress(row)`` as each ends.

    Returns ``{"config", "seed", "summary", "rows"}`` (rows in seed order).
    """
    seeds = list(range(seed, seed + int(config["objects"])))
    rows = []
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        futures = [pool.submit(supervised, s, config) for s in seeds]
        for fut in concurrent.futures.as_completed(futures):
            row = fut.result()
            rows.append(row)
            if progress is not None:
                progress(row)
    rows.sort(key=lambda r: r["seed"])
    kept = {k: v for k, v in config.items() if k != "references"}  # the saved references stay in their file
    return {"config": kept, "seed": seed, "summary": summarise(rows), "rows": rows}


def compact(row: dict[str, Any]) -> dict[str, Any]:
    """A row for the report's summary: the object, the verdicts, the errors and the times (no levels)."""
    ans, ref = row.get("answer") or {}, reference_of(row)
    acc = ans.get("accuracy") or {}
    keep = ("status", "success", "squeeze_depth", "finger_force", "vertices", "seconds", "draws_ok", "spread")
    return {"seed": row["seed"], "object": row["object"],
            "answer": {k: ans.get(k) for k in keep} | {"levels": len(acc.get("levels", [])),
                                                       "converged": acc.get("converged"), "note": acc.get("note"),
                                                       "estimated_error": acc.get("estimated_error")},
            "reference": {k: ref.get(k) for k in keep}, "comparison": evaluate(row)}


def run(quick: bool, out_dir: Path, stages: Any) -> tuple[dict[str, Any], dict[str, str]]:
    """The study as a stage of the report: its summary and compact rows (every row in ``coverage_rows.json``)."""
    cfg = CONFIGS["quick" if quick else "full"]
    part: dict[str, Any] = {"config": cfg}

    def store(result: dict[str, Any]) -> None:
        from fem_grasp.io.output import json_safe

        Path(out_dir).mkdir(parents=True, exist_ok=True)
        (Path(out_dir) / "coverage_rows.json").write_text(json.dumps(json_safe(result), indent=1), encoding="utf-8")
        part["coverage"] = {"summary": result["summary"], "objects": [compact(r) for r in result["rows"]]}

    stages.run("stated error against a reference (random objects)", lambda: sweep(cfg), store)
    return part, {}


__all__ = ["CONFIGS", "QUANTITIES", "RANGES", "REQUIRED_COVERAGE", "SHAPES", "STAGES", "TARGET_VERTICES",
           "CoverageObject", "capsule", "capsule_volume", "checks", "combine_draws", "compact", "evaluate", "passed",
           "reference_plan", "run", "run_object", "section", "summarise", "supervised", "sweep"]
