"""Linear elasticity of the object (paper §II): stiffness, gravity, rigid modes and the contact response.

1. :mod:`~fem_grasp.elastic.fem` — P1 tetrahedra: the stiffness K of eq. (2), vectorised over elements,
   the lumped gravity loads G of §II-B and the six rigid modes of Theorem 1 (pure functions of arrays);
2. :class:`Body` — a mesh with E, ν and a weight: K, G, the mass and centre of mass, cached on first use;
3. :mod:`~fem_grasp.elastic.compliance` and :mod:`~fem_grasp.elastic.spectral` — the two ways to solve
   eq. (3): a sparse generalised inverse of K (factorised once, columns cached per contact node; CHOLMOD
   called directly by :mod:`~fem_grasp.elastic.cholmod`), or the paper's dense eigendecomposition K = VΛVᵀ;
4. :class:`ContactResponse` — for a contact index set ℂ, the reduced stiffness C of eq. (5),
   F̄ = C(Δ̄ − D̄) + mg e/√n, and the displacement field of eq. (4); :func:`solve_contact` does one solve.

Contact forces and gravity balance in force and torque to round-off (:func:`equilibrium_residual`).
:mod:`~fem_grasp.elastic.fields` turns a displacement into what a mechanician reads: strains, stresses,
the von Mises stress and the strain energy density per element, and the displacement less its rigid motion.
"""

from .body import Body
from .fem import STANDARD_GRAVITY
from .response import (
                       CollinearContactError,
                       ContactResponse,
                       ContactSolution,
                       check_contact_set,
                       equilibrium_residual,
                       solve_contact,
)

__all__ = ["Body", "CollinearContactError", "ContactResponse", "ContactSolution", "STANDARD_GRAVITY",
           "check_contact_set", "equilibrium_residual", "solve_contact"]
