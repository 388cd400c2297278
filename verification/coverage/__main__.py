"""``python -m verification coverage [--quick] [--objects N] [--seed S] [--accuracy A] [--refinement R]
[--reference-draws K] [--references JSON] [--workers W] [--json PATH]``
(or ``--reanalyse PATH``): does the accuracy loop's stated error cover its actual error on random objects?"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from fem_grasp.grasp.options import REFINEMENTS, PickupOptions

from . import CONFIGS, sweep
from .summary import HEADER, passed, reference_of, summarise, summary_lines, table_line


def _json(value: object) -> object:
    """Standard JSON (infinities and NaN as null) for ``--json``."""
    from fem_grasp.io.output import json_safe

    return json_safe(value)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m verification coverage",
                                 description="Does pickup(..., accuracy=A)'s estimated error cover its actual error "
                                             "against a finer reference, on random objects?")
    ap.add_argument("--quick", action="store_true", help="3 objects at 10 %%, the answer's budget 150 s, the reference's cap 300 s")
    ap.add_argument("--objects", type=int, help="objects to draw (default: 10; 3 with --quick)")
    ap.add_argument("--seed", type=int, default=0, help="object i is drawn from numpy's default_rng(seed + i)")
    ap.add_argument("--accuracy", type=float, help="the target accuracy A (default: 0.05; 0.10 with --quick)")
    ap.add_argument("--refinement", choices=REFINEMENTS, default=PickupOptions.refinement,
                    help="how the answer's levels are made finer (PickupOptions.refinement; default the library's, "
                         f"{PickupOptions.refinement}); the reference is a remeshed level either way")
    ap.add_argument("--reference-draws", type=int,
                    help="draws of the reference's mesh whose mean is the reference (default: 3; 1 with --quick)")
    ap.add_argument("--references", type=Path, metavar="JSON",
                    help="take each object's reference from a saved --json file where it is finer than the "
                         "answer's last level (the same references for two runs); compute the others")
    ap.add_argument("--workers", type=int, default=2, help="objects run at a time, one process each")
    ap.add_argument("--json", type=Path, help="write the configuration, the summary and every row here")
    ap.add_argument("--reanalyse", type=Path, metavar="JSON",
                    help="print the table and the summary of a saved --json file; run nothing")
    args = ap.parse_args(argv)
    if args.reanalyse is not None:
        try:
            saved = json.loads(args.reanalyse.read_text(encoding="utf-8"))
            rows = saved["rows"]
        except (OSError, ValueError, KeyError, TypeError) as exc:
            ap.error(f"cannot read the rows of {args.reanalyse}: {exc}")
        summary = summarise(rows)
        print(HEADER)
        for row in rows:
            print(table_line(row))
    else:
        cfg = dict(CONFIGS["quick" if args.quick else "full"])
        if args.objects is not None:
            if args.objects < 1:
                ap.error(f"--objects must be at least 1, got {args.objects}")
            cfg["objects"] = args.objects
        if args.accuracy is not None:
            if not (0.0 < args.accuracy < 1.0 and math.isfinite(args.accuracy)):
                ap.error(f"--accuracy must be a relative error in (0, 1), e.g. 0.05; got {args.accuracy}")
            cfg["accuracy"] = args.accuracy
        cfg["refinement"] = args.refinement
        if args.reference_draws is not None:
            if args.reference_draws < 1:
                ap.error(f"--reference-draws must be at least 1, got {args.reference_draws}")
            cfg["reference_draws"] = args.reference_draws
        if args.references is not None:
            try:
                saved = json.loads(args.references.read_text(encoding="utf-8"))
                cfg["references"] = {int(r["seed"]): dict(reference_of(r), object=r["object"]) for r in saved["rows"]}
                cfg["references_file"] = str(args.references)
            except (OSError, ValueError, KeyError, TypeError) as exc:
                ap.error(f"cannot read the references of {args.references}: {exc}")
        if args.workers < 1:
            ap.error(f"--workers must be at least 1, got {args.workers}")
        print(f"{cfg['objects']} objects from seed {args.seed}, accuracy {cfg['accuracy']:g}, "
              f"{cfg['refinement']} levels, answer budget "
              f"{cfg['answer_seconds']:g} s, reference cap {cfg['reference_seconds']:g} s per draw, "
              f"{cfg.get('reference_draws', 1)} draw(s), {args.workers} at a time",
              flush=True)
        print(HEADER, flush=True)
        result = sweep(cfg, args.seed, args.workers, lambda row: print(table_line(row), flush=True))
        summary = result["summary"]
        if args.json:
            args.json.parent.mkdir(parents=True, exist_ok=True)
            args.json.write_text(json.dumps(_json(result), indent=1), encoding="utf-8")
    for line in summary_lines(summary):
        print(line)
    return 0 if all(passed(summary)) else 1


if __name__ == "__main__":
    sys.exit(main())
