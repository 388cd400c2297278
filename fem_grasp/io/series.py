"""The ParaView time series of a pickup: a frame for the resting state and one for each snapshot, written as VTU
steps under ``series/`` and collected in ``object.pvd``, ``finger1.pvd`` and ``finger2.pvd`` (with h5py, also as
XDMF 3 + HDF5: :mod:`fem_grasp.io.xdmf`); ``table.vtu`` is the table plane.

Each object step holds the *deformed* node positions (so that object,
fingertips and table line up without a filter) and

* point data ``displacement`` (m): from the posed, undeformed body;
  ``elastic_displacement`` (m): the same less its best-fitting rigid motion
  (the lift's translation hides the deformation in |δ|);
  ``contact_state``: 0 no contact, 1 sticking, 2 sliding;
  ``contact_body``: 0 none, 1 finger 1, 2 finger 2, 3 table;
  ``contact_force`` (N): the force on the object at each contact node (zero elsewhere);
* cell data ``von_mises`` (Pa) and ``strain_energy_density`` (J/m³), per
  tetrahedron (:mod:`fem_grasp.elastic.fields`);
* field data, one value per frame: ``phase`` (0 rest, 1 squeeze, 2 lift),
  ``squeeze_depth`` ρ (m), ``lift_height`` (m), ``liftable_weight`` (N, the
  lift test's w at that ρ), ``finger_path`` (m, the time value below) and
  ``frame``.

**Time.**  The time value of each frame (in the PVD and XDMF files) is the
*finger path* in metres (:func:`finger_path`): the squeeze depth ρ during the
squeeze, then ρ at the lift's start plus the lift height — how far finger 1 has
moved.  A failed lift that sends the run back to the squeeze adds nothing
(the squeeze resumes from the lift's start).  Frames at the same finger
position (a cascade of events settled at one ρ, the lift start) follow one
another :data:`TIME_TICK` × the longest finger path apart (nanometres), so that
every frame keeps its own time.  Frame 0 is the resting state (label ``rest``, time 0); frame k ≥ 1 is
``result.snapshots[k − 1]``; ``result.json["series"]["frames"]`` lists each
frame's label, phase, ρ, lift height and time.
"""

from __future__ import annotations

import logging
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any, Callable, Sequence
from xml.sax.saxutils import quoteattr

import numpy as np

from .._files import atomic_write_text
from ..errors import OutputError
from .folder import add_to_marker
from .vtu import cells_xml, write_grid
from .xdmf import has_h5py, write_xdmf

__all__ = ["BODY_CODES", "PHASE_CODES", "TIME_TICK", "contact_point_data", "finger_path", "fingertip_surface",
           "frame_times", "frames_of", "hemisphere", "mechanics_fields", "read_pvd", "write_series", "write_vtu"]

log = logging.getLogger(__name__)

CONTACT_NONE, CONTACT_STICK, CONTACT_SLIP = 0, 1, 2
BODY_CODES = {"finger1": 1, "finger2": 2, "table": 3}
#: Field data ``phase`` of each frame.
PHASE_CODES = {"rest": 0, "squeeze": 1, "lift": 2}
#: Frames at one finger position follow one another this far apart (× the longest finger path) in time.
TIME_TICK = 1e-9
#: Threads that write the frames (:func:`write_series`).
SERIES_THREADS = 2


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


def finger_path(frames: Sequence[dict[str, Any]]) -> np.ndarray:
    """(k,) how far finger 1 has moved at each frame, metres: ρ during the squeeze, then ρ at the lift's start
    plus the lift height; a return from a failed lift to the squeeze adds nothing (module notes)."""
    out, s, prev = [], 0.0, None
    for fr in frames:
        rho, h = float(fr["squeeze_depth"]), float(fr["lift_height"])
        if prev is not None:
            s += max(0.0, rho - prev[0]) + max(0.0, h - prev[1])
        prev = (rho, h)
        out.append(s)
    return np.array(out)


def frame_times(frames: Sequence[dict[str, Any]]) -> np.ndarray:
    """(k,) the time value of each frame: :func:`finger_path`, strictly increasing (a frame at the same finger
    position as the one before comes :data:`TIME_TICK` × the longest path after it)."""
    t = finger_path(frames)
    tick = TIME_TICK * max(float(t.max(initial=0.0)), 1e-3)
    for k in range(1, len(t)):
        if t[k] <= t[k - 1]:
            t[k] = t[k - 1] + tick
    return t


