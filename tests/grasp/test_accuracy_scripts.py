"""The accuracy study's scripts (``scripts/``): they run, and measure what they say they measure."""

from __future__ import annotations

import importlib.util
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

SCRIPTS = Path(__file__).resolve().parents[2] / "scripts"


def _load(name: str):
    path = SCRIPTS / f"{name}.py"
    if not path.exists():
        pytest.skip("scripts/ is in the source tree, not in the installed package")
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.requires("gmsh")
def test_pinned_reference_grasps_exactly_at_the_rules_points(capsys):
    from fem_grasp.io.scene import Scene

    module = _load("pinned_reference")
    scene = Scene.load("tomato")
    points, increment = module.rule_points(scene, 0.05)
    # the rule's points: on the tomato's side, opposite each other through its axis, at one height when posed
    assert points.shape == (2, 3) and 0.3 < increment * 1e3 < 1.0
    assert np.linalg.norm(points[0] - points[1]) > 0.06
    runs = list(module.pinned_series(scene, points, increment, [900], [1, 2]))
    assert [r["increment"] for r in runs] == pytest.approx([increment, increment / 2])
    for run in runs:  # every pinned mesh grasps at the points themselves, not at nodes near them
        assert np.abs(run["finger_points"] - points).max() < 1e-9
        a = run["answer"]
        assert a.success and 5e-3 < a.squeeze_depth < 15e-3 and a.finger_force > scene.weight
    # a finer increment finds ρ* to within the coarser one's quantisation: at most one coarse increment apart
    assert abs(runs[1]["answer"].squeeze_depth - runs[0]["answer"].squeeze_depth) <= increment * (1 + 1e-9)
    assert module.main(["tomato", "--vertices", "900", "--divisions", "1", "--no-loops"]) == 0
    out = capsys.readouterr().out
    row = next(line for line in out.splitlines() if line.strip().startswith(f"{runs[0]['vertices']:,d}"))
    assert float(row.split()[3]) == pytest.approx(1e3 * runs[0]["answer"].squeeze_depth, abs=1e-3)
    # its reference: the finest run, uncertain by the next finest mesh's difference (ρ*: at least the increment)
    entry = module.reference_entry(runs, points, scene.weight)
    assert entry["rho"]["value"] == runs[-1]["answer"].squeeze_depth and entry["rho"]["error"] is None
    assert entry["points"] == points.tolist() and len(entry["runs"]) == 2
    coarse, fine = (dict(runs[1], answer=replace(runs[1]["answer"], squeeze_depth=rho, finger_force=f))
                    for rho, f in ((0.0100, 5.0), (0.0096, 5.2)))
    two = module.reference_entry([coarse, fine], points, scene.weight)
    assert two["rho"]["error"] == pytest.approx(max(0.0004 / 0.0096, fine["increment"] / 0.0096))
    assert two["force"]["error"] == pytest.approx(0.2 / 5.2) and two["rho"]["value"] == 0.0096
