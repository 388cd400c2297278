"""Fields from a displacement (fem_grasp.elastic.fields): strain, von Mises stress, strain energy density, rigid part."""

import numpy as np
import pytest

from fem_grasp import Body, box_mesh
from fem_grasp.elastic.fem import rigid_modes
from fem_grasp.elastic.fields import (
    elastic_displacement,
    element_strains,
    element_stresses,
    strain_energy_density,
    von_mises,
)

E, NU = 2e4, 0.3


@pytest.fixture(scope="module")
def mesh():
    return box_mesh((0, 0, 0), (0.03, 0.02, 0.025), (3, 2, 2))


def test_a_uniaxial_strain_gives_hookes_stress_and_von_mises(mesh):
    """u = (ε₀x, 0, 0) is reproduced exactly by P1: σ_xx = (λ + 2μ)ε₀, σ_yy = σ_zz = λε₀, von Mises 2με₀."""
    eps0 = 1e-3
    u = np.zeros_like(mesh.points)
    u[:, 0] = eps0 * mesh.points[:, 0]
    lam = E * NU / ((1 + NU) * (1 - 2 * NU))
    mu = E / (2 * (1 + NU))
    eps = element_strains(mesh.points, mesh.tets, u)
    np.testing.assert_allclose(eps[:, 0, 0], eps0, rtol=1e-12)
    sig = element_stresses(mesh.points, mesh.tets, u, E, NU)
    np.testing.assert_allclose(sig[:, 0, 0], (lam + 2 * mu) * eps0, rtol=1e-12)
    np.testing.assert_allclose(sig[:, 1, 1], lam * eps0, rtol=1e-12)
    np.testing.assert_allclose(von_mises(sig), 2 * mu * eps0, rtol=1e-12)
    np.testing.assert_allclose(strain_energy_density(mesh.points, mesh.tets, u, E, NU),
                               0.5 * (lam + 2 * mu) * eps0 ** 2, rtol=1e-12)


def test_the_energy_densities_add_up_to_eq_2(mesh):
    """Σ_e V_e ½σ:ε = ½ ΔᵀKΔ for any displacement (the element's share of the strain energy, eq. 2)."""
    rng = np.random.default_rng(0)
    u = 1e-4 * rng.normal(size=mesh.points.shape)
    body = Body(mesh, E, NU, weight=0.3)
    energy = float(mesh.volumes @ strain_energy_density(mesh.points, mesh.tets, u, E, NU))
    assert energy == pytest.approx(0.5 * u.ravel() @ (body.stiffness @ u.ravel()), rel=1e-12)


def test_a_rigid_motion_has_no_strain_and_no_elastic_part(mesh):
    rng = np.random.default_rng(1)
    rigid = (rigid_modes(mesh.points, mesh.points.mean(axis=0)) @ (1e-3 * rng.normal(size=6))).reshape(-1, 3)
    assert np.abs(element_strains(mesh.points, mesh.tets, rigid)).max() < 1e-15
    np.testing.assert_allclose(elastic_displacement(mesh.points, mesh.tets, rigid), 0.0, atol=1e-16)
    # a stretch plus a lift and a turn: the rigid motion goes, the stretch's strain stays
    stretch = np.zeros_like(mesh.points)
    stretch[:, 0] = 1e-3 * (mesh.points[:, 0] - 0.015)
    moved = stretch + rigid + np.array([0.0, 0.0, 0.01])
    elastic = elastic_displacement(mesh.points, mesh.tets, moved)
    np.testing.assert_allclose(elastic, elastic_displacement(mesh.points, mesh.tets, stretch), atol=1e-15)
    np.testing.assert_allclose(element_strains(mesh.points, mesh.tets, elastic),
                               element_strains(mesh.points, mesh.tets, stretch), atol=1e-15)
    assert np.abs(elastic).max() < 2e-5  # millimetres of lift gone, micrometres of stretch left


def test_a_series_of_one_mesh_gives_the_same_fields_from_its_precomputed_gradients_and_volumes(mesh):
    """The time series evaluates every frame with the reference's shape gradients and lumped volumes computed
    once: the same strains, stresses, energy densities and elastic part as from the points alone."""
    from fem_grasp.elastic.fem import lumped_volumes, shape_gradients
    from fem_grasp.io.series import mechanics_fields

    u = 1e-4 * np.random.default_rng(2).normal(size=mesh.points.shape)
    grads, _ = shape_gradients(mesh.points, mesh.tets)
    np.testing.assert_array_equal(element_strains(mesh.points, mesh.tets, u, grads),
                                  element_strains(mesh.points, mesh.tets, u))
    pd, cd = mechanics_fields(mesh.points, mesh.tets, u, E, NU, grads, lumped_volumes(mesh.points, mesh.tets))
    np.testing.assert_allclose(pd["elastic_displacement"], elastic_displacement(mesh.points, mesh.tets, u),
                               rtol=0, atol=1e-15)
    np.testing.assert_allclose(cd["von_mises"], von_mises(element_stresses(mesh.points, mesh.tets, u, E, NU)),
                               rtol=1e-13)
    np.testing.assert_allclose(cd["strain_energy_density"], strain_energy_density(mesh.points, mesh.tets, u, E, NU),
                               rtol=1e-13)
