"""Tetrahedral meshes: the data type, gmsh solids, and scans (paper §II-B's "tetrahedral mesh with n vertices").

* :mod:`~fem_grasp.mesh.tetmesh` — :class:`TetMesh`, immutable and validated on construction (no NaN, no
  folded or flat tetrahedra, one manifold solid), its surface, volumes and outward vertex normals;
  :func:`box_mesh` needs no mesher;
* :mod:`~fem_grasp.mesh.shapes` — gmsh solids: ellipsoids, domes, fused spheres and the paper's four objects
  of Table I at a given vertex count, graded where the fingertips touch (:class:`Refinement`);
* :mod:`~fem_grasp.mesh.scan` — a closed triangle surface (STL, OBJ, PLY) checked and filled with tetrahedra;
* :mod:`~fem_grasp.mesh.gmsh_session` — the one deterministic gmsh session both use;
* :mod:`~fem_grasp.mesh.remesh` — geometries meshed afresh at any spacing, graded at contact patches;
  :mod:`~fem_grasp.mesh.bisection` — a mesh refined in place by longest-edge bisection (nested levels);
* :mod:`~fem_grasp.mesh.units` — the length unit of a mesh file (scans in mm), and warnings naming the likely
  unit when an object's size or density is implausible.

gmsh is optional: everything but meshing works without it.
"""

from .scan import SurfaceError, check_surface, mesh_surface, read_surface
from .shapes import Refinement, dome, ellipsoid, fused_spheres, paper_mesh
from .tetmesh import MeshError, TetMesh, box_mesh, vertex_normals

__all__ = ["MeshError", "Refinement", "SurfaceError", "TetMesh", "box_mesh", "check_surface", "dome", "ellipsoid",
           "fused_spheres", "mesh_surface", "paper_mesh", "read_surface", "vertex_normals"]
