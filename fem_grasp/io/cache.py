"""Caches between runs: gmsh meshes and resting states, each reused only when it is provably the same.

* :func:`cached_mesh` — a mesh built by gmsh (a paper shape at a vertex count, a scanned surface) is
  stored in ``cache_dir`` under a key of what built it and gmsh's version;
* :func:`cached_rest` — a resting state (paper §III-A) is stored under a key of everything it depends on
  (:func:`rest_key`: the mesh, E, ν, density, g, μ_𝒫, the table, the down direction, and the digest of
  the package's code, :func:`rest_code_digest`), and used only after its contact set re-solves to the
  stored forces and positions and :meth:`~fem_grasp.grasp.rest.RestState.check` passes.

Every entry is written atomically; a damaged or foreign entry is ignored and rebuilt.
"""

from __future__ import annotations

import hashlib
import io
import logging
import os
from pathlib import Path
from typing import TYPE_CHECKING, Callable

import numpy as np

from .._files import atomic_write_bytes
from .output import package_version

if TYPE_CHECKING:
    from ..elastic.body import Body
    from ..grasp.rest import RestState
    from ..mesh.tetmesh import TetMesh

__all__ = ["REST_CACHE_FORMAT", "REST_CACHE_RTOL", "REST_CODE", "REST_GROUND", "cached_mesh", "cached_rest",
           "default_cache_dir", "digest", "load_rest", "rest_code_digest", "rest_code_files", "rest_key", "save_rest"]

log = logging.getLogger(__name__)

#: The subpackages whose code a resting state depends on (everything below ``io``) …
REST_CODE = ("mesh", "elastic", "contact", "grasp")
#: … and the ground-floor modules they import.
REST_GROUND = ("errors.py", "validation.py", "threads.py")


def digest(data: bytes) -> str:
    """A short hex digest of ``data`` (cache keys)."""

    return hashlib.sha256(data).hexdigest()[:16]


def cached_mesh(cache_dir: Path | None, key: tuple, build: Callable[[], "TetMesh"]) -> "TetMesh":
    """Build a mesh, or load it from ``cache_dir`` (an .npz keyed by ``key`` and the gmsh version)."""
    from ..mesh.tetmesh import TetMesh

    if cache_dir is None:
        return build()
    try:
        from ..mesh.gmsh_session import import_gmsh

        version = getattr(import_gmsh(), "__version__", "?")
    except ImportError:
        version = "none"
    h = hashlib.sha256(repr((key, version)).encode()).hexdigest()[:20]
    path = Path(cache_dir) / f"mesh-{h}.npz"
    if path.exists():
        try:
            with np.load(path) as z:
                mesh = TetMesh(z["points"], z["tets"])
            log.info("mesh from cache %s", path)
            return mesh
        except Exception as exc:  # a damaged cache entry is rebuilt
            log.warning("ignoring unreadable mesh cache %s: %s", path, exc)
    mesh = build()
    buf = io.BytesIO()
    np.savez(buf, points=mesh.points, tets=mesh.tets)
    Path(cache_dir).mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, buf.getvalue())
    return mesh


#: Bump when the cached fields change.
REST_CACHE_FORMAT = 1
#: A cached state is used only if re-solving its contact set reproduces its forces to this (relative to mg + Σ|f|).
REST_CACHE_RTOL = 1e-8


def default_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/fem_grasp`` or ``~/.cache/fem_grasp``."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "fem_grasp"


def rest_code_files() -> list[Path]:
    """Every source file a resting state can depend on: all of ``fem_grasp/{mesh,elastic,contact,grasp}/``
    and the ground-floor modules (no hand-kept list of modules to forget one from)."""
    root = Path(__file__).resolve().parents[1]
    return sorted(f for sub in REST_CODE for f in (root / sub).rglob("*.py")) + [root / f for f in REST_GROUND]


def rest_code_digest() -> str:
    """Digest of the package version and of :func:`rest_code_files` (a change of any invalidates the cache)."""
    root = Path(__file__).resolve().parents[1]
    h = hashlib.sha256(package_version().encode())
    for f in rest_code_files():
        h.update(str(f.relative_to(root)).encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:16]


