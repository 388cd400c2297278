"""``python -m verification random_scenes [--scenes N]``: random valid scenes never crash."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from . import __doc__ as DOC
from . import problems, sweep


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m verification random_scenes", description=DOC.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=500)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    def progress(done: int, row: dict) -> None:
        flag = "" if not problems(row) else "  <-- " + "; ".join(problems(row))
        print(f"  {done}/{args.scenes} {row['outcome']} ({row['seconds']:.1f} s){flag}", flush=True)

    result = sweep(args.scenes, args.seed, args.workers, progress)
    print(f"{args.scenes} random scenes: " + ", ".join(f"{k} {v}" for k, v in sorted(result["outcomes"].items()))
          + f"; median {result['median_seconds']:.1f} s, longest {result['max_seconds']:.1f} s")
    for p in result["problems"]:
        print(f"  seed {p['seed']}: {'; '.join(p['problems'])}")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(result, indent=1, default=float), encoding="utf-8")
    return 1 if result["problems"] else 0


if __name__ == "__main__":
    sys.exit(main())
