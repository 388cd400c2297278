"""Results on disk: ``result.json`` and a ParaView time series of the whole pickup.

An output folder written by :func:`write_run` holds::

    result.json            schema-versioned summary, scene, events, w(ρ), every snapshot's contacts
    object.pvd             time series of the object (open this in ParaView)
    finger1.pvd            the fingertips, one sphere per step (front and back hemispheres)
    finger2.pvd
    table.vtu              the table plane (a square under the object)
    series/*.vtu           the steps (meshio VTU, XML binary)
    .fem_grasp.json        marks the folder as ours and lists the files we wrote

Each object step holds the *deformed* node positions (so that object,
fingertips and table line up without a filter) and point data

* ``displacement`` (m): from the posed, undeformed body;
* ``contact_state``: 0 no contact, 1 sticking, 2 sliding;
* ``contact_body``: 0 none, 1 finger 1, 2 finger 2, 3 table;
* ``contact_force`` (N): the force on the object at each contact node (zero elsewhere).

Frame 0 is the resting state (label ``rest``); frame k ≥ 1 is
``result.snapshots[k − 1]``.  PVD time steps are the frame indices;
``result.json["series"]["frames"]`` gives each frame's label, phase, squeeze
depth ρ and lift height.

Every file is written atomically (a temporary file in the same folder, then
:func:`os.replace`), and a folder that is not empty and was not written by
fem_grasp is refused unless ``force`` is given.
"""

from __future__ import annotations

import datetime
import json
import logging
import math
import os
import tempfile
from pathlib import Path
from typing import Any, Callable, Sequence
from xml.sax.saxutils import quoteattr

import numpy as np

__all__ = ["SCHEMA", "SCHEMA_VERSION", "OutputError", "atomic_write_bytes", "atomic_write_text", "json_safe", "prepare_out_dir",
           "frames_of", "fingertip_surface", "write_series", "write_result_json", "write_run", "read_result", "hemisphere",
           "contact_point_data", "write_rest", "MARKER"]

log = logging.getLogger(__name__)

SCHEMA = "fem_grasp.result"
#: Version of the result.json layout (bump on incompatible change).
SCHEMA_VERSION = 1
#: Marker file naming the files fem_grasp wrote into an output folder.
MARKER = ".fem_grasp.json"

CONTACT_NONE, CONTACT_STICK, CONTACT_SLIP = 0, 1, 2
BODY_CODES = {"finger1": 1, "finger2": 2, "table": 3}


class OutputError(OSError):
    """An output folder cannot be used (not ours and not empty, or not writable)."""


def package_version() -> str:
    """The installed fem_grasp version ("unknown" when run from a source tree without metadata)."""
    try:
        from importlib.metadata import version

        return version("fem_grasp")
    except Exception:  # noqa: BLE001 - metadata missing
        return "unknown"


# ------------------------------------------------------------ atomic writes
def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


_UMASK = _umask()


