"""Small meshes for tests, made without a mesher."""

import numpy as np

from fem_grasp import TetMesh, box_mesh


def perturbed_box(rng, divisions=(3, 3, 3), amount=0.15):
    """A box whose interior nodes are jiggled: irregular tets without a mesher."""
    m = box_mesh((0, 0, 0), (0.03, 0.02, 0.025), divisions)
    p = m.points.copy()
    interior = np.setdiff1d(np.arange(m.n_points), m.surface_nodes)
    h = 0.02 / max(divisions)
    p[interior] += amount * h * rng.uniform(-1, 1, (len(interior), 3))
    return TetMesh(p, m.tets)
