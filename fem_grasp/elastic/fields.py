"""Fields a mechanician reads from a displacement: strain, stress, von Mises stress, strain energy density.

P1 tetrahedra have one strain per element: ε = sym(∇δ) with ∇δ = Σ_a δ_a ⊗ ∇φ_a (eq. 1), and Hooke's law
σ = λ tr(ε) I + 2μ ε, so that the element's share of eq. (2) is ½ σ:ε times its volume.  All functions
take the *undeformed* points (the reference the displacement is measured from) and return one value per
element, in SI units: stresses in Pa, energy densities in J/m³.

:func:`elastic_displacement` removes the best-fitting rigid motion (the six fields of Theorem 1, weighted
by each node's lumped volume) from a displacement: what is left is the deformation, which the lift's
translation would otherwise hide in a picture of |δ|.
"""

from __future__ import annotations

import numpy as np

from .fem import lame_parameters, lumped_volumes, rigid_modes, shape_gradients

__all__ = ["elastic_displacement", "element_strains", "element_stresses", "energy_density_of_strains", "hooke_stresses",
           "strain_energy_density", "von_mises"]


def element_strains(points: np.ndarray, tets: np.ndarray, displacement: np.ndarray,
                    grads: np.ndarray | None = None) -> np.ndarray:
    """(t, 3, 3) small-strain tensor ε = ½(∇δ + ∇δᵀ) in each tetrahedron (dimensionless).

    ``grads``: the (t, 4, 3) shape gradients of ``points`` and ``tets``
    (:func:`~fem_grasp.elastic.fem.shape_gradients`), when many displacements of one mesh are evaluated.
    """
    if grads is None:
        grads, _ = shape_gradients(points, tets)
    u = np.asarray(displacement, dtype=float).reshape(-1, 3)[tets]  # (t, 4, 3)
    g = np.matmul(u.transpose(0, 2, 1), grads)  # ∂u_i/∂x_j = Σ_a u_ai ∂φ_a/∂x_j
    return 0.5 * (g + g.transpose(0, 2, 1))


def hooke_stresses(strains: np.ndarray, young: float, poisson: float) -> np.ndarray:
    """(t, 3, 3) Cauchy stress σ = λ tr(ε) I + 2μ ε of (t, 3, 3) strains, Pa."""
    lam, mu = lame_parameters(young, poisson)
    tr = np.trace(strains, axis1=1, axis2=2)
    return lam * tr[:, None, None] * np.eye(3) + 2.0 * mu * strains


def element_stresses(points: np.ndarray, tets: np.ndarray, displacement: np.ndarray, young: float,
                     poisson: float) -> np.ndarray:
    """(t, 3, 3) Cauchy stress σ = λ tr(ε) I + 2μ ε in each tetrahedron, Pa."""
    return hooke_stresses(element_strains(points, tets, displacement), young, poisson)


def von_mises(stress: np.ndarray) -> np.ndarray:
    """(t,) von Mises equivalent stress √(3/2 s:s), s the deviatoric part of σ (same unit as ``stress``)."""
    s = np.asarray(stress, dtype=float)
    dev = s - np.trace(s, axis1=1, axis2=2)[:, None, None] / 3.0 * np.eye(3)
    return np.sqrt(1.5 * np.einsum("tij,tij->t", dev, dev))


def strain_energy_density(points: np.ndarray, tets: np.ndarray, displacement: np.ndarray, young: float,
                          poisson: float) -> np.ndarray:
    """(t,) strain energy per unit volume ½ σ:ε, J/m³ (summed with the volumes: U of eq. 2)."""
    return energy_density_of_strains(element_strains(points, tets, displacement), young, poisson)


def energy_density_of_strains(strains: np.ndarray, young: float, poisson: float) -> np.ndarray:
    """(t,) ½ σ:ε = ½ λ (tr ε)² + μ ε:ε of (t, 3, 3) strains, J/m³."""
    lam, mu = lame_parameters(young, poisson)
    tr = np.trace(strains, axis1=1, axis2=2)
    return 0.5 * lam * tr ** 2 + mu * np.einsum("tij,tij->t", strains, strains)


def elastic_displacement(points: np.ndarray, tets: np.ndarray, displacement: np.ndarray,
                         volumes: np.ndarray | None = None) -> np.ndarray:
    """(n, 3) ``displacement`` less its best-fitting rigid motion (least squares over the six fields of
    Theorem 1, each node weighted by its lumped volume; rotations about the volume centroid).  ``volumes``:
    the nodes' lumped volumes (:func:`~fem_grasp.elastic.fem.lumped_volumes`), when given."""
    points = np.asarray(points, dtype=float)
    u = np.asarray(displacement, dtype=float).reshape(-1, 3)
    w = lumped_volumes(points, tets) if volumes is None else np.asarray(volumes, dtype=float)
    center = (w @ points) / w.sum()
    r = rigid_modes(points, center)  # (3n, 6)
    sw = np.sqrt(np.repeat(w, 3))
    coef, *_ = np.linalg.lstsq(r * sw[:, None], u.reshape(-1) * sw, rcond=None)
    return (u.reshape(-1) - r @ coef).reshape(-1, 3)
