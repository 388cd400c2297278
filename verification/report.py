"""The full verification report: every study in turn, ``python -m verification all [--quick] [--out DIR]``.

Runs the stages of each study (:data:`STUDIES`, in this order), collects their headline checks, and writes
``report.html`` — the checks, then each study's own section — the PNGs it embeds and ``summary.json`` (every
number the report quotes, under each study's name) to ``verification/out/`` by default.  This module imports
the studies; no study imports it.

The full run takes about a quarter of an hour on a two-core machine for the dolfinx and Hertz studies, about
50 minutes for the 500 random scenes (one core), three quarters of an hour for the frictional contact and the
softness study, hours for the pickup's convergence study from an empty cache (``make converge`` fills the
same cache) and up to a few hours for the stated-error coverage study (10 objects).  ``--quick`` took 9 minutes
on two cores (AMD EPYC, shared with other jobs) before the coverage study, which adds about 7 minutes (3 objects,
one at a time) to it.  The exit status is 1 if a stage failed or a headline check failed.
"""

from __future__ import annotations

import datetime
import importlib
import json
import os
import platform
from pathlib import Path
from typing import Any

import numpy as np

from fem_grasp.io.output import json_safe

from ._common.html import checks_table, fmt, table, write_page
from ._common.run import DEFAULT_OUT, Stages, print_checks, setup_logging, study_parser

#: The studies of the report, in the report's order: each a package with ``STAGES``, ``run``, ``checks`` and
#: ``section`` (:mod:`verification._common.run`).
STUDIES = ("dolfinx", "hertz", "roundoff", "random_scenes", "converge", "coverage", "friction", "softness")


def environment() -> dict[str, Any]:
    """Versions of the libraries the checks ran with, the CPU count and the date."""
    import dolfinx
    import scipy

    from .dolfinx import has_cholmod

    env = {"python": platform.python_version(), "numpy": np.__version__, "scipy": scipy.__version__,
           "dolfinx": dolfinx.__version__, "cpus": os.cpu_count(), "cholmod": has_cholmod(),
           "date": datetime.datetime.now().isoformat(timespec="seconds")}
    for mod in ("gmsh", "pyvista", "matplotlib"):
        try:
            env[mod] = __import__(mod).__version__
        except Exception:  # noqa: BLE001 - optional
            env[mod] = None
    return env


def write_report(summary: dict[str, Any], out_dir: str | Path) -> Path:
    """Write ``report.html`` in ``out_dir`` from ``summary`` alone; return its path."""
    s = summary
    env = s.get("environment", {})
    body = [f"<p class='note'>Mode: <b>{'quick' if s.get('quick') else 'full'}</b>; total wall time "
            f"{fmt(s.get('total_seconds'))} s; {fmt(env.get('date'))}; dolfinx {fmt(env.get('dolfinx'))}, "
            f"numpy {fmt(env.get('numpy'))}, scipy {fmt(env.get('scipy'))}, gmsh {fmt(env.get('gmsh'))}, "
            f"pyvista {fmt(env.get('pyvista'))}; {fmt(env.get('cpus'))} CPUs. Every number below is also in "
            f"<code>summary.json</code>.</p>"]
    if s.get("failures"):
        body.append("<h2 class='fail'>Stages that failed</h2>"
                    + table(["stage", "error"], [[k, v] for k, v in s["failures"].items()]))
    body += ["<h2>Headline checks</h2>", checks_table(s.get("checks", []))]
    images = s.get("images", {})
    for name in STUDIES:
        if s.get(name):
            body.append(importlib.import_module(f"verification.{name}").section(s[name], images))
    if s.get("stage_seconds"):
        body.append("<h2>Timing</h2>" + table(["stage", "seconds"], [[k, v] for k, v in s["stage_seconds"].items()]))
    return write_page(Path(out_dir) / "report.html", "fem_grasp verification report", body)


def main(argv: list[str] | None = None) -> int:
    parser = study_parser("python -m verification all", "The full verification report: every study in turn, its "
                          "checks and sections in report.html, every number in summary.json.",
                          "small meshes, fewer levels and scenes (about 10 minutes)")
    args = parser.parse_args(argv)
    setup_logging(args.verbose, args.log_file)
    out_dir: Path = args.out
    out_dir.mkdir(parents=True, exist_ok=True)
    studies = {name: importlib.import_module(f"verification.{name}") for name in STUDIES}
    stages = Stages(sum(study.STAGES for study in studies.values()))
    summary: dict[str, Any] = {"quick": args.quick, "environment": environment(), "images": {}}
    for name, study in studies.items():
        part, images = study.run(args.quick, out_dir, stages)
        summary[name] = part
        summary["images"].update(images)
    stages.close()
    summary["checks"] = [c for name, study in studies.items() for c in study.checks(summary[name])]
    summary["stage_seconds"], summary["failures"] = stages.seconds, stages.failures
    summary["total_seconds"] = stages.elapsed()
    summary = json_safe(summary)
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=1), encoding="utf-8")
    path = write_report(summary, out_dir)
    print(f"[{summary['total_seconds']:6.1f} s] wrote {path} and summary.json")
    print_checks(summary["checks"])
    if summary["failures"]:
        print("failed stages:", ", ".join(summary["failures"]))
    failed = [c["name"] for c in summary["checks"] if not c["ok"]]
    return 1 if failed or summary["failures"] else 0


__all__ = ["DEFAULT_OUT", "STUDIES", "environment", "main", "write_report"]
