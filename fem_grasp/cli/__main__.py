"""``python -m fem_grasp.cli``: the ``fem-grasp`` command line, as ``python -m fem_grasp``."""

import sys

from . import main

sys.exit(main())
