"""``python -m verification STUDY [options]``: one study of the independent verification, or all of them.

``python -m verification STUDY --help`` lists a study's own options.
"""

from __future__ import annotations

import sys

from ._common.cli import dispatch

#: Each study: one line of help and the module whose ``main(argv)`` runs it.
STUDIES = {
    "all": ("every study into one report (make verify)", "verification.report"),
    "dolfinx": ("fem_grasp against dolfinx; linear studies", "verification.dolfinx.__main__"),
    "hertz": ("sphere indentation against Hertz theory; node contact against a weighted gap",
              "verification.hertz.__main__"),
    "roundoff": ("same answer under round-off perturbations", "verification.roundoff.__main__"),
    "random_scenes": ("random valid scenes never crash", "verification.random_scenes.__main__"),
    "converge": ("pickup answer under refinement (make converge)", "verification.converge.__main__"),
    "coverage": ("the accuracy loop's stated error against a reference", "verification.coverage.__main__"),
    "friction": ("frictional contact against a reference solver", "verification.friction.__main__"),
    "softness": ("forces against the rigid grasp (Table III)", "verification.softness.__main__"),
}


def main(argv: list[str] | None = None) -> int:
    return dispatch("python -m verification", "Independent verification of fem_grasp, one study at a time or all.",
                    STUDIES, argv, metavar="STUDY",
                    epilog="python -m verification STUDY --help: the study's own options.")


if __name__ == "__main__":
    sys.exit(main())
