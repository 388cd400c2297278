"""The named errors a user can catch, in one place (the ground floor: every subpackage imports from here).

Bad input is refused before any solve with a ``ValueError`` subclass whose
message names the quantity, index and value; a computation that cannot go on
raises a ``RuntimeError`` subclass that says why; a result that fails its
contact-law checks raises an ``AssertionError`` subclass.  docs/limits.md lists
every case with its message and its test.

Bad input (``ValueError`` subclasses):

* :class:`MeshError` — :class:`~fem_grasp.mesh.TetMesh` (NaN, folded or flat tetrahedra, pieces, …);
* :class:`SurfaceError` — :mod:`fem_grasp.mesh.scan` (open, non-manifold or self-intersecting scans);
* :class:`MaterialError` — :class:`~fem_grasp.elastic.Body` (E, ν, weight, density, g);
* :class:`SceneError` — scene files and pickup settings, with ``file`` and ``key``; its subclasses
  :class:`DirectionError` (squeeze directions), :class:`ContactNodeError` (contact node indices) and
  :class:`PlacementError` (fingertips that miss the object or start inside it) and :class:`UnitsError` (a mesh
  whose size or density says it is in another length unit);
* :class:`CollinearContactError` — contact sets that leave a rotation free (Theorem 3).

Computations that cannot go on (``RuntimeError`` subclasses): :class:`FrictionError` (the resting
iteration's table slip, eq. 6), :class:`RelaxationFailure` (no static stick/slip state: gross slip),
:class:`TrackingError` (the event tracking), :class:`RestConvergenceError` (the object does not come to
rest on the table), :class:`MainGuardError` (a script that starts worker processes outside
``if __name__ == "__main__":``).

Results that break a contact law (``AssertionError`` subclasses): :class:`RestCheckError`,
:class:`PickupCheckError`.  Output folders that are not ours or not writable: :class:`OutputError`
(an ``OSError``).  ν close to ½: :class:`LockingWarning` (P1 tetrahedra lock); a size or density that
says the mesh is in another unit, run anyway because the scene allows it: :class:`UnitsWarning`.
"""

from __future__ import annotations

__all__ = ["CollinearContactError", "ContactNodeError", "DirectionError", "FrictionError", "LockingWarning",
           "MainGuardError", "MaterialError", "MeshError", "OutputError", "PickupCheckError", "PlacementError", "RelaxationFailure",
           "RestCheckError", "RestConvergenceError", "SceneError", "SurfaceError", "TrackingError", "UnitsError", "UnitsWarning"]


# ------------------------------------------------------------------ bad input
class MeshError(ValueError):
    """A mesh that cannot be used for finite elements."""


class SurfaceError(ValueError):
    """A surface cannot be meshed: not closed, non-manifold, self-intersecting, … (the message says where)."""


class MaterialError(ValueError):
    """A material or load parameter (E, ν, density, weight, g) that no elastic body has."""


class SceneError(ValueError):
    """A scene parameter (friction, squeeze directions, contacts, fingertips) that cannot be simulated.

    Raised for scene files too, whose message then starts with the file and the key; ``file`` and
    ``key`` hold them (None when the error does not come from a scene file).
    """

    def __init__(self, message: str, *, file: str | None = None, key: str | None = None) -> None:
        super().__init__(message)
        self.file = file
        self.key = key


class UnitsError(SceneError):
    """An object whose size or density says its mesh is in another length unit (millimetres read as metres):
    refused before any computation unless the scene allows it (``allow_implausible_units``)."""


class DirectionError(SceneError):
    """A squeeze direction that is zero, non-finite, upward or does not squeeze."""


class ContactNodeError(SceneError):
    """A contact node index that is out of range, repeated or not on the surface."""


class PlacementError(SceneError):
    """A fingertip that misses the object, starts inside it, or goes through the table or the other finger."""


class CollinearContactError(ValueError):
    """The contact set leaves a rigid rotation free (Theorem 3): M is singular."""


class OutputError(OSError):
    """An output folder cannot be used (not ours and not empty, or not writable)."""


# ------------------------------------------------------- computations that stop
class FrictionError(RuntimeError):
    """A slip system has no admissible solution or its solver failed."""


class RelaxationFailure(RuntimeError):
    """No static stick/slip/release state was found (friction cannot hold the contacts: gross slip).

    Parameters
    ----------
    message : what failed, in words
    kind : the verdict's kind, one of :attr:`KINDS`: ``"gross slip"`` (friction cannot hold the contacts: no static
        state), ``"lost support"`` (a contact would move away without bound to carry no force), ``"singular"``
        (a contact's own stiffness block is singular) or ``"non-finite"`` (the sweeps produced NaN or inf)
    contact : the contact the sweeps were at when they stopped, if one is named; on a load with no static state
        which contact the sweep order meets first is decided by round-off, so it is a pointer, not part of the
        verdict
    """

    KINDS = ("gross slip", "lost support", "singular", "non-finite")

    def __init__(self, message: str, kind: str = "gross slip", contact: int | None = None):
        if kind not in self.KINDS:
            raise ValueError(f"unknown relaxation failure kind {kind!r}; expected one of {self.KINDS}")
        super().__init__(message)
        self.kind = kind
        self.contact = contact

    def __reduce__(self):  # pickles (subprocesses, Dask workers) with its kind and contact
        return type(self), (str(self), self.kind, self.contact)


class TrackingError(RuntimeError):
    """The quasi-static tracking cannot go on (no slip solution, lost support, pinched node, …)."""


class MainGuardError(RuntimeError):
    """A call that starts spawned processes (a search's local Dask cluster, the reports' pictures) from a script's
    top level outside ``if __name__ == "__main__":``, where every spawned process would run it again."""


class RestConvergenceError(RuntimeError):
    """The resting iteration did not settle within its iteration budget, or cannot go on."""


# --------------------------------------------------------- results that fail
class RestCheckError(AssertionError):
    """A resting state fails one of its contact-law or equilibrium checks."""


class PickupCheckError(AssertionError):
    """A snapshot fails one of its contact-law or equilibrium checks."""


# ----------------------------------------------------------------- warnings
class LockingWarning(UserWarning):
    """ν close to ½: linear tetrahedra are too stiff (volumetric locking); displacements are underestimated."""


class UnitsWarning(UserWarning):
    """An object whose size or density says its mesh is in another length unit (millimetres read as metres)."""
