"""Coulomb's friction law at a contact node: the cone and its tests (paper §III, eqs. 6–7).

Conventions: ``f`` is the force exerted *on the object* at a contact node and
n̂ the unit normal there pointing *into* the object.  The contact holds when it
is compressive, ``f·n̂ > 0`` (else event B, break), and sticks while it lies
inside the friction cone ``|f_t| ≤ μ f·n̂`` with ``f_t = f − (f·n̂)n̂`` (else
event C, slip).  A sliding node sits on the cone boundary

    (1 + μ²)(f·n̂)² = f·f                                   (eqs. 6, 7)

and moves opposite to its tangential force (:func:`slip_directions`).

The slip systems that put sliding nodes back on their cones are elsewhere:
the mixed table and fingertip slip of eqs. (6)–(8) in
:mod:`~fem_grasp.contact.slip_system`, and the static return mapping in
:mod:`~fem_grasp.contact.relaxation`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["CONE_RTOL", "cone_ratio", "cone_residual", "cone_violation", "in_cone", "is_compressive",
           "normal_component", "slip_directions", "tangential_component"]

#: Default relative tolerance of the cone tests: a force is outside the cone when
#: ``|f_t| > μ f·n̂ + CONE_RTOL · f·n̂``.
CONE_RTOL = 1e-9


# ----------------------------------------------------------------- cone tests
def _forces_normals(forces: np.ndarray, normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    f = np.asarray(forces, dtype=float)
    n = np.asarray(normals, dtype=float)
    if f.shape[-1] != 3 or n.shape[-1] != 3:
        raise ValueError(f"forces and normals must have a last axis of length 3, got {f.shape} and {n.shape}")
    return f, np.broadcast_to(n, f.shape)


def normal_component(forces: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """f·n̂ for each contact: positive when the contact pushes on the object (compressive)."""
    f, n = _forces_normals(forces, normals)
    return np.einsum("...i,...i->...", f, n)


def tangential_component(forces: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """f_t = f − (f·n̂)n̂, the friction part of each contact force."""
    f, n = _forces_normals(forces, normals)
    return f - normal_component(f, n)[..., None] * n


def cone_residual(forces: np.ndarray, normals: np.ndarray, mu: float | np.ndarray) -> np.ndarray:
    """(1 + μ²)(f·n̂)² − f·f, the left minus right side of eqs. (6)/(7).

    Equals μ²(f·n̂)² − |f_t|²: positive strictly inside the (double) cone, zero on
    its boundary, negative outside.
    """
    f, n = _forces_normals(forces, normals)
    fn = normal_component(f, n)
    return (1.0 + np.asarray(mu, dtype=float) ** 2) * fn**2 - np.einsum("...i,...i->...", f, f)


def cone_violation(forces: np.ndarray, normals: np.ndarray, mu: float | np.ndarray) -> np.ndarray:
    """|f_t| − μ f·n̂ in newtons: ≤ 0 inside the friction cone, > 0 outside it (event C)."""
    f, n = _forces_normals(forces, normals)
    return np.linalg.norm(tangential_component(f, n), axis=-1) - np.asarray(mu, dtype=float) * normal_component(f, n)


def cone_ratio(forces: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """|f_t| / f·n̂, the friction coefficient a contact needs (inf for non-compressive contacts)."""
    f, n = _forces_normals(forces, normals)
    fn = normal_component(f, n)
    ft = np.linalg.norm(tangential_component(f, n), axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(fn > 0, ft / np.where(fn > 0, fn, 1.0), np.inf)


def is_compressive(forces: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """f·n̂ > 0: the contact pushes the object (otherwise it breaks, event B)."""
    return normal_component(forces, normals) > 0.0


def in_cone(forces: np.ndarray, normals: np.ndarray, mu: float | np.ndarray, rtol: float = CONE_RTOL) -> np.ndarray:
    """Compressive and ``|f_t| ≤ (μ + rtol) f·n̂``: the contact can stick."""
    f, n = _forces_normals(forces, normals)
    fn = normal_component(f, n)
    ft = np.linalg.norm(tangential_component(f, n), axis=-1)
    return (fn > 0.0) & (ft <= (np.asarray(mu, dtype=float) + rtol) * fn)


def slip_directions(forces: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Unit tangential force directions t̂ = f_t/|f_t|; a sliding node moves along −t̂.

    Raises ``ValueError`` for a contact whose tangential force vanishes (its slip
    direction is undefined).
    """
    ft = tangential_component(forces, normals)
    norm = np.linalg.norm(ft, axis=-1)
    scale = np.linalg.norm(np.asarray(forces, dtype=float), axis=-1)
    if np.any(norm <= 1e-14 * np.maximum(scale, np.finfo(float).tiny)):
        raise ValueError("a contact with zero tangential force has no slip direction")
    return ft / norm[..., None]
