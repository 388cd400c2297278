"""The candidate placements of a search (fem_grasp.grasp.candidates): valid, spread, deterministic for a seed."""

import math

import numpy as np
import pytest

from fem_grasp import Body, box_mesh, rest
from fem_grasp.errors import SceneError
from fem_grasp.grasp.candidates import PAPER_TILT, candidate_grid, placement_candidates, squeeze_directions
from fem_grasp.grasp.placement import check_finger_placement

MU, RADIUS = 0.5, 0.01


@pytest.fixture(scope="module")
def resting_block():
    """The quick foam block: a 3 × 4 × 3 cm box on a 4 × 4 × 4 grid, resting."""
    body = Body(box_mesh((-0.015, -0.02, 0.0), (0.015, 0.02, 0.03), (4, 4, 4)), 2e4, 0.3, weight=0.3)
    return rest(body, MU)


def test_the_paper_squeeze_is_azimuth_90_at_the_paper_tilt():
    d1, d2 = squeeze_directions(90.0, PAPER_TILT)
    assert np.allclose(d1, [0.0, 0.974, -0.227], atol=2e-4) and np.allclose(d2, [0.0, -0.974, -0.227], atol=2e-4)


def test_every_candidate_is_antipodal_clear_of_the_table_outside_the_object_and_force_closure(resting_block):
    rs = resting_block
    cs = placement_candidates(rs, mu_finger=MU, mu_table=MU, radius=RADIUS, count=12, tilts=[0.0, PAPER_TILT, 25.0])
    assert len(cs) == 12 and cs.valid >= 12 and sum(cs.rejected.values()) > 0
    assert [c.index for c in cs] == list(range(12)) and len({c.key for c in cs}) == 12
    pos = rs.positions
    out = rs.body.mesh.outward_normals(pos)
    for c in cs:
        ij = list(c.finger_nodes)
        assert np.allclose(c.points, pos[ij])
        d1, d2 = c.directions
        assert math.isclose(-d1[2], math.sin(math.radians(c.tilt)), abs_tol=1e-12) and np.isclose(d1 @ d2,
                                                                                                   -math.cos(2 * math.radians(c.tilt)))
        line = (pos[ij[1]] - pos[ij[0]]) / np.linalg.norm(pos[ij[1]] - pos[ij[0]])
        inward = -out[ij] / np.linalg.norm(out[ij], axis=1, keepdims=True)
        assert inward[0] @ line >= math.cos(math.atan(MU)) - 1e-9 and -inward[1] @ line >= math.cos(math.atan(MU)) - 1e-9
        centers = pos[ij] + RADIUS * out[ij]
        clearance = max(0.1 * RADIUS, -d1[2] * c.max_squeeze)
        assert (centers[:, 2] - RADIUS - rs.table_z).min() >= clearance
        check_finger_placement(pos, rs.body.mesh.surface_nodes, centers, RADIUS, contact_nodes=ij, normals=out,
                               directions=np.stack([d1, c.ratio * d2]))
        assert c.closure_quality > 0


def test_the_same_seed_gives_the_same_candidates_and_the_choice_spreads(resting_block):
    kw = dict(mu_finger=MU, mu_table=MU, radius=RADIUS, count=6, azimuths=12)
    a = placement_candidates(resting_block, seed=3, **kw)
    b = placement_candidates(resting_block, seed=3, **kw)
    assert [c.to_dict() for c in a] == [c.to_dict() for c in b]
    assert a.valid > 6
    # spread: the six cover more than half of the azimuths' range
    az = sorted(c.azimuth for c in a)
    assert az[-1] - az[0] > 90
    everything = placement_candidates(resting_block, **{**kw, "count": 1000})
    assert len(everything) == everything.valid == a.valid  # fewer valid than asked: all of them


def test_the_grid_and_its_errors():
    g = candidate_grid(64)
    assert g["tilts"] == [PAPER_TILT] and g["ratios"] == [1.0] and len(g["azimuths"]) == g["heights"]
    assert max(g["azimuths"]) < 180  # s = 1: φ and φ + 180° are the same grasp
    assert max(candidate_grid(64, ratios=[0.5, 1.0])["azimuths"]) > 180
    assert candidate_grid(8, azimuths=(0, 90, 3))["azimuths"] == [0.0, 45.0, 90.0]
    with pytest.raises(SceneError, match="tilt"):
        candidate_grid(8, tilts=[-10.0])
    with pytest.raises(SceneError, match="ratio"):
        candidate_grid(8, ratios=[-1.0])


def test_heights_outside_the_object_are_refused(resting_block):
    with pytest.raises(SceneError, match="fractions"):
        placement_candidates(resting_block, mu_finger=MU, mu_table=MU, radius=RADIUS, heights=[1.5])
