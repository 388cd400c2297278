"""Spectral (paper, eqs. 3-5 literally) against sparse backend on the four paper objects.

Prints agreement and wall times and writes bench/out/spectral_vs_sparse.json.
Run with `make spectral-vs-sparse`.  Each backend starts from a fresh Body, so
its time includes everything it needs (eigendecomposition or factorisation).
"""

from __future__ import annotations

import json
import platform
import time
from pathlib import Path

import numpy as np

from fem_grasp import solve_contact
from fem_grasp.grasp import objects, placement


def demo_contacts(body) -> tuple[np.ndarray, np.ndarray]:
    """Three low support nodes plus two finger nodes at the centre-of-mass height, squeezed 1 mm along d̂1, d̂2."""
    support = placement.spread_triple(body.mesh.points, placement.lowest_nodes(body.mesh))
    fingers = placement.finger_contact_nodes(body.mesh, body.center_of_mass[2])
    nodes = np.concatenate([support, fingers])
    disp = np.zeros((5, 3))
    disp[3:] = 1e-3 * np.array(placement.PAPER_SQUEEZE_DIRECTIONS)
    return nodes, disp


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / np.abs(b).max())


def main() -> dict:
    rows = []
    for name in objects.NAMES:
        nodes, disp = demo_contacts(objects.load(name))
        sols, times = {}, {}
        for backend in ("spectral", "sparse"):
            body = objects.load(name)  # fresh: nothing cached
            t0 = time.perf_counter()
            sols[backend] = solve_contact(body, nodes, disp, backend=backend)
            times[backend] = time.perf_counter() - t0
        eq = max(sols["sparse"].equilibrium_residual() + sols["spectral"].equilibrium_residual())
        rows.append(dict(object=name, vertices=body.n_nodes, contacts=len(nodes),
                         force_rel_diff=rel(sols["sparse"].forces, sols["spectral"].forces),
                         field_rel_diff=rel(sols["sparse"].displacements, sols["spectral"].displacements),
                         equilibrium=eq, spectral_s=times["spectral"], sparse_s=times["sparse"],
                         speedup=times["spectral"] / times["sparse"]))
    print(f"{'object':10s} {'vertices':>8s} {'|dF|/|F|':>9s} {'|dU|/|U|':>9s} {'equil.':>8s} "
          f"{'spectral s':>10s} {'sparse s':>9s} {'ratio':>6s}")
    for r in rows:
        print(f"{r['object']:10s} {r['vertices']:8d} {r['force_rel_diff']:9.1e} {r['field_rel_diff']:9.1e} "
              f"{r['equilibrium']:8.1e} {r['spectral_s']:10.2f} {r['sparse_s']:9.3f} {r['speedup']:6.0f}")
    out = dict(machine=f"{platform.machine()} {platform.processor() or ''} cores={__import__('os').cpu_count()}",
               python=platform.python_version(), numpy=np.__version__, rows=rows)
    path = Path("bench/out/spectral_vs_sparse.json")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=2))
    print(f"wrote {path}")
    return out


if __name__ == "__main__":
    main()
