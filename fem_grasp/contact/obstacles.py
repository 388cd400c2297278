"""The rigid obstacles the object touches: the table plane 𝒫 and the hemispherical fingertips ℱ₁, ℱ₂ (paper §III).

Every obstacle answers the same questions about points of the deformed object,
so the contact machinery treats the table and the fingertips alike
(:class:`Obstacle`):

* :meth:`signed_distance` — positive outside the obstacle (free), negative
  inside it (penetration, paper event A);
* :meth:`inward_normals` — the unit normal n̂ at the contact pointing *into the
  object*, the axis of the friction cone of eqs. (6)–(7);
* :meth:`project` — the closest point on the obstacle's surface, where a
  penetrating node is placed when it becomes a contact (:meth:`project_point`
  for a single point).

A contact belongs to one obstacle, named by its owner code: :data:`FINGER1`,
:data:`FINGER2` or :data:`TABLE` (indices into :data:`OBSTACLES`).  A
fingertip is a whole sphere (only the half facing the object is ever
touched); a node sliding on it moves on a great circle (Fig. 1, eqs. 7–8):
:func:`great_circle_axes`, :meth:`Fingertip.great_circle_point`.  The tangent
bases of the cones' planes are :func:`tangent_basis` / :func:`tangent_bases`.

The compiled return-mapping kernels (:mod:`fem_grasp.contact.kernels.gauss_seidel`)
carry the same sphere and plane geometry in scalar form, for numba.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

__all__ = ["DEFAULT_RADIUS", "FINGER1", "FINGER2", "OBSTACLES", "TABLE", "Fingertip", "Obstacle", "TablePlane",
           "cross_rows", "great_circle_axes", "sphere_gaps", "sphere_normals", "tangent_basis", "tangent_bases"]

#: Owner codes of the contacts: which obstacle a contact node touches.
FINGER1, FINGER2, TABLE = 0, 1, 2
#: Names of the obstacles, indexed by the owner codes above.
OBSTACLES = ("finger1", "finger2", "table")
#: Default fingertip radius (m): a Barrett Hand fingertip is about 1 cm in radius.
DEFAULT_RADIUS = 0.01


@runtime_checkable
class Obstacle(Protocol):
    """What the contact phases need to know about a rigid obstacle."""

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        """(k,) distance of each point from the obstacle's surface, negative inside it."""
        ...

    def inward_normals(self, points: np.ndarray) -> np.ndarray:
        """(k, 3) unit normals at the nearest surface points, pointing into the object."""
        ...

    def project(self, points: np.ndarray) -> np.ndarray:
        """(k, 3) nearest points on the obstacle's surface."""
        ...

    def project_point(self, point: np.ndarray) -> np.ndarray:
        """(3,) nearest point on the obstacle's surface to one point (3,)."""
        ...


def _points(points: np.ndarray) -> np.ndarray:
    p = np.asarray(points, dtype=float)
    if p.shape[-1] != 3:
        raise ValueError(f"points must have shape (..., 3), got {p.shape}")
    return p


# ---------------------------------------------------------------- the table
@dataclass(frozen=True)
class TablePlane:
    """The supporting plane 𝒫: the half-space below it is solid table.

    Parameters
    ----------
    height : float
        The plane is ``up · x = height``; with the default ``up = +z`` that is
        ``z = height`` (the ``table_z`` of :func:`fem_grasp.grasp.rest.rest`).
    up : (3,) array_like
        Unit normal of the plane pointing out of the table, i.e. into an
        object resting on it (default +z, opposite to gravity).

    Notes
    -----
    For a node resting on the table the inward normal of the object is
    ``up``, so the paper's ẑ in eq. (6) is :attr:`up`.
    """

    height: float = 0.0
    up: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))

    def __post_init__(self) -> None:
        up = np.asarray(self.up, dtype=float).reshape(-1)
        if up.shape != (3,) or not np.isfinite(up).all() or np.linalg.norm(up) == 0:
            raise ValueError(f"up must be a non-zero 3-vector, got {self.up!r}")
        if not np.isfinite(self.height):
            raise ValueError(f"height must be finite, got {self.height!r}")
        up = up / np.linalg.norm(up)
        up.setflags(write=False)
        object.__setattr__(self, "up", up)
        object.__setattr__(self, "height", float(self.height))

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        """Height of each point above the plane (negative below it: penetration)."""
        return _points(points) @ self.up - self.height

    def penetration(self, points: np.ndarray) -> np.ndarray:
        """Depth of each point below the plane, zero for points on or above it."""
        return np.maximum(-self.signed_distance(points), 0.0)

    def inward_normals(self, points: np.ndarray) -> np.ndarray:
        """The object's inward normal at table contacts: ``up``, once per row of ``points`` (k, 3)."""
        p = _points(points)
        return np.broadcast_to(self.up, p.shape).copy()

    def project(self, points: np.ndarray) -> np.ndarray:
        """Orthogonal projection onto the plane (moves points along ``up`` only)."""
        p = _points(points)
        return p - np.multiply.outer(self.signed_distance(p), self.up)

    def project_point(self, point: np.ndarray) -> np.ndarray:
        """:meth:`project` of one point (3,)."""
        return self.project(np.asarray(point, dtype=float)[None, :])[0]

    def tangent_basis(self) -> np.ndarray:
        """(2, 3) orthonormal vectors spanning the plane, right-handed with ``up``."""
        return tangent_basis(self.up)


# ------------------------------------------------------------ the fingertips
def sphere_gaps(points: np.ndarray, center: np.ndarray, radius: float) -> np.ndarray:
    """|p − O| − R for each point (k, 3): its distance outside the fingertip sphere, negative inside (event A).

    The one numpy copy of the gap (the compiled one is :func:`~fem_grasp.contact.kernels.events.event_functions`'s,
    tested against it)."""
    return np.linalg.norm(np.atleast_2d(points) - np.asarray(center, dtype=float), axis=1) - radius


