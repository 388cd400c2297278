"""Shared helpers of the scene / CLI / output / report / scan tests: generated surfaces and one CLI run."""

from __future__ import annotations

import atexit
import shutil
import tempfile
from functools import lru_cache
from pathlib import Path

import numpy as np


def icosphere(radius: float = 0.03, levels: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """A closed, outward-oriented triangulated sphere: (points, faces)."""
    t = (1 + 5 ** 0.5) / 2
    v = [np.array(p, float) for p in ([-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                                      [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1])]
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6],
         [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10],
         [8, 6, 7], [9, 8, 1]]
    for _ in range(levels):
        cache: dict[tuple[int, int], int] = {}

        def mid(a: int, b: int) -> int:
            key = (min(a, b), max(a, b))
            if key not in cache:
                cache[key] = len(v)
                v.append(0.5 * (v[a] + v[b]))
            return cache[key]

        nf = []
        for a, b, c in f:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            nf += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        f = nf
    p = np.array(v)
    return radius * p / np.linalg.norm(p, axis=1, keepdims=True), np.array(f, dtype=np.int64)


def write_stl(path: Path, points: np.ndarray, faces: np.ndarray) -> Path:
    """Write triangles as STL (meshio), every facet with its own three vertices as scanners do."""
    import meshio

    meshio.write(path, meshio.Mesh(points[faces].reshape(-1, 3), [("triangle", np.arange(3 * len(faces)).reshape(-1, 3))]))
    return path


_TMP = Path(tempfile.mkdtemp(prefix="fem_grasp_ux_tests_"))
atexit.register(shutil.rmtree, _TMP, ignore_errors=True)


@lru_cache(maxsize=None)
def cli_run(scene: str, *flags: str) -> tuple[int, Path]:
    """Run ``fem-grasp run SCENE --quick --out DIR *flags`` in-process once per session; (exit status, DIR)."""
    from fem_grasp.cli import main

    out = _TMP / ("run-" + "-".join([scene, *[f.strip("-") for f in flags]]))
    code = main(["run", scene, "--quick", "--quiet", "--out", str(out), "--cache", str(_TMP / "cache"), *flags])
    return code, out


def cache_dir() -> Path:
    return _TMP / "cache"
