"""The rigid fingertip pressed into a block (verification/hertz/indenter.py): its quadrature, mortar matrices,
complementarity solver and contact answers."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.optimize

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # `pytest` run without `python -m` does not put the root on sys.path
    sys.path.insert(0, str(ROOT))

pytest.importorskip("verification", reason="the source tree's verification/ package (not installed with fem_grasp)")
pytest.importorskip("gmsh")

from verification.hertz import hertz_force  # noqa: E402
from verification.hertz.indenter import (  # noqa: E402
    BlockIndentation,
    complementarity,
    dual_moments,
    indenter_study,
    quarter_block,
    triangle_moments,
)
from verification.hertz.report import indenter_checks  # noqa: E402


def _monomial_integral(area: float, powers: tuple[int, int, int]) -> float:
    """∫ λ₁^a λ₂^b λ₃^c dA over a triangle = 2 A a! b! c! / (a + b + c + 2)!."""
    a, b, c = powers
    return 2.0 * area * math.factorial(a) * math.factorial(b) * math.factorial(c) / math.factorial(a + b + c + 2)


def test_hat_function_moments_are_exact_for_a_quadratic_profile():
    """∫ N_i (x² + y²) dA (a cubic in the barycentric coordinates) by the degree-4 rule, against the exact monomial
    integrals; the element mass factor's entries sum to the area, each row to a third of it."""
    rng = np.random.default_rng(3)
    xy = rng.uniform(-1.0, 1.0, size=(5, 3, 2))
    area, moments, element = triangle_moments(xy, lambda q: (q**2).sum(axis=-1))
    for t in range(len(xy)):
        e1, e2 = xy[t, 1] - xy[t, 0], xy[t, 2] - xy[t, 0]
        assert area[t] == pytest.approx(0.5 * abs(e1[0] * e2[1] - e1[1] * e2[0]), rel=1e-14)
        for i in range(3):
            exact = 0.0
            for j in range(3):
                for k in range(3):
                    powers = [0, 0, 0]
                    for idx in (i, j, k):
                        powers[idx] += 1
                    exact += xy[t, j] @ xy[t, k] * _monomial_integral(area[t], tuple(powers))
            assert moments[t, i] == pytest.approx(exact, rel=1e-12)
    assert element.sum() == pytest.approx(1.0, rel=1e-15)
    np.testing.assert_allclose(element.sum(axis=1), 1.0 / 3.0, rtol=1e-15)


def test_complementarity_solves_the_bound_constrained_quadratic_program():
    """The active-set answer is the minimiser of ½ λᵀAλ − bᵀλ over λ ≥ 0 (NNLS on A's Cholesky factor),
    with g = Aλ − b ≥ 0 and λ·g = 0 to round-off."""
    rng = np.random.default_rng(7)
    for n in (5, 40):
        q = rng.standard_normal((n, n))
        a = q @ q.T + n * np.eye(n)
        b = rng.standard_normal(n) * n
        lam, g, _ = complementarity(a, b)
        low = np.linalg.cholesky(a)
        ref, _ = scipy.optimize.nnls(low.T, np.linalg.solve(low, b))
        np.testing.assert_allclose(lam, ref, atol=1e-10 * np.abs(ref).max())
        assert lam.min() >= 0.0
        assert g.min() >= -1e-12 * np.abs(b).max()
        assert np.abs(lam * g).max() <= 1e-12 * np.abs(b).max() * np.abs(lam).max()


@pytest.fixture(scope="module")
def indentation():
    radius = 0.01
    a = math.sqrt(radius * 0.02 * radius)
    mesh = quarter_block(radius, radius, 0.25 * a, 0.08 * radius, 1.3 * a)
    return BlockIndentation(mesh, radius, 2e4, 0.3, 1.6 * a)


def test_mortar_matrices(indentation):
    """The surface mass matrix is symmetric positive definite with row sums ∫ N_k dA (so a uniform gap weighs
    as a node's area), and the sphere's height moments lie between the smallest and largest h times the area."""
    m, areas = indentation.mass, indentation.areas
    np.testing.assert_allclose(m, m.T, atol=0)
    assert np.linalg.eigvalsh(m).min() > 0
    np.testing.assert_allclose(m.sum(axis=1), areas, rtol=1e-13)
    np.testing.assert_allclose(indentation.mortar, indentation.mortar.T, rtol=1e-9, atol=1e-9 * np.abs(
        indentation.mortar).max())
    on = areas > 0
    mean_height = indentation.height_moments[on] / areas[on]
    assert (mean_height >= 0).all() and (mean_height <= indentation.heights.max() * 1.5).all()


def test_every_contact_satisfies_its_conditions_and_approaches_hertz(indentation):
    """At three indentations the three discretisations give a force growing with δ, near Hertz's (the block is
    finite and clamped: within 20 %), and within 10 % of each other; no tension, no penetration."""
    radius = indentation.radius
    deltas = np.array([0.005, 0.01, 0.02]) * radius
    hertz = hertz_force(deltas, radius, 2e4, 0.3)
    for method in (indentation.node_contact, indentation.weighted_gap, indentation.dual_gap):
        rows = [method(d) for d in deltas]
        forces = np.array([r["force"] for r in rows])
        assert (np.diff(forces) > 0).all()
        np.testing.assert_allclose(forces / hertz, 1.0, atol=0.2)
        for r in rows:
            assert r["max_tension_rel"] <= 1e-12
            assert r["max_penetration_rel"] <= 1e-9
            assert r["max_complementarity_rel"] <= 1e-9
            assert r["n_active"] >= 3
    node = np.array([indentation.node_contact(d)["force"] for d in deltas])
    for method in (indentation.weighted_gap, indentation.dual_gap):
        np.testing.assert_allclose(np.array([method(d)["force"] for d in deltas]) / node, 1.0, atol=0.1)


def test_dual_heights_are_exact_for_a_linear_profile(indentation):
    """The dual basis reproduces a P1 function's nodal values (∫ Φ_k f dA = A_k f_k, triangle by triangle): a plane's
    heights in place of the sphere's come back at the nodes."""
    xy = indentation.mesh.points[indentation.candidates][:, :2]
    plane = lambda q: 0.3 * q[..., 0] - 0.7 * q[..., 1] + 0.01  # noqa: E731
    tris = indentation.triangles
    _, moments, _ = triangle_moments(xy[tris], plane)
    dual = np.bincount(tris.ravel(), dual_moments(moments).ravel(), minlength=len(xy))
    inner = indentation.areas > 0
    np.testing.assert_allclose(dual[inner] / indentation.areas[inner], plane(xy[inner]), rtol=1e-12, atol=1e-15)


def test_quick_study_passes_its_checks():
    """The study's quick configuration: every headline check of the report passes."""
    from verification.hertz import INDENTER_CONFIGS

    study = indenter_study(**INDENTER_CONFIGS["quick"])
    checks = indenter_checks({"indenter": study})
    assert checks and all(c["ok"] for c in checks), [c for c in checks if not c["ok"]]
