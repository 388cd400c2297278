"""fem_grasp: two-finger squeeze-and-lift of soft 3D objects with P1 finite elements.

Implements "Picking up Soft 3D Objects with Two Fingers" (squeeze, lift test
and lift of a deformable body by two rigid hemispherical fingertips).  The core
imports with numpy and scipy alone.
"""

from .contact import friction
from .contact import obstacles
from .grasp import pose
from .elastic.body import Body
from .contact.obstacles import Fingertip
from .contact.friction import FrictionError
from .contact.obstacles import TablePlane
from .mesh.tetmesh import MeshError, TetMesh, box_mesh
from .grasp.pose import RestingPose, resting_pose
from .elastic.response import CollinearContactError, ContactResponse, ContactSolution, solve_contact
from .grasp.rest import RestCheckError, RestConvergenceError, RestState, rest

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
from .grasp.closure import ClosureResult, force_closure  # noqa: E402
from .grasp.pickup import PickupResult, Snapshot, pickup  # noqa: E402
from .grasp.rigid import RigidGrasp, rigid_grasp  # noqa: E402
from .contact.tracking import ContactEvent, ContactState, TrackingError  # noqa: E402

__all__ += ["ClosureResult", "ContactEvent", "ContactState", "PickupResult", "RigidGrasp", "Snapshot",
            "TrackingError", "force_closure", "pickup", "rigid_grasp"]

# Input validation (issue #8): the named errors a user can catch.
from .validation import (ContactNodeError, DirectionError, LockingWarning, MaterialError,  # noqa: E402
                         PlacementError, SceneError)

__all__ += ["ContactNodeError", "DirectionError", "LockingWarning", "MaterialError", "PlacementError", "SceneError"]