def _liftable_at(liftable: Sequence[Sequence[float]], rho: float) -> float:
    """The lift test's latest liftable weight at or before squeeze depth ``rho`` (0 before the first test)."""
    w = 0.0
    for r, v in liftable:
        if r <= rho * (1 + 1e-12) + 1e-15:
            w = float(v)
    return w


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


def write_vtu(path: str | Path, mesh: Any, field_data: dict[str, np.ndarray] | None = None) -> Path:
    """Write a ``meshio.Mesh`` of one block of triangles or tetrahedra as VTU, atomically, with VTK field data
    (one tuple per array, ``<FieldData>``, which meshio's own VTU writer drops; its reader, ParaView and VTK
    read it).  :mod:`fem_grasp.io.vtu` writes it."""
    if len(mesh.cells) != 1:
        raise OutputError(f"cannot write {path}: one block of cells expected, got {len(mesh.cells)}")
    block = mesh.cells[0]
    cell_data = {k: v[0] for k, v in mesh.cell_data.items()}
    return write_grid(path, mesh.points, cells_xml(block.type, block.data), mesh.point_data, cell_data, field_data)


def mechanics_fields(reference: np.ndarray, tets: np.ndarray, displacement: np.ndarray, young: float,
                     poisson: float, grads: np.ndarray | None = None,
                     volumes: np.ndarray | None = None) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """(point data, cell data) a mechanician reads: ``elastic_displacement`` (m, less the rigid motion) per node,
    ``von_mises`` (Pa) and ``strain_energy_density`` (J/m³) per tetrahedron (:mod:`fem_grasp.elastic.fields`).

    ``grads`` and ``volumes``: the reference's shape gradients and lumped volumes, when a series of
    displacements of one mesh is evaluated (computed here otherwise).
    """
    from ..elastic.fields import (
        elastic_displacement,
        element_strains,
        energy_density_of_strains,
        hooke_stresses,
        von_mises,
    )

    eps = element_strains(reference, tets, displacement, grads)
    pd = {"elastic_displacement": elastic_displacement(reference, tets, displacement, volumes)}
    cd = {"von_mises": von_mises(hooke_stresses(eps, young, poisson)),
          "strain_energy_density": energy_density_of_strains(eps, young, poisson)}
    return pd, cd