def _atomic(path: Path, write: Callable[[Path], None]) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix,
                               dir=path.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        write(tmp_path)
        os.chmod(tmp_path, 0o666 & ~_UMASK)  # mkstemp makes 0600; give the file the usual permissions
        os.replace(tmp_path, path)
    except BaseException:
        tmp_path.unlink(missing_ok=True)
        raise
    return path


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same folder and :func:`os.replace`."""
    return _atomic(Path(path), lambda p: p.write_bytes(data))


def atomic_write_text(path: str | Path, text: str) -> Path:
    return atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_mesh(path: str | Path, mesh: Any, file_format: str = "vtu") -> Path:
    """Write a ``meshio.Mesh`` atomically."""
    import meshio

    return _atomic(Path(path), lambda p: meshio.write(p, mesh, file_format=file_format))


# ------------------------------------------------------------ the folder
def prepare_out_dir(path: str | Path, force: bool = False) -> Path:
    """Create ``path`` or check that it may be written into.

    A folder that exists, is not empty and has no :data:`MARKER` was not
    written by fem_grasp: it is refused unless ``force``.  Files listed in a
    previous marker are removed (so that no stale step of an earlier run
    remains); nothing else is touched.

    Raises
    ------
    OutputError
        The folder is a file, is not ours and not empty (without ``force``), or cannot be created.
    """
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise OutputError(f"output path {out} exists and is not a folder")
    marker = out / MARKER
    if out.is_dir() and any(out.iterdir()):
        if marker.exists():
            try:
                old = json.loads(marker.read_text()).get("files", [])
            except (OSError, ValueError):
                old = []
            for rel in old:
                f = (out / rel).resolve()
                if out.resolve() in f.parents and f.is_file():
                    f.unlink()
        elif not force:
            raise OutputError(f"output folder {out} is not empty and was not written by fem_grasp (no {MARKER}); "
                              "choose another folder or pass --force to write into it")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot create output folder {out}: {exc}") from None
    return out


def _write_marker(out: Path, files: Sequence[str]) -> None:
    atomic_write_text(out / MARKER, json.dumps({"written_by": "fem_grasp", "version": package_version(),
                                                "files": sorted(set(files))}, indent=1))


def _add_to_marker(out: Path, files: Sequence[str]) -> None:
    old: list[str] = []
    if (out / MARKER).exists():
        try:
            old = json.loads((out / MARKER).read_text()).get("files", [])
        except (OSError, ValueError):
            old = []
    _write_marker(out, list(old) + list(files))


# ------------------------------------------------------------ frames
def frames_of(result: Any) -> list[dict[str, Any]]:
    """The frames of the time series: the resting state, then every snapshot of ``result``.

    Each frame is a dict with label, phase, squeeze_depth, lift_height,
    positions (n, 3), finger_centers (2, 3) or None, finger_radius,
    contact_nodes / contact_forces / sliding (dicts keyed finger1, finger2,
    table) and snapshot (index into ``result.snapshots`` or None).
    """
    frames = []
    snaps = list(result.snapshots)
    if result.final is not None and (not snaps or snaps[-1] is not result.final):
        snaps.append(result.final)
    first_centres = snaps[0].finger_centers if snaps else None
    rs = result.rest
    if rs is not None:
        empty3, empty = np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
        frames.append({"label": "rest", "phase": "rest", "squeeze_depth": 0.0, "lift_height": 0.0,
                       "positions": rs.positions, "finger_centers": first_centres,
                       "finger_radius": result.finger_radius,
                       "contact_nodes": {"finger1": empty, "finger2": empty, "table": rs.contact_nodes},
                       "contact_forces": {"finger1": empty3, "finger2": empty3, "table": rs.contact_forces},
                       "sliding": {"finger1": empty.astype(bool), "finger2": empty.astype(bool),
                                   "table": rs.sliding},
                       "snapshot": None})
    for i, s in enumerate(snaps):
        frames.append({"label": s.label, "phase": s.phase, "squeeze_depth": float(s.squeeze_depth),
                       "lift_height": float(s.lift_height), "positions": s.positions,
                       "finger_centers": s.finger_centers, "finger_radius": s.finger_radius,
                       "contact_nodes": s.contact_nodes, "contact_forces": s.contact_forces, "sliding": s.sliding,
                       "snapshot": i if i < len(result.snapshots) else None})
    return frames


def contact_point_data(n: int, frame: dict[str, Any]) -> dict[str, np.ndarray]:
    """Per-node contact state (0/1/2), contact body (0–3) and contact force (n, 3) of one frame."""
    state = np.zeros(n, dtype=np.int32)
    body = np.zeros(n, dtype=np.int32)
    force = np.zeros((n, 3))
    for name, code in BODY_CODES.items():
        k = np.asarray(frame["contact_nodes"][name], dtype=np.int64)
        if not len(k):
            continue
        state[k] = np.where(np.asarray(frame["sliding"][name], bool), CONTACT_SLIP, CONTACT_STICK)
        body[k] = code
        force[k] = np.asarray(frame["contact_forces"][name], float)
    return {"contact_state": state, "contact_body": body, "contact_force": force}


def hemisphere(center: np.ndarray, radius: float, axis: np.ndarray, n_theta: int = 10,
               n_phi: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """A triangulated hemisphere of ``radius`` about ``center`` whose pole points along ``axis``.

    Returns (points (k, 3), triangles (t, 3)).
    """
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    u = np.cross(a, [0.0, 0.0, 1.0] if abs(a[2]) < 0.9 else [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(a, u)
    theta = np.linspace(0.0, 0.5 * np.pi, n_theta + 1)[1:]  # polar angle from the pole
    phi = np.linspace(0.0, 2 * np.pi, n_phi, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    dirs = (np.cos(t)[..., None] * a + np.sin(t)[..., None] * (np.cos(p)[..., None] * u + np.sin(p)[..., None] * v))
    pts = np.vstack([a[None], dirs.reshape(-1, 3)])
    ring = lambda i, j: 1 + i * n_phi + (j % n_phi)  # noqa: E731
    tris = [[0, ring(0, j), ring(0, j + 1)] for j in range(n_phi)]
    for i in range(n_theta - 1):
        for j in range(n_phi):
            tris.append([ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)])
            tris.append([ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)])
    return np.asarray(center, float) + radius * pts, np.array(tris, dtype=np.int64)


def fingertip_surface(center: np.ndarray, radius: float, axis: np.ndarray, n_theta: int = 10,
                      n_phi: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """The whole fingertip sphere as two hemispheres, the front one (facing the object) first.

    A deep squeeze buries the front hemisphere in the object; the back one
    stays visible.  Returns (points, triangles).
    """
    p1, t1 = hemisphere(center, radius, axis, n_theta, n_phi)
    p2, t2 = hemisphere(center, radius, -np.asarray(axis, float), n_theta, n_phi)
    return np.vstack([p1, p2]), np.vstack([t1, t2 + len(p1)])


def _pvd(entries: Sequence[tuple[float, str]]) -> str:
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">', "  <Collection>"]
    for t, f in entries:
        lines.append(f'    <DataSet timestep="{t:.17g}" group="" part="0" file={quoteattr(f)}/>')
    lines += ["  </Collection>", "</VTKFile>", ""]
    return "\n".join(lines)


def write_series(out: str | Path, result: Any, progress: Callable[[int, int], None] | None = None) -> dict[str, Any]:
    """Write the time series of ``result`` into ``out`` (module notes); return its index for result.json."""
    import meshio

    out = Path(out)
    reference = result.body.mesh.points
    tets = result.body.mesh.tets
    n = len(reference)
    frames = frames_of(result)
    # Listed in the marker before they are written: a run interrupted half-way leaves no file that the
    # next run into this folder would not clear.
    planned = [f"series/object_{k:04d}.vtu" for k in range(len(frames))]
    planned += [f"series/{name}_{k:04d}.vtu" for k, fr in enumerate(frames) if fr["finger_centers"] is not None
                for name in ("finger1", "finger2")]
    _add_to_marker(out, planned + ["object.pvd", "finger1.pvd", "finger2.pvd", "table.vtu"])
    files: list[str] = []
    entries: dict[str, list[tuple[float, str]]] = {"object": [], "finger1": [], "finger2": []}
    d1, d2 = (np.asarray(d, float) for d in result.directions)
    index = []
    for k, fr in enumerate(frames):
        pd = {"displacement": fr["positions"] - reference}
        pd.update(contact_point_data(n, fr))
        mesh = meshio.Mesh(np.asarray(fr["positions"], float), [("tetra", tets)], point_data=pd)
        rel = f"series/object_{k:04d}.vtu"
        atomic_write_mesh(out / rel, mesh)
        files.append(rel)
        entries["object"].append((float(k), rel))
        if fr["finger_centers"] is not None:
            for f, (name, axis) in enumerate((("finger1", d1), ("finger2", d2))):
                pts, tris = fingertip_surface(fr["finger_centers"][f], fr["finger_radius"], axis)
                rel_f = f"series/{name}_{k:04d}.vtu"
                atomic_write_mesh(out / rel_f, meshio.Mesh(pts, [("triangle", tris)]))
                files.append(rel_f)
                entries[name].append((float(k), rel_f))
        index.append({"index": k, "file": rel, "label": fr["label"], "phase": fr["phase"],
                      "squeeze_depth": fr["squeeze_depth"], "lift_height": fr["lift_height"],
                      "snapshot": fr["snapshot"]})
        if progress is not None:
            progress(k + 1, len(frames))
    series: dict[str, Any] = {"frames": index}
    for name, ent in entries.items():
        if ent:
            atomic_write_text(out / f"{name}.pvd", _pvd(ent))
            files.append(f"{name}.pvd")
            series[name] = f"{name}.pvd"
    # The table: a square under the object, 1.5 × its horizontal extent.
    z = result.rest.table_z if result.rest is not None else 0.0
    lo, hi = reference.min(axis=0), reference.max(axis=0)
    c, half = 0.5 * (lo + hi), 0.75 * float(max(hi[0] - lo[0], hi[1] - lo[1]))
    sq = np.array([[c[0] - half, c[1] - half, z], [c[0] + half, c[1] - half, z],
                   [c[0] + half, c[1] + half, z], [c[0] - half, c[1] + half, z]])
    atomic_write_mesh(out / "table.vtu", meshio.Mesh(sq, [("triangle", np.array([[0, 1, 2], [0, 2, 3]]))]))
    files.append("table.vtu")
    series["table"] = "table.vtu"
    series["files"] = files
    return series


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


_HEAVY = ("positions", "reference_points", "tets")


def result_summary(result: Any) -> dict[str, Any]:
    """The figures a user reads first."""
    rigid = result.rigid
    return {
        "success": bool(result.success), "reason": result.reason, "squeeze_depth": result.squeeze_depth,
        "n_final_contacts": result.n_final_contacts, "finger_normal_force": result.finger_normal_force,
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
    res = result.to_dict()
    for k in _HEAVY:
        res.pop(k, None)
    for s in res.get("snapshots", []):
        s.pop("positions", None)
    if res.get("final"):
        res["final"].pop("positions", None)
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
        # "converged", "levels": [...], ...} (fem_grasp.accuracy.AccuracyReport); None for a single run.
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
    _write_marker(out, series["files"] + ["result.json"])
    log.info("wrote %s (result.json, object.pvd, %d frames)", out, len(series["frames"]))
    return out


def write_rest(out: str | Path, state: Any, scene: Any = None, force: bool = False,
               extra: dict[str, Any] | None = None) -> Path:
    """Write a resting state: ``rest.json`` and ``rest.vtu`` (displacement, contact point data)."""
    import meshio

    out = prepare_out_dir(out, force)
    n = state.body.n_nodes
    frame = {"contact_nodes": {"finger1": [], "finger2": [], "table": state.contact_nodes},
             "contact_forces": {"finger1": np.zeros((0, 3)), "finger2": np.zeros((0, 3)),
                                "table": state.contact_forces},
             "sliding": {"finger1": [], "finger2": [], "table": state.sliding}}
    pd = {"displacement": state.displacements}
    pd.update(contact_point_data(n, frame))
    atomic_write_mesh(out / "rest.vtu", meshio.Mesh(state.positions, [("tetra", state.body.mesh.tets)],
                                                    point_data=pd))
    figures = state.check(raise_on_failure=False)
    doc = {"schema": "fem_grasp.rest", "schema_version": SCHEMA_VERSION, "fem_grasp_version": package_version(),
           "scene": None if scene is None else scene.to_dict(), "check": figures,
           "n_contacts": state.n_contacts, "n_sliding": int(state.sliding.sum()), "max_sag": state.max_sag,
           "iterations": state.iterations, "wall_time": state.wall_time, "table_z": state.table_z,
           "support_triangle": state.support_triangle, "contact_nodes": state.contact_nodes,
           "contact_forces": state.contact_forces, "sliding": state.sliding}
    doc.update(extra or {})
    atomic_write_text(out / "rest.json", json.dumps(json_safe(doc), indent=1, allow_nan=False))
    _add_to_marker(out, ["rest.vtu", "rest.json"])
    return out
