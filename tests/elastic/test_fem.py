import numpy as np
import pytest

from fem_grasp import Body, box_mesh
from fem_grasp.elastic import fem
from tests.helpers import perturbed_box


def strain_energy_eq2(mesh, u, young, poisson):
    """Eq. (2) evaluated from the strains (1) of a P1 field, independently of K."""
    grads, vol = fem.shape_gradients(mesh.points, mesh.tets)
    du = np.einsum("tai,taj->tij", u[mesh.tets], grads)  # du_i/dx_j per element
    ex, ey, ez = du[:, 0, 0], du[:, 1, 1], du[:, 2, 2]
    gxy, gxz, gyz = du[:, 1, 0] + du[:, 0, 1], du[:, 2, 0] + du[:, 0, 2], du[:, 2, 1] + du[:, 1, 2]
    nu = poisson
    dens = (ex**2 + ey**2 + ez**2) + nu / (1 - 2 * nu) * (ex + ey + ez) ** 2 + 0.5 * (gxy**2 + gxz**2 + gyz**2)
    return young / (2 * (1 + nu)) * np.sum(dens * np.abs(vol))


def test_rigid_modes_span_null_space(rng):
    body = Body(perturbed_box(rng), 2e5, 0.35, weight=1.0)
    k, r = body.stiffness, body.rigid_modes
    knorm = abs(k).max()
    for j in range(6):
        assert np.linalg.norm(k @ r[:, j]) <= 1e-12 * knorm * np.linalg.norm(r[:, j]) * np.sqrt(k.shape[0])
    ev = np.linalg.eigvalsh(k.toarray())
    assert np.all(ev > -1e-12 * ev[-1])
    # Exactly six (near-)zero eigenvalues, then a clear gap.
    assert ev[5] < 1e-12 * ev[-1]
    assert ev[6] > 1e-6 * ev[-1]


def test_stiffness_is_symmetric_and_scales_with_E(box_body):
    k = box_body.stiffness
    assert abs(k - k.T).max() == 0.0
    k2 = box_body.with_material(young=3 * box_body.young).stiffness
    assert abs(k2 - 3 * k).max() <= 1e-14 * abs(k).max()


@pytest.mark.parametrize("nu", [-0.5, 0.0, 0.3, 0.49])
def test_linear_field_gives_exact_constant_strain_energy(rng, nu):
    mesh = perturbed_box(rng)
    young = 7e4
    body = Body(mesh, young, nu, weight=1.0)
    grad = rng.standard_normal((3, 3)) * 1e-3
    u = mesh.points @ grad.T + rng.standard_normal(3) * 1e-4
    eps = 0.5 * (grad + grad.T)
    lam, mu = fem.lame_parameters(young, nu)
    exact = mesh.volume * (mu * np.sum(eps * eps) + 0.5 * lam * np.trace(eps) ** 2)
    np.testing.assert_allclose(body.strain_energy(u), exact, rtol=1e-12)


def test_quadratic_form_matches_eq2_on_random_fields(rng):
    mesh = perturbed_box(rng)
    body = Body(mesh, 3e6, 0.25, weight=1.0)
    for _ in range(3):
        u = rng.standard_normal((mesh.n_points, 3)) * 1e-3
        np.testing.assert_allclose(body.strain_energy(u), strain_energy_eq2(mesh, u, 3e6, 0.25), rtol=1e-12)


def test_gravity_is_orthogonal_to_five_rigid_modes(rng):
    body = Body(perturbed_box(rng), 1e5, 0.3, weight=2.5)
    dots = body.rigid_modes.T @ body.gravity_loads
    scale = body.weight * body.mesh.diameter
    np.testing.assert_allclose(dots[[0, 1, 3, 4, 5]], 0.0, atol=1e-14 * scale)
    np.testing.assert_allclose(dots[2], -body.weight, rtol=1e-13)
    np.testing.assert_allclose(body.mass * body.gravity, 2.5, rtol=1e-14)
    # Lumping: each element's mass evenly to its four vertices.
    g = body.gravity_loads.reshape(-1, 3)
    assert np.all(g[:, :2] == 0) and np.all(g[:, 2] < 0)


