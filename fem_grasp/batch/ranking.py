"""How a placement search ranks its grasps, and which of them could be the best within their errors."""

from __future__ import annotations

from typing import Any

from ..errors import SearchError

__all__ = ["ERROR_COLUMNS", "RANKINGS", "STATED_RANKINGS", "rank_table"]

#: How grasps that pick the object up are ranked: column, ascending.
RANKINGS = {
    "force": ("finger_normal_force", True),   # the least finger normal force at lift-off (Table III's measure)
    "squeeze": ("rho_star", True),            # the least squeeze depth ρ*
    "margin": ("margin", False),              # the largest w(ρ*)/mg when the lift starts
}
#: The rankings whose quantity a scene's stated error (``solver.expected_error``: of ρ* and the finger force) covers.
STATED_RANKINGS = {"force", "squeeze"}
#: Each ranking's column of per-candidate estimated relative errors (the accuracy loop's).
ERROR_COLUMNS = {"force": "error_finger_force", "squeeze": "error_rho_star"}


def rank_table(table: Any, by: str = "force", error: float | None = None, *, per_row: bool = False) -> Any:
    """``table`` ranked: the grasps (``grasped``: picked up, or the lift test passed when the lift is not
    simulated) first, best first by :data:`RANKINGS` ``[by]``; then the others by how close they came (margin,
    largest first); errors last.  Adds ``rank`` (1, 2, … for the grasps, 0 for the rest) and ``within_error``: the
    grasps whose ranking quantity q could be the best one's q₁ given their errors, so that the best one itself and
    every grasp flagged could be the best.

    * ``per_row``: each answer carries its own estimated relative error e (the columns ``error_finger_force`` and
      ``error_rho_star`` of a search with an accuracy target, :data:`ERROR_COLUMNS`), and a grasp overlaps the best
      when |q − q₁| ≤ e·|q| + e₁·|q₁|; a grasp whose error, or the best one's, is not known (NaN) or unbounded (inf)
      is flagged: it could be the best;
    * else ``error``, the one relative error every answer carries (the scene's stated ``expected_error`` of ρ* and
      the finger force, one run on its mesh): the same rule with e = e₁, |q − q₁| ≤ e (|q| + |q₁|); all flagged when
      it is inf, none when it is not known (None).

    No grasp is flagged for a ranking the errors do not cover (``margin``)."""
    if by not in RANKINGS:
        raise SearchError(f"unknown ranking {by!r}; choose one of {sorted(RANKINGS)}")
    col, ascending = RANKINGS[by]
    ok = table[table["grasped"]].sort_values([col, "candidate"], ascending=[ascending, True], kind="stable")
    rest = table[~table["grasped"] & (table["status"] == "ok")].sort_values(
        ["margin", "candidate"], ascending=[False, True], kind="stable")
    err = table[table["status"] != "ok"].sort_values("candidate", kind="stable")
    import numpy as np
    import pandas as pd

    ranked = pd.concat([ok, rest, err]).reset_index(drop=True)
    ranked.insert(0, "rank", [k + 1 if k < len(ok) else 0 for k in range(len(ranked))])
    within = np.zeros(len(ranked), dtype=bool)
    if by in STATED_RANKINGS and len(ok):
        q = ranked[col].to_numpy(float)[:len(ok)]
        if per_row:
            if ERROR_COLUMNS[by] not in ranked:
                raise SearchError(f"per-row errors: the table has no column {ERROR_COLUMNS[by]!r}")
            e = ranked[ERROR_COLUMNS[by]].to_numpy(float)[:len(ok)]
        elif error is not None and error >= 0:
            e = np.full(len(ok), float(error))
        else:
            e = None
        if e is not None:
            unknown = ~np.isfinite(e) | ~np.isfinite(e[0])
            with np.errstate(invalid="ignore"):
                near = np.abs(q - q[0]) <= e * np.abs(q) + e[0] * abs(q[0])
            within[:len(ok)] = unknown | near
    ranked["within_error"] = within
    return ranked
