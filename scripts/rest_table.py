"""Resting configurations of the four paper objects on the table (paper §III-A).

For each object of Table I (its weight, ν and μ) at one Young's modulus,
print the number of contact nodes, how many of them slide, the largest sag,
the iterations and the wall time of :func:`fem_grasp.grasp.rest.rest`, and the
contact-law/equilibrium checks.

Usage::

    python scripts/rest_table.py                 # E = 1e4 Pa (objects.EFFECTIVE_YOUNG_ESTIMATE)
    python scripts/rest_table.py --young 3e4
    python scripts/rest_table.py --young table   # Table I's printed moduli (micrometre sag)
    python scripts/rest_table.py --into docs/physics.md   # also rewrite the guide's table (``make rest-table``)

The guide's table (docs/physics.md, "Resting on the table") sits between the markers :data:`BEGIN` and
:data:`END`; ``--into`` replaces what is between them, so the page shows what this script printed last.
``--readme`` is another name for ``--into``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Sequence

from fem_grasp.grasp import objects
from fem_grasp.grasp.rest import rest

#: The guide's rest table (docs/physics.md) is between these lines.
BEGIN = "<!-- rest-table: written by `make rest-table` (scripts/rest_table.py --into docs/physics.md) -->"
END = "<!-- rest-table: end -->"


def replace_block(text: str, block: str, begin: str = BEGIN, end: str = END) -> str:
    """``text`` with what lies between the lines ``begin`` and ``end`` replaced by ``block``."""
    if begin not in text or end not in text:
        raise SystemExit(f"the file has no {begin!r} … {end!r} block to rewrite")
    head, rest_ = text.split(begin, 1)
    _, tail = rest_.split(end, 1)
    return f"{head}{begin}\n{block}\n{end}{tail}"


def rows(young: str | float, names: Sequence[str] = objects.NAMES) -> list[dict]:
    """Run :func:`rest` for each paper object; return one dict of figures per object."""
    out = []
    for name in names:
        row = objects.TABLE_I[name]
        e = row.young if young == "table" else float(young)
        body = objects.load(name, young=e)
        start = time.perf_counter()
        state = rest(body, row.friction)
        elapsed = time.perf_counter() - start
        checks = state.check()
        out.append({
            "name": name, "nodes": body.n_nodes, "young": e, "poisson": row.poisson, "mu": row.friction,
            "contacts": state.n_contacts, "sliding": int(state.sliding.sum()), "sag_mm": 1e3 * state.max_sag,
            "iterations": state.iterations, "time_s": elapsed,
            "residual": max(checks["force_residual"], checks["torque_residual"]),
        })
    return out


def format_table(results: list[dict]) -> str:
    head = ("| object | nodes | E (Pa) | ν | μ | contact nodes | sliding | max sag (mm) | iterations | time (s) "
            "| equilibrium residual |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in results:
        lines.append(f"| {r['name']} | {r['nodes']} | {r['young']:.1e} | {r['poisson']} | {r['mu']} | {r['contacts']} "
                     f"| {r['sliding']} | {r['sag_mm']:.3g} | {r['iterations']} | {r['time_s']:.2f} "
                     f"| {r['residual']:.1e} |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--young", default=str(objects.EFFECTIVE_YOUNG_ESTIMATE),
                        help="Young's modulus in Pa, or 'table' for Table I's printed values (default %(default)s)")
    parser.add_argument("--objects", nargs="*", default=list(objects.NAMES), choices=objects.NAMES)
    parser.add_argument("--into", "--readme", dest="into", type=Path, metavar="FILE",
                        help="rewrite the table between the markers of FILE (docs/physics.md)")
    args = parser.parse_args(argv)
    young = args.young if args.young == "table" else float(args.young)
    print(f"Resting configurations on the table (paper §III-A), Table I weight, ν and μ, "
          f"E = {'Table I' if young == 'table' else f'{young:g} Pa'}; table at z = 0.")
    table = format_table(rows(young, args.objects))
    print(table)
    if args.into is not None:
        args.into.write_text(replace_block(args.into.read_text(encoding="utf-8"), table), encoding="utf-8")
        print(f"wrote the table into {args.into}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