def test_density_and_weight_are_exclusive_and_consistent():
    mesh = box_mesh((0, 0, 0), (0.1, 0.1, 0.1), (1, 1, 1))
    b = Body(mesh, 1e5, 0.3, density=1000.0)
    np.testing.assert_allclose(b.mass, 1.0)
    np.testing.assert_allclose(b.weight, 9.8)
    with pytest.raises(ValueError, match="exactly one of weight"):
        Body(mesh, 1e5, 0.3)
    with pytest.raises(ValueError, match="exactly one of weight"):
        Body(mesh, 1e5, 0.3, weight=1.0, density=1.0)
    with pytest.raises(ValueError, match="weight must be a positive"):
        Body(mesh, 1e5, 0.3, weight=-1.0)


@pytest.mark.parametrize("young, poisson, match", [
    (0.0, 0.3, "Young's modulus E must be a positive"),
    (-1e5, 0.3, "Young's modulus"),
    (np.nan, 0.3, "Young's modulus"),
    (1e5, 0.5, r"Poisson's ratio ν must lie strictly inside \(-1, 1/2\)"),
    (1e5, -1.0, "Poisson's ratio"),
    (1e5, 0.7, "Poisson's ratio"),
])
def test_material_is_validated(young, poisson, match):
    with pytest.raises(ValueError, match=match):
        Body(box_mesh(), young, poisson, weight=1.0)


def test_center_of_mass_of_box():
    b = Body(box_mesh((1, 2, 3), (2, 4, 7), (2, 3, 2)), 1e5, 0.3, weight=1.0)
    np.testing.assert_allclose(b.center_of_mass, [1.5, 3.0, 5.0], rtol=1e-14)


# ----------------------------------------------------------------- assembly
def reference_stiffness(points, tets, young, poisson):
    """K by scattering every (12, 12) element matrix with np.add.at: slow and obvious."""
    lam, mu = fem.lame_parameters(young, poisson)
    grads, vol = fem.shape_gradients(points, tets)
    ke = fem.element_stiffness(grads, np.abs(vol), lam, mu)
    dofs = fem.element_dofs(tets)
    k = np.zeros((3 * len(points), 3 * len(points)))
    np.add.at(k, (dofs[:, :, None], dofs[:, None, :]), ke)
    return k


def test_assembly_matches_element_by_element_scatter(rng, monkeypatch):
    mesh = perturbed_box(rng, divisions=(3, 2, 2))
    ref = reference_stiffness(mesh.points, mesh.tets, 2e5, 0.3)
    k = fem.stiffness_matrix(mesh.points, mesh.tets, 2e5, 0.3)
    assert np.abs(k.toarray() - ref).max() <= 1e-14 * np.abs(ref).max()
    assert abs(k - k.T).max() == 0.0
    # The sparsity is exactly the node adjacency: a 3×3 block per pair of nodes sharing an element.
    adj = np.zeros((mesh.n_points, mesh.n_points), dtype=bool)
    adj[mesh.tets[:, :, None], mesh.tets[:, None, :]] = True
    assert k.nnz == 9 * adj.sum()
    # Tiny passes (blocks split across many passes) give the same matrix bit for bit.
    monkeypatch.setattr(fem, "ASSEMBLY_BLOCK", 7)
    assert abs(fem.stiffness_matrix(mesh.points, mesh.tets, 2e5, 0.3) - k).max() == 0.0


def test_sparsity_pattern_is_reusable_and_checked(rng):
    mesh = perturbed_box(rng)
    pattern = fem.stiffness_pattern(mesh.tets, mesh.n_points)
    k = fem.stiffness_matrix(mesh.points, mesh.tets, 1e5, 0.25)
    moved = mesh.points * 1.5
    k2 = fem.stiffness_matrix(moved, mesh.tets, 3e5, 0.25, pattern=pattern)
    # Scaling the mesh by s scales K by s (3D P1: gradients 1/s, volumes s³); E by 3 scales it by 3.
    assert abs(k2 - 4.5 * k).max() <= 1e-14 * abs(k2).max()
    assert abs(fem.stiffness_matrix(mesh.points, mesh.tets, 1e5, 0.25, pattern=pattern) - k).max() == 0.0
    other = box_mesh(divisions=(1, 1, 1))
    with pytest.raises(ValueError, match="stiffness pattern is for"):
        fem.stiffness_matrix(other.points, other.tets, 1e5, 0.25, pattern=pattern)


def test_zero_volume_element_is_named():
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0]], float)
    tets = np.array([[0, 1, 2, 3], [0, 1, 2, 4]])  # the second is flat (all in z = 0)
    with pytest.raises(ValueError, match="first: element 1"):
        fem.shape_gradients(points, tets)
