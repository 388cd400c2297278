"""Every example in examples/ runs to the end as a script (a new example must be listed here with quick arguments).

The examples' outputs are checked in detail elsewhere (``grasp/test_objects.py`` for demo.py,
``test_cli.py`` for scene_demo.py, ``io/test_scene.py`` for sweep.py); this test guarantees that none of them is left behind by a change.
"""

import os
import subprocess
import sys

import pytest

from tests.helpers import ROOT

EXAMPLES = sorted(p.name for p in (ROOT / "examples").glob("*.py"))
#: Command-line arguments that keep each example quick (its --out folder is appended).
QUICK_ARGS = {"demo.py": ["--object", "tomato"], "scene_demo.py": ["football", "--no-report"],
              "sweep.py": ["foam_block", "--youngs", "20 kPa", "40 kPa", "--mus", "0.5", "--no-lift"]}


def test_every_example_has_quick_arguments():
    assert set(EXAMPLES) == set(QUICK_ARGS), "list the new example's quick arguments in QUICK_ARGS"


@pytest.mark.parametrize("example", EXAMPLES)
def test_the_example_runs_as_a_script(example, tmp_path):
    env = dict(os.environ, PYTHONPATH=str(ROOT))  # this checkout's package, as the examples import it
    out = subprocess.run([sys.executable, str(ROOT / "examples" / example), *QUICK_ARGS[example],
                          "--out", str(tmp_path / "out")], cwd=ROOT, env=env, capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    assert any((tmp_path / "out").iterdir())  # it wrote its files


@pytest.mark.gmsh
def test_the_own_object_example_scene_loads_and_its_quick_variant_runs(tmp_path):
    """examples/own_object.toml, the template for a mesh of one's own: its millimetre scan is read as a
    7 cm object (units = "mm") and its quick variant lifts it at a squeeze of millimetres."""
    pytest.importorskip("gmsh")
    from fem_grasp.io.scene import load_scene

    scene = load_scene(ROOT / "examples" / "own_object.toml", quick=True)
    assert scene.object.kind == "mesh" and scene.object.units == "mm" and scene.object.mesh.exists()
    result = scene.with_(lift=False).run(cache_dir=tmp_path / "cache")
    assert 0.05 < result.body.mesh.diameter < 0.15  # metres: the scan's millimetres were converted
    assert result.outcome == "lift not run", result.reason  # the lift test passes
    assert 1e-3 < result.squeeze_depth < 0.03
