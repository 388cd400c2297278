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
  whose size or density says it is in another length unit), :class:`SearchError` (a placement search that cannot
  run as asked) and its :class:`SchedulerError` (a Dask scheduler out of reach or without workers);
* :class:`CollinearContactError` — contact sets that leave a rotation free (Theorem 3).

Computations that cannot go on (``RuntimeError`` subclasses): :class:`FrictionError` (a slip system
with no admissible solution), :class:`RelaxationFailure` (no static stick/slip state: gross slip),
:class:`TrackingError` (the event tracking), :class:`RestConvergenceError` (the object does not come to
rest on the table), :class:`MainGuardError` (a script that starts worker processes outside
``if __name__ == "__main__":``).

Results that break a contact law (``AssertionError`` subclasses): :class:`RestCheckError`,
:class:`PickupCheckError`.  Output folders that are not ours or not writable: :class:`OutputError`
(an ``OSError``).  An optional dependency that is not installed: :class:`MissingExtraError` (an
``ImportError`` naming the extra that brings it, raised by :func:`require`).  ν close to ½:
:class:`LockingWarning` (P1 tetrahedra lock); a size or density that says the mesh is in another unit, run
anyway because the scene allows it: :class:`UnitsWarning`.
"""

from __future__ import annotations

import importlib
import importlib.util
from types import ModuleType

__all__ = ["EXTRAS", "CollinearContactError", "ContactNodeError", "DirectionError", "FrictionError", "LockingWarning",
           "MainGuardError", "MaterialError", "MeshError", "MissingExtraError", "OutputError", "PickupCheckError",
           "PlacementError", "RelaxationFailure", "RestCheckError", "RestConvergenceError", "SceneError", "SchedulerError",
           "SearchError", "SurfaceError", "TrackingError", "UnitsError", "UnitsWarning", "require"]


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


class SearchError(SceneError):
    """A search that cannot run as asked (a folder of another search to resume, no candidate, …)."""


class SchedulerError(SearchError):
    """The Dask scheduler cannot be reached, or has no worker, within the connection timeout."""


class CollinearContactError(ValueError):
    """The contact set leaves a rigid rotation free (Theorem 3): M is singular."""


class OutputError(OSError):
    """An output folder cannot be used (not ours and not empty, or not writable)."""


# ------------------------------------------------------- optional dependencies
#: The optional extras of the package (``pip install "fem_grasp[extra]"``) and what each brings.
EXTRAS: dict[str, str] = {
    "report": "pyvista and matplotlib: report.html and its pictures (`--report`, `fem-grasp report`)",
    "search": "dask, pandas and pyarrow: the placement search (`fem-grasp search`, fem_grasp.search)",
    "mesh": "gmsh: meshing (`fem-grasp mesh`, `--quick`, scans, object.vertices, accuracy)",
    "xdmf": "h5py: object.xdmf + object.h5 beside the ParaView series",
    "fast": "numba: the compiled contact kernels (about 5x faster pickups)",
    "cholmod": "scikit-sparse: the CHOLMOD sparse Cholesky factorisation (needs SuiteSparse's headers to build)",
}


class MissingExtraError(ImportError):
    """An optional dependency is not installed: the message names the extra that brings it.

    ``extra`` is the extra's name (a key of :data:`EXTRAS`), ``name`` the module that could not be imported.
    """

    def __init__(self, message: str, *, extra: str, name: str | None = None) -> None:
        super().__init__(message, name=name)
        self.extra = extra


#: How to get gmsh besides the extra: Debian's gmsh is not a pip distribution, so the extra would add a second one.
_GMSH_DEBIAN = ("; on Debian/Ubuntu the package python3-gmsh serves as well (`apt-get install python3-gmsh`, "
                "then a venv made with --system-site-packages)")


def require(module: str, extra: str, purpose: str, *, load: bool = True) -> ModuleType | None:
    """Import ``module``, or raise :class:`MissingExtraError` naming the ``extra`` that installs it.

    Parameters
    ----------
    module : the module to import (``"pyvista"``, ``"dask.distributed"``)
    extra : the extra of fem_grasp that brings it (a key of :data:`EXTRAS`)
    purpose : what needs it, the start of the message (``"fem-grasp run --report"``)
    load : False to check only that ``module`` is installed, without importing it here (pyvista is imported
        in a process of its own: :mod:`fem_grasp.io.report`)

    Returns
    -------
    The imported module (None with ``load=False``).

    Raises
    ------
    MissingExtraError
        ``module`` (or a library it needs) cannot be imported.
    """
    if extra not in EXTRAS:
        raise ValueError(f"unknown extra {extra!r}; choose one of {', '.join(EXTRAS)}")
    try:
        if not load:
            if importlib.util.find_spec(module) is None:  # None also for a module set to None in sys.modules
                raise ModuleNotFoundError(f"No module named {module!r}", name=module)
            return None
        return importlib.import_module(module)
    # OSError: a module found whose shared library is not (libgmsh); ValueError: find_spec of a module without
    # __spec__
    except (ImportError, OSError, ValueError) as exc:
        missing = getattr(exc, "name", None) if isinstance(exc, ModuleNotFoundError) else None
        why = (f"{missing} is not installed" if missing
               else f"{module} cannot be imported ({type(exc).__name__}: {exc})")
        hint = _GMSH_DEBIAN if extra == "mesh" else ""
        raise MissingExtraError(f"{purpose} needs the {extra!r} extra ({why}): pip install \"fem_grasp[{extra}]\""
                                f"{hint}", extra=extra, name=missing or module) from exc


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
