"""Benchmark meshes: the paper's orange at a range of vertex counts, generated once with gmsh and cached.

gmsh takes seconds to minutes per mesh at 50k–100k vertices, so each mesh is
stored as ``bench/out/meshes/<name>_<target>.npz`` and reused by later runs
(delete the folder to regenerate).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from fem_grasp.mesh.tetmesh import TetMesh

log = logging.getLogger(__name__)

CACHE = Path(__file__).resolve().parent / "out" / "meshes"


def cached_mesh(name: str, target_vertices: int, cache: Path = CACHE) -> TetMesh:
    """``fem_grasp.mesh.shapes.paper_mesh(name, target_vertices)``, cached on disk."""
    path = cache / f"{name}_{int(target_vertices)}.npz"
    if path.exists():
        with np.load(path) as data:
            return TetMesh(data["points"], data["tets"])
    from fem_grasp.mesh.shapes import paper_mesh

    mesh = paper_mesh(name, target_vertices)
    cache.mkdir(parents=True, exist_ok=True)
    np.savez(path, points=mesh.points, tets=mesh.tets)
    log.info("cached %s (%d vertices) in %s", name, mesh.n_points, path)
    return mesh


if __name__ == "__main__":  # pre-build: python -m bench.meshes 1000 3000 ...
    import sys

    logging.basicConfig(level=logging.INFO)
    for t in sys.argv[1:]:
        m = cached_mesh("orange", int(t))
        print(t, m.n_points, m.n_tets, flush=True)
