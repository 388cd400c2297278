"""fem_grasp: two-finger squeeze-and-lift of soft 3D objects with P1 finite elements.

Implements "Picking up Soft 3D Objects with Two Fingers" (squeeze, lift test
and lift of a deformable body by two rigid hemispherical fingertips).  The core
imports with numpy and scipy alone.
"""

from .body import Body
from .mesh import MeshError, TetMesh, box_mesh
from .response import CollinearContactError, ContactResponse, ContactSolution, solve_contact

__all__ = [
    "Body",
    "CollinearContactError",
    "ContactResponse",
    "ContactSolution",
    "MeshError",
    "TetMesh",
    "box_mesh",
    "solve_contact",
]
__version__ = "0.1.0"
