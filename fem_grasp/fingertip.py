"""A rigid hemispherical fingertip (paper §III, Fig. 1).

The fingertip is the sphere of radius ``radius`` about ``center`` O (only the
hemisphere facing the object ever touches it).  A node touching it sits on the
sphere; the normal pointing into the object there is n̂ = (p̃ − O)/|p̃ − O|.
A sliding node moves on the great circle through p̃ in the plane of n̂ and its
tangential force: q = O + c (p̃ − O) + s (N̂ × (p̃ − O)), c² + s² = 1 (eq. 8).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

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
