"""The placement search (fem_grasp.batch) on a real Dask LocalCluster of two worker processes.

The object is a small soft box (64 nodes) whose candidates take about a second each, with the lift not
simulated (a grasp is then one whose lift test passes): the tests are about the engine, not the mechanics.
The cluster is started once for the module and closed at its end.
"""

import os
import signal
import time

import numpy as np
import pytest

from fem_grasp import Body, box_mesh, search
from fem_grasp.batch import SearchError, read_results
from fem_grasp.batch.engine import MANIFEST
from fem_grasp.cli import main
from fem_grasp.grasp import Candidate
from tests.helpers import box_scene_toml

pytest.importorskip("dask.distributed")
pytest.importorskip("pyarrow")

#: Four candidates, one per azimuth (the box has one valid height): about a second each.
AZIMUTHS = [0, 60, 140, 160]
SETTINGS = dict(mu_finger=0.5, mu_table=0.5, finger_radius=0.01, lift=False, step=1e-3, name="box")
#: Columns that differ between runs of the same candidate: wall times and the process that ran it.
RUN_COLUMNS = ["time", "cpu_time", "setup_time", "worker"]

BOX_SCENE = box_scene_toml((3, 3, 3), '[fingers]\nradius = "1 cm"\n[solver]\nstep = "1 mm"\nlift = false\n',
                           'name = "box"\ndescription = "a small soft box for the search tests"\n')


def small_box() -> Body:
    return Body(box_mesh((-0.015, -0.02, 0.0), (0.015, 0.02, 0.03), (3, 3, 3)), 2e4, 0.3, weight=0.3)


def same_rows(a, b):
    """The two tables hold the same rows, but for wall times and workers: the same verdicts, reasons, nodes and
    counts, and every number equal to round-off (1e-9 relative: numpy's vectorised sums may differ in the last
    bit between two runs of one process, with the alignment of their arrays)."""
    cols = [c for c in a.columns if c not in RUN_COLUMNS]
    assert list(a["key"]) == list(b["key"])
    for c in cols:
        x, y = a[c].to_numpy(), b[c].to_numpy()
        if x.dtype.kind == "f":
            assert np.allclose(x, y, rtol=1e-9, atol=1e-15, equal_nan=True), (c, x, y)
        else:
            assert list(x) == list(y), c


@pytest.fixture(scope="module")
def serial():
    """The plain loop in this process: the reference every engine must reproduce."""
    r = search(small_box(), None, azimuths=AZIMUTHS, workers=0, **SETTINGS)
    assert len(r.table) == 4 and r.engine == "serial" and r.n_errors == 0
    assert 0 < r.n_grasped < 4  # some pass the lift test, some do not
    return r.table


def test_dask_gives_the_serial_answers_and_each_worker_builds_the_shared_state_once(client, serial):
    r = search(small_box(), None, azimuths=AZIMUTHS, client=client, **SETTINGS)
    same_rows(r.table, serial)
    assert r.n_errors == 0
    workers = set(r.table["worker"])
    assert workers and os.getpid() not in {int(w.rsplit(":", 1)[1]) for w in workers}
    for w in workers:  # the factorised body, its columns and the rest: built once per process, not per candidate
        assert (r.table[r.table["worker"] == w]["setup_time"] > 0).sum() <= 1


def test_an_interrupted_search_resumes_without_recomputing_and_gives_the_same_table(client, serial, tmp_path):
    out = tmp_path / "search"
    seen = []

    def interrupt_after_two(row):
        seen.append(row["key"])
        if len(seen) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        search(small_box(), out, azimuths=AZIMUTHS, workers=0, report=False, best=0, on_row=interrupt_after_two,
               **SETTINGS)
    partial = read_results(out)
    assert list(partial["key"]) == sorted(seen, key=lambda k: list(serial["key"]).index(k))  # written as they came
    evaluated = []
    r = search(small_box(), out, azimuths=AZIMUTHS, client=client, resume=True, report=False, best=0,
               on_row=lambda row: evaluated.append(row["key"]), **SETTINGS)
    assert r.resumed == 2 and sorted(evaluated) == sorted(set(serial["key"]) - set(seen))
    same_rows(r.table, serial)
    same_rows(read_results(out), serial)  # the Parquet file holds the final table …
    (out / "results.parquet").unlink()
    same_rows(read_results(out), serial)  # … and so does the CSV
    # another object's search in the same folder is refused
    with pytest.raises(SearchError, match="another object"):
        search(small_box().with_material(young=3e4), out, azimuths=AZIMUTHS, workers=0, resume=True, **SETTINGS)


