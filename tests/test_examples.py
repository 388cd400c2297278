"""Every example in examples/ runs to the end as a script (a new example must be listed here with quick arguments).

The examples' outputs are checked in detail elsewhere (``grasp/test_objects.py`` for demo.py,
``test_cli.py`` for scene_demo.py, ``io/test_scene.py`` for sweep.py); this test guarantees that none of them is left behind by a change.
"""

import os
import subprocess
import sys

import pytest

from tests.helpers import ROOT

if not (ROOT / "examples").is_dir():
    pytest.skip("examples/ is in the source tree, not in the installed package", allow_module_level=True)

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
