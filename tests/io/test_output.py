"""Outputs (fem_grasp.io.output): result.json schema, ParaView time series read back with meshio, atomic writes."""

import json
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest

from fem_grasp.io.output import (
    MARKER,
    SCHEMA,
    SCHEMA_VERSION,
    OutputError,
    atomic_write_text,
    hemisphere,
    prepare_out_dir,
    read_result,
)
from tests.helpers import cli_run


@pytest.fixture(scope="module")
def run():
    code, out = cli_run("foam_block", "--no-lift")
    return out, read_result(out)


def _pvd_files(path):
    return [(float(d.get("timestep")), d.get("file")) for d in ET.parse(path).getroot().iter("DataSet")]


def test_result_json_has_schema_summary_and_no_stray_files(run):
    out, doc = run
    assert doc["schema"] == SCHEMA and doc["schema_version"] == SCHEMA_VERSION
    for key in ("success", "reason", "squeeze_depth", "n_final_contacts", "finger_normal_force", "event_counts"):
        assert key in doc["summary"]
    assert doc["summary"]["n_events"] == len(doc["result"]["events"]) == sum(doc["summary"]["event_counts"].values())
    json.loads((out / "result.json").read_text(), parse_constant=lambda c: pytest.fail(f"non-strict JSON {c}"))
    assert not list(out.rglob("*.tmp*")) and not list(out.rglob(".*.vtu"))  # atomic writes leave nothing behind
    listed = set(json.loads((out / MARKER).read_text())["files"])
    on_disk = {str(p.relative_to(out)) for p in out.rglob("*") if p.is_file() and p.name != MARKER}
    assert listed == on_disk


def test_time_series_round_trips_and_matches_result_json(run):
    out, doc = run
    res = doc["result"]
    frames = doc["series"]["frames"]
    steps = _pvd_files(out / "object.pvd")
    assert [f for _, f in steps] == [fr["file"] for fr in frames] and [t for t, _ in steps] == list(range(len(steps)))
    assert frames[0]["label"] == "rest" and len(frames) == len(res["snapshots"]) + 1
    reference = None
    for fr in frames:
        m = meshio.read(out / fr["file"])
        pd = m.point_data
        assert set(pd) == {"displacement", "contact_state", "contact_body", "contact_force"}
        ref = m.points - pd["displacement"]
        if reference is None:
            reference = ref
        np.testing.assert_allclose(ref, reference, atol=1e-12)  # one reference shape under every frame
        if fr["snapshot"] is None:
            rest = doc["rest"]
            nodes = {"table": rest["contact_nodes"], "finger1": [], "finger2": []}
            forces = {"table": rest["contact_forces"]}
            sliding = {"table": rest["sliding"]}
        else:
            s = res["snapshots"][fr["snapshot"]]
            nodes, forces, sliding = s["contact_nodes"], s["contact_forces"], s["sliding"]
        in_contact = np.zeros(len(m.points), bool)
        for code, body in ((1, "finger1"), (2, "finger2"), (3, "table")):
            k = np.asarray(nodes[body], int)
            in_contact[k] = True
            if not len(k):
                continue
            np.testing.assert_array_equal(pd["contact_body"][k], code)
            np.testing.assert_allclose(pd["contact_force"][k], forces[body], rtol=0, atol=1e-12)
            np.testing.assert_array_equal(pd["contact_state"][k], np.where(sliding[body], 2, 1))
        assert (pd["contact_body"][~in_contact] == 0).all() and (pd["contact_state"][~in_contact] == 0).all()
        assert (pd["contact_force"][~in_contact] == 0).all()
        # Contact forces and gravity balance: Σf = +mg ẑ (forces on the object hold its weight).
        np.testing.assert_allclose(pd["contact_force"].sum(axis=0), [0, 0, doc["summary"]["weight"]],
                                   atol=1e-8 * doc["summary"]["weight"] + 1e-9 * np.abs(pd["contact_force"]).sum())