def rest_key(body: "Body", mu_table: float, table_z: float = 0.0, down: np.ndarray | None = None) -> str:
    """Hash of everything a resting state depends on: mesh, E, ν, density, g, μ_𝒫, table, down, code."""
    import hashlib

    h = hashlib.sha256()
    h.update(np.ascontiguousarray(body.mesh.points, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(body.mesh.tets, dtype=np.int64).tobytes())
    h.update(repr((REST_CACHE_FORMAT, float(body.young), float(body.poisson), float(body.density),
                   float(body.gravity), float(mu_table), float(table_z),
                   None if down is None else [float(x) for x in down], rest_code_digest())).encode())
    return h.hexdigest()[:24]


def save_rest(path: Path, state: "RestState") -> None:
    """Write what :func:`load_rest` needs to rebuild a :class:`~fem_grasp.grasp.rest.RestState` (atomic .npz)."""
    buf = io.BytesIO()
    np.savez(buf, format=np.array(REST_CACHE_FORMAT), table_z=np.array(state.table_z),
             mu_table=np.array(state.mu_table), rotation=state.pose.rotation, translation=state.pose.translation,
             triangle=state.pose.triangle, margin=np.array(state.pose.margin), positions=state.positions,
             contact_nodes=state.contact_nodes, contact_forces=state.contact_forces,
             contact_displacements=state.contact_displacements, sliding=state.sliding,
             iterations=np.array(state.iterations), wall_time=np.array(state.wall_time))
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, buf.getvalue())


def load_rest(path: Path, body: "Body", backend: str = "sparse") -> "RestState | None":
    """Rebuild a resting state of ``body`` from :func:`save_rest`'s file, or None if it is not valid.

    The posed body is rebuilt from the stored rigid motion; the contact
    solution is recomputed from the stored contact displacements (one solve),
    and the entry is rejected unless that reproduces the stored forces and
    positions and :meth:`~fem_grasp.grasp.rest.RestState.check` passes.  The
    iteration history is not stored (``history`` is empty).
    """
    from ..elastic.response import ContactResponse
    from ..grasp.pose import RestingPose
    from ..grasp.rest import RestState

    try:
        with np.load(path) as z:
            d = {k: z[k] for k in z.files}
        if int(d["format"]) != REST_CACHE_FORMAT:
            return None
        posed = body.transformed(d["rotation"], d["translation"])
        nodes = d["contact_nodes"].astype(np.int64)
        sol = ContactResponse(posed, nodes, backend=backend).solve(d["contact_displacements"])
        scale = posed.weight + float(np.abs(d["contact_forces"]).sum())
        if (np.abs(sol.forces - d["contact_forces"]).max() > REST_CACHE_RTOL * scale
                or np.abs(sol.positions - d["positions"]).max() > 1e-9 * posed.mesh.diameter):
            log.warning("cached resting state %s does not reproduce its forces; recomputing", path)
            return None
        pose = RestingPose(posed, d["triangle"].astype(np.int64), d["rotation"], d["translation"],
                           float(d["margin"]), None)
        state = RestState(posed, float(d["table_z"]), float(d["mu_table"]), sol.positions, sol.displacements, nodes,
                          sol.forces, d["contact_displacements"], d["sliding"].astype(bool),
                          d["triangle"].astype(np.int64), [], int(d["iterations"]), float(d["wall_time"]), pose, sol)
        if not state.check(raise_on_failure=False)["ok"]:
            log.warning("cached resting state %s fails its checks; recomputing", path)
            return None
        return state
    except Exception as exc:  # any damaged or foreign file: recompute
        log.warning("ignoring unreadable resting-state cache %s: %s", path, exc)
        return None


def cached_rest(body: "Body", mu_table: float, *, backend: str = "sparse", down: np.ndarray | None = None,
                cache_dir: Path | None = None) -> tuple["RestState", bool]:
    """The resting state of ``body`` (:func:`fem_grasp.grasp.rest.rest`), reused from ``cache_dir`` when valid.

    Returns
    -------
    (RestState, bool)
        The state and whether it came from the cache.
    """
    from ..grasp.rest import rest

    path = None
    if cache_dir is not None:
        path = Path(cache_dir) / f"rest-{rest_key(body, mu_table, 0.0, down)}.npz"
        if path.exists():
            state = load_rest(path, body, backend)
            if state is not None:
                log.info("resting state from cache %s", path)
                return state, True
    state = rest(body, mu_table, backend=backend, down=None if down is None else np.asarray(down, float))
    if path is not None:
        try:
            save_rest(path, state)
        except OSError as exc:
            log.warning("could not cache the resting state in %s: %s", path, exc)
    return state, False
