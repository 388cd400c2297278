"""``python -m fem_grasp``: the ``fem-grasp`` command line (:mod:`fem_grasp.cli`)."""

import sys

from .cli import main

sys.exit(main())