def test_fingertips_are_spheres_of_the_fingertip_radius_at_the_snapshot_centres(run):
    out, doc = run
    res = doc["result"]
    for f, name in enumerate(("finger1", "finger2")):
        steps = _pvd_files(out / f"{name}.pvd")
        assert len(steps) == len(doc["series"]["frames"])
        for t, rel in steps[1:]:
            snap = res["snapshots"][int(t) - 1]
            m = meshio.read(out / rel)
            c = np.asarray(snap["finger_centers"][f])
            np.testing.assert_allclose(np.linalg.norm(m.points - c, axis=1), res["finger_radius"], rtol=1e-12)
            d = np.asarray(res["directions"][f])
            along = (m.points - c) @ d  # both hemispheres: the front one, facing the squeeze direction, and the back
            assert along.max() == pytest.approx(res["finger_radius"]) and along.min() == pytest.approx(-res["finger_radius"])
    table = meshio.read(out / "table.vtu")
    np.testing.assert_allclose(table.points[:, 2], doc["rest"]["table_z"])


def test_hemisphere_geometry():
    p, t = hemisphere([1.0, 2.0, 3.0], 0.5, [0, 1, 0], n_theta=6, n_phi=12)
    np.testing.assert_allclose(np.linalg.norm(p - [1, 2, 3], axis=1), 0.5)
    assert ((p[:, 1] - 2.0) >= -1e-12).all() and t.max() == len(p) - 1 and len(t) == 12 + 2 * 12 * 5


def test_out_dir_rules(tmp_path):
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    with pytest.raises(OutputError, match="not written by fem_grasp"):
        prepare_out_dir(foreign)
    prepare_out_dir(foreign, force=True)
    assert (foreign / "notes.txt").read_text() == "mine"  # --force writes beside, never deletes the user's files
    # Our own folder: files from the previous manifest are removed (no stale steps), others kept.
    ours = tmp_path / "ours"
    prepare_out_dir(ours)
    atomic_write_text(ours / "series" / "object_0009.vtu", "old step")
    atomic_write_text(ours / "keep.txt", "user file")
    atomic_write_text(ours / MARKER, json.dumps({"written_by": "fem_grasp", "files": ["series/object_0009.vtu"]}))
    prepare_out_dir(ours)
    assert not (ours / "series" / "object_0009.vtu").exists() and (ours / "keep.txt").exists()
    with pytest.raises(OutputError, match="not a folder"):
        prepare_out_dir(ours / "keep.txt")
    with pytest.raises(OutputError, match="does not exist"):
        read_result(tmp_path / "empty")


