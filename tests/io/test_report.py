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


def test_run_with_report_draws_in_the_renderer_it_started_beside_the_pickup():
    """``fem-grasp run --report`` starts the render process (warmed: pyvista loaded, one picture drawn) before
    the pickup and draws the report's pictures in it: every picture there and not blank, as the report
    command's; ``start_views`` hands the 3-D views to the process and returns at once."""
    from fem_grasp.io.render import render_process, start_views, warm_renderer

    code, out = cli_run("foam_block", "--report")
    assert code == 0 and (out / "report.html").exists()
    for name in PICTURES:
        rgb = (_image(out / name).reshape(-1, 3) * 255).astype(np.int64)
        assert len(np.unique(rgb[:, 0] * 65536 + rgb[:, 1] * 256 + rgb[:, 2])) > 50, name
    with render_process(warm=True) as pool:
        assert pool.apply(warm_renderer) is None  # warming twice is harmless
        handle = start_views(out, read_result(out), pool)  # drawn while this process goes on
        drawn = handle.get(timeout=300)
    assert sorted(v["path"].rsplit("/", 1)[-1] for v in drawn) == ["lift_start.png", "lifted.png", "rest.png"]
    assert all(v["n_stick"] + v["n_slip"] > 0 for v in drawn[1:])  # the squeezed frames show their contacts


def test_force_arrows_point_at_their_nodes_from_outside_the_object_and_both_fingers_are_seen(views):
    """Each finger-force arrow ends at its contact node and starts outside the object; the fingertips are
    translucent and the camera looks across the squeeze axis, so the arrows of both fingers are seen (red) in the
    picture."""
    drawn, doc, out = views
    v = drawn["lift_start.png"]
    assert v["arrows"] and len(v["fingertips"]) == 2
    img = _image(out / "lift_start.png")
    h, w = img.shape[:2]
    r = [np.asarray(f["center"]) for f in v["fingertips"]]
    longest = max(b["length"] for b in v["arrows"])
    seen: dict[int, list[bool]] = {0: [], 1: []}
    for a in v["arrows"]:
        tip, tail = np.asarray(a["tip"]), np.asarray(a["tail"])
        on = min(abs(np.linalg.norm(tip - q) - v["fingertips"][0]["radius"]) for q in r)
        assert on < 1e-6, "the arrow's tip is its contact node, on a fingertip"
        # the tail is on the fingertip's side of the node: the arrow comes from outside the object
        finger = int(np.argmin([np.linalg.norm(tip - x) for x in r]))
        assert (tail - tip) @ (r[finger] - tip) > 0
        if a["length"] > 0.3 * longest:
            x, y = (int(round(t)) for t in a["shaft_px"])
            assert 0 <= x < w and 0 <= y < h
            patch = img[max(y - 1, 0): y + 2, max(x - 1, 0): x + 2].reshape(-1, 3)
            seen[finger].append(bool(((patch[:, 0] - patch[:, 1] > 0.25) & (patch[:, 0] - patch[:, 2] > 0.25)).any()))
    for finger, s in seen.items():  # red shafts on both sides, neither finger hidden by the object
        assert s and np.mean(s) >= 0.75, (finger, seen)


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


def test_the_camera_looks_across_the_squeeze_axis_from_above_so_both_fingertips_are_seen(views):
    """The 3D views' camera is perpendicular to the line between the fingertips, above the object: both
    fingertips lie at the same distance from it, and the line of sight to each fingertip centre misses the object
    (neither is behind it), where a camera along the squeeze axis has one fingertip hidden."""
    from fem_grasp.io.report import view_direction

    drawn, doc, out = views
    for name, v in drawn.items():
        if len(v["fingertips"]) != 2:
            continue
        c1, c2 = (np.asarray(f["center"]) for f in v["fingertips"])
        cam, focal = np.asarray(v["camera"]), np.asarray(v["focal"])
        look = (cam - focal) / np.linalg.norm(cam - focal)
        axis = (c2 - c1) / np.linalg.norm(c2 - c1)
        assert abs(look @ axis) < 0.05, name  # across the squeeze axis (the pictures share the lift start's)
        assert look[2] > 0.3, name  # from above
        assert np.linalg.norm(cam - c1) == pytest.approx(np.linalg.norm(cam - c2), rel=0.05), name

    # on a ball of radius 1 squeezed along an arbitrary horizontal axis, with fingertips of radius 0.5
    rng = np.random.default_rng(3)
    for _ in range(20):
        a = rng.normal(size=3)
        a[2] = 0.3 * a[2]  # squeeze directions tilt a little, as the paper's do
        a /= np.linalg.norm(a)
        centres = np.array([-1.5 * a, 1.5 * a])
        v = view_direction(centres)
        assert abs(v @ a) < 1e-9 and v[2] > 0
        cam = 8.0 * v
        for c in centres:  # the sight line from the camera to each fingertip centre stays outside the ball
            d = c - cam
            t = np.clip(-(cam @ d) / (d @ d), 0.0, 1.0)
            assert np.linalg.norm(cam + t * d) > 1.0
        # the old fixed oblique camera, looking along the squeeze axis, hides the far fingertip
        cam_along = 8.0 * a
        d = centres[0] - cam_along
        t = np.clip(-(cam_along @ d) / (d @ d), 0.0, 1.0)
        assert np.linalg.norm(cam_along + t * d) < 1.0


def test_the_lifted_picture_says_one_lift_height_and_how_it_was_drawn(views):
    drawn, doc, out = views
    lifted = drawn["lifted.png"]
    frame = doc["series"]["frames"][-1]
    shown = 1e3 * (frame["lift_height"] + lifted["lift_offset"])
    assert f"fingers raised {shown:.3g} mm" in lifted["title"], lifted["title"]  # where the picture shows them
    assert f"the table let go at {1e3 * frame['lift_height']:.3g} mm" in lifted["note"], lifted["note"]
    assert f"drawn {1e3 * lifted['lift_offset']:.3g} mm higher" in lifted["note"]
    assert "lift =" not in lifted["title"]
