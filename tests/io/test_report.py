"""The rendered report (fem_grasp.io.report): pictures exist, are not blank, show what a mechanician reads, and
report.html shows them all."""

import shutil

import numpy as np
import pytest

from fem_grasp.cli import main
from fem_grasp.io.output import read_result
from fem_grasp.io.report import LIFTED_CLEARANCE, PICTURES, render_views
from tests.helpers import cli_run

pytest.importorskip("pyvista")
pytest.importorskip("matplotlib")


@pytest.fixture(scope="module")
def report():
    code, out = cli_run("foam_block")  # picked up: rest, lift start and lifted
    assert code == 0
    assert main(["report", str(out), "--quiet"]) == 0
    return out


@pytest.fixture(scope="module")
def views(report, tmp_path_factory):
    """What render_views drew (a second rendering, into a copy of the folder)."""
    copy = tmp_path_factory.mktemp("views") / "o"
    shutil.copytree(report, copy)
    doc = read_result(copy)
    return {v["path"].rsplit("/", 1)[-1]: v for v in render_views(copy, doc)}, doc, copy


def _image(path):
    from matplotlib.image import imread

    return imread(path)[..., :3]


def test_pictures_are_rendered_and_not_blank(report):
    for name in PICTURES:
        img = _image(report / name)
        assert img.shape[0] > 300 and img.shape[1] > 500, name
        # Not a blank canvas: many distinct colours, and the centre of the 3D views holds the object.
        rgb = (img.reshape(-1, 3) * 255).astype(np.int64)
        colours = len(np.unique(rgb[:, 0] * 65536 + rgb[:, 1] * 256 + rgb[:, 2]))
        assert colours > 50, (name, colours)
    for name in ("rest.png", "lift_start.png", "lifted.png"):
        img = _image(report / name)
        h, w = img.shape[:2]
        centre = img[h // 3: 2 * h // 3, w // 4: 3 * w // 4]
        assert (centre.min(axis=2) < 0.9).mean() > 0.2, name  # at least a fifth of the centre is not white


def test_force_arrows_point_at_their_nodes_from_outside_the_object_and_show_through_the_fingertips(views):
    """Each finger-force arrow ends at its contact node and starts outside the object; the fingertips are
    translucent, so the arrowheads on the finger facing the camera are seen (red) in the picture."""
    drawn, doc, out = views
    v = drawn["lift_start.png"]
    assert v["arrows"] and len(v["fingertips"]) == 2
    img = _image(out / "lift_start.png")
    h, w = img.shape[:2]
    near = int(np.argmax([f["center"][1] for f in v["fingertips"]]))  # the camera looks from +x, +y
    c = np.asarray(v["fingertips"][near]["center"])
    seen = []
    for a in v["arrows"]:
        tip, tail = np.asarray(a["tip"]), np.asarray(a["tail"])
        r = np.asarray(v["fingertips"][0]["center"]), np.asarray(v["fingertips"][1]["center"])
        on = min(abs(np.linalg.norm(tip - q) - v["fingertips"][0]["radius"]) for q in r)
        assert on < 1e-6, "the arrow's tip is its contact node, on a fingertip"
        # the tail is on the fingertip's side of the node: the arrow comes from outside the object
        q = r[int(np.argmin([np.linalg.norm(tip - x) for x in r]))]
        assert (tail - tip) @ (q - tip) > 0
        longest = max(b["length"] for b in v["arrows"])
        if np.linalg.norm(tip - c) < 2 * v["fingertips"][near]["radius"] and a["length"] > 0.3 * longest:
            x, y = (int(round(t)) for t in a["head_px"])
            assert 0 <= x < w and 0 <= y < h
            patch = img[max(y - 1, 0): y + 2, max(x - 1, 0): x + 2].reshape(-1, 3)
            seen.append(bool(((patch[:, 0] - patch[:, 1] > 0.25) & (patch[:, 0] - patch[:, 2] > 0.25)).any()))
    assert seen and np.mean(seen) >= 0.75, seen  # red arrowheads, not hidden by an opaque fingertip


def test_stick_and_slip_are_shown_node_by_node_with_a_legend(views):
    drawn, doc, out = views
    for name, v in drawn.items():
        assert any(lbl.startswith("contact") for lbl in v["legend"]) or name == "rest.png"
        if v["n_slip"]:
            assert f"contact slides ({v['n_slip']})" in v["legend"]
            img = _image(out / name)
            orange = (img[..., 0] > 0.85) & (np.abs(img[..., 1] - 0.5) < 0.12) & (img[..., 2] < 0.2)
            assert orange.sum() > 20, name  # the orange dots are in the picture
        if v["n_stick"]:
            assert f"contact sticks ({v['n_stick']})" in v["legend"]
    last = doc["series"]["frames"][-1]
    snap = doc["result"]["snapshots"][last["snapshot"]]
    assert drawn["lifted.png"]["n_slip"] == sum(sum(s) for s in snap["sliding"].values())


def test_the_lifted_picture_shows_the_object_off_the_table(views):
    drawn, doc, out = views
    import meshio

    height = float(np.ptp(meshio.read(out / doc["series"]["frames"][0]["file"]).points[:, 2]))
    lifted = drawn["lifted.png"]
    assert lifted["lift_offset"] == pytest.approx(LIFTED_CLEARANCE * height)
    assert lifted["table_gap"] >= 0.2 * height  # a visible distance, not the lift-off instant
    assert drawn["rest.png"]["lift_offset"] == 0 and drawn["rest.png"]["table_gap"] == pytest.approx(0, abs=1e-6)


def test_the_colour_is_a_stress_with_its_unit_and_can_be_the_elastic_displacement(views):
    drawn, doc, out = views
    for v in drawn.values():
        assert v["colour"] == "von Mises stress (kPa, log scale)" and 0 < v["clim"][0] < v["clim"][1]
    other = render_views(out, doc, colour="elastic")
    assert other[0]["colour"] == "|displacement less its rigid motion| (mm)"
    with pytest.raises(ValueError, match="colour must be one of"):
        render_views(out, doc, colour="rainbow")


def test_html_references_every_picture_the_data_and_the_finger_forces(report):
    text = (report / "report.html").read_text()
    for name in PICTURES:
        assert f'src="{name}"' in text
    assert 'href="result.json"' in text and "object.pvd" in text and "foam_block" in text
    assert "Finger forces at lift-off (N)" in text and "grip (along its squeeze direction)" in text
    assert "Table III of the paper compares the normal sum" in text and "finger path" in text
