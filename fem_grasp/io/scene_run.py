"""Running a scene as ``fem-grasp run`` does: its body, its resting state (cached, re-solved before use) and
the pickup, with errors about the fingers raised naming the scene file and its key.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import SceneError

__all__ = ["pickup_scene"]

log = logging.getLogger(__name__)

if TYPE_CHECKING:
    from ..grasp.pickup import PickupResult
    from ..mesh.tetmesh import TetMesh
    from .scene import Scene


def pickup_scene(scene: Scene, cache_dir: Path | None = None, phase: Any = None) -> tuple["PickupResult", bool]:
    """Run a scene as ``fem-grasp run`` does: its body (mesh cached in ``cache_dir``), its resting state (cached,
    re-solved before use), then :func:`~fem_grasp.grasp.pickup.pickup` with its settings.

    ``phase``, when given, is called with a phase name ("meshing the object", "resting on the table",
    "squeeze, lift test, lift") and returns a context manager around that phase (the CLI's progress bar).
    Errors about the fingers (contact nodes, placement, squeeze directions) are raised naming the scene file
    and its key.  ``result.timings["rest"]`` is the time the resting state took (to solve or to check from the
    cache; refined, the last level's).  Returns (result, whether its resting state came from the cache).
    """
    import contextlib
    import time

    from ..grasp.pickup import pickup
    from .cache import cached_rest

    step = phase if phase is not None else (lambda name: contextlib.nullcontext())
    with step("meshing the object"):
        body = scene.body(cache_dir)
        _check_contacts(scene, body.mesh)
    t0 = time.perf_counter()
    with step("resting on the table"):
        rs, cached = cached_rest(body, scene.mu_table, backend=scene.backend, down=scene.object.down,
                                 cache_dir=cache_dir)
    t_rest = time.perf_counter() - t0
    refine = scene.accuracy is not None and not scene.quick
    geometry, no_geometry = (_geometry(scene, body.mesh) if refine else (None, ""))
    refine = refine and geometry is not None
    with step("squeeze and lift, refining" if refine else "squeeze, lift test, lift"):
        try:
            options = scene.pickup_options()
            if refine:
                result = pickup(body, options.replace(accuracy=scene.accuracy, geometry=geometry), rest_state=rs)
            else:
                result = pickup(body, options, rest_state=rs)
                from ..grasp.accuracy import single_run_report

                # One run, always said so: not converged; the scene states how far such a run is from the converged
                # answer (its solver.expected_error, measured by the convergence study), or nothing is known.
                result.accuracy = single_run_report(
                    result, scene.accuracy, scene.expected_error,
                    "--quick: one run on the coarse mesh, no refinement" if scene.quick else
                    no_geometry or "one run on the scene's mesh (accuracy off)",
                    refinable=not (scene.quick or no_geometry))
        except SceneError as exc:
            raise _in_scene(scene, exc) from None
    if refine:  # the result is the last level's, whose resting state the loop solved (its timings say how long)
        return result, False
    result.timings["rest"] = t_rest
    result.timings["total"] = result.timings.get("total", 0.0) + t_rest
    return result, cached


def _geometry(scene: Scene, mesh: "TetMesh") -> tuple[Any, str]:
    """What the accuracy loop remeshes (the scene's geometry, else the mesh's boundary) and "", or None and why
    it cannot refine: without gmsh (a core install), or for a volume mesh whose boundary is not a closed manifold
    surface, the scene is run once on its mesh, and its answer says so."""
    from ..errors import MissingExtraError, require
    from ..mesh.remesh import NoGeometryError, geometry_of_mesh

    try:
        require("gmsh", "mesh", f"refining the answer to {100 * scene.accuracy:g} %", load=False)
        geometry = scene.geometry()
        return (geometry, "") if geometry is not None else (geometry_of_mesh(mesh), "")
    except (MissingExtraError, NoGeometryError) as exc:
        log.warning("%s: one run on the scene's mesh, not refined: %s", scene.name, exc)
        return None, f"one run on the scene's mesh, not refined: {exc}"


def _check_contacts(scene: Scene, mesh: "TetMesh") -> None:
    """Node indices given in the scene exist and lie on the surface (else a SceneError naming the file and key)."""
    if scene.contacts is None:
        return
    src = scene.path or "<scene>"
    surface = set(mesh.surface_nodes.tolist())
    for k in scene.contacts:
        if k >= mesh.n_points:
            raise SceneError(f"{src}: fingers.contacts: node {k} does not exist (the mesh has {mesh.n_points} nodes, "
                             f"0 … {mesh.n_points - 1}); with --quick the mesh differs, use contacts = \"auto\"",
                             file=str(src), key="fingers.contacts")
        if k not in surface:
            raise SceneError(f"{src}: fingers.contacts: node {k} is not on the surface of the mesh",
                             file=str(src), key="fingers.contacts")


#: The scene key an error about the fingers is about.
_ERROR_KEYS = {"DirectionError": "fingers.directions", "ContactNodeError": "fingers.contacts",
               "PlacementError": "fingers.contacts"}


def _in_scene(scene: Scene, exc: SceneError) -> SceneError:
    """``exc`` (raised by pickup() for the scene's settings) again, its message starting with the file and key."""
    if exc.file is not None:
        return exc
    src = str(scene.path) if scene.path is not None else "<scene>"
    key = _ERROR_KEYS.get(type(exc).__name__, "fingers")
    how = "" if scene.contacts is not None or key != "fingers.contacts" else \
        f" (contacts chosen by the rule {scene.placement_rule!r})"
    return type(exc)(f"{src}: {key}{how}: {exc}", file=src, key=key)
