"""Sweep: how the squeeze depth and the finger forces depend on Young's modulus E and the friction μ.

Runs a shipped scene over a grid of (E, μ) and returns one row per run as a pandas DataFrame;
``python examples/sweep.py [SCENE] [--full] [--youngs E ...] [--mus MU ...] [--no-lift] [--out DIR]`` prints it
and writes sweep.csv.
"""

from __future__ import annotations

import argparse
import itertools
from pathlib import Path

import pandas as pd

import fem_grasp


def sweep(scene="foam_block", youngs=("10 kPa", "20 kPa", "40 kPa"), mus=(0.4, 0.6), quick=True, lift=True):
    rows = []
    for young, mu in itertools.product(youngs, mus):
        r = fem_grasp.run_scene(scene, quick=quick, young=young, mu=mu, lift=lift)  # = `fem-grasp run`
        f1, f2 = r.finger_forces or (None, None)
        rows.append({"E (Pa)": r.body.young, "mu": mu, "picked up": r.success, "rho (mm)": 1e3 * r.squeeze_depth,
                     "contacts": r.n_final_contacts, "sum f.n (N)": r.finger_normal_force,
                     "grip 1 (N)": f1.grip if f1 else None, "grip 2 (N)": f2.grip if f2 else None,
                     "events": len(r.events), "outcome": r.outcome})
    return pd.DataFrame(rows)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene", nargs="?", default="foam_block")
    ap.add_argument("--full", action="store_true", help="the scene's full mesh instead of its quick variant")
    ap.add_argument("--youngs", nargs="+", default=["10 kPa", "20 kPa", "40 kPa"], help="moduli, e.g. '20 kPa'")
    ap.add_argument("--mus", nargs="+", type=float, default=[0.4, 0.6], help="friction, fingers and table")
    ap.add_argument("--no-lift", action="store_true", help="stop when the lift test passes (quicker)")
    ap.add_argument("--out", type=Path, default=Path("out/sweep"))
    args = ap.parse_args(argv)
    table = sweep(args.scene, args.youngs, args.mus, quick=not args.full, lift=not args.no_lift)
    print(table.to_string(index=False))
    args.out.mkdir(parents=True, exist_ok=True)
    table.to_csv(args.out / "sweep.csv", index=False)


if __name__ == "__main__":
    main()
