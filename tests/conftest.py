import numpy as np
import pytest

from fem_grasp import Body, box_mesh


@pytest.fixture(scope="session")
def box_body() -> Body:
    """A 4×3×2 cm box of 1 N, mildly soft, on a 4×3×3 grid."""
    mesh = box_mesh((0, 0, 0), (0.04, 0.03, 0.02), (4, 3, 3))
    return Body(mesh, young=5e4, poisson=0.3, weight=1.0)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
