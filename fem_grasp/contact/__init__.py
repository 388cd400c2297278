"""Frictional contact of the object with the table and the fingertips (paper §III-A and §III-C, eqs. 5–8).

The obstacles are rigid: the table plane 𝒫 and two hemispherical fingertips ℱ₁, ℱ₂
(:mod:`~fem_grasp.contact.obstacles`).  A contact node holds when f·n̂ > 0 and |f − (f·n̂)n̂| ≤ μ f·n̂
(:mod:`~fem_grasp.contact.friction`, the cone law); a sliding node sits on its cone and moves against its
tangential force.  The configuration — which nodes touch ℱ₁, ℱ₂, 𝒫 (𝕀, 𝕁, 𝕂) and which slide (ℙ) — is
followed as a parameter t (squeeze depth, lift height, gravity load) grows, by the
:class:`~fem_grasp.contact.tracking.Tracker`.  One increment t → t + Δt:

1. **held prediction** — every finger contact moves with its finger, table contacts stay; the forces
   follow from eq. (5), F̄ = C Δ̄ + λ F̄₀ (:class:`~fem_grasp.elastic.ContactResponse`);
2. **slip solve** — the sliding nodes slide back onto their cones: eq. (6) on the table, eqs. (7)–(8) on
   the great circles of the fingertips (:mod:`~fem_grasp.contact.slip_system`, Newton's method from the
   held state, the homotopy continuation of paper footnote 2 as fallback,
   :mod:`~fem_grasp.contact.homotopy`);
3. **event test** — A (a free node would penetrate), B (a tensile normal force), C (a sticking force leaves
   its cone), D (a slip rate reaches zero);
4. **locate** — the first event's t, to 1e-10 × the diameter (interpolation safeguarded by regula falsi:
   the paper's "Newton polish");
5. **apply** — the configuration changes there, and cascades at the same t are settled;
6. **implicit fallback** — where the rate problem has no solution (a friction limit, chatter, large
   contact sets), the increment is a return mapping instead: the static stick / slide / release state of
   all contacts at once (:mod:`~fem_grasp.contact.relaxation`, projected Gauss–Seidel finished by Newton).

The resting iteration of §III-A is the same tracking with the gravity load factor as parameter
(:func:`fem_grasp.grasp.rest.rest`).  The inner loops are
compiled by numba when it is installed (:mod:`~fem_grasp.contact.kernels`, :func:`warm_up`): the return
mapping's sweeps and polish, and each trial state's held prediction, slip system (assembly, Newton, homotopy,
read-out) and event functions, with the numpy versions kept as the reference the tests compare.
"""

from ..errors import FrictionError, RelaxationFailure, TrackingError
from .friction import in_cone, is_compressive
from .obstacles import DEFAULT_RADIUS, FINGER1, FINGER2, OBSTACLES, TABLE, Fingertip, TablePlane
from .relaxation import Relaxation, relax_contacts
from .tracking import ContactEvent, ContactState, Tracker, run
from .warm_up import warm_up

__all__ = ["DEFAULT_RADIUS", "FINGER1", "FINGER2", "OBSTACLES", "TABLE", "ContactEvent", "ContactState", "Fingertip",
           "FrictionError", "Relaxation", "RelaxationFailure", "TablePlane", "Tracker", "TrackingError", "in_cone",
           "is_compressive", "relax_contacts", "run", "warm_up"]
