"""``fem-grasp search``: where to grasp, Algorithm 1 for many finger placements (:func:`fem_grasp.batch.search`),
and the table of the best grasps it prints.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from .common import EXIT_FAILED, EXIT_OK, BadInput, cache_dir_of, echo, progress_on, scene_of

__all__ = ["cmd_search"]


def _grid_option(text: str | None, option: str) -> Any:
    """``N`` (a count), ``LO:HI:N`` (N values from LO to HI) or ``A,B,C`` (these values)."""
    if text is None:
        return None
    t = text.strip()
    try:
        if ":" in t:
            lo, hi, n = t.split(":")
            return (float(lo), float(hi), int(n))
        if "," in t or "." in t:
            return [float(v) for v in t.split(",") if v.strip()]
        return int(t)
    except ValueError:
        raise BadInput(f"{option} {text!r}: write a count N, a range LO:HI:N, or values A,B,C") from None


#: What each ranking of the search ranks by, in words.
_RANKED_BY = {"force": "the least finger normal force Σ f·n̂", "squeeze": "the least squeeze depth rho*",
              "margin": "the largest w/mg"}


def _best_table(best: Any, rank: str, error: float | None, accuracy: float | None = None) -> list[str]:
    """The best grasps of a search as a table whose headers are the result files' column names (with units);
    ``≈`` marks those within the error of the best one (``within_error``, :func:`fem_grasp.batch.rank_table`): the
    stated ``error`` of every one-level answer, or, with an ``accuracy`` target, each answer's own estimated errors
    (the columns ``±rho_%`` and ``±force_%``, with its ``levels``; "—" where the error is not known)."""
    if not len(best):
        return []
    cols: tuple[tuple[str, Any, str], ...] = (
        ("rank", None, ""), ("nodes", None, ""), ("azimuth_deg", "azimuth_deg", ".0f"),
        ("tilt_deg", "tilt_deg", ".1f"), ("s", "ratio", "g"), ("height_mm", "height", ".3g"),
        ("rho_star_mm", "rho_star", ".4g"), ("grip1_N", "grip1", ".3g"), ("grip2_N", "grip2", ".3g"),
        ("finger_normal_force_N", "finger_normal_force", ".3g"))
    if accuracy is not None:
        cols += (("±rho_%", "error_rho_star", ".1f"), ("±force_%", "error_finger_force", ".1f"),
                 ("levels", "levels", "d"))
    rows = []
    for _, r in best.iterrows():
        cells = []
        for head, col, fmt in cols:
            if head == "rank":
                cells.append(f"{int(r['rank'])}{' ≈' if r.get('within_error', False) else ''}")
            elif head == "nodes":
                cells.append(f"{int(r['node_i'])}, {int(r['node_j'])}")
            elif head == "levels":
                cells.append(f"{int(r['levels'])}{'' if r['converged'] else '*'}")
            else:
                scale = 1e3 if head.endswith("_mm") else 100.0 if head.endswith("_%") else 1.0
                v = float(r[col]) * scale
                cells.append(format(v, fmt) if np.isfinite(v) else "—")
        rows.append(cells)
    widths = [max(len(h), *(len(c[k]) for c in rows)) for k, (h, _, _) in enumerate(cols)]
    line = lambda cells: "  " + "  ".join(c.ljust(w) for c, w in zip(cells, widths)).rstrip()  # noqa: E731
    if accuracy is not None:
        note = (f"; each answer refined to {100 * accuracy:g} % (levels: meshes run, * not converged) with its own "
                "estimated error (±, — when not known)")
        if rank in ("force", "squeeze"):
            note += ("; ≈: its range and the best one's overlap, each with its own error (|q − q₁| ≤ e·|q| + "
                     "e₁·|q₁|), or its error is not known, so it could be the best")
    elif error is None or rank not in ("force", "squeeze"):
        note = ("; no error stated for this scene, so which of them are equally good is not known" if error is None
                else "")
    elif not np.isfinite(error):
        note = "; ≈: the scene states that one run may even give the wrong verdict, so any of them may be the best"
    else:
        note = (f"; ≈: within the stated error (±{100 * error:.3g} % each) of the best, so as good as it as far as "
                "this mesh can tell")
    return [f"best       ranked by {_RANKED_BY[rank]}{note}", line([h for h, _, _ in cols]), *map(line, rows)]


def cmd_search(args: argparse.Namespace) -> int:
    from ..batch.engine import search
    from ..io.scene import parse_accuracy

    scene = scene_of(args)
    if args.workers is not None and args.workers < 0:
        raise BadInput("--workers must be >= 0 (0: a plain loop in this process)")
    accuracy = None if args.accuracy is None else parse_accuracy(args.accuracy, "--accuracy")
    grid = {k: _grid_option(getattr(args, k), f"--{k}") for k in ("heights", "azimuths", "tilts", "ratios")}
    for k in ("tilts", "ratios"):  # a bare number of tilts or ratios is that value, not a count
        if isinstance(grid[k], int):
            grid[k] = [float(grid[k])]
    result = search(scene, args.out, candidates=args.candidates, seed=args.seed, cone=args.cone,
                    workers=args.workers, scheduler=args.scheduler, resume=args.resume, force=args.force,
                    rank=args.rank, best=args.best if args.out else 0, report=not args.no_report and bool(args.out),
                    cache_dir=cache_dir_of(args), connect_timeout=args.connect_timeout,
                    progress=progress_on(args), accuracy=accuracy, **grid)
    t, cs = result.table, result.candidates
    n_ok, n_err = result.n_grasped, result.n_errors
    rejected = ", ".join(f"{k} {v}" for k, v in cs.rejected.items()) or "none"
    echo(args, f"search     {scene.name}{' (quick)' if scene.quick else ''}: {len(t)} candidates of {cs.valid} valid "
               f"grid points (rejected: {rejected}); {result.engine}")
    verdict = "picked up" if result.lifts else "pass the lift test (the lift is not simulated)"
    echo(args, f"result     {n_ok} {verdict}, {len(t) - n_ok - n_err} not, {n_err} errors"
               + (f" ({result.resumed} from an earlier run)" if result.resumed else ""))
    best = result.ranked[result.ranked["rank"] > 0].head(max(args.best, 5))
    for line in _best_table(best, args.rank, result.expected_error, result.accuracy):
        echo(args, line)
    per = t["time"].median() if len(t) else float("nan")
    echo(args, "time       " + ", ".join(f"{k} {v:.1f} s" for k, v in result.timings.items())
               + f"; median {per:.2f} s per candidate")
    if args.out:
        out = Path(args.out)
        echo(args, f"files      {out}/results.parquet, {out}/results.csv (one row per candidate), {out}/search.json")
        if result.report is not None:
            echo(args, f"report     {result.report}" + (f" (best grasps: {out}/best/01 …)" if result.best else ""))
    return EXIT_OK if n_ok else EXIT_FAILED
