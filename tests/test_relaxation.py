"""The static stick/slide/release state of all contacts at once (fem_grasp.relaxation).

Checked against a hand-computed single contact, and on a real body (a box
squeezed sideways on the table) against Coulomb's law at every contact.
"""

import numpy as np
import pytest

from fem_grasp import Body, box_mesh
from fem_grasp.relaxation import RELEASE, SLIDE, STICK, RelaxationFailure, relax_contacts

UP = np.array([0.0, 0.0, 1.0])


@pytest.mark.parametrize("force, status", [((0.2, 0.0, 1.0), STICK), ((0.8, 0.0, 1.0), SLIDE),
                                           ((0.3, 0.1, -0.5), RELEASE)])
def test_one_table_contact_by_hand(force, status):
    k, mu = 50.0, 0.5
    f0 = np.array([force])
    res = relax_contacts(k * np.eye(3), f0, np.zeros((1, 3)), [None], UP, np.array([mu]), force_scale=1.0)
    assert res.status[0] == status
    if status == STICK:
        assert np.all(res.displacements == 0) and np.allclose(res.forces, f0)
    elif status == SLIDE:
        # Isotropic stiffness: it slides straight back by (f_t − μ f_n)/k, its normal force unchanged.
        slide = (0.8 - mu * 1.0) / k
        assert res.displacements[0] == pytest.approx([-slide, 0.0, 0.0], abs=1e-13)
        assert res.forces[0] == pytest.approx([mu, 0.0, 1.0], abs=1e-11)
        assert res.slips[0] == pytest.approx(slide, rel=1e-10)
    else:
        assert np.allclose(res.forces, 0.0, atol=1e-14)
        assert res.displacements[0, 2] > 0  # it lifts off the table


def _squeezed_box(mu=0.5, depth=2e-3):
    body = Body(box_mesh((-0.015, -0.02, 0.0), (0.015, 0.02, 0.03), (3, 3, 3)), 2e4, 0.3, weight=0.3)
    p = body.mesh.points
    table = np.flatnonzero(np.isclose(p[:, 2], 0.0))
    side = [int(np.argmin(np.linalg.norm(p - q, axis=1))) for q in ([0, -0.02, 0.02], [0, 0.02, 0.02])]
    nodes = np.concatenate([table, side])
    resp = body.contact_response(nodes)
    radius = 0.01
    # The fingers push the side nodes inward and downward (paper §IV's squeeze directions).
    d = np.array([[0.0, 0.974, -0.227], [0.0, -0.974, -0.227]])
    disp = np.zeros((len(nodes), 3))
    disp[-2:] = depth * d
    forces = (resp.reduced_stiffness @ disp.reshape(-1)).reshape(-1, 3) + resp.gravity_forces
    q0 = p[nodes] + disp
    centers = [None] * len(table) + [q0[-2] + radius * np.array([0, -1.0, 0]), q0[-1] + radius * np.array([0, 1.0, 0])]
    mu_k = np.full(len(nodes), mu)
    return resp.reduced_stiffness, forces, q0, centers, mu_k, radius


def test_a_squeezed_box_reaches_a_state_that_obeys_coulombs_law_everywhere():
    c, f0, q0, centers, mu, radius = _squeezed_box()
    fs = float(np.abs(f0).max())
    res = relax_contacts(c, f0, q0, centers, UP, mu, fs)
    assert set(res.status) >= {STICK, SLIDE}  # a real mix: some table nodes slide outward, some stick
    assert np.allclose(res.forces, f0 + (c @ res.displacements.reshape(-1)).reshape(-1, 3), atol=1e-14 * fs)
    fn = np.einsum("ki,ki->k", res.forces, res.normals)
    ft = res.forces - fn[:, None] * res.normals
    ftn = np.linalg.norm(ft, axis=1)
    for k, st in enumerate(res.status):
        q = q0[k] + res.displacements[k]
        gap = q[2] - q0[k][2] if centers[k] is None else np.linalg.norm(q - centers[k]) - radius
        if st == STICK:
            assert np.all(res.displacements[k] == 0)
            assert fn[k] >= 0 and ftn[k] <= mu[k] * fn[k] + 1e-10 * fs
        elif st == SLIDE:
            assert abs(gap) < 1e-15  # on its obstacle: the plane, or the fingertip sphere
            assert fn[k] > 0 and ftn[k] == pytest.approx(mu[k] * fn[k], abs=1e-10 * fs)
            # Friction opposes the motion (maximum dissipation): f_t ∥ −(tangential part of δ).
            move = res.displacements[k] - (res.displacements[k] @ res.normals[k]) * res.normals[k]
            assert ft[k] @ move / (ftn[k] * np.linalg.norm(move)) == pytest.approx(-1.0, abs=1e-6)
        else:
            assert np.allclose(res.forces[k], 0, atol=1e-10 * fs) and gap >= 0
    # The state is static: relaxing it again moves nothing.
    again = relax_contacts(c, res.forces, q0 + res.displacements, centers, UP, mu, fs)
    assert np.all(again.status != SLIDE) or np.abs(again.displacements).max() < 1e-12 * radius


def test_a_sideways_load_no_friction_can_hold_is_refused():
    body = Body(box_mesh((-0.015, -0.02, 0.0), (0.015, 0.02, 0.03), (3, 3, 3)), 2e4, 0.3, weight=0.3)
    p = body.mesh.points
    table = np.flatnonzero(np.isclose(p[:, 2], 0.0))
    c = body.contact_response(table).reduced_stiffness
    # Only the table holds, and the load's tangential total is twice what μ times its normal total allows.
    # C annihilates rigid translations, so the force sum is the same whatever the contacts do: no static
    # state exists, and the contacts slide on until the slip bound.
    f = np.tile([1.0, 0.0, 1.0], (len(table), 1))
    with pytest.raises(RelaxationFailure, match="cannot hold|no longer hold"):
        relax_contacts(c, f, p[table], [None] * len(table), UP, np.full(len(table), 0.5), 1.0, max_slip=1e-3,
                       max_sweeps=2000)


def test_a_release_beyond_the_slip_bound_is_refused_not_returned():
    # A nearly free contact pulled off the table would fly a kilometre to carry no force: refused by name
    # (never an overflow or a NaN in the result).
    with pytest.raises(RelaxationFailure, match="no longer hold"):
        relax_contacts(1e-3 * np.eye(3), np.array([[0.0, 0.0, -1.0]]), np.zeros((1, 3)), [None], UP,
                       np.array([0.5]), force_scale=1.0, max_slip=1e-2)
