"""fem_grasp against FEniCSx/dolfinx on small meshes (verification/dolfinx/).

These tests need dolfinx: they fail, rather than skip, when it is missing —
the cross-check is part of what the project promises.  Only the gmsh-made
ellipsoid is skipped without gmsh.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # `pytest` run without `python -m` does not put the root on sys.path
    sys.path.insert(0, str(ROOT))

import dolfinx  # noqa: E402,F401  - a hard requirement: ImportError must fail the run

from fem_grasp import Body, CollinearContactError, TetMesh, box_mesh, solve_contact  # noqa: E402
from verification._common import render  # noqa: E402
from verification.dolfinx import crosscheck  # noqa: E402
from verification.dolfinx.crosscheck import rel_max_diff, rigid_fields  # noqa: E402
from verification.dolfinx.manufactured import GENERAL_FIELD, solve_fem_grasp_p1  # noqa: E402
from verification.dolfinx.quadrature import tetrahedron_rule  # noqa: E402
from verification.dolfinx.reference import DolfinxModel, solve_manufactured  # noqa: E402

pytestmark = pytest.mark.dolfinx

TIGHT = 1e-12  # operators: K, G, energies, null space
SOLVE = 1e-9  # contact solves


def _ellipsoid() -> TetMesh:
    pytest.importorskip("gmsh")
    from fem_grasp.mesh.shapes import ellipsoid

    return TetMesh(*ellipsoid((0.04, 0.03, 0.025), 0.012))


MESHES = {
    "box": lambda: box_mesh((0, 0, 0), (0.04, 0.03, 0.02), (4, 3, 3)),
    "ellipsoid": _ellipsoid,
}


@pytest.fixture(scope="module", params=sorted(MESHES))
def pair(request) -> tuple[Body, DolfinxModel]:
    mesh = MESHES[request.param]()
    body = Body(mesh, young=5e4, poisson=0.35, weight=1.2)
    return body, DolfinxModel(mesh)


def test_dof_map_is_a_permutation(pair):
    body, model = pair
    n = body.n_nodes
    assert np.array_equal(np.sort(model.perm), np.arange(3 * n))
    coords = model.V.tabulate_dof_coordinates()
    assert np.allclose(coords[model.block_of_node], body.mesh.points, rtol=0, atol=1e-12 * body.mesh.diameter)


def test_stiffness_matches_dolfinx(pair):
    body, model = pair
    assert rel_max_diff(body.stiffness, model.stiffness(body.young, body.poisson)) <= TIGHT


def test_gravity_matches_dolfinx_and_lumping(pair):
    body, model = pair
    gd = model.gravity_loads(body.density, body.gravity)
    assert rel_max_diff(body.gravity_loads, gd) <= TIGHT
    # dolfinx's consistent P1 load ∫ρg φ_a is exactly §II-B's lumping: a quarter of each element's weight per vertex.
    mesh = body.mesh
    lumped = np.zeros((mesh.n_points, 3))
    np.add.at(lumped[:, 2], mesh.tets.ravel(), np.repeat(-body.density * body.gravity * mesh.volumes / 4.0, 4))
    assert rel_max_diff(gd, lumped.ravel()) <= TIGHT
    assert abs(gd.sum() + body.weight) <= TIGHT * body.weight


def test_strain_energy_of_random_fields(pair):
    body, model = pair
    rng = np.random.default_rng(1)
    for _ in range(4):
        u = 1e-3 * body.mesh.diameter * rng.standard_normal(3 * body.n_nodes)
        e_dx = model.strain_energy(u, body.young, body.poisson)
        assert abs(body.strain_energy(u) - e_dx) <= TIGHT * e_dx


def test_rigid_modes_are_the_null_space(pair):
    body, model = pair
    kd = model.stiffness(body.young, body.poisson)
    norm = crosscheck.norm2(kd)
    modes = rigid_fields(body.mesh.points, body.center_of_mass)
    for r in modes.T:
        assert np.linalg.norm(kd @ r) <= TIGHT * norm * np.linalg.norm(r)
        assert np.linalg.norm(body.stiffness @ r) <= TIGHT * norm * np.linalg.norm(r)
    assert rel_max_diff(body.rigid_modes, modes) <= TIGHT


def test_six_zero_eigenvalues(pair):
    body, model = pair
    norm = crosscheck.norm2(body.stiffness)
    assert np.all(np.abs(crosscheck.null_eigenvalues(body.stiffness)) <= TIGHT * norm)
    elastic = crosscheck.elastic_eigenvalues(body.stiffness, body.rigid_modes)
    assert elastic[0] > 1e-6 * norm
    reference = crosscheck.elastic_eigenvalues(model.stiffness(body.young, body.poisson), body.rigid_modes)
    assert np.all(np.abs(elastic - reference) <= TIGHT * norm)


@pytest.mark.parametrize("backend", ["sparse", "spectral"])
@pytest.mark.parametrize("case_index", [0, 1], ids=["grasp", "random"])
def test_contact_solution_matches_dolfinx(pair, backend, case_index):
    body, model = pair
    case = crosscheck.contact_cases(body, np.random.default_rng(3))[case_index]
    assert len(case.nodes) >= 3
    sol = solve_contact(body, case.nodes, case.displacements, backend=backend)
    ref = model.solve_contact(body.young, body.poisson, body.density, body.gravity, case.nodes, case.displacements)
    assert rel_max_diff(sol.displacements, ref.displacements) <= SOLVE
    assert rel_max_diff(sol.forces, ref.forces) <= SOLVE
    assert abs(sol.strain_energy - ref.strain_energy) <= SOLVE * ref.strain_energy
    assert max(sol.equilibrium_residual()) <= 1e-10
    # dolfinx's reactions balance gravity too: an independent check of the sign convention F = KΔ − G.
    assert np.linalg.norm(ref.forces.sum(axis=0) - [0.0, 0.0, body.weight]) <= 1e-10 * body.weight


def test_collinear_contacts_are_refused():
    body = Body(box_mesh((0, 0, 0), (0.04, 0.04, 0.04), (2, 2, 2)), 1e5, 0.3, weight=1.0)
    p = body.mesh.points
    line = np.flatnonzero(np.isclose(p[:, 1], 0) & np.isclose(p[:, 2], 0))
    assert len(line) == 3
    for backend in ("sparse", "spectral"):
        with pytest.raises(CollinearContactError):
            solve_contact(body, line, np.zeros((3, 3)), backend=backend)


def test_quadrature_rule_is_exact_to_degree_5():
    from math import factorial

    bary, w = tetrahedron_rule(3)
    x, y, z = bary[:, 1], bary[:, 2], bary[:, 3]
    for a, b, c in [(0, 0, 0), (1, 2, 0), (2, 0, 3), (1, 1, 1), (5, 0, 0), (0, 2, 3)]:
        exact = 6.0 * factorial(a) * factorial(b) * factorial(c) / factorial(a + b + c + 3)
        assert abs(w @ (x**a * y**b * z**c) - exact) <= 1e-14


def test_manufactured_solution_p1_matches_dolfinx_and_converges():
    errs = []
    for n in (3, 6):
        mesh = box_mesh(divisions=(n, n, n))
        fg = solve_fem_grasp_p1(mesh, GENERAL_FIELD, 1e5, 0.3)
        dx = solve_manufactured(mesh, GENERAL_FIELD, 1e5, 0.3, degree=1)
        assert abs(fg.energy_error / dx.energy_error - 1) <= 1e-3
        assert abs(fg.l2_error / dx.l2_error - 1) <= 1e-3
        errs.append(fg)
    assert 0.8 <= np.log2(errs[0].energy_error / errs[1].energy_error) <= 1.2
    assert 1.6 <= np.log2(errs[0].l2_error / errs[1].l2_error) <= 2.4


def test_offscreen_render(tmp_path):
    plt = pytest.importorskip("matplotlib.pyplot")
    body = Body(box_mesh((0, 0, 0), (0.04, 0.03, 0.02), (3, 2, 2)), 1e4, 0.3, weight=1.0)
    case = crosscheck.contact_cases(body, np.random.default_rng(0))[0]
    sol = solve_contact(body, case.nodes, case.displacements)
    paths = render.render([render.contact_job(sol, tmp_path / "contact.png", "box", size=(320, 240)),
                           render.mesh_job(body.mesh, tmp_path / "mesh.png", "box", size=(200, 160))])
    for path, (w, h) in zip(paths, [(320, 240), (200, 160)]):
        image = plt.imread(path)
        assert image.shape[:2] == (h, w)
        rgb = image[..., :3].reshape(-1, 3)
        assert len(np.unique(np.round(rgb, 2), axis=0)) > 10  # not a blank frame
        assert (np.abs(rgb - 1.0).max(axis=1) > 0.05).mean() > 0.02  # something other than the white background
