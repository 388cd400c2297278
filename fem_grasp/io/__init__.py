"""Files: scene descriptions in, results out (the applications' side of the package).

* :mod:`~fem_grasp.io.scene` — a pickup described in TOML, with units ("10 kPa", "2 cm"), checked key by key
  (:meth:`Scene.load`, :meth:`Scene.with_`, :meth:`Scene.run`; :func:`run_scene` in one line, the same answer
  as ``fem-grasp run``); its parts: :mod:`~fem_grasp.io.quantities` (numbers with units),
  :mod:`~fem_grasp.io.scene_file` (finding and reading scene files), :mod:`~fem_grasp.io.scene_changes`
  (:meth:`Scene.with_`), :mod:`~fem_grasp.io.scene_mesh` (the object's mesh) and :mod:`~fem_grasp.io.scene_run`
  (the pickup of a scene);
* :mod:`~fem_grasp.io.cache` — gmsh meshes and resting states cached between runs, each used only after it
  re-solves to the same forces;
* :mod:`~fem_grasp.io.output` — ``result.json`` and a ParaView time series of the pickup; its parts:
  :mod:`~fem_grasp.io.folder` (output folders and their marker file), :mod:`~fem_grasp.io.series` (the time
  series) and :mod:`~fem_grasp.io.xdmf` (its XDMF/HDF5 copy);
* :mod:`~fem_grasp.io.report` — ``report.html``: pictures (pyvista, off-screen), w(ρ) and the event timeline; its
  parts: :mod:`~fem_grasp.io.frames` (the frames it draws, read back), :mod:`~fem_grasp.io.render` (the 3-D views)
  and :mod:`~fem_grasp.io.plots` (the 2-D plots).
"""

from .output import read_result, write_run
from .scene import Scene, load_scene, pickup_scene, resolve_scene, run_scene, shipped_scenes

__all__ = ["Scene", "load_scene", "pickup_scene", "read_result", "resolve_scene", "run_scene", "shipped_scenes",
           "write_run"]
