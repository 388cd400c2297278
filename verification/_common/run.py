"""Running a study: its stages one after another (timed, a failure kept while the rest run), its checks, its page.

A study package exposes ``run(quick, out_dir, stages)`` (its stages, run through a :class:`Stages`; returns
its part of the summary and the pictures it wrote), ``checks(part)`` (its headline checks) and
``section(part, images)`` (its section of the report, HTML).  :func:`study_main` is the command line of such a
study alone; :mod:`verification.report` runs them all into one report.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import sys
import time
import traceback
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .html import checks_table, fmt, write_page

ROOT = Path(__file__).resolve().parents[2]
#: Where the verification writes its reports, pictures and JSON (git-ignored).
DEFAULT_OUT = ROOT / "verification" / "out"


class Stages:
    """Named stages run in turn: each one timed, printed as it starts, shown on a progress bar.

    A stage that raises is recorded in :attr:`failures` (type and message, the traceback printed) and the
    next one runs: one broken check must not hide the others.
    """

    def __init__(self, count: int) -> None:
        from fem_grasp.progress import PhaseBar

        self.t_start = time.perf_counter()
        self.seconds: dict[str, float] = {}
        self.failures: dict[str, str] = {}
        self.bar = PhaseBar(["stage"] * count)  # a bar on a terminal, nothing in CI or a pipe

    def elapsed(self) -> float:
        """Seconds since these stages were set up."""
        return time.perf_counter() - self.t_start

    def run(self, name: str, fn: Callable[[], Any], store: Callable[[Any], None] | None = None) -> None:
        """Run stage ``name``: call ``fn`` and hand its result to ``store``."""
        print(f"[{self.elapsed():6.1f} s] {name} ...", flush=True)
        t0 = time.perf_counter()
        try:
            with self.bar.phase(name):
                value = fn()
                if store is not None:
                    store(value)
        except Exception as exc:  # noqa: BLE001 - a failed stage is reported, the rest still run
            self.failures[name] = f"{type(exc).__name__}: {exc}"
            traceback.print_exc()
        self.seconds[name] = time.perf_counter() - t0

    def close(self) -> None:
        self.bar.close()


def cpu_model() -> str:
    """The CPU's model name (Linux's /proc/cpuinfo), else the platform's word for it."""
    import platform

    try:
        return next(line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                    if line.startswith("model name"))
    except (OSError, StopIteration):
        return platform.processor() or platform.machine()


def finite_max(values: Any) -> float:
    """The largest of ``values`` ignoring None and NaN; NaN when none is left."""
    vals = [float(v) for v in values if v is not None and not (isinstance(v, float) and math.isnan(v))]
    return max(vals) if vals else float("nan")


def check(name: str, value: float, threshold: str, ok: bool) -> dict[str, Any]:
    """One row of a pass/fail table."""
    return {"name": name, "value": float(value), "threshold": threshold, "ok": bool(ok)}


def json_safe(x: Any) -> Any:
    """Plain JSON types: numpy scalars and arrays converted, tuples as lists, non-finite floats as None, keys that
    start with ``_`` (working data) left out."""
    if isinstance(x, dict):
        return {str(k): json_safe(v) for k, v in x.items() if not str(k).startswith("_")}
    if isinstance(x, (list, tuple)):
        return [json_safe(v) for v in x]
    if isinstance(x, np.ndarray):
        return json_safe(x.tolist())
    if isinstance(x, (np.bool_, bool)):
        return bool(x)
    if isinstance(x, (np.integer, int)):
        return int(x)
    if isinstance(x, (np.floating, float)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, Path):
        return str(x)
    return x


def setup_logging(verbose: bool = False, log_file: str | None = None) -> None:
    """Warnings on the terminal (everything from info with ``verbose``), info and up into ``log_file``."""
    handlers: list[logging.Handler] = [logging.StreamHandler()]
    handlers[0].setLevel(logging.INFO if verbose else logging.WARNING)
    if log_file:
        handlers.append(logging.FileHandler(log_file, encoding="utf-8"))
        handlers[1].setLevel(logging.INFO)
    logging.basicConfig(level=logging.INFO if (verbose or log_file) else logging.WARNING,
                        format="%(asctime)s %(name)s %(levelname)s %(message)s", handlers=handlers)


def print_checks(checks: list[dict[str, Any]]) -> None:
    for c in checks:
        print(f"  {'PASS' if c['ok'] else 'FAIL'}  {c['name']}: {fmt(c['value'])} ({c['threshold']})")


def study_parser(prog: str, description: str, quick_help: str) -> argparse.ArgumentParser:
    """The options of a study run on its own: ``--quick``, ``--out``, ``-v``, ``--log-file``."""
    ap = argparse.ArgumentParser(prog=prog, description=description)
    ap.add_argument("--quick", action="store_true", help=quick_help)
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"output directory (default {DEFAULT_OUT})")
    ap.add_argument("-v", "--verbose", action="store_true", help="log the progress of every solve")
    ap.add_argument("--log-file", metavar="FILE", help="also write the log (info and up) to FILE")
    return ap


def study_main(study: Any, name: str, title: str, argv: list[str] | None, quick_help: str,
               prog: str | None = None) -> int:
    """Run one study package alone: its stages, checks and section, written as ``NAME.json`` and ``NAME.html`` in
    ``--out``.  Exit status 1 when a stage failed or a check did not pass."""
    ap = study_parser(prog or f"python -m verification {name}", (study.__doc__ or title).strip().splitlines()[0],
                      quick_help)
    args = ap.parse_args(argv)
    setup_logging(args.verbose, args.log_file)
    args.out.mkdir(parents=True, exist_ok=True)
    stages = Stages(study.STAGES)
    part, images = study.run(args.quick, args.out, stages)
    stages.close()
    part["checks"] = study.checks(part)
    part["stage_seconds"], part["failures"] = stages.seconds, stages.failures
    part["total_seconds"] = stages.elapsed()
    part = json_safe(part)
    (args.out / f"{name}.json").write_text(json.dumps(part, indent=1), encoding="utf-8")
    body = [f"<p class='note'>{'quick' if args.quick else 'full'} run, {part['total_seconds']:.0f} s</p>"]
    if stages.failures:
        body.append("<h2 class='fail'>Stages that failed</h2><ul>"
                    + "".join(f"<li>{fmt(k)}: {fmt(v)}</li>" for k, v in stages.failures.items()) + "</ul>")
    body += [checks_table(part["checks"]), study.section(part, images)]
    path = write_page(args.out / f"{name}.html", title, body)
    print_checks(part["checks"])
    if stages.failures:
        print("failed stages:", ", ".join(stages.failures), file=sys.stderr)
    print(f"wrote {path} and {name}.json ({part['total_seconds']:.0f} s)")
    return 0 if all(c["ok"] for c in part["checks"]) and not stages.failures else 1
