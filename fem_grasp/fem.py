"""Linear P1 finite elements for 3D elasticity (paper §II-A, §II-B).

Pure functions over arrays.  Degrees of freedom are node-major: DOF ``3*k + i``
is component ``i`` (x, y, z) of the displacement δ_k of node ``k``, matching
the paper's Δ = (δ_1ᵀ, …, δ_nᵀ)ᵀ.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .mesh import signed_volumes

#: Gravitational acceleration used by the paper (m/s²).
STANDARD_GRAVITY = 9.8


def check_material(young: float, poisson: float) -> None:
    """Raise ``ValueError`` unless E > 0 and −1 < ν < ½ (paper eq. 2)."""
    if not np.isfinite(young) or young <= 0:
        raise ValueError(f"Young's modulus E must be a positive number of pascals, got {young!r}")
    if not np.isfinite(poisson) or not -1.0 < poisson < 0.5:
        raise ValueError(f"Poisson's ratio ν must lie strictly inside (-1, 1/2), got {poisson!r}")


def lame_parameters(young: float, poisson: float) -> tuple[float, float]:
    """Lamé's λ and shear modulus μ from E and ν.

    Eq. (2) is ``∫ μ ε:ε + (λ/2)(tr ε)² dV`` with μ = E/(2(1+ν)) and
    λ/2 = μ ν/(1−2ν).
    """
    check_material(young, poisson)
    mu = young / (2.0 * (1.0 + poisson))
    lam = young * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson))
    return lam, mu


def shape_gradients(points: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gradients of the four P1 shape functions in every tetrahedron.

    Returns
    -------
    grads : (t, 4, 3) array
        ``grads[e, a]`` is ∇φ_a on element ``e`` (constant inside it).
    volumes : (t,) array
        Signed element volumes.
    """
    p = points[tets]  # (t, 4, 3)
    jac = np.swapaxes(p[:, 1:] - p[:, :1], 1, 2)  # columns x_a − x_0
    det = np.linalg.det(jac)
    inv = np.linalg.inv(jac)  # rows are ∇φ_1..∇φ_3
    grads = np.concatenate([-inv.sum(axis=1, keepdims=True), inv], axis=1)
    return grads, det / 6.0


def element_dofs(tets: np.ndarray) -> np.ndarray:
    """(t, 12) global DOF numbers of each element, node-major."""
    return (3 * tets[:, :, None] + np.arange(3)).reshape(len(tets), 12)


def element_stiffness(grads: np.ndarray, volumes: np.ndarray, lam: float, mu: float) -> np.ndarray:
    """(t, 12, 12) element stiffness matrices, the Hessian of eq. (2) on each element.

    ``K_e[a i, b j] = V (λ ∂_iφ_a ∂_jφ_b + μ ∂_jφ_a ∂_iφ_b + μ δ_ij ∇φ_a·∇φ_b)``.
    """
    g = grads
    ke = lam * np.einsum("tai,tbj->taibj", g, g)
    ke += mu * np.einsum("taj,tbi->taibj", g, g)
    ke += mu * np.einsum("tak,tbk,ij->taibj", g, g, np.eye(3))
    ke *= volumes[:, None, None, None, None]
    return ke.reshape(len(g), 12, 12)


def stiffness_matrix(points: np.ndarray, tets: np.ndarray, young: float, poisson: float) -> sp.csr_matrix:
    """Assemble the 3n×3n stiffness matrix K with U = ½ΔᵀKΔ (eq. 2), vectorised over elements."""
    lam, mu = lame_parameters(young, poisson)
    grads, vol = shape_gradients(points, tets)
    ke = element_stiffness(grads, np.abs(vol), lam, mu)
    dofs = element_dofs(tets)
    rows = np.repeat(dofs, 12, axis=1).ravel()
    cols = np.tile(dofs, (1, 12)).ravel()
    n = 3 * len(points)
    k = sp.csr_matrix((ke.ravel(), (rows, cols)), shape=(n, n))
    k.sum_duplicates()
    # Exact symmetry (assembly order can leave last-bit asymmetry).
    return ((k + k.T) * 0.5).tocsr()


def lumped_volumes(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """(n,) volume charged to each node: a quarter of each adjacent element's volume."""
    v = np.abs(signed_volumes(points, tets))
    return np.bincount(tets.ravel(), weights=np.repeat(v / 4.0, 4), minlength=len(points))


def gravity_loads(points: np.ndarray, tets: np.ndarray, density: float, gravity: float = STANDARD_GRAVITY,
                  down: np.ndarray | None = None) -> np.ndarray:
    """Nodal gravity vector G (3n,) of §II-B: each element's mass charged evenly to its four vertices.

    ``down`` is the unit direction of gravity (default −z).
    """
    down = np.array([0.0, 0.0, -1.0]) if down is None else np.asarray(down, dtype=float)
    m = density * lumped_volumes(points, tets)
    return (gravity * m[:, None] * down[None, :]).ravel()


def rigid_modes(points: np.ndarray, center: np.ndarray | None = None) -> np.ndarray:
    """(3n, 6) rigid-body fields of Theorem 1: t_x, t_y, t_z, r_x, r_y, r_z.

    Rotations are taken about ``center`` (the paper puts the origin at the
    centre of mass); r_x displaces (x, y, z) by (0, −z, y), and so on.
    """
    c = np.zeros(3) if center is None else np.asarray(center, dtype=float)
    x, y, z = (points - c).T
    n = len(points)
    zero, one = np.zeros(n), np.ones(n)
    fields = [
        (one, zero, zero),
        (zero, one, zero),
        (zero, zero, one),
        (zero, -z, y),
        (z, zero, -x),
        (-y, x, zero),
    ]
    return np.stack([np.stack(f, axis=1).ravel() for f in fields], axis=1)
