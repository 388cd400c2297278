"""Outputs (fem_grasp.io.output): result.json schema, ParaView time series read back with meshio, atomic writes."""

import json
import xml.etree.ElementTree as ET
from pathlib import Path

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
    for key in ("success", "reason", "squeeze_depth", "n_final_contacts", "finger_normal_force", "event_counts",
                "outcome", "finger_forces", "table_iii_measure"):
        assert key in doc["summary"]
    forces = doc["summary"]["finger_forces"]  # each finger four ways (grasp.forces), and what Table III compares
    assert set(forces) == {"finger1", "finger2"} and "normal sum" in doc["summary"]["table_iii_measure"]
    assert forces["finger1"]["normal_sum"] + forces["finger2"]["normal_sum"] == pytest.approx(
        doc["summary"]["finger_normal_force"], rel=1e-12)
    assert {"resultant", "magnitude", "grip", "vertical", "normal_sum", "contacts"} <= set(forces["finger1"])
    assert doc["summary"]["n_events"] == len(doc["result"]["events"]) == sum(doc["summary"]["event_counts"].values())
    # the mesh and the node positions are in the time series, not in result.json
    assert not {"reference_points", "tets"} & set(doc["result"])
    assert all("positions" not in snap for snap in doc["result"]["snapshots"] + [doc["result"]["final"] or {}])
    assert doc["result"]["snapshots"] and all("contact_forces" in snap for snap in doc["result"]["snapshots"])
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
    assert [f for _, f in steps] == [fr["file"] for fr in frames] and [t for t, _ in steps] == [fr["time"] for fr in frames]
    assert frames[0]["label"] == "rest" and len(frames) == len(res["snapshots"]) + 1
    reference = None
    for fr in frames:
        m = meshio.read(out / fr["file"])
        pd = m.point_data
        assert set(pd) == {"displacement", "elastic_displacement", "contact_state", "contact_body", "contact_force"}
        assert set(m.cell_data) == {"von_mises", "strain_energy_density"}
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
        frames = doc["series"]["frames"]
        assert len(steps) == len(frames) and [t for t, _ in steps] == [fr["time"] for fr in frames]
        for (t, rel), fr in list(zip(steps, frames))[1:]:
            snap = res["snapshots"][fr["snapshot"]]
            m = meshio.read(out / rel)
            c = np.asarray(snap["finger_centers"][f])
            np.testing.assert_allclose(np.linalg.norm(m.points - c, axis=1), res["finger_radius"], rtol=1e-12)
            d = np.asarray(res["directions"][f])
            along = (m.points - c) @ d  # both hemispheres: the front one, facing the squeeze direction, and the back
            assert along.max() == pytest.approx(res["finger_radius"]) and along.min() == pytest.approx(-res["finger_radius"])
    table = meshio.read(out / "table.vtu")
    np.testing.assert_allclose(table.points[:, 2], doc["rest"]["table_z"])


# ------------------------------------------------------------ ParaView time and field data (issue 25, item 4)
def test_the_time_value_is_the_finger_path_and_every_frame_says_where_it_is(run):
    """PVD time = ρ during the squeeze, then ρ at lift start + lift height (strictly increasing); field data
    phase, squeeze_depth, lift_height, liftable_weight on every frame, read back by meshio and by VTK."""
    from fem_grasp.io.output import PHASE_CODES, TIME_TICK

    out, doc = run
    frames = doc["series"]["frames"]
    times = np.array([t for t, _ in _pvd_files(out / "object.pvd")])
    assert (np.diff(times) > 0).all() and times[0] == 0.0
    longest = max(fr["finger_path"] for fr in frames)
    liftable = doc["result"]["liftable"]
    start = None
    for fr, t in zip(frames, times):
        if fr["phase"] == "lift" and start is None:
            start = fr["squeeze_depth"]
        path = fr["squeeze_depth"] if fr["phase"] != "lift" else start + fr["lift_height"]
        assert fr["finger_path"] == pytest.approx(path, rel=1e-12, abs=1e-15)
        assert t == pytest.approx(path, abs=len(frames) * TIME_TICK * longest)
        fd = {k: np.asarray(v).ravel() for k, v in meshio.read(out / fr["file"]).field_data.items()}
        assert set(fd) >= {"phase", "squeeze_depth", "lift_height", "liftable_weight", "finger_path"}
        assert fd["phase"][0] == PHASE_CODES[fr["phase"]]
        assert fd["squeeze_depth"][0] == fr["squeeze_depth"] and fd["lift_height"][0] == fr["lift_height"]
        w = [v for r, v in liftable if r <= fr["squeeze_depth"] * (1 + 1e-12) + 1e-15]
        assert fd["liftable_weight"][0] == pytest.approx(w[-1] if w else 0.0)
    vtk = pytest.importorskip("vtk")
    reader = vtk.vtkXMLUnstructuredGridReader()
    reader.SetFileName(str(out / frames[-1]["file"]))
    reader.Update()
    fd = reader.GetOutput().GetFieldData()
    names = {fd.GetArrayName(i) for i in range(fd.GetNumberOfArrays())}
    assert {"phase", "squeeze_depth", "lift_height", "liftable_weight"} <= names
    assert fd.GetArray("squeeze_depth").GetTuple1(0) == pytest.approx(frames[-1]["squeeze_depth"])


