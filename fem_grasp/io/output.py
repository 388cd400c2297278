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
from typing import Any, Callable, Sequence
from xml.sax.saxutils import quoteattr

import numpy as np

from .._files import atomic_write, atomic_write_bytes, atomic_write_mesh, atomic_write_text
from .._version import version
from ..errors import OutputError

__all__ = ["SCHEMA", "SCHEMA_VERSION", "OutputError", "atomic_write_bytes", "atomic_write_text", "json_safe", "prepare_out_dir",
           "frames_of", "fingertip_surface", "write_series", "write_result_json", "write_run", "read_result", "hemisphere",
           "contact_point_data", "write_rest", "MARKER", "add_to_marker", "PHASE_CODES", "finger_path", "frame_times",
           "check_out_path", "write_xdmf", "FILE_SUFFIXES", "read_pvd", "TIME_TICK", "write_vtu", "mechanics_fields"]

log = logging.getLogger(__name__)

SCHEMA = "fem_grasp.result"
#: Version of the result.json layout (bump on incompatible change).
SCHEMA_VERSION = 1
#: Marker file naming the files fem_grasp wrote into an output folder.
MARKER = ".fem_grasp.json"

CONTACT_NONE, CONTACT_STICK, CONTACT_SLIP = 0, 1, 2
BODY_CODES = {"finger1": 1, "finger2": 2, "table": 3}
#: Field data ``phase`` of each frame.
PHASE_CODES = {"rest": 0, "squeeze": 1, "lift": 2}
#: Frames at one finger position follow one another this far apart (× the longest finger path) in time.
TIME_TICK = 1e-9
#: Names that look like a file, not a folder: ``--out x.xdmf`` is refused rather than made a folder.
FILE_SUFFIXES = (".xdmf", ".xmf", ".h5", ".hdf5", ".vtu", ".vtk", ".pvd", ".json", ".png", ".html", ".msh")


def package_version() -> str:
    """fem_grasp's version (``fem_grasp.__version__``: the installed metadata, or the source tree's pyproject.toml)."""
    return version()


# ------------------------------------------------------------ the folder
def check_out_path(path: str | Path) -> Path:
    """Refuse an output *folder* name that ends like a file (``out.xdmf``): say what is written instead.

    Raises
    ------
    OutputError
        The name ends in one of :data:`FILE_SUFFIXES` and is not an existing folder.
    """
    out = Path(path)
    if out.suffix.lower() in FILE_SUFFIXES and not out.is_dir():
        xdmf = (" The XDMF/HDF5 time series is written inside the folder as object.xdmf + object.h5"
                + ("" if _has_h5py() else ' (with h5py: pip install "fem_grasp[xdmf]")') + ".")
        raise OutputError(f"--out {out}: --out names a folder, not a file (it would create a folder called "
                          f"{out.name!r}); give a folder such as {str(out.with_suffix('')) or 'out'!r}. fem_grasp "
                          f"writes result.json, object.pvd (ParaView) and the steps there.{xdmf}")
    return out


_H5PY: list[bool] = []


def _has_h5py() -> bool:
    """Whether h5py can be used in this process (checked once).  h5py's own HDF5 cannot load into a process
    that has loaded another HDF5 library first (dolfinx's, through PETSc): then no XDMF copy is written."""
    if not _H5PY:
        try:
            import h5py  # noqa: F401
            _H5PY.append(True)
        except ImportError:
            log.info("h5py is not installed: no object.xdmf, the .pvd series holds the same data "
                     "(pip install \"fem_grasp[xdmf]\" adds it)")
            _H5PY.append(False)
        except Exception as exc:  # noqa: BLE001 - installed but cannot load here
            log.warning("h5py cannot be loaded in this process (%s: %s; another HDF5 library was loaded first, "
                        "e.g. by dolfinx): no object.xdmf, the .pvd series holds the same data",
                        type(exc).__name__, exc)
            _H5PY.append(False)
    return _H5PY[0]


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


