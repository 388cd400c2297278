"""``python -m verification friction study [--quick] [--out DIR]``: every frictional-contact stage, with its report
(``friction.html``, ``friction.json``); the same stages run in the full report."""

from __future__ import annotations

import sys

from .. import friction
from .._common.run import study_main


def main(argv: list[str] | None = None) -> int:
    return study_main(friction, "friction", "Frictional contact against an independent reference", argv,
                      quick_help="the quick foam block, three random scenes, two increments (minutes)",
                      prog="python -m verification friction study")


if __name__ == "__main__":
    sys.exit(main())
