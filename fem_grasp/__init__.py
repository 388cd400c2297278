"""fem_grasp: two-finger squeeze-and-lift of soft 3D objects with P1 finite elements.

Implements *Picking up Soft 3D Objects with Two Fingers* (squeeze, lift test and lift of a deformable
body by two rigid hemispherical fingertips).  The subpackages follow the paper and import one way,
``mesh`` < ``elastic`` < ``contact`` < ``grasp`` < ``io`` < ``batch``: meshes, the linear elasticity of §II,
the frictional contact of §III-A/C, Algorithm 1 of §III, files, and many pickups at once (:func:`search`,
where to grasp).  The core imports with numpy and scipy
alone; ``fem_grasp.objects``, ``fem_grasp.shapes`` and the other modules below load on first use.

A scene in one line, the same answer as ``fem-grasp run tomato --young "15 kPa"``::

    import fem_grasp
    result = fem_grasp.run_scene("tomato", young="15 kPa")      # or Scene.load("tomato").with_(...).run()
"""

from __future__ import annotations

import importlib
from typing import Any

from . import _version, contact, elastic, errors, grasp, io, mesh
from .contact import ContactEvent, ContactState, Fingertip, TablePlane
from .elastic import Body, ContactResponse, ContactSolution, solve_contact
from .errors import (
    CollinearContactError,
    ContactNodeError,
    DirectionError,
    FrictionError,
    LockingWarning,
    MaterialError,
    MeshError,
    PlacementError,
    RestCheckError,
    RestConvergenceError,
    SceneError,
    TrackingError,
)
from .grasp import (
    ClosureResult,
    PickupOptions,
    PickupResult,
    RestingPose,
    RestState,
    RigidGrasp,
    Snapshot,
    force_closure,
    pickup,
    rest,
    resting_pose,
    rigid_grasp,
)
from .io import Scene, run_scene
from .mesh import TetMesh, box_mesh
from .settings import EngineSettings

#: The installed distribution's version (:mod:`importlib.metadata`), or a source tree's ``pyproject.toml``.
__version__ = _version.version()

#: Modules reachable as attributes of the package, imported on first use (``fem_grasp.objects.load(...)``).
_LAZY = {"objects": "fem_grasp.grasp.objects", "placement": "fem_grasp.grasp.placement",
         "shapes": "fem_grasp.mesh.shapes", "scan": "fem_grasp.mesh.scan", "scene": "fem_grasp.io.scene",
         "output": "fem_grasp.io.output", "report": "fem_grasp.io.report", "batch": "fem_grasp.batch"}

__all__ = ["Body", "ClosureResult", "CollinearContactError", "ContactEvent", "ContactNodeError", "ContactResponse",
           "ContactSolution", "ContactState", "DirectionError", "EngineSettings", "Fingertip", "FrictionError", "LockingWarning",
           "MaterialError", "MeshError", "PickupOptions", "PickupResult", "PlacementError", "RestCheckError",
           "RestConvergenceError", "RestState", "RestingPose", "RigidGrasp", "Scene", "SceneError", "Snapshot", "TablePlane", "TetMesh",
           "TrackingError", "box_mesh", "contact", "elastic", "errors", "force_closure", "grasp", "io", "mesh",
           "pickup", "rest", "resting_pose", "rigid_grasp", "run_scene", "search", "solve_contact", *_LAZY]


def search(scene: Any, out: Any = None, **kwargs: Any) -> Any:
    """Where to grasp: Algorithm 1 for many finger placements of one object, serially or on a Dask cluster.

    :func:`fem_grasp.batch.engine.search` (imported on first use; needs the ``search`` extra), which documents
    the arguments: ``fem_grasp.search("tomato", "out/search", candidates=64, workers=2)``.

    Its worker processes (and the report's pictures) are spawned and import the calling script: in a script,
    call it under ``if __name__ == "__main__":`` (else :class:`~fem_grasp.errors.MainGuardError`, before
    anything starts).
    """
    from .batch.engine import search as run

    return run(scene, out, **kwargs)


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        module = importlib.import_module(_LAZY[name])
        globals()[name] = module
        return module
    raise AttributeError(f"module 'fem_grasp' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