def add_to_marker(out: Path, files: Sequence[str]) -> None:
    """Record ``files`` (relative to ``out``) in the folder's :data:`MARKER` as written by fem_grasp."""
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
    """Write a ``meshio.Mesh`` as VTU, atomically, with VTK field data (one tuple per array, ``<FieldData>``:
    meshio's VTU writer drops field data; its reader, ParaView and VTK read it)."""
    import meshio

    def write(tmp: Path) -> None:
        meshio.write(tmp, mesh, file_format="vtu")
        if not field_data:
            return
        arrays = []
        for name, v in field_data.items():
            v = np.atleast_1d(np.asarray(v))
            kind = "Int32" if np.issubdtype(v.dtype, np.integer) else "Float64"
            text = " ".join(str(int(x)) if kind == "Int32" else format(float(x), ".17g") for x in v.ravel())
            arrays.append(f'<DataArray type="{kind}" Name={quoteattr(name)} NumberOfTuples="{len(v)}" '
                          f'format="ascii">{text}</DataArray>')
        xml = tmp.read_text(encoding="utf-8")
        head = "<UnstructuredGrid>"
        if head not in xml:  # pragma: no cover - meshio's layout changed
            raise OutputError(f"cannot add field data to {path}: no {head} element in meshio's VTU")
        tmp.write_text(xml.replace(head, head + "\n<FieldData>\n" + "\n".join(arrays) + "\n</FieldData>", 1),
                       encoding="utf-8")

    return atomic_write(path, write)


def mechanics_fields(reference: np.ndarray, tets: np.ndarray, displacement: np.ndarray, young: float,
            poisson: float) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """(point data, cell data) a mechanician reads: ``elastic_displacement`` (m, less the rigid motion) per node,
    ``von_mises`` (Pa) and ``strain_energy_density`` (J/m³) per tetrahedron (:mod:`fem_grasp.elastic.fields`)."""
    from ..elastic.fields import elastic_displacement, element_stresses, strain_energy_density, von_mises

    pd = {"elastic_displacement": elastic_displacement(reference, tets, displacement)}
    cd = {"von_mises": von_mises(element_stresses(reference, tets, displacement, young, poisson)),
          "strain_energy_density": strain_energy_density(reference, tets, displacement, young, poisson)}
    return pd, cd


def write_series(out: str | Path, result: Any, progress: Callable[[int, int], None] | None = None) -> dict[str, Any]:
    """Write the time series of ``result`` into ``out`` (module notes); return its index for result.json."""
    import meshio

    out = Path(out)
    reference = result.body.mesh.points
    tets = result.body.mesh.tets
    n = len(reference)
    frames = frames_of(result)
    times = frame_times(frames)
    path = finger_path(frames)
    xdmf = _has_h5py()
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
    for k, fr in enumerate(frames):
        disp = np.asarray(fr["positions"], float) - reference
        pd = {"displacement": disp}
        extra_pd, cd = mechanics_fields(reference, tets, disp, result.body.young, result.body.poisson)
        pd.update(extra_pd)
        pd.update(contact_point_data(n, fr))
        field = {"phase": PHASE_CODES.get(fr["phase"], 1), "squeeze_depth": fr["squeeze_depth"],
                 "lift_height": fr["lift_height"], "liftable_weight": _liftable_at(result.liftable, fr["squeeze_depth"]),
                 "finger_path": float(path[k]), "frame": k}
        field_data = {key: np.array([v], dtype=np.int32 if key in ("phase", "frame") else float)
                      for key, v in field.items()}
        mesh = meshio.Mesh(np.asarray(fr["positions"], float), [("tetra", tets)], point_data=pd,
                           cell_data={key: [v] for key, v in cd.items()})
        rel = f"series/object_{k:04d}.vtu"
        write_vtu(out / rel, mesh, field_data)
        files.append(rel)
        entries["object"].append((float(times[k]), rel))
        if xdmf:
            steps.append((float(times[k]), np.asarray(fr["positions"], float), pd, cd, field))
        if fr["finger_centers"] is not None:
            for f, (name, axis) in enumerate((("finger1", d1), ("finger2", d2))):
                pts, tris = fingertip_surface(fr["finger_centers"][f], fr["finger_radius"], axis)
                rel_f = f"series/{name}_{k:04d}.vtu"
                atomic_write_mesh(out / rel_f, meshio.Mesh(pts, [("triangle", tris)]))
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
    atomic_write_mesh(out / "table.vtu", meshio.Mesh(sq, [("triangle", np.array([[0, 1, 2], [0, 2, 3]]))]))
    files.append("table.vtu")
    series["table"] = "table.vtu"
    series["files"] = files
    return series


