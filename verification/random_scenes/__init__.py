"""Random valid scenes never crash: every pickup ends in a named outcome with its checks passing.

A scene here is a gmsh ellipsoid or two fused spheres of random size and
aspect, a random material (E from 1e3 to 1e7 Pa, ν from 0 to 0.45), random
friction on the fingers and the table (μ from 0.05 to 1.5), a random
fingertip radius, squeeze tilt (0–40° below the horizontal) and ratio s
(0–1), and the default finger placement.  Every such scene is valid input,
so :func:`run_scene` must end in one of :data:`fem_grasp.grasp.pickup.OUTCOMES`
with :meth:`~fem_grasp.grasp.pickup.PickupResult.check` passing on every snapshot
— or, before the pickup proper, in the object not coming to rest on the table
(:data:`NO_REST`).  Any other exception is a bug.

``tests/test_random_scenes.py`` draws about 50 scenes with hypothesis inside
``make test``; ``python -m verification random_scenes --scenes 500`` (a stage of
the full report, 40 scenes with ``--quick``) draws more with numpy, two processes
at a time.  Headline check and report section: :mod:`.report`.
"""

from __future__ import annotations

import logging
import math
import multiprocessing
import time
import traceback
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .report import checks, section

log = logging.getLogger(__name__)

#: Parameter ranges of a random scene (SI units; angles in degrees).
RANGES: dict[str, tuple[float, float]] = {
    "size": (0.015, 0.05),  # the first semi-axis, or the larger sphere's radius, metres
    "aspect_y": (0.6, 1.2),  # ellipsoid: b / a
    "aspect_z": (0.5, 1.2),  # ellipsoid: c / a
    "sphere_ratio": (0.5, 1.0),  # fused spheres: r₂ / r₁
    "overlap": (0.45, 0.9),  # fused spheres: distance / (r₁ + r₂)
    "log10_young": (3.0, 7.0),
    "poisson": (0.0, 0.45),
    "mu_finger": (0.05, 1.5),
    "mu_table": (0.05, 1.5),
    "radius_ratio": (0.3, 1.0),  # fingertip radius / the body's smallest semi-axis or radius
    "tilt": (0.0, 40.0),
    "ratio": (0.0, 1.0),
    "density": (100.0, 1000.0),
}
#: Vertices aimed at per scene: enough for contact patches of several nodes, few enough for ~50 pickups in
#: a couple of minutes.
TARGET_VERTICES = 100
#: The ends that are not a pickup outcome but a valid answer too: the object does not come to rest.
NO_REST = ("FrictionError", "RestConvergenceError")


@dataclass(frozen=True)
class RandomScene:
    """The parameters of one random scene (see :data:`RANGES`)."""

    shape: str  # "ellipsoid" or "fused spheres"
    size: float
    aspect_y: float
    aspect_z: float
    sphere_ratio: float
    overlap: float
    log10_young: float
    poisson: float
    mu_finger: float
    mu_table: float
    radius_ratio: float
    tilt: float
    ratio: float
    density: float

    @classmethod
    def draw(cls, rng: np.random.Generator) -> "RandomScene":
        """A scene with every parameter uniform in its range."""
        values = {k: float(rng.uniform(lo, hi)) for k, (lo, hi) in RANGES.items()}
        return cls(shape=str(rng.choice(["ellipsoid", "fused spheres"])), **values)

    def mesh(self):
        """The gmsh mesh of the shape, at about :data:`TARGET_VERTICES` vertices; and its smallest radius."""
        from fem_grasp import TetMesh
        from fem_grasp.mesh.shapes import ellipsoid, fused_spheres

        if self.shape == "ellipsoid":
            axes = (self.size, self.size * self.aspect_y, self.size * self.aspect_z)
            volume = 4.0 / 3.0 * math.pi * np.prod(axes)
            build, smallest = (lambda h: ellipsoid(axes, h)), min(axes)
        else:
            r1, r2 = self.size, self.size * self.sphere_ratio
            d = max(self.overlap * (r1 + r2), 1.05 * (r1 - r2))
            volume = 4.0 / 3.0 * math.pi * (r1**3 + r2**3)
            build, smallest = (lambda h: fused_spheres((r1, r2), d, h)), r2
        # gmsh gives about 2.5 V / h³ vertices at these sizes
        h = (2.5 * volume / TARGET_VERTICES) ** (1.0 / 3.0)
        return TetMesh(*build(h)), smallest

    def pickup_arguments(self, smallest: float) -> dict[str, Any]:
        t = math.radians(self.tilt)
        d1 = np.array([0.0, math.cos(t), -math.sin(t)])
        d2 = np.array([0.0, -math.cos(t), -math.sin(t)])
        return {"mu_finger": self.mu_finger, "mu_table": self.mu_table,
                "finger_radius": self.radius_ratio * smallest, "directions": (d1, d2), "ratio": self.ratio}


