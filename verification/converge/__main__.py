"""``python -m verification converge``: run or read the study, print its tables, write converge.json and the plots."""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from . import __doc__ as DOC
from . import references, study
from .report import markdown, print_scene_errors, print_tables
from .runner import worker
from .specs import DEFAULT_OUT, OBJECTS


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m verification converge", description=DOC.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a few levels per series (minutes)")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    ap.add_argument("--objects", nargs="+", choices=OBJECTS, default=list(OBJECTS))
    ap.add_argument("--series", nargs="+", help="run only these series (uniform graded graded_table seed step h "
                                               "reference adaptive diagnose); the analysis reads every cached one")
    ap.add_argument("--report-only", action="store_true", help="analyse and plot the cached records; compute nothing")
    ap.add_argument("--stale", action="store_true", help="recompute records made with other fem_grasp sources")
    ap.add_argument("--docs", type=Path, help="also copy the plots into this folder (the README's: docs/)")
    ap.add_argument("--markdown", action="store_true", help="print the README's tables")
    ap.add_argument("--scene-errors", action="store_true",
                    help="print the shipped scenes' errors against the reference (their [solver] expected_error)")
    ap.add_argument("--write-references", action="store_true",
                    help="write the references the cache holds into verification/converge/references.json, which "
                         "the benchmarks measure answers against on machines without the study (full study only)")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument("--record", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("--memory-gib", type=float, default=9.0, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.write_references and args.quick:
        ap.error("--write-references keeps the full study's references only (drop --quick)")
    if args.worker:
        return worker(args.worker, args.record, args.memory_gib)
    logging.basicConfig(level=logging.WARNING, format="%(asctime)s %(name)s %(levelname)s %(message)s")
    analysis = study(args.quick, args.out, tuple(args.objects), compute=not args.report_only, stale=args.stale,
                     series_filter=set(args.series) if args.series else None)
    print(markdown(analysis)) if args.markdown else print_tables(analysis)
    if args.scene_errors:
        print_scene_errors(analysis)
    print(f"\nwrote {args.out / 'converge.json'} and {', '.join(analysis['images'].values())}")
    if args.write_references:
        written = references.write(analysis)
        print(f"wrote the references of {', '.join(written) or 'no object'} into {references.REFERENCES}")
    if args.docs:
        import shutil

        args.docs.mkdir(parents=True, exist_ok=True)
        for name in analysis["images"].values():
            shutil.copy(args.out / name, args.docs / name)
        print(f"copied the plots into {args.docs}")
    return 0



if __name__ == "__main__":
    sys.exit(main())
