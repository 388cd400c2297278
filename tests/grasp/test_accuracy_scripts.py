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


def test_draw_scatter_summarises_the_squeeze_and_the_lift_test(capsys):
    """The spreads across draws: ρ* and the lift-off force as (max − min) / mean, the squeeze's Σ f·n̂ compared at
    common depths up to the shallowest ρ*, the depth over which w(ρ) sat at its last weight below mg, and finger 1's
    share of the weight at lift-off (of the draws that lifted)."""
    module = _load("draw_scatter")
    weight = 1.0
    draws = [{"vertices": 100, "squeeze_depth": 0.010, "finger_force": 4.0, "weight": weight,
              "squeeze": [(0.0, 0.0), (0.010, 5.0)],
              "liftable": [(0.008, 0.9), (0.009, 0.95), (0.0095, 0.95), (0.010, 1.0)], "finger_vertical": [0.4, 0.6],
              "rest_tilt": 2.4},
             {"vertices": 110, "squeeze_depth": 0.012, "finger_force": 6.0, "weight": weight,
              "squeeze": [(0.0, 0.0), (0.012, 6.6)],  # 10 % stiffer than the first at every depth
              "liftable": [(0.0115, 0.95), (0.012, 1.0)], "finger_vertical": None}]  # not lifted: no share
    s = module.summary(draws)
    assert s["squeeze_depth_spread"] == pytest.approx(100 * 0.002 / 0.011)
    assert s["finger_force_spread"] == pytest.approx(100 * 2.0 / 5.0)
    assert s["depths_mm"][0] == pytest.approx(module.FIRST_DEPTH * 10.0) and s["depths_mm"][-1] == pytest.approx(10.0)
    # forces 0.5 ρ/mm and 0.55 ρ/mm: a spread of 0.05 / 0.525 at every depth
    assert s["squeeze_force_spread"] == pytest.approx([100 * 0.05 / 0.525] * module.DEPTHS)
    assert s["plateau"] == pytest.approx([0.1, 0.5 / 12])
    assert s["finger1_share"] == pytest.approx([0.4]) and s["rest_tilt"] == pytest.approx([2.4])
    # a facet whose outward normal leans 3° towards +y, the body turned so that it faces down: +3° towards +y,
    # -3° towards -y, none across
    from fem_grasp.grasp.pose import rotation_between

    lean = np.array([0.0, np.sin(np.radians(3.0)), -np.cos(np.radians(3.0))])
    turned = rotation_between(lean, np.array([0.0, 0.0, -1.0]))
    assert module.rest_tilt(turned, np.array([0.0, 0.97, -0.23])) == pytest.approx(3.0)
    assert module.rest_tilt(turned, np.array([0.0, -0.97, -0.23])) == pytest.approx(-3.0)
    assert module.rest_tilt(turned, np.array([1.0, 0.0, 0.0])) == pytest.approx(0.0, abs=1e-12)
    with pytest.raises(SystemExit):
        module.main(["tomato", "--draws", "1"])
    with pytest.raises(SystemExit):
        module.main(["no_such_scene", "--draws", "2"])
    assert "no shipped scene of that name" in capsys.readouterr().err
