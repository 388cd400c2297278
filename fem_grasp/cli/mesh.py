"""``fem-grasp mesh``: a closed surface scan (STL, OBJ, PLY, OFF) checked and filled with tetrahedra (gmsh),
read in its length unit and written in metres.
"""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path

from .common import EXIT_OK, BadInput, echo

__all__ = ["cmd_mesh"]

log = logging.getLogger(__name__)


def cmd_mesh(args: argparse.Namespace) -> int:
    from .._files import atomic_write_mesh
    from ..mesh.scan import DENSE_SCAN_VERTICES, SURFACE_SUFFIXES, check_surface, mesh_surface, read_surface
    from ..mesh.units import size_warning

    src, dst = Path(args.input), Path(args.output)
    if src.suffix.lower() not in SURFACE_SUFFIXES:
        raise BadInput(f"{src}: expected a surface file ({', '.join(SURFACE_SUFFIXES)}), got {src.suffix or 'no suffix'}")
    if dst.exists() and not args.force:
        raise BadInput(f"{dst} exists; pass --force to overwrite it")
    surf = read_surface(src, args.units)
    warning = size_warning(surf.diameter, args.units, str(src), hint="--units")
    if warning:
        log.warning("%s", warning)
    surf = check_surface(surf)
    if args.vertices is None and args.size is None and len(surf.points) > DENSE_SCAN_VERTICES:
        log.warning("%s has %d surface vertices; the mesh keeps them all. Pass --vertices N to simplify",
                    src, len(surf.points))
    t0 = time.perf_counter()
    mesh = mesh_surface(surf, target_vertices=args.vertices, size=args.size, check=False)
    atomic_write_mesh(dst, mesh.to_meshio(), file_format=_meshio_format(dst))
    q = mesh.quality
    unit = "" if args.units == "m" else f", read in {args.units} and written in metres"
    echo(args, f"{src}: {len(surf.points)} surface vertices, {len(surf.faces)} triangles, closed and manifold{unit}")
    echo(args, f"{dst}: {mesh.n_points} vertices, {mesh.n_tets} tets, volume {mesh.volume * 1e6:.4g} cm^3 "
               f"(surface encloses {surf.volume * 1e6:.4g}), diameter {mesh.diameter * 1e3:.4g} mm, min quality "
               f"{q.min():.3g}, {time.perf_counter() - t0:.2f} s")
    return EXIT_OK


def _meshio_format(path: Path) -> str:
    import meshio

    try:
        return meshio._helpers._filetypes_from_path(path)[0]  # type: ignore[attr-defined]
    except Exception:
        raise BadInput(f"{path}: meshio cannot write files ending in {''.join(path.suffixes) or '(none)'}; "
                       "use .vtu, .msh, .xdmf, .mesh, …") from None
