"""Demo: a scene file from Python — load, pick up, check, write the ParaView series and the report.

The same as ``fem-grasp run tomato --quick --out out/tomato_py --report``; run with
``python examples/scene_demo.py [SCENE] [--full] [--out DIR] [--no-report]``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from fem_grasp import Scene
from fem_grasp.io.output import write_run


def run(scene_name: str = "tomato", quick: bool = True, out: Path | None = None, report: bool = True,
        lift: bool = True):
    scene = Scene.load(scene_name, quick=quick).with_(lift=lift)  # a shipped scene or your own .toml
    result = scene.run()  # Algorithm 1 as `fem-grasp run` does it: rest, squeeze + lift test, lift
    result.check()  # equilibrium, non-penetration, Coulomb on every snapshot (raises if violated)
    print(f"{scene.name}: {'picked up' if result.success else 'not picked up: ' + result.reason}; "
          f"rho = {result.squeeze_depth * 1e3:.2f} mm, {len(result.events)} events, "
          f"finger normal force (Table III's Σ f·n̂) {result.finger_normal_force:.3f} N")
    for k, f in enumerate(result.finger_forces or (), start=1):
        print(f"  finger {k}: |resultant| {f.magnitude:.3f} N, grip {f.grip:.3f} N, carries {f.vertical:.3f} N")
    if out is not None:
        write_run(out, result, scene)  # result.json + object.pvd, finger1/2.pvd, table.vtu
        if report:
            from fem_grasp.io.report import write_report

            print("report:", write_report(out))
    return result


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene", nargs="?", default="tomato")
    ap.add_argument("--full", action="store_true", help="the full mesh instead of the quick variant")
    ap.add_argument("--out", type=Path, default=Path("out/scene_demo"))
    ap.add_argument("--no-report", action="store_true")
    args = ap.parse_args(argv)
    run(args.scene, not args.full, args.out, not args.no_report)


if __name__ == "__main__":
    main()
