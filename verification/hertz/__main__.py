"""``python -m verification hertz [--quick] [--out DIR]``: sphere indentation against Hertz theory."""

from __future__ import annotations

import sys

from .. import hertz
from .._common.run import study_main


def main(argv: list[str] | None = None) -> int:
    return study_main(hertz, "hertz", "Sphere indentation against Hertz theory", argv,
                      quick_help="two mesh levels instead of five, the indenter two spacings and two seeds "
                                 "(about a minute)")


if __name__ == "__main__":
    sys.exit(main())
