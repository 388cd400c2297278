"""Remeshing a box (what the accuracy loop does for a box scene): the finger contacts are kept as mesh nodes
wherever they lie on the surface, and gmsh works from any thread (a Dask worker's task runs in one)."""

import subprocess
import sys

import numpy as np
import pytest

from fem_grasp.mesh.remesh import BoxGeometry

pytest.importorskip("gmsh")

BOX = BoxGeometry((-0.015, -0.02, 0.0), (0.015, 0.02, 0.03))


def test_points_on_faces_edges_and_corners_become_nodes_and_a_point_inside_is_refused():
    points = np.array([[0.0, 0.02, 0.011],       # on a face
                       [-0.015, -0.02, 0.02],    # on a vertical edge
                       [0.015, 0.0, 0.03],       # on a top edge
                       [0.015, 0.02, 0.0]])      # a corner
    mesh = BOX.build(0.006, embed=points)
    gap = np.linalg.norm(mesh.points[:, None] - points[None], axis=2).min(axis=0)
    assert np.all(gap < 1e-12), gap
    assert np.isclose(mesh.volume, 0.03 * 0.04 * 0.03, rtol=1e-9)
    with pytest.raises(ValueError, match="not on the box's surface"):
        BOX.build(0.006, embed=np.array([[0.0, 0.0, 0.01]]))


def test_gmsh_is_imported_and_run_on_a_thread_other_than_the_main_one():
    code = ("import threading\n"
            "from fem_grasp.mesh.remesh import BoxGeometry\n"
            "out = []\n"
            "t = threading.Thread(target=lambda: out.append(BoxGeometry((0, 0, 0), (0.03, 0.04, 0.03)).build(0.01)))\n"
            "t.start(); t.join()\n"
            "assert out and out[0].n_points > 8, out\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
