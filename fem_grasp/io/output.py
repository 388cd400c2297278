"""Results on disk: ``result.json`` and a ParaView time series of the whole pickup.

An output folder written by :func:`write_run` holds::

    result.json            schema-versioned summary, scene, events, w(ρ), every snapshot's contacts
    object.pvd             time series of the object (open this in ParaView)
    object.xdmf, object.h5 the same series as XDMF 3 + HDF5 (when h5py is installed)
    finger1.pvd            the fingertips, one sphere per step (front and back hemispheres)
    finger2.pvd
    table.vtu              the table plane (a square under the object)
    series/*.vtu           the steps (meshio VTU, XML binary)
    .fem_grasp.json        marks the folder as ours and lists the files we wrote

What each step holds and the time value of each frame: :mod:`fem_grasp.io.series` (and
:mod:`fem_grasp.io.xdmf`); the folder's checks and its marker file: :mod:`fem_grasp.io.folder`.

Every file is written atomically (a temporary file in the same folder, then
:func:`os.replace`), and a folder that is not empty and was not written by
fem_grasp is refused unless ``force`` is given.  ``--out`` names a folder:
a name that ends like a file (``x.xdmf``, ``x.vtu``) is refused.
"""

from __future__ import annotations

import datetime
import json
import logging
import math
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .._files import atomic_write_bytes, atomic_write_text
from ..errors import OutputError
from .folder import (
    FILE_SUFFIXES,
    MARKER,
    add_to_marker,
    check_out_path,
    package_version,
    prepare_out_dir,
    write_marker,
)
from .series import (
    PHASE_CODES,
    TIME_TICK,
    contact_point_data,
    finger_path,
    fingertip_surface,
    frame_times,
    frames_of,
    hemisphere,
    mechanics_fields,
    read_pvd,
    write_series,
    write_vtu,
)
from .vtu import cells_xml, write_grid
from .xdmf import write_xdmf

__all__ = ["SCHEMA", "SCHEMA_VERSION", "OutputError", "atomic_write_bytes", "atomic_write_text", "json_safe", "prepare_out_dir",
           "frames_of", "fingertip_surface", "write_series", "write_result_json", "write_run", "read_result", "hemisphere",
           "contact_point_data", "write_rest", "MARKER", "add_to_marker", "PHASE_CODES", "finger_path", "frame_times",
           "check_out_path", "write_xdmf", "FILE_SUFFIXES", "read_pvd", "TIME_TICK", "write_vtu", "mechanics_fields"]

log = logging.getLogger(__name__)

SCHEMA = "fem_grasp.result"
#: Version of the result.json layout (bump on incompatible change).
SCHEMA_VERSION = 1


# ------------------------------------------------------------ JSON
def json_safe(x: Any) -> Any:
    """JSON-safe: numpy → Python, NaN/±inf → None (strict JSON)."""
    if isinstance(x, dict):
        return {str(k): json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [json_safe(v) for v in x]
    if isinstance(x, np.ndarray):
        return json_safe(x.tolist())
    if isinstance(x, (np.floating, float)):
        v = float(x)
        return v if math.isfinite(v) else None
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.bool_,)):
        return bool(x)
    if isinstance(x, Path):
        return str(x)
    return x


def result_summary(result: Any) -> dict[str, Any]:
    """The figures a user reads first."""
    from ..grasp.forces import TABLE_III_MEASURE

    rigid = result.rigid
    forces = result.finger_forces
    return {
        "success": bool(result.success), "outcome": result.outcome, "reason": result.reason,
        "squeeze_depth": result.squeeze_depth,
        "n_final_contacts": result.n_final_contacts, "finger_normal_force": result.finger_normal_force,
        "finger_forces": None if forces is None else {f"finger{k}": f.to_dict() for k, f in enumerate(forces, 1)},
        "table_iii_measure": TABLE_III_MEASURE,
        "rigid_total_normal_force": None if rigid is None or not rigid.feasible else rigid.total_normal_force,
        "max_liftable_weight": max((w for _, w in result.liftable), default=0.0), "weight": result.body.weight,
        "event_counts": result.event_counts(), "n_events": len(result.events), "n_snapshots": len(result.snapshots),
        "n_nodes": result.body.n_nodes, "n_tets": result.body.mesh.n_tets, "timings": dict(result.timings),
        "accuracy_target": None if not getattr(result, "accuracy", None) else result.accuracy["target"],
        "estimated_error": None if not getattr(result, "accuracy", None) else result.accuracy["estimated_error"],
    }


