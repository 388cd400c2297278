"""gmsh meshes graded at one point, and Hertz's force law: what the two indentation set-ups share."""

from __future__ import annotations

from typing import Callable

import numpy as np

from fem_grasp import TetMesh


def graded_mesh(add_geometry: Callable[[object], None], point: tuple[float, float, float], near_size: float,
                far_size: float, refine_radius: float, seed: int = 1) -> TetMesh:
    """gmsh tetrahedra of the solid that ``add_geometry(gmsh.model.occ)`` builds, with edge length ``near_size``
    within ``refine_radius`` of ``point``, growing linearly to ``far_size`` at twice that distance.

    ``seed`` is gmsh's random seed: meshes of the same sizes with other seeds differ only in where the nodes fall.
    """
    import gmsh

    gmsh.initialize([], False)
    try:
        for key, val in {"General.Terminal": 0, "General.NumThreads": 1, "Mesh.RandomSeed": seed,
                         "Mesh.MeshSizeExtendFromBoundary": 0, "Mesh.MeshSizeFromPoints": 0,
                         "Mesh.MeshSizeFromCurvature": 0, "Mesh.Algorithm": 6, "Mesh.Algorithm3D": 1,
                         "Mesh.Optimize": 1}.items():
            gmsh.option.setNumber(key, val)
        gmsh.model.add("graded")
        occ = gmsh.model.occ
        add_geometry(occ)
        occ.synchronize()
        centre = occ.addPoint(*point)
        occ.synchronize()
        fields = gmsh.model.mesh.field
        dist = fields.add("Distance")
        fields.setNumbers(dist, "PointsList", [centre])
        thr = fields.add("Threshold")
        fields.setNumber(thr, "InField", dist)
        fields.setNumber(thr, "SizeMin", near_size)
        fields.setNumber(thr, "SizeMax", far_size)
        fields.setNumber(thr, "DistMin", refine_radius)
        fields.setNumber(thr, "DistMax", 2.0 * refine_radius)
        fields.setAsBackgroundMesh(thr)
        gmsh.model.mesh.generate(3)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        _, elem_nodes = gmsh.model.mesh.getElementsByType(4)
    finally:
        gmsh.finalize()
    points = coords.reshape(-1, 3)
    lookup = np.zeros(int(tags.max()) + 1, dtype=np.int64)
    lookup[tags.astype(np.int64)] = np.arange(len(tags))
    tets = lookup[elem_nodes.astype(np.int64)].reshape(-1, 4)
    used, tets = np.unique(tets, return_inverse=True)
    return TetMesh(points[used], tets.reshape(-1, 4))


def hertz_force(delta: np.ndarray | float, radius: float, young: float, poisson: float) -> np.ndarray:
    """Hertz's load F = (4/3) E* R^½ δ^3/2, E* = E / (1 − ν²): an elastic sphere pressed by δ onto a rigid plane,
    or a rigid sphere pressed by δ into an elastic half-space."""
    e_star = young / (1.0 - poisson**2)
    return 4.0 / 3.0 * e_star * np.sqrt(radius) * np.asarray(delta, dtype=float) ** 1.5