# ------------------------------------------------------------ interrupts (issue #8)
def _interrupted_after_half(write):
    """A writer that writes half of its output into the temporary file, then is interrupted (Ctrl-C)."""

    def half(path, *args, **kwargs):
        write(path, *args, **kwargs)
        data = open(path, "rb").read()
        open(path, "wb").write(data[: len(data) // 2])
        raise KeyboardInterrupt

    return half


def _files(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())


def test_an_interrupted_mesh_write_keeps_the_previous_file_and_leaves_no_temporary(tmp_path, monkeypatch):
    from fem_grasp import box_mesh
    from fem_grasp.io.output import atomic_write_mesh

    old, new = box_mesh((0, 0, 0), (1, 1, 1), (1, 1, 1)), box_mesh((0, 0, 0), (2, 2, 2), (2, 2, 2))
    dest = atomic_write_mesh(tmp_path / "object.vtu", old.to_meshio())
    before = dest.read_bytes()
    monkeypatch.setattr(meshio, "write", _interrupted_after_half(meshio.write))
    with pytest.raises(KeyboardInterrupt):
        atomic_write_mesh(dest, new.to_meshio())
    with pytest.raises(KeyboardInterrupt):
        atomic_write_mesh(tmp_path / "fresh.vtu", new.to_meshio())
    monkeypatch.undo()
    assert _files(tmp_path) == ["object.vtu"]  # no half-written fresh.vtu, no temporary file
    assert dest.read_bytes() == before
    np.testing.assert_array_equal(meshio.read(dest).points, old.points)


def test_an_interrupted_json_write_keeps_the_previous_file(tmp_path, monkeypatch):
    """``atomic_write_text`` and ``PickupResult.to_json(path)`` (which used a plain write before issue #8)."""
    import pathlib

    from fem_grasp import Body, box_mesh
    from fem_grasp.grasp.pickup import pickup

    body = Body(box_mesh((-0.015, -0.02, 0.0), (0.015, 0.02, 0.03), (3, 3, 3)), 2e4, 0.3, weight=0.3)
    res = pickup(body, mu_finger=0.5, mu_table=0.0, contacts=(18, 30), finger_radius=0.02)  # fails at step 1
    path = tmp_path / "pickup.json"
    text = res.to_json(path)
    atomic_write_text(tmp_path / "notes.txt", "complete")
    monkeypatch.setattr(pathlib.Path, "write_bytes", _interrupted_after_half(pathlib.Path.write_bytes))
    with pytest.raises(KeyboardInterrupt):
        res.to_json(path, indent=2)
    with pytest.raises(KeyboardInterrupt):
        atomic_write_text(tmp_path / "notes.txt", "a longer replacement")
    monkeypatch.undo()
    assert _files(tmp_path) == ["notes.txt", "pickup.json"]
    assert path.read_text() == text and json.loads(text)["success"] is False
    assert (tmp_path / "notes.txt").read_text() == "complete"


def test_an_interrupted_run_leaves_only_complete_files_and_the_folder_reusable(tmp_path, monkeypatch, capsys):
    """Ctrl-C while the CLI writes the third file of the time series: exit 130, every file left is complete
    (the previous run's result.json, listed in its manifest, was cleared when the run started), and the
    next run writes the folder whole again."""
    from fem_grasp.cli import main

    out = tmp_path / "o"
    argv = ["run", "football", "--quick", "--no-lift", "--no-cache", "--quiet", "--out", str(out)]
    assert main(argv) == 1
    complete = _files(out)
    calls = []
    real = meshio.write

    def third_call_interrupted(path, *args, **kwargs):
        calls.append(path)
        return (_interrupted_after_half(real) if len(calls) == 3 else real)(path, *args, **kwargs)

    monkeypatch.setattr(meshio, "write", third_call_interrupted)
    assert main(argv) == 130
    assert "interrupted" in capsys.readouterr().err
    monkeypatch.undo()
    left = _files(out)
    assert "result.json" not in left and set(left) <= set(complete)  # nothing half-written, no temporary
    for f in left:
        if f.endswith(".vtu"):
            assert len(meshio.read(out / f).points) > 0
    assert main(argv) == 1
    assert _files(out) == complete
    assert set(json.loads((out / MARKER).read_text())["files"]) == set(complete) - {MARKER}


def test_files_of_an_interrupted_run_are_cleared_by_the_next_run_even_if_it_writes_fewer(tmp_path, monkeypatch):
    """The series files are in the folder's manifest before they are written, so an interrupted long run
    leaves nothing that a shorter run into the same folder would keep as a stale frame."""
    import dataclasses

    from fem_grasp import Body, box_mesh
    from fem_grasp.grasp.pickup import pickup
    from fem_grasp.io import output

    body = Body(box_mesh((-0.015, -0.02, 0.0), (0.015, 0.02, 0.03), (4, 4, 4)), 2e4, 0.3, weight=0.3)
    long = pickup(body, mu_finger=0.5, mu_table=0.5, finger_radius=0.01, lift=False)
    assert len(long.snapshots) >= 4
    short = dataclasses.replace(long, snapshots=long.snapshots[:2])
    out = tmp_path / "o"
    real = output.write_result_json

    def interrupted(*a, **k):
        raise KeyboardInterrupt  # every frame written, result.json and the final manifest not

    monkeypatch.setattr(output, "write_result_json", interrupted)
    with pytest.raises(KeyboardInterrupt):
        output.write_run(out, long)
    monkeypatch.setattr(output, "write_result_json", real)
    frames_long = {f for f in _files(out) if f.startswith("series/object_")}
    output.write_run(out, short)
    frames_short = {f for f in _files(out) if f.startswith("series/object_")}
    assert len(frames_short) == len(output.frames_of(short)) < len(frames_long)
    listed = set(json.loads((out / MARKER).read_text())["files"])
    assert set(_files(out)) - {MARKER} == listed  # no frame of the longer run is left behind
