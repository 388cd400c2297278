"""``python -m verification dolfinx [--quick] [--out DIR]``: fem_grasp against dolfinx and the linear studies."""

from __future__ import annotations

import sys

from .. import dolfinx
from .._common.run import study_main


def main(argv: list[str] | None = None) -> int:
    return study_main(dolfinx, "dolfinx", "fem_grasp against dolfinx: cross-checks, manufactured solutions, "
                      "locking, stability", argv, quick_help="small meshes and fewer levels (minutes)")


if __name__ == "__main__":
    sys.exit(main())
