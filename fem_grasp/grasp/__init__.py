"""Picking the object up with two fingers: Algorithm 1 of the paper (§III), end to end.

1. **force closure** of the initial finger contacts p_i, p_j with the support triangle's centre
   (:mod:`~fem_grasp.grasp.closure`); the contacts themselves come from a placement rule
   (:mod:`~fem_grasp.grasp.placement`), checked before anything is solved;
2. **the resting configuration** (§III-A): the object is posed on a stable facet of its convex hull
   (:mod:`~fem_grasp.grasp.pose`) and sags under gravity while its table contacts grow and slip
   (:func:`rest`);
3. **the squeeze** (§III-C): ℱ₁ translates by ρ d̂₁ and ℱ₂ by s ρ d̂₂ (:mod:`~fem_grasp.grasp.squeeze`);
4. **the lift test** (§III-B) after every increment: the liftable weight w(ρ) with the table removed
   (:mod:`~fem_grasp.grasp.lift_test`);
5. **the lift** once w(ρ) ≥ mg: both fingers rise until the object leaves the table
   (:mod:`~fem_grasp.grasp.lift`);
6. **failure** when the squeeze reaches its maximum depth, or a lift fails and the squeeze resumes.

:func:`pickup` runs the whole algorithm with the grasp's options (:class:`PickupOptions`: friction, fingertip
radius, contacts, squeeze directions and ratio, maximum squeeze and its increment, lift-test step h, lift,
backend, accuracy target) and returns a :class:`PickupResult`; failures are results with
an :attr:`~PickupResult.outcome` (:data:`OUTCOMES`).  :mod:`~fem_grasp.grasp.rigid` is the rigid-body
comparison of Table III, :mod:`~fem_grasp.grasp.objects` the four objects of Table I, and
:mod:`~fem_grasp.grasp.checks` the one contact-law checker every result is held to.

Where to grasp: :mod:`~fem_grasp.grasp.candidates` makes candidate placements and squeezes (step 1 for many
of them) and :mod:`~fem_grasp.grasp.evaluation` runs Algorithm 1 for each on one shared resting state and
factorisation; :mod:`fem_grasp.batch` runs them serially or on a Dask cluster.
"""

from .candidates import Candidate, CandidateSet, placement_candidates
from .closure import ClosureResult, force_closure
from .evaluation import Evaluator, SearchSetup
from .forces import FingerForce
from .lift_test import LiftTest
from .options import PickupOptions
from .pickup import OUTCOMES, LiftAttempt, PickupResult, Snapshot, pickup
from .pose import RestingPose, resting_pose
from .rest import RestState, rest
from .rigid import RigidGrasp, rigid_grasp

__all__ = ["OUTCOMES", "Candidate", "CandidateSet", "ClosureResult", "Evaluator", "FingerForce", "LiftAttempt",
           "LiftTest", "PickupOptions", "PickupResult", "RestState", "RestingPose", "RigidGrasp", "SearchSetup",
           "Snapshot", "force_closure", "pickup", "placement_candidates", "rest", "resting_pose", "rigid_grasp"]