def write_xdmf(path: str | Path, tets: np.ndarray,
               steps: Sequence[tuple[float, np.ndarray, dict[str, np.ndarray], dict[str, np.ndarray],
                                     dict[str, float]]]) -> Path:
    """An XDMF 3 temporal collection (``path``) with its heavy data in HDF5 beside it (``path`` with ``.h5``).

    ``steps``: (time, deformed points (n, 3), point data, cell data, field data) per frame.  Each frame is a
    grid of its own deformed geometry sharing one topology; point and cell data are node- and
    cell-centred attributes, field data grid-centred ones (ParaView shows them as field data).
    """
    import h5py

    path = Path(path)
    h5 = path.with_suffix(".h5")
    tets = np.asarray(tets, dtype=np.int64)

    def heavy(tmp: Path) -> None:
        with h5py.File(tmp, "w") as f:
            f.create_dataset("topology", data=tets)
            for k, (_, pts, pd, cd, _) in enumerate(steps):
                g = f.create_group(f"frames/{k:04d}")
                g.create_dataset("geometry", data=np.asarray(pts, float))
                for name, v in {**pd, **cd}.items():
                    g.create_dataset(name, data=np.asarray(v))

    def item(dataset: str, shape: tuple[int, ...], dtype: np.dtype) -> str:
        kind = "Int" if np.issubdtype(dtype, np.integer) else "Float"
        return (f'<DataItem Dimensions="{" ".join(str(d) for d in shape)}" NumberType="{kind}" '
                f'Precision="{np.dtype(dtype).itemsize}" Format="HDF">{h5.name}:/{dataset}</DataItem>')

    def attribute(name: str, value: np.ndarray, center: str, dataset: str) -> str:
        kind = "Vector" if value.ndim == 2 and value.shape[1] == 3 else "Scalar"
        return (f'<Attribute Name={quoteattr(name)} AttributeType="{kind}" Center="{center}">'
                f'{item(dataset, value.shape, value.dtype)}</Attribute>')

    grids = []
    for k, (t, pts, pd, cd, field) in enumerate(steps):
        g = f"frames/{k:04d}"
        parts = [f'<Grid Name="frame_{k:04d}" GridType="Uniform">', f'<Time Value="{t:.17g}"/>',
                 f'<Topology TopologyType="Tetrahedron" NumberOfElements="{len(tets)}">'
                 f'{item("topology", tets.shape, tets.dtype)}</Topology>',
                 f'<Geometry GeometryType="XYZ">{item(g + "/geometry", np.shape(pts), np.dtype(float))}</Geometry>']
        parts += [attribute(name, np.asarray(v), "Node", f"{g}/{name}") for name, v in pd.items()]
        parts += [attribute(name, np.asarray(v), "Cell", f"{g}/{name}") for name, v in cd.items()]
        for name, v in field.items():
            kind, prec = ("Int", 4) if isinstance(v, (int, np.integer)) else ("Float", 8)
            parts.append(f'<Attribute Name={quoteattr(name)} AttributeType="Scalar" Center="Grid">'
                         f'<DataItem Dimensions="1" NumberType="{kind}" Precision="{prec}" Format="XML">'
                         f'{v if kind == "Int" else format(float(v), ".17g")}</DataItem></Attribute>')
        parts.append("</Grid>")
        grids.append("\n      ".join(parts))
    text = ('<?xml version="1.0"?>\n<Xdmf Version="3.0">\n  <Domain>\n'
            '    <Grid Name="object" GridType="Collection" CollectionType="Temporal">\n      '
            + "\n      ".join(grids) + "\n    </Grid>\n  </Domain>\n</Xdmf>\n")
    atomic_write(h5, heavy)
    atomic_write_text(path, text)
    return path


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
    extra_pd, cd = mechanics_fields(state.body.mesh.points, state.body.mesh.tets, state.displacements, state.body.young,
                           state.body.poisson)
    pd.update(extra_pd)
    pd.update(contact_point_data(n, frame))
    atomic_write_mesh(out / "rest.vtu", meshio.Mesh(state.positions, [("tetra", state.body.mesh.tets)],
                                                    point_data=pd, cell_data={k: [v] for k, v in cd.items()}))
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
