"""The rendered report (fem_grasp.io.report): pictures exist, are not blank, and report.html shows them all."""

import numpy as np
import pytest

from fem_grasp.cli import main
from fem_grasp.io.report import PICTURES
from tests.helpers import cli_run

pytest.importorskip("pyvista")
pytest.importorskip("matplotlib")


@pytest.fixture(scope="module")
def report():
    code, out = cli_run("foam_block", "--no-lift")
    assert main(["report", str(out), "--quiet"]) == 0
    return out


def test_pictures_are_rendered_and_not_blank(report):
    from matplotlib.image import imread

    for name in PICTURES:
        img = imread(report / name)[..., :3]
        assert img.shape[0] > 300 and img.shape[1] > 500, name
        # Not a blank canvas: many distinct colours, and the centre of the 3D views holds the object.
        rgb = (img.reshape(-1, 3) * 255).astype(np.int64)
        colours = len(np.unique(rgb[:, 0] * 65536 + rgb[:, 1] * 256 + rgb[:, 2]))
        assert colours > 50, (name, colours)
    for name in ("rest.png", "lift_start.png", "lifted.png"):
        img = imread(report / name)[..., :3]
        h, w = img.shape[:2]
        centre = img[h // 3: 2 * h // 3, w // 4: 3 * w // 4]
        assert (centre.min(axis=2) < 0.9).mean() > 0.2, name  # at least a fifth of the centre is not white


def test_html_references_every_picture_and_the_data(report):
    text = (report / "report.html").read_text()
    for name in PICTURES:
        assert f'src="{name}"' in text
    assert 'href="result.json"' in text and "object.pvd" in text and "foam_block" in text
