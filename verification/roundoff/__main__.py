"""``python -m verification roundoff [--quick] [--json PATH]``: pickups under round-off perturbations."""

from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

from . import __doc__ as DOC
from . import _worker, spread_table, sweep


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m verification roundoff", description=DOC.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the shipped scenes' quick variants, fewer variants")
    ap.add_argument("--json", type=Path, help="write the whole result here")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument("--out", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("--cases", help=argparse.SUPPRESS)
    ap.add_argument("--seed", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        _worker(args.worker, args.quick, args.seed, json.loads(args.cases), args.out)
        return 0
    logging.basicConfig(level=logging.WARNING)
    result = sweep(args.quick, progress=lambda s: print("  " + s, flush=True))
    print(spread_table(result))
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(result, indent=1), encoding="utf-8")
    for v in result["violations"]:
        print("VIOLATION:", v)
    return 1 if result["violations"] else 0


if __name__ == "__main__":
    sys.exit(main())
