"""``python -m verification softness``: the finger forces at lift-off against the rigid grasp (Table III)."""

from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

from .._common.run import json_safe
from . import PAPER_OBJECTS, YOUNGS, conclusions, plot, study
from . import __doc__ as DOC


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m verification softness", description=DOC.splitlines()[0])
    p.add_argument("--objects", nargs="+", default=list(PAPER_OBJECTS))
    p.add_argument("--youngs", nargs="+", type=float, default=list(YOUNGS))
    p.add_argument("--fine", action="store_true", help="also a mesh graded to R/4 under the fingertips")
    p.add_argument("--fine-youngs", nargs="+", type=float, help="moduli for the finer mesh (default: --youngs)")
    p.add_argument("--no-shipped", action="store_true", help="only the finer mesh")
    p.add_argument("--json", type=Path)
    p.add_argument("--plot", type=Path)
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    s = study(tuple(args.objects), tuple(args.youngs), args.fine,
              tuple(args.fine_youngs) if args.fine_youngs else None, shipped=not args.no_shipped)
    s["conclusions"] = conclusions(s)
    for r in s["rows"]:
        if "ratio" in r:
            q = r["ratio"]
            print(f"{r['object']:10s} {r['mesh']:10s} E = {r['young']:8.3g} Pa: ρ* = {r['squeeze_depth'] * 1e3:7.3f} mm "
                  f"(step {r['step'] * 1e3:.3g}), "
                  f"Σf·n̂ {r['normal']:.3f} N (rigid {r['rigid']['normal']:.3f}, ×{q['normal']:.3f}), grip ×{q['grip']:.3f}, "
                  f"resultant ×{q['resultant']:.3f}, wrap {r['wrap']:.3f}, utilisation {r['utilisation']:.2f}, "
                  f"w/mg {r['liftable_excess']:.3f}")
        else:
            print(f"{r['object']:10s} {r['mesh']:10s} E = {r['young']:8.3g} Pa: not picked up ({r['reason'][:80]})")
    for k, v in s["conclusions"].items():
        print(k, v)
    if args.json:
        args.json.write_text(json.dumps(json_safe(s), indent=1), encoding="utf-8")
    if args.plot:
        plot(s, args.plot)
    return 0


if __name__ == "__main__":
    sys.exit(main())