def write_series(out: str | Path, result: Any, progress: Callable[[int, int], None] | None = None) -> dict[str, Any]:
    """Write the time series of ``result`` into ``out`` (module notes); return its index for result.json."""
    from ..elastic.fem import lumped_volumes, shape_gradients

    out = Path(out)
    reference = result.body.mesh.points
    tets = result.body.mesh.tets
    n = len(reference)
    grads, _ = shape_gradients(reference, tets)
    volumes = lumped_volumes(reference, tets)
    tetra_cells = cells_xml("tetra", tets)
    # Every fingertip surface has the same triangles (only its centre, radius and axis move the points).
    _, tip_triangles = fingertip_surface(np.zeros(3), 1.0, np.array([0.0, 1.0, 0.0]))
    tip_cells = cells_xml("triangle", tip_triangles)
    frames = frames_of(result)
    times = frame_times(frames)
    path = finger_path(frames)
    xdmf = has_h5py()
    # Listed in the marker before they are written: a run interrupted half-way leaves no file that the
    # next run into this folder would not clear.
    planned = [f"series/object_{k:04d}.vtu" for k in range(len(frames))]
    planned += [f"series/{name}_{k:04d}.vtu" for k, fr in enumerate(frames) if fr["finger_centers"] is not None
                for name in ("finger1", "finger2")]
    add_to_marker(out, planned + ["object.pvd", "finger1.pvd", "finger2.pvd", "table.vtu"]
                  + (["object.xdmf", "object.h5"] if xdmf else []))
    files: list[str] = []
    entries: dict[str, list[tuple[float, str]]] = {"object": [], "finger1": [], "finger2": []}
    d1, d2 = (np.asarray(d, float) for d in result.directions)
    index = []
    steps = []

    def write_frame(k: int, fr: dict[str, Any]) -> tuple[dict, dict, dict, list[tuple[str, str]]]:
        """Frame k's fields, its object step and its fingertips written; (point data, cell data, field values,
        [(finger name, file)])."""
        disp = np.asarray(fr["positions"], float) - reference
        pd = {"displacement": disp}
        extra_pd, cd = mechanics_fields(reference, tets, disp, result.body.young, result.body.poisson, grads,
                                        volumes)
        pd.update(extra_pd)
        pd.update(contact_point_data(n, fr))
        field = {"phase": PHASE_CODES.get(fr["phase"], 1), "squeeze_depth": fr["squeeze_depth"],
                 "lift_height": fr["lift_height"], "liftable_weight": _liftable_at(result.liftable, fr["squeeze_depth"]),
                 "finger_path": float(path[k]), "frame": k}
        field_data = {key: np.array([v], dtype=np.int32 if key in ("phase", "frame") else float)
                      for key, v in field.items()}
        write_grid(out / f"series/object_{k:04d}.vtu", fr["positions"], tetra_cells, pd, cd, field_data)
        fingers = []
        if fr["finger_centers"] is not None:
            for f, (name, axis) in enumerate((("finger1", d1), ("finger2", d2))):
                pts, _ = fingertip_surface(fr["finger_centers"][f], fr["finger_radius"], axis)
                rel_f = f"series/{name}_{k:04d}.vtu"
                write_grid(out / rel_f, pts, tip_cells)
                fingers.append((name, rel_f))
        return pd, cd, field, fingers

    # Frames are written on two threads: most of a step's time is zlib's compression and numpy's element
    # fields, which release the GIL.
    with ThreadPoolExecutor(max_workers=SERIES_THREADS) as pool:
        written = pool.map(write_frame, range(len(frames)), frames)
        for k, (fr, (pd, cd, field, fingers)) in enumerate(zip(frames, written)):
            rel = f"series/object_{k:04d}.vtu"
            files.append(rel)
            entries["object"].append((float(times[k]), rel))
            if xdmf:
                steps.append((float(times[k]), np.asarray(fr["positions"], float), pd, cd, field))
            for name, rel_f in fingers:
                files.append(rel_f)
                entries[name].append((float(times[k]), rel_f))
            index.append({"index": k, "file": rel, "label": fr["label"], "phase": fr["phase"],
                          "squeeze_depth": fr["squeeze_depth"], "lift_height": fr["lift_height"],
                          "finger_path": float(path[k]), "time": float(times[k]),
                          "liftable_weight": field["liftable_weight"], "snapshot": fr["snapshot"]})
            if progress is not None:
                progress(k + 1, len(frames))
    series: dict[str, Any] = {"frames": index, "time": "finger_path (m): squeeze depth, then + lift height"}
    for name, ent in entries.items():
        if ent:
            atomic_write_text(out / f"{name}.pvd", _pvd(ent))
            files.append(f"{name}.pvd")
            series[name] = f"{name}.pvd"
    if xdmf:
        write_xdmf(out / "object.xdmf", tets, steps)
        files += ["object.h5", "object.xdmf"]
        series["xdmf"] = "object.xdmf"
    else:
        log.info("h5py is not installed: no object.xdmf (the PVD series holds the same data)")
    # The table: a square under the object, 1.5 × its horizontal extent.
    z = result.rest.table_z if result.rest is not None else 0.0
    lo, hi = reference.min(axis=0), reference.max(axis=0)
    c, half = 0.5 * (lo + hi), 0.75 * float(max(hi[0] - lo[0], hi[1] - lo[1]))
    sq = np.array([[c[0] - half, c[1] - half, z], [c[0] + half, c[1] - half, z],
                   [c[0] + half, c[1] + half, z], [c[0] - half, c[1] + half, z]])
    write_grid(out / "table.vtu", sq, cells_xml("triangle", np.array([[0, 1, 2], [0, 2, 3]])))
    files.append("table.vtu")
    series["table"] = "table.vtu"
    series["files"] = files
    return series


def read_pvd(path: str | Path) -> list[tuple[float, str]]:
    """The (time value, file) entries of a ParaView collection (``.pvd``), in file order.

    Raises
    ------
    OutputError
        Not a readable VTK collection file.
    """
    import xml.etree.ElementTree as ET

    p = Path(path)
    try:
        root = ET.parse(p).getroot()
    except (OSError, ET.ParseError) as exc:
        raise OutputError(f"{p}: not a readable ParaView collection (.pvd): {exc}") from None
    if root.get("type") != "Collection":
        raise OutputError(f"{p}: not a ParaView collection (VTKFile type {root.get('type')!r})")
    return [(float(d.get("timestep", "nan")), str(d.get("file"))) for d in root.iter("DataSet")]