def run_scene(scene: RandomScene) -> dict[str, Any]:
    """Pick the scene up; the outcome, the checks, and any exception with its traceback."""
    from fem_grasp import Body
    from fem_grasp.grasp.pickup import pickup

    t0 = time.perf_counter()
    row: dict[str, Any] = {"scene": asdict(scene)}
    try:
        mesh, smallest = scene.mesh()
        row["vertices"] = mesh.n_points
        body = Body(mesh, 10.0**scene.log10_young, scene.poisson, density=scene.density)
        res = pickup(body, **scene.pickup_arguments(smallest))
        figures = res.check(raise_on_failure=False)
        row.update(outcome=res.outcome, reason=res.reason, squeeze_depth=res.squeeze_depth,
                   events=len(res.events), checks_ok=all(f["ok"] for f in figures),
                   check_failures=sorted({x for f in figures for x in f["failures"]}))
    except Exception as exc:  # noqa: BLE001 - sorted below: a named answer or a bug
        name = type(exc).__name__
        row.update(outcome="does not rest" if name in NO_REST else "crash", reason=f"{name}: {exc}",
                   traceback=traceback.format_exc())
    row["seconds"] = time.perf_counter() - t0
    return row


def problems(row: dict[str, Any]) -> list[str]:
    """What is wrong with a run (empty: a named outcome, every check passed)."""
    from fem_grasp.grasp.pickup import OUTCOMES

    out = []
    if row["outcome"] == "crash":
        out.append(f"crash: {row['reason']}")
    elif row["outcome"] != "does not rest":
        if row["outcome"] not in OUTCOMES:
            out.append(f"unknown outcome {row['outcome']!r}")
        if not row["checks_ok"]:
            out.append("check() fails: " + "; ".join(row["check_failures"]))
    return out


def _run_seed(seed: int) -> dict[str, Any]:
    return run_scene(RandomScene.draw(np.random.default_rng(seed)))


def sweep(n: int, seed: int = 0, workers: int = 2, progress: Callable[[int, dict], None] | None = None
          ) -> dict[str, Any]:
    """Draw ``n`` scenes (seeds seed … seed + n − 1) and run them on ``workers`` processes;
    ``progress(done, row)`` after each."""
    from fem_grasp.progress import progress as bar

    seeds = list(range(seed, seed + n))
    rows = []
    # Fresh interpreters, not forks: a fork of a process that has loaded dolfinx (and so MPI), as the
    # verification run has, hangs in its workers.
    with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        for row in bar(pool.map(_run_seed, seeds), total=n, desc="random scenes", unit="scene"):
            rows.append(row)
            if progress is not None:
                progress(len(rows), row)
    for s, row in zip(seeds, rows):
        row["seed"] = s
    counts: dict[str, int] = {}
    for row in rows:
        counts[row["outcome"]] = counts.get(row["outcome"], 0) + 1
    bad = [{"seed": r["seed"], "problems": problems(r), "scene": r["scene"]} for r in rows if problems(r)]
    times = [r["seconds"] for r in rows]
    return {"scenes": n, "outcomes": counts, "problems": bad, "median_seconds": float(np.median(times)),
            "max_seconds": float(max(times)), "rows": rows}


#: Scenes drawn by the full report (and with ``--quick``).
CONFIGS: dict[str, dict[str, Any]] = {"full": {"scenes": 500}, "quick": {"scenes": 40}}
#: Stages of :func:`run`.
STAGES = 1


def run(quick: bool, out_dir: Path, stages: Any) -> tuple[dict[str, Any], dict[str, str]]:
    """The sweep as a stage of the report: its part of the summary (counts and problems, not every row)."""
    cfg = CONFIGS["quick" if quick else "full"]
    part: dict[str, Any] = {"config": cfg}
    stages.run("random scenes", lambda: sweep(cfg["scenes"]),
               lambda v: part.__setitem__("random_scenes", {k: v[k] for k in v if k != "rows"}))
    return part, {}


__all__ = ["CONFIGS", "NO_REST", "RANGES", "STAGES", "RandomScene", "checks", "problems", "run", "run_scene", "section",
           "sweep"]
