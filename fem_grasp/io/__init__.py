"""Files: scene descriptions in, results out (the applications' side of the package).

* :mod:`~fem_grasp.io.scene` — a pickup described in TOML, with units ("10 kPa", "2 cm"), checked key by key
  (:meth:`Scene.load`, :meth:`Scene.with_`, :meth:`Scene.run`; :func:`run_scene` in one line, the same answer
  as ``fem-grasp run``);
* :mod:`~fem_grasp.io.cache` — gmsh meshes and resting states cached between runs, each used only after it
  re-solves to the same forces;
* :mod:`~fem_grasp.io.output` — ``result.json`` and a ParaView time series of the pickup;
* :mod:`~fem_grasp.io.report` — ``report.html``: pictures (pyvista, off-screen), w(ρ) and the event timeline.
"""

from .output import read_result, write_run
from .scene import Scene, load_scene, pickup_scene, resolve_scene, run_scene, shipped_scenes

__all__ = ["Scene", "load_scene", "pickup_scene", "read_result", "resolve_scene", "run_scene", "shipped_scenes",
           "write_run"]
