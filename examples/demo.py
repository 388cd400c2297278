"""Demo: a paper object held at three low nodes and squeezed 2 mm by two finger nodes, under gravity.

Prints the contact forces and equilibrium residuals and writes a VTU that
ParaView opens (displacement and contact-force point data).  Run with
`make demo` or `python examples/demo.py --object tomato --out out`.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np

from fem_grasp import solve_contact
from fem_grasp.grasp import objects, placement


def run(name: str = "tomato", young: float = objects.EFFECTIVE_YOUNG_ESTIMATE, squeeze: float = 2e-3,
        out: Path | None = None, backend: str = "sparse") -> dict:
    body = objects.load(name, young=young)
    support = placement.spread_triple(body.mesh.points, placement.lowest_nodes(body.mesh))
    fingers = placement.finger_contact_nodes(body.mesh, body.center_of_mass[2])
    nodes = np.concatenate([support, fingers])
    disp = np.zeros((len(nodes), 3))
    disp[3:] = squeeze * np.array(placement.PAPER_SQUEEZE_DIRECTIONS)
    sol = solve_contact(body, nodes, disp, backend=backend)
    force_res, torque_res = sol.equilibrium_residual()

    print(f"{name}: {body.n_nodes} nodes, {body.mesh.n_tets} tets, weight {body.weight:.3f} N, "
          f"E = {young:.3g} Pa, nu = {body.poisson}, squeeze {squeeze * 1e3:.1f} mm along d1, d2")
    print(f"{'role':8s} {'node':>5s} {'fx [N]':>9s} {'fy [N]':>9s} {'fz [N]':>9s}")
    for role, k, f in zip(["table"] * 3 + ["finger1", "finger2"], nodes, sol.forces):
        print(f"{role:8s} {k:5d} {f[0]:9.4f} {f[1]:9.4f} {f[2]:9.4f}")
    print(f"sum of contact forces {sol.forces.sum(axis=0).round(12)} N balances weight {body.weight:.4f} N; "
          f"relative residual force {force_res:.1e}, torque {torque_res:.1e}")
    print(f"max displacement {np.linalg.norm(sol.displacements, axis=1).max() * 1e3:.2f} mm, "
          f"strain energy {sol.strain_energy:.3e} J")
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        force_field = np.zeros_like(sol.displacements)
        force_field[nodes] = sol.forces
        path = out / f"{name}_contact.vtu"
        body.mesh.write(path, point_data={"displacement": sol.displacements, "contact_force": force_field})
        print(f"wrote {path} (open in ParaView; warp by 'displacement', glyph 'contact_force')")
    return dict(forces=sol.forces, residual=(force_res, torque_res), solution=sol)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--object", default="tomato", choices=objects.NAMES)
    ap.add_argument("--young", type=float, default=objects.EFFECTIVE_YOUNG_ESTIMATE, help="Young's modulus, Pa")
    ap.add_argument("--squeeze", type=float, default=2e-3, help="finger displacement along d1, d2, metres")
    ap.add_argument("--backend", default="sparse", choices=["sparse", "spectral"])
    ap.add_argument("--out", type=Path, default=None, help="folder for the VTU file")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    run(args.object, args.young, args.squeeze, args.out, args.backend)


if __name__ == "__main__":
    main()