def sphere_normals(points: np.ndarray, center: np.ndarray) -> np.ndarray:
    """n̂ = (p − O)/|p − O| for each point (k, 3): the unit normal into the object at a fingertip contact.

    The one numpy copy of the normal (the compiled one is
    :func:`~fem_grasp.contact.kernels.events.contact_normals`, tested against it)."""
    d = np.atleast_2d(points) - np.asarray(center, dtype=float)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


@dataclass(frozen=True)
class Fingertip:
    """A rigid hemispherical fingertip: the sphere of radius ``radius`` (m) about ``center`` O (3,) (m).

    A node touching it sits on the sphere; the normal pointing into the object
    there is n̂ = (p̃ − O)/|p̃ − O|.  A sliding node moves on the great circle
    through p̃ in the plane of n̂ and its tangential force (:meth:`great_circle_point`).
    """

    center: np.ndarray
    radius: float = DEFAULT_RADIUS

    def __post_init__(self) -> None:
        c = np.asarray(self.center, dtype=float)
        if c.shape != (3,) or not np.isfinite(c).all():
            raise ValueError(f"fingertip centre must be 3 finite coordinates, got {self.center!r}")
        if not np.isfinite(self.radius) or self.radius <= 0:
            raise ValueError(f"fingertip radius must be a positive length in metres, got {self.radius!r}")
        object.__setattr__(self, "center", c)

    @classmethod
    def tangent_at(cls, point: np.ndarray, outward_normal: np.ndarray, radius: float = DEFAULT_RADIUS) -> "Fingertip":
        """A fingertip touching the object at ``point`` whose outward unit normal there is ``outward_normal``."""
        n = np.asarray(outward_normal, dtype=float)
        norm = np.linalg.norm(n)
        if not norm > 0:
            raise ValueError("cannot place a fingertip: the surface normal at the contact node is zero")
        return cls(np.asarray(point, dtype=float) + radius * n / norm, radius)

    def translated(self, offset: np.ndarray) -> "Fingertip":
        return Fingertip(self.center + np.asarray(offset, dtype=float), self.radius)

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        """Distance of each point outside the sphere; negative inside (penetration, event A)."""
        return sphere_gaps(points, self.center, self.radius)

    def inward_normals(self, points: np.ndarray) -> np.ndarray:
        """Unit normals n̂ at points on the sphere, pointing into the object (away from O)."""
        return sphere_normals(points, self.center)

    def project(self, points: np.ndarray) -> np.ndarray:
        """Radial projection of points (k, 3) onto the sphere."""
        return self.center + self.radius * self.inward_normals(points)

    def project_point(self, point: np.ndarray) -> np.ndarray:
        """Radial projection of one point (3,) onto the sphere."""
        d = np.asarray(point, dtype=float) - self.center
        return self.center + self.radius * d / np.linalg.norm(d)

    def slip_axis(self, point: np.ndarray, force: np.ndarray) -> np.ndarray:
        """N̂, the unit normal of the great circle a node at ``point`` slides on under ``force`` (§III-C).

        Raises ``ValueError`` when the force has no tangential part (no slip direction).
        """
        n = self.inward_normals(point)
        f = np.asarray(force, dtype=float).reshape(1, 3)
        f_t = f - (f @ n[0]) * n
        if np.linalg.norm(f_t) <= 1e-300 or np.linalg.norm(f_t) <= 1e-14 * np.linalg.norm(f):
            raise ValueError("the contact force has no tangential component; the slip direction is undefined")
        return great_circle_axes(n, f_t)[0]

    def great_circle_point(self, point: np.ndarray, axis: np.ndarray, c: float, s: float) -> np.ndarray:
        """q = O + c (p̃ − O) + s (N̂ × (p̃ − O)): p̃ rotated about N̂ by θ, c = cos θ, s = sin θ (eqs. 7–8)."""
        r = np.asarray(point, dtype=float) - self.center
        return self.center + c * r + s * np.cross(axis, r)


# ------------------------------------------------------------------ geometry
def cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of two (k, 3) arrays (np.cross without its overhead)."""
    return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1], a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                     a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)


def great_circle_axes(normals: np.ndarray, tangents: np.ndarray) -> np.ndarray:
    """(k, 3) unit axes N̂ ∝ n̂ × t of the great circles through points of inward normals n̂ (k, 3) that slide
    in the tangential directions t (k, 3) (paper Fig. 1: N̂ along n̂ × f⊥)."""
    axis = cross_rows(normals, tangents)
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    return axis


def tangent_basis(normal: np.ndarray) -> np.ndarray:
    """(2, 3) orthonormal basis (e₁, e₂) of the plane ⟂ ``normal`` with e₁ × e₂ = n̂."""
    n = np.asarray(normal, dtype=float)
    n = n / np.linalg.norm(n)
    helper = np.eye(3)[int(np.argmin(np.abs(n)))]
    e1 = np.cross(helper, n)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    return np.stack([e1, e2])


def tangent_bases(normals: np.ndarray) -> np.ndarray:
    """(k, 2, 3): :func:`tangent_basis` of each row of ``normals`` (k, 3), computed for all at once."""
    n = np.asarray(normals, dtype=float).reshape(-1, 3)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    helper = np.eye(3)[np.argmin(np.abs(n), axis=1)]
    e1 = cross_rows(helper, n)  # np.cross's numbers, without its overhead (a return mapping's records call this)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = cross_rows(n, e1)
    return np.stack([e1, e2], axis=1)
