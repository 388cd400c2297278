"""Rigid obstacles the object touches: the table plane 𝒫 (paper §III).

Every obstacle answers the same three questions about points of the deformed
object, so the contact phases can treat the table and (later) the
hemispherical fingertips ℱ₁, ℱ₂ alike:

* :meth:`signed_distance` — positive outside the obstacle (free), negative
  inside it (penetration, paper event A);
* :meth:`inward_normal` — the unit normal n̂ at the contact pointing *into the
  object*, the axis of the friction cone of eqs. (6)–(7);
* :meth:`project` — the closest point on the obstacle's surface, where a
  penetrating node is placed when it becomes a contact.

Only the table exists for now.  A ``Fingertip`` (a sphere of radius r centred
at O, with the great-circle slip of eqs. (7)–(8)) will implement the same
:class:`Obstacle` protocol.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

__all__ = ["Obstacle", "TablePlane"]


@runtime_checkable
class Obstacle(Protocol):
    """What the contact phases need to know about a rigid obstacle."""

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        """(k,) distance of each point from the obstacle's surface, negative inside it."""
        ...

    def inward_normal(self, points: np.ndarray) -> np.ndarray:
        """(k, 3) unit normals at the nearest surface points, pointing into the object."""
        ...

    def project(self, points: np.ndarray) -> np.ndarray:
        """(k, 3) nearest points on the obstacle's surface."""
        ...


def _points(points: np.ndarray) -> np.ndarray:
    p = np.asarray(points, dtype=float)
    if p.shape[-1] != 3:
        raise ValueError(f"points must have shape (..., 3), got {p.shape}")
    return p


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

    def inward_normal(self, points: np.ndarray | None = None) -> np.ndarray:
        """The object's inward normal at a table contact: ``up`` for every point.

        With ``points`` of shape (k, 3) the normal is repeated k times.
        """
        if points is None:
            return self.up.copy()
        p = _points(points)
        return np.broadcast_to(self.up, p.shape).copy()

    def project(self, points: np.ndarray) -> np.ndarray:
        """Orthogonal projection onto the plane (moves points along ``up`` only)."""
        p = _points(points)
        return p - np.multiply.outer(self.signed_distance(p), self.up)

    def tangent_basis(self) -> np.ndarray:
        """(2, 3) orthonormal vectors spanning the plane, right-handed with ``up``."""
        return tangent_basis(self.up)


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
    e1 = np.cross(helper, n)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(n, e1)
    return np.stack([e1, e2], axis=1)

#: Default fingertip radius (m): a Barrett Hand fingertip is about 1 cm in radius.
DEFAULT_RADIUS = 0.01


@dataclass(frozen=True)
class Fingertip:
    """A rigid sphere of radius ``radius`` (m) about ``center`` (3,) (m)."""

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
        return np.linalg.norm(np.atleast_2d(points) - self.center, axis=1) - self.radius

    def inward_normals(self, points: np.ndarray) -> np.ndarray:
        """Unit normals n̂ at points on the sphere, pointing into the object (away from O)."""
        d = np.atleast_2d(points) - self.center
        return d / np.linalg.norm(d, axis=1, keepdims=True)

    def project(self, points: np.ndarray) -> np.ndarray:
        """Radial projection of points onto the sphere."""
        return self.center + self.radius * self.inward_normals(points)


def slip_axis(point: np.ndarray, fingertip: Fingertip, force: np.ndarray) -> np.ndarray:
    """N̂, the unit normal of the great circle a node slides on: along n̂ × f⊥ (§III-C).

    Raises ``ValueError`` when the force has no tangential part (no slip direction).
    """
    n = fingertip.inward_normals(point)[0]
    f = np.asarray(force, dtype=float)
    f_t = f - (f @ n) * n
    axis = np.cross(n, f_t)
    norm = np.linalg.norm(axis)
    if norm <= 1e-300 or norm <= 1e-14 * np.linalg.norm(f):
        raise ValueError("the contact force has no tangential component; the slip direction is undefined")
    return axis / norm


def great_circle_point(point: np.ndarray, fingertip: Fingertip, axis: np.ndarray, c: float, s: float) -> np.ndarray:
    """q = O + c (p̃ − O) + s (N̂ × (p̃ − O)): p̃ rotated about N̂ by θ with c = cos θ, s = sin θ."""
    r = np.asarray(point, dtype=float) - fingertip.center
    return fingertip.center + c * r + s * np.cross(axis, r)
