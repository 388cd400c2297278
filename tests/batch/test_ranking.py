"""Ranking a search's table: the grasps within the stated error of the best one are flagged."""

import math

import pytest

from fem_grasp.batch import rank_table

pd = pytest.importorskip("pandas")


def _table(forces, grasped=None):
    n = len(forces)
    grasped = [True] * n if grasped is None else grasped
    return pd.DataFrame({"candidate": range(n), "grasped": grasped, "status": ["ok"] * n,
                         "finger_normal_force": forces, "rho_star": [0.005] * n, "margin": [1.0] * n})


def test_grasps_within_the_combined_error_of_the_best_are_flagged_and_the_others_not():
    # with ±10 % each, 1.0 N and 1.2 N overlap (1.1 ≥ 1.08) and 1.0 N and 1.3 N do not (1.1 < 1.17)
    ranked = rank_table(_table([1.3, 1.0, 1.2, 2.0], grasped=[True, True, True, False]), "force", 0.10)
    flags = dict(zip(ranked["finger_normal_force"], ranked["within_error"]))
    assert flags == {1.0: True, 1.2: True, 1.3: False, 2.0: False}
    assert list(ranked["rank"]) == [1, 2, 3, 0]


def test_no_flags_without_a_stated_error_or_for_a_ranking_it_does_not_cover_and_all_when_unbounded():
    table = _table([1.0, 1.01])
    assert not rank_table(table, "force", None)["within_error"].any()
    assert not rank_table(table, "margin", 0.2)["within_error"].any()
    assert rank_table(table, "force", math.inf)["within_error"].all()