def write_result_json(out: str | Path, result: Any, scene: Any = None, series: dict[str, Any] | None = None,
                      extra: dict[str, Any] | None = None) -> Path:
    """Write ``result.json`` (schema :data:`SCHEMA` version :data:`SCHEMA_VERSION`).

    Keys: schema, schema_version, fem_grasp_version, created, scene, summary,
    rest, result (:meth:`PickupResult.to_dict` without node positions and
    tetrahedra, which the time series holds), series, plus ``extra``.
    """
    res = result.to_dict(geometry=False)
    rs = result.rest
    doc = {
        "schema": SCHEMA, "schema_version": SCHEMA_VERSION, "fem_grasp_version": package_version(),
        "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "scene": None if scene is None else scene.to_dict(),
        "summary": result_summary(result),
        "rest": None if rs is None else {"n_contacts": rs.n_contacts, "n_sliding": int(rs.sliding.sum()),
                                         "max_sag": rs.max_sag, "iterations": rs.iterations,
                                         "table_z": rs.table_z, "support_triangle": rs.support_triangle,
                                         "contact_nodes": rs.contact_nodes, "contact_forces": rs.contact_forces,
                                         "sliding": rs.sliding},
        "result": res,
        "series": series,
        # With pickup(..., accuracy=...): {"target", "estimated_error": {"squeeze_depth", "finger_force"},
        # "converged", "levels": [...], ...} (fem_grasp.grasp.accuracy.AccuracyReport); None for a single run.
        "accuracy": getattr(result, "accuracy", None),
    }
    res.pop("accuracy", None)
    doc.update(extra or {})
    path = Path(out) / "result.json"
    atomic_write_text(path, json.dumps(json_safe(doc), indent=1, allow_nan=False))
    return path


def read_result(out: str | Path) -> dict[str, Any]:
    """Read ``result.json`` from an output folder, checking its schema.

    Raises
    ------
    OutputError
        No result.json, not JSON, or another schema / a newer schema version.
    """
    path = Path(out) / "result.json"
    if not path.exists():
        raise OutputError(f"{path} does not exist: run `fem-grasp run SCENE --out {out}` first")
    try:
        doc = json.loads(path.read_text())
    except ValueError as exc:
        raise OutputError(f"{path} is not valid JSON: {exc}") from None
    if doc.get("schema") != SCHEMA:
        raise OutputError(f"{path} is not a fem_grasp result (schema {doc.get('schema')!r})")
    if int(doc.get("schema_version", 0)) > SCHEMA_VERSION:
        raise OutputError(f"{path} has schema version {doc['schema_version']}, newer than this fem_grasp reads "
                          f"({SCHEMA_VERSION}); upgrade fem_grasp")
    return doc


def write_run(out: str | Path, result: Any, scene: Any = None, force: bool = False,
              extra: dict[str, Any] | None = None,
              progress: Callable[[int, int], None] | None = None) -> Path:
    """Write result.json and the time series of one pickup into ``out`` (see the module notes)."""
    out = prepare_out_dir(out, force)
    series = write_series(out, result, progress)
    write_result_json(out, result, scene, series, extra)
    write_marker(out, series["files"] + ["result.json"])
    log.info("wrote %s (result.json, object.pvd, %d frames)", out, len(series["frames"]))
    return out


def write_rest(out: str | Path, state: Any, scene: Any = None, force: bool = False,
               extra: dict[str, Any] | None = None) -> Path:
    """Write a resting state: ``rest.json`` and ``rest.vtu`` (displacement, contact point data)."""
    out = prepare_out_dir(out, force)
    n = state.body.n_nodes
    frame = {"contact_nodes": {"finger1": [], "finger2": [], "table": state.contact_nodes},
             "contact_forces": {"finger1": np.zeros((0, 3)), "finger2": np.zeros((0, 3)),
                                "table": state.contact_forces},
             "sliding": {"finger1": [], "finger2": [], "table": state.sliding}}
    pd = {"displacement": state.displacements}
    extra_pd, cd = mechanics_fields(state.body.mesh.points, state.body.mesh.tets, state.displacements, state.body.young,
                           state.body.poisson)
    pd.update(extra_pd)
    pd.update(contact_point_data(n, frame))
    write_grid(out / "rest.vtu", state.positions, cells_xml("tetra", state.body.mesh.tets), pd, cd)
    figures = state.check(raise_on_failure=False)
    doc = {"schema": "fem_grasp.rest", "schema_version": SCHEMA_VERSION, "fem_grasp_version": package_version(),
           "scene": None if scene is None else scene.to_dict(), "check": figures,
           "n_contacts": state.n_contacts, "n_sliding": int(state.sliding.sum()), "max_sag": state.max_sag,
           "iterations": state.iterations, "wall_time": state.wall_time, "table_z": state.table_z,
           "support_triangle": state.support_triangle, "contact_nodes": state.contact_nodes,
           "contact_forces": state.contact_forces, "sliding": state.sliding}
    doc.update(extra or {})
    atomic_write_text(out / "rest.json", json.dumps(json_safe(doc), indent=1, allow_nan=False))
    add_to_marker(out, ["rest.vtu", "rest.json"])
    return out