def test_the_xdmf_series_holds_the_same_frames_at_the_same_times(tmp_path):
    """object.xdmf + object.h5 (h5py): one grid per frame with its deformed geometry, the same point, cell and
    field data, the same time values; read back with VTK's XDMF reader.  The run is a fresh process: h5py cannot
    load into one that has loaded dolfinx's HDF5 (as the verification tests do), and then writes no XDMF."""
    import importlib.util
    import subprocess
    import sys

    if importlib.util.find_spec("h5py") is None:  # not imported here: this process may hold dolfinx's HDF5
        pytest.skip("h5py is not installed (the xdmf extra)")
    vtk = pytest.importorskip("vtk")
    from vtk.util.numpy_support import vtk_to_numpy

    from tests.helpers import ROOT, cache_dir

    out = tmp_path / "o"
    r = subprocess.run([sys.executable, "-m", "fem_grasp", "run", "foam_block", "--quick", "--no-lift", "--quiet",
                        "--out", str(out), "--cache", str(cache_dir())], cwd=ROOT, capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 1, r.stderr[-2000:]
    doc = read_result(out)
    frames = doc["series"]["frames"]
    assert doc["series"]["xdmf"] == "object.xdmf" and (out / "object.h5").exists()
    root = ET.parse(out / "object.xdmf").getroot()
    grids = root.find("Domain/Grid").findall("Grid")
    assert [float(g.find("Time").get("Value")) for g in grids] == [fr["time"] for fr in frames]
    reader = vtk.vtkXdmfReader()
    reader.SetFileName(str(out / "object.xdmf"))
    reader.UpdateInformation()
    steps = reader.GetOutputInformation(0).Get(vtk.vtkStreamingDemandDrivenPipeline.TIME_STEPS())
    assert list(steps) == [fr["time"] for fr in frames]
    for k in (0, len(frames) - 1):
        reader.UpdateTimeStep(steps[k])
        grid = reader.GetOutputDataObject(0)
        m = meshio.read(out / frames[k]["file"])
        np.testing.assert_array_equal(vtk_to_numpy(grid.GetPoints().GetData()), m.points)
        np.testing.assert_array_equal(vtk_to_numpy(grid.GetCellData().GetArray("von_mises")), m.cell_data["von_mises"][0])
        np.testing.assert_array_equal(vtk_to_numpy(grid.GetPointData().GetArray("contact_state")),
                                      m.point_data["contact_state"])
        assert grid.GetFieldData().GetArray("lift_height").GetTuple1(0) == frames[k]["lift_height"]
        assert grid.GetFieldData().GetArray("phase").GetTuple1(0) == m.field_data["phase"][0]


def test_an_out_folder_named_like_a_file_is_refused(tmp_path, capsys):
    from fem_grasp.cli import main
    from fem_grasp.io.output import check_out_path

    for name in ("x.xdmf", "run.vtu", "r.h5"):
        with pytest.raises(OutputError, match="names a folder, not a file"):
            check_out_path(tmp_path / name)
    assert check_out_path(tmp_path / "x") == tmp_path / "x"
    assert main(["run", "foam_block", "--quick", "--out", str(tmp_path / "x.xdmf")]) == 2
    err = capsys.readouterr().err
    assert "object.xdmf + object.h5" in err and not (tmp_path / "x.xdmf").exists()


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
    from fem_grasp._files import atomic_write_mesh

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


@pytest.mark.requires("gmsh")  # the quick scene remeshes its object
def test_an_interrupted_run_leaves_only_complete_files_and_the_folder_reusable(tmp_path, monkeypatch, capsys):
    """Ctrl-C while the CLI writes the third file of the time series: exit 130, every file left is complete
    (the previous run's result.json, listed in its manifest, was cleared when the run started), and the
    next run writes the folder whole again."""
    from fem_grasp._files import _atomic
    from fem_grasp.cli import main
    from fem_grasp.io import vtu

    out = tmp_path / "o"
    argv = ["run", "football", "--quick", "--no-lift", "--no-cache", "--quiet", "--out", str(out)]
    assert main(argv) == 1
    complete = _files(out)
    calls = []
    real = vtu.atomic_write_text

    def third_call_interrupted(path, text):
        calls.append(path)
        if len(calls) == 3:  # half of the text in the temporary file, then Ctrl-C
            return _atomic(Path(path), _interrupted_after_half(lambda tmp: tmp.write_bytes(text.encode())))
        return real(path, text)

    monkeypatch.setattr(vtu, "atomic_write_text", third_call_interrupted)
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
