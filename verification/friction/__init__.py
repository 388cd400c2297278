"""fem_grasp's frictional contact against an independent reference (the squeeze, the lift test and the lift).

fem_grasp tracks the contact evolution of *Picking up Soft 3D Objects with Two Fingers* (H. Lin, F. Guo,
F. Wang, Y.-B. Jia, ICRA 2014) event by event.  :mod:`.reference` solves the same quasi-static frictional
problem another way — each increment one static contact problem, a semismooth Newton method on the
Alart–Curnier equations, on K and G assembled by dolfinx — sharing no code with fem_grasp's contact modules
(formulation and tolerances: ``verification/friction/README.md``).

``python -m verification friction compare SCENE``  one scene against the reference (:mod:`.compare`)
``python -m verification friction random OUT_DIR``  seeded random valid scenes (:mod:`.random_scenes`)
``python -m verification friction diagnose SCENE``  both lift tests on one squeeze state (:mod:`.diagnose`)
``python -m verification friction study [--quick]``  every stage below, with its report (``friction.html``)

The study's stages (:func:`run`, also stages of the full report): the shipped scenes at several reference
increments, seeded random scenes, and fem_grasp's own increment divided (the step study); its headline checks
and section are in :mod:`.report`.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from .._common.run import Stages
from . import compare as fr
from .report import checks, convergence_plot, section

__all__ = ["CONFIGS", "STAGES", "checks", "run", "section"]

log = logging.getLogger(__name__)

CONFIGS: dict[str, dict[str, Any]] = {
    "full": {
        "scenes": [("foam_block", False), ("slippery_ball", False), ("orange", False), ("football", False),
                   ("tomato", False), ("steam_bun", False)],
        "levels": (1, 2, 4, 8),
        "random": {"count": 20, "levels": (1, 4)},
        "step_study": [("foam_block", True, (1.0, 4.0, 16.0), (1, 4)), ("foam_block", False, (1.0, 4.0, 16.0), (1,))],
    },
    "quick": {
        "scenes": [("foam_block", True)],
        "levels": (1, 2),
        "random": {"count": 3, "levels": (1,)},
        "step_study": [("foam_block", True, (1.0, 4.0), (1,))],
    },
}
#: Stages of :func:`run`.
STAGES = 4


def run(quick: bool, out_dir: Path, stages: Stages) -> tuple[dict[str, Any], dict[str, str]]:
    """Every frictional-contact stage; returns the summary part and the pictures written."""
    from .random_scenes import compare_random

    cfg = CONFIGS["quick" if quick else "full"]
    out: dict[str, Any] = {"config": cfg}
    images: dict[str, str] = {}

    def scenes() -> list[dict[str, Any]]:
        done = []
        for name, q in cfg["scenes"]:
            s = fr.run_case(name, levels=cfg["levels"], quick=q)
            done.append(s)
            print(f"  {name}{' (quick)' if q else ''}: verdicts {s['verdict_fem_grasp']} / {s['verdict_reference']}, "
                  f"max |Δf|/F_s {s['force_max_finest']:.2e}, {s['seconds']:.0f} s", flush=True)
        return done

    def random() -> list[dict[str, Any]]:
        rows = compare_random(out_dir / "random_scenes", cfg["random"]["count"], levels=cfg["random"]["levels"])
        print(f"  random scenes: verdicts agree on {sum(r['verdicts_agree'] for r in rows)} of {len(rows)}", flush=True)
        return rows

    stages.run("frictional contact: shipped scenes", scenes, lambda v: out.__setitem__("scenes", v))
    stages.run("frictional contact: random scenes", random, lambda v: out.__setitem__("random", v))
    stages.run("frictional contact: fem_grasp's increment",
               lambda: [fr.step_study(name, divisors=divs, increments=ms, quick=q)
                        for name, q, divs, ms in cfg["step_study"]],
               lambda v: out.__setitem__("step_study", v))
    stages.run("frictional contact: plot", lambda: images.__setitem__("friction_convergence", convergence_plot(
        out.get("scenes", []), out.get("step_study", []), out_dir / "friction_convergence.png").name))
    return out, images
