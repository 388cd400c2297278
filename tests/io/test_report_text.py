"""The report's words and numbers about accuracy (fem_grasp.io.report), without rendering: they read as the
command line's summary does."""

import math

from fem_grasp.grasp.accuracy import percent_error
from fem_grasp.io.report import _accuracy_html, _accuracy_state


def _level(level, change):
    return {"level": level, "vertices": 1000 * (level + 1), "inner_size": 0.004 / 2**level, "outer_size": 0.007,
            "step": 5e-4, "lift_test_step": 0.06, "success": True, "squeeze_depth": 0.009, "finger_force": 4.4,
            "seconds": 1.0, "mesh_seconds": 0.1, "finger_nodes": [10, 12], "table_nodes": 30, "change": change}


def test_percent_error_reads_as_a_percentage_at_every_size():
    assert percent_error(1.13) == "113 %"
    assert percent_error(0.123) == "12 %"
    assert percent_error(0.058) == "5.8 %"
    assert percent_error(0.0) == "0 %"
    assert percent_error(math.inf) == percent_error(None) == "unknown"


def test_errors_and_changes_above_100_percent_are_not_printed_in_exponent_notation():
    acc = {"target": 0.05, "converged": False, "estimated_error": {"squeeze_depth": 1.13, "finger_force": 1.79},
           "levels": [_level(0, None), _level(1, {"squeeze_depth": 1.5, "finger_force": 0.061})]}
    page = _accuracy_html(acc)
    assert "150 % / 6.1 %" in page and "e+" not in page
    assert "Each level remeshes" in page
    assert "Each level bisects the level before (nested levels)" in _accuracy_html({**acc, "refinement": "nested"})
    one = {"target": 0.05, "converged": False, "expected_error_stated": True,
           "estimated_error": {"squeeze_depth": 1.2, "finger_force": 1.2}, "levels": [_level(0, None)]}
    assert _accuracy_state(one) == "one run on this mesh, within about 120 % (the scene's convergence study)"
