"""fem_grasp: two-finger squeeze-and-lift of soft 3D objects with P1 finite elements.

Implements "Picking up Soft 3D Objects with Two Fingers" (squeeze, lift test
and lift of a deformable body by two rigid hemispherical fingertips).  The core
imports with numpy and scipy alone.
"""

from . import friction, geometry, pose
from .body import Body
from .fingertip import Fingertip
from .friction import FrictionError
from .geometry import TablePlane
from .mesh import MeshError, TetMesh, box_mesh
from .pose import RestingPose, resting_pose
from .response import CollinearContactError, ContactResponse, ContactSolution, solve_contact
from .rest import RestCheckError, RestConvergenceError, RestState, rest

__all__ = [
    "Body",
    "CollinearContactError",
    "ContactResponse",
    "ContactSolution",
    "Fingertip",
    "FrictionError",
    "MeshError",
    "RestCheckError",
    "RestConvergenceError",
    "RestState",
    "RestingPose",
    "TablePlane",
    "TetMesh",
    "box_mesh",
    "friction",
    "geometry",
    "pose",
    "rest",
    "resting_pose",
    "solve_contact",
]
__version__ = "0.1.0"

# Algorithm 1 (issue #5): force closure, squeeze, lift test, lift, pickup, rigid comparison.
from .closure import ClosureResult, force_closure  # noqa: E402
from .pickup import PickupResult, Snapshot, pickup  # noqa: E402
from .rigid import RigidGrasp, rigid_grasp  # noqa: E402
from .tracking import ContactEvent, ContactState, TrackingError  # noqa: E402

__all__ += ["ClosureResult", "ContactEvent", "ContactState", "PickupResult", "RigidGrasp", "Snapshot",
            "TrackingError", "force_closure", "pickup", "rigid_grasp"]

# Input validation (issue #8): the named errors a user can catch.
from .validation import (ContactNodeError, DirectionError, LockingWarning, MaterialError,  # noqa: E402
                         PlacementError, SceneError)

__all__ += ["ContactNodeError", "DirectionError", "LockingWarning", "MaterialError", "PlacementError", "SceneError"]

