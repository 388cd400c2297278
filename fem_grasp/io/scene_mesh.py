"""The object of a scene as a mesh: a paper shape, a volume mesh or a surface scan in its length unit (remeshed
with gmsh and cached when asked), or a box; a mesh file whose size or density says that its unit is wrong is
refused before anything is computed.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import MeshError, SceneError

__all__ = ["check_units", "scene_mesh"]

if TYPE_CHECKING:
    from ..mesh.tetmesh import TetMesh
    from .scene import Scene

log = logging.getLogger(__name__)


def scene_mesh(scene: Scene, cache_dir: Path | None = None) -> "TetMesh":
    """The :class:`~fem_grasp.mesh.TetMesh` of the scene's object (gmsh meshes are cached in ``cache_dir``):
    :meth:`Scene.load_mesh <fem_grasp.io.scene.Scene.load_mesh>`."""
    from ..mesh.tetmesh import TetMesh, box_mesh
    from .cache import cached_mesh, digest

    spec = scene.object
    if spec.kind == "box":
        lx, ly, lz = spec.box
        return box_mesh((-lx / 2, -ly / 2, 0.0), (lx / 2, ly / 2, lz), spec.divisions)
    if spec.kind == "paper":
        if spec.vertices is None:
            from ..grasp import objects

            return objects.load_mesh(spec.paper)
        from ..mesh.shapes import PAPER_SHAPES

        # the shape's spec is in the key: a changed stand-in shape must not be served from the cache
        return cached_mesh(cache_dir, ("paper", spec.paper, spec.vertices, PAPER_SHAPES[spec.paper]),
                            lambda: _paper_mesh(spec.paper, spec.vertices))
    path = spec.mesh
    from ..mesh import scan
    from ..mesh.units import LENGTH_UNITS

    scale = LENGTH_UNITS[spec.units]
    data = path.read_bytes()
    if path.suffix.lower() in scan.SURFACE_SUFFIXES:
        def surface() -> "TetMesh":
            surf = scan.read_surface(path, spec.units)
            return scan.mesh_surface(surf, target_vertices=spec.vertices, size=spec.size)

        return cached_mesh(cache_dir, ("surface", digest(data), spec.vertices, spec.size, spec.units), surface)
    try:
        volume = TetMesh.from_file(path)
    except MeshError:
        raise
    except Exception as exc:  # meshio raises many types for unreadable files
        raise SceneError(f"{scene.path or '<scene>'}: object.mesh: cannot read {path} as a volume mesh "
                         f"({type(exc).__name__}: {exc})", file=None if scene.path is None else str(scene.path),
                         key="object.mesh") from None
    if scale != 1.0:
        volume = TetMesh(volume.points * scale, volume.tets)
    if spec.vertices is None and spec.size is None:
        return volume
    # object.vertices / object.size on a volume mesh: remesh the solid its boundary encloses (gmsh)
    log.info("%s: remeshing the volume mesh's boundary at %s", path,
             f"about {spec.vertices} vertices" if spec.vertices else f"size {spec.size:g} m")
    boundary = scan.Surface(volume.points, volume.surface_faces, str(path))
    return cached_mesh(cache_dir, ("volume", digest(data), spec.vertices, spec.size, spec.units),
                       lambda: scan.mesh_surface(boundary, target_vertices=spec.vertices, size=spec.size))


def check_units(scene: Scene, mesh: "TetMesh") -> None:
    """Refuse a mesh whose size or density says it is in another length unit (:class:`UnitsError`, before
    anything is computed), or warn (:class:`~fem_grasp.errors.UnitsWarning`) when the scene allows it."""
    from ..errors import UnitsError
    from ..mesh.units import density_warning, implausible, size_warning, warn_implausible

    spec = scene.object
    mass = None if scene.weight is None else scene.weight / scene.gravity
    problems, guess = implausible(mesh.diameter, mesh.volume, mass, spec.units)
    if not problems:
        return
    src = f"{scene.path or '<scene>'}: object.mesh ({spec.mesh.name})"
    if spec.allow_implausible_units:
        warn_implausible(size_warning(mesh.diameter, spec.units, src, hint="object.units"))
        if mass is not None:
            warn_implausible(density_warning(mass, mesh.volume, spec.units, src, hint="object.units"))
        return
    names = {"m": "metres", "cm": "centimetres", "mm": "millimetres"}
    fix = (f"the file is probably in {names[guess]}: set units = \"{guess}\" in the scene's [object] table "
           f"(Python: scene.with_(units=\"{guess}\"))" if guess is not None else
           "check the unit of the mesh (object.units = \"mm\" or \"cm\") and the weight, mass or density")
    read = f"read in {names[spec.units]}"
    file = None if scene.path is None else str(scene.path)
    raise UnitsError(
        f"{src}: {read}, {' and '.join(problems)}; {fix}. Nothing was computed, as squeeze depths and forces of "
        "an object in the wrong unit mean nothing. If the object really is so, run it anyway with "
        "--allow-implausible-units (scene: allow_implausible_units = true in [object]; Python: "
        "allow_implausible_units=True)", file=file, key="object.units")


def _paper_mesh(name: str, vertices: int) -> "TetMesh":
    from ..mesh import shapes

    return shapes.paper_mesh(name, vertices)
