"""``python -m verification friction ACTION …``: fem_grasp's frictional contact against the independent reference."""

from __future__ import annotations

import sys

from .._common.cli import dispatch

ACTIONS = {
    "compare": ("one scene against the reference (exit 1: differ)", "verification.friction.compare"),
    "random": ("seeded random valid scenes (--compare: each)", "verification.friction.random_scenes"),
    "diagnose": ("both lift tests on one squeeze state", "verification.friction.diagnose"),
    "study": ("every stage of the study, with its report", "verification.friction.study"),
}


def main(argv: list[str] | None = None) -> int:
    return dispatch("python -m verification friction", (__doc__ or "").splitlines()[0].split(": ", 1)[-1], ACTIONS,
                    argv, metavar="ACTION")


if __name__ == "__main__":
    sys.exit(main())