def test_a_worker_killed_mid_candidate_loses_nothing(client, serial):
    killed = []  # (pid, the candidates it was evaluating)

    def kill_a_busy_worker(row):
        if killed:
            return
        for worker, keys in client.processing().items():
            running = [k for k in map(str, keys) if k.startswith("fem-grasp-") and "-setup-" not in k]
            if running:
                pid = client.run(os.getpid, workers=[worker])[worker]
                os.kill(pid, signal.SIGKILL)
                killed.append((pid, [k[len("fem-grasp-"):].rsplit("-", 1)[0] for k in running]))
                return

    r = search(small_box(), None, azimuths=AZIMUTHS, client=client, on_row=kill_a_busy_worker, **SETTINGS)
    assert killed, "no worker was busy when the first row arrived"
    pid, lost = killed[0]
    assert r.n_errors == 0
    same_rows(r.table, serial)  # the killed worker's candidates were evaluated again elsewhere
    again = r.table.set_index("key").loc[lost, "worker"]
    assert lost and not any(w.endswith(f":{pid}") for w in again)
    client.wait_for_workers(2, timeout=120)  # the nanny restarts it


def test_a_candidate_that_raises_is_recorded_and_the_search_goes_on(client, serial):
    good = search(small_box(), None, azimuths=AZIMUTHS[:1], workers=0, **SETTINGS).candidates.candidates[0]
    mesh = small_box().mesh
    interior = int(np.setdiff1d(np.arange(mesh.n_points), mesh.surface_nodes)[0])
    bad = Candidate(1, (interior, good.finger_nodes[1]), good.azimuth, good.tilt, good.ratio, good.height,
                    good.max_squeeze, good.points)
    r = search(small_box(), None, candidate_list=[good, bad], client=client, **SETTINGS)
    row = r.table.set_index("candidate")
    assert row.loc[0, "status"] == "ok" and row.loc[0, "outcome"] == serial.loc[0, "outcome"]
    assert row.loc[1, "status"] == "error" and row.loc[1, "outcome"] == "error"
    assert "ContactNodeError" in row.loc[1, "error"] and "surface" in row.loc[1, "error"]
    assert r.ranked.iloc[-1]["candidate"] == 1  # errors rank last


def test_fem_grasp_search_on_a_running_scheduler_prints_the_best_grasps_and_writes_the_report(client, capsys,
                                                                                             tmp_path):
    scene = tmp_path / "box.toml"
    scene.write_text(BOX_SCENE)
    out = tmp_path / "out"
    code = main(["search", str(scene), "--out", str(out), "--scheduler", client.scheduler.address,
                 "--azimuths", "0,60,160", "--best", "1", "--no-cache"])
    text, err = capsys.readouterr()
    assert code == 0, (text, err)
    assert "3 candidates" in text and "pass the lift test" in text and "best       ranked by" in text
    assert "rho_star_mm" in text and "height_mm" in text and "no error stated" in text, text
    assert f"{out}/results.parquet" in text and f"{out}/report.html" in text
    for name in ("results.parquet", "results.csv", MANIFEST, "report.html", "candidates.png", "search_plots.png",
                 "best/01/result.json", "best/01/report.html", "best/01/lifted.png"):
        assert (out / name).exists(), name
    html = (out / "report.html").read_text()
    assert "<svg" in html and "<title>candidate" in html and "best/01/report.html" in html
    assert "not liftable" in html  # the failures' reasons are in the table and the hover text
    # a new search in the same folder (ours) replaces the old one
    assert main(["search", str(scene), "--out", str(out), "--workers", "0", "--azimuths", "0,", "--no-report",
                 "--best", "0", "--no-cache", "--quiet"]) == 1  # this one candidate does not pass
    assert len(read_results(out)) == 1


def test_the_result_files_name_each_column_with_its_unit_and_read_back_in_si(serial, tmp_path):
    import pandas as pd

    from fem_grasp.batch.store import ResultStore

    store = ResultStore(tmp_path, serial.to_dict("records"))
    store.flush()
    csv = pd.read_csv(tmp_path / "results.csv")
    for name in ("height_mm", "rho_star_mm", "grip1_N", "finger_normal_force_N", "time_s", "azimuth_deg"):
        assert name in csv.columns, name
    assert "rho_star" not in csv.columns and "height" not in csv.columns
    # the same numbers, in the unit the name says: heights of a few centimetres are tens of millimetres
    assert np.allclose(csv["height_mm"], 1e3 * serial["height"]) and (csv["height_mm"] > 5).all()
    assert np.allclose(csv["grip1_N"], serial["grip1"], equal_nan=True)
    same_rows(read_results(tmp_path), serial)  # and read back in SI


def test_an_unreachable_scheduler_is_a_clear_error_within_the_timeout(capsys, tmp_path):
    scene = tmp_path / "box.toml"
    scene.write_text(BOX_SCENE)
    t0 = time.perf_counter()
    code = main(["search", str(scene), "--scheduler", "tcp://127.0.0.1:9", "--connect-timeout", "2", "--no-cache"])
    err = capsys.readouterr().err
    assert code == 2 and "cannot reach the Dask scheduler at tcp://127.0.0.1:9" in err
    assert time.perf_counter() - t0 < 20
