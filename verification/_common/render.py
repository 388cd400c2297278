"""Off-screen pyvista pictures of meshes and contact solutions.

pyvista (VTK 9 wheels) renders off-screen through EGL on a headless machine;
``VTK_DEFAULT_OPENGL_WINDOW`` is set before pyvista is imported so that VTK
does not look for an X display.

Rendering runs in a fresh interpreter (``multiprocessing`` "spawn"): once
dolfinx's C++ extension is loaded, VTK's scalar-bar layout aborts the process
with ``std::bad_alloc`` inside ``std::regex`` (an ABI clash between the VTK
wheels and Debian's libdolfinx).  Jobs therefore carry plain arrays, and
:func:`render` runs a batch of them in one child process.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from fem_grasp import ContactSolution, TetMesh

log = logging.getLogger(__name__)

Job = tuple[str, dict[str, Any]]


def mesh_job(mesh: "TetMesh", path: str | Path, title: str = "", size: tuple[int, int] = (800, 600)) -> Job:
    """A job drawing the surface of ``mesh`` and its interior tetrahedra, cut open at the centre."""
    return ("mesh", {"points": np.asarray(mesh.points), "tets": np.asarray(mesh.tets), "path": str(path),
                     "title": title, "size": tuple(size)})


def contact_job(solution: "ContactSolution", path: str | Path, title: str = "", warp: float | None = None,
                size: tuple[int, int] = (900, 700)) -> Job:
    """A job drawing the deformed body coloured by |δ| (mm), contact forces on the object as arrows.

    ``warp`` magnifies displacements; by default the largest displacement
    shows as 8 % of the diameter (never below 1).
    """
    mesh = solution.body.mesh
    return ("contact", {"points": np.asarray(mesh.points), "tets": np.asarray(mesh.tets),
                        "displacements": np.asarray(solution.displacements), "nodes": np.asarray(solution.nodes),
                        "forces": np.asarray(solution.forces), "path": str(path), "title": title, "warp": warp,
                        "size": tuple(size)})


def render(jobs: list[Job]) -> list[Path]:
    """Run render jobs in one freshly spawned Python process; return the PNG paths."""
    if not jobs:
        return []
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(1) as pool:
        paths = pool.map(_run_job, jobs)
    for p in paths:
        log.info("wrote %s", p)
    return [Path(p) for p in paths]


def render_mesh(mesh: "TetMesh", path: str | Path, title: str = "", size: tuple[int, int] = (800, 600)) -> Path:
    """Render one mesh picture (see :func:`mesh_job`)."""
    return render([mesh_job(mesh, path, title, size)])[0]


def render_contact(solution: "ContactSolution", path: str | Path, title: str = "", warp: float | None = None,
                   size: tuple[int, int] = (900, 700)) -> Path:
    """Render one contact-solution picture (see :func:`contact_job`)."""
    return render([contact_job(solution, path, title, warp, size)])[0]


# ------------------------------------------------------- child process side
def _run_job(job: Job) -> str:
    kind, kw = job
    return {"mesh": _draw_mesh, "contact": _draw_contact}[kind](**kw)


def _pyvista():
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    pv.OFF_SCREEN = True
    return pv


def _grid(points: np.ndarray, tets: np.ndarray):
    pv = _pyvista()
    cells = np.hstack([np.full((len(tets), 1), 4), tets]).ravel()
    types = np.full(len(tets), pv.CellType.TETRA, dtype=np.uint8)
    return pv.UnstructuredGrid(cells, types, np.asarray(points, dtype=float))


def _surface(grid):
    try:
        return grid.extract_surface(algorithm="dataset_surface")
    except TypeError:  # older pyvista without the keyword
        return grid.extract_surface()


def _diameter(points: np.ndarray) -> float:
    return float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))


def _draw_mesh(points, tets, path, title, size) -> str:
    pv = _pyvista()
    grid = _grid(points, tets)
    plotter = pv.Plotter(off_screen=True, window_size=list(size))
    plotter.set_background("white")
    centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
    clipped = grid.clip(normal=(0, 1, 0), origin=centre, crinkle=True)  # keep y < centre
    plotter.add_mesh(clipped, color="#e8a33d", show_edges=True, edge_color="#3b2a10", line_width=0.5)
    plotter.add_mesh(_surface(grid), color="#e8a33d", opacity=0.18, show_edges=False)
    plotter.add_text(f"{title}  ({len(points)} vertices, {len(tets)} tets; cut open at y = centre)",
                     font_size=10, color="black")
    plotter.view_isometric()
    plotter.camera.azimuth = 20
    plotter.screenshot(path)
    plotter.close()
    return path


def _draw_contact(points, tets, displacements, nodes, forces, path, title, warp, size) -> str:
    pv = _pyvista()
    u = displacements
    diam = _diameter(points)
    umax = float(np.linalg.norm(u, axis=1).max())
    if warp is None:
        warp = max(1.0, 0.08 * diam / umax) if umax > 0 else 1.0
    grid = _grid(points + warp * u, tets)
    grid.point_data["displacement magnitude (mm)"] = 1e3 * np.linalg.norm(u, axis=1)
    plotter = pv.Plotter(off_screen=True, window_size=list(size))
    plotter.set_background("white")
    plotter.add_mesh(_surface(grid), scalars="displacement magnitude (mm)", cmap="viridis", show_edges=True,
                     edge_color="#555555", line_width=0.3,
                     scalar_bar_args={"color": "black", "title": "displacement magnitude (mm)"})
    fmax = float(np.linalg.norm(forces, axis=1).max())
    if fmax > 0:
        scale = 0.25 * diam / fmax
        # Arrows end at the contact node: the force pushes (or pulls) the object there.
        origins = points[nodes] + warp * u[nodes] - forces * scale
        arrows = pv.PolyData(origins)
        arrows["force"] = forces * scale
        glyphs = arrows.glyph(orient="force", scale="force", factor=1.0, geom=pv.Arrow())
        plotter.add_mesh(glyphs, color="#d62728")
    plotter.add_text(f"{title}: displacements magnified x{warp:.3g}; red arrows: contact forces on the object "
                     f"(largest {fmax:.3g} N)", font_size=9, color="black")
    plotter.view_xz()
    plotter.camera.elevation = 25
    plotter.camera.azimuth = 30
    plotter.screenshot(path)
    plotter.close()
    return path
