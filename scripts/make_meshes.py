#!/usr/bin/env python3
"""Regenerate fem_grasp/scenes/meshes/{tomato,orange,steam_bun,football}.vtu at the paper's Table I vertex counts.

Each mesh is graded to the fingertips (``fem_grasp.grasp.objects.graded_paper_mesh``):
spacing R/2 within 2R of where the paper scenes' placement rule puts the
fingers, coarser elsewhere, at Table I's vertex count.

Needs gmsh's Python module (Debian: ``apt-get install python3-gmsh``, run with
/usr/bin/python3 or a ``--system-site-packages`` venv) and meshio.  The meshes are
deterministic: re-running gives identical files with the same gmsh version.

Usage::

    python scripts/make_meshes.py [--out-dir fem_grasp/scenes/meshes] [--rel-tol 0.01] [--no-write]

The vertex-count search aims at ``--rel-tol`` (default 1 %) and falls back to the
contract's ±5 % if gmsh cannot land that close.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

#: Every committed mesh is within this relative tolerance of Table I's vertex count.
CONTRACT_TOL = 0.05

import numpy as np

REPO = Path(__file__).resolve().parents[1]
try:
    from fem_grasp.grasp import objects
    from fem_grasp.mesh import shapes
except ImportError:  # running from a checkout without `pip install -e .`
    sys.path.insert(0, str(REPO))
    from fem_grasp.grasp import objects
    from fem_grasp.mesh import shapes


def dihedral_angles(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """(t, 6) interior dihedral angles of each tetrahedron, in degrees."""
    p = points[tets]
    normals = []
    for k in range(4):  # outward normal of the face opposite vertex k
        a, b, c = (p[:, i] for i in range(4) if i != k)
        n = np.cross(b - a, c - a)
        n *= np.where(np.einsum("ij,ij->i", n, p[:, k] - a) > 0, -1.0, 1.0)[:, None]
        normals.append(n / np.linalg.norm(n, axis=1, keepdims=True))
    pairs = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    cos = np.stack([np.einsum("ij,ij->i", normals[k], normals[l]) for k, l in pairs], axis=1)
    return 180.0 - np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


README = """\
# Meshes of the paper's four objects

Tetrahedral (P1, `tetra` cells only) VTU meshes standing in for the scanned objects of
Table I of the paper, generated with gmsh by `fem_grasp.mesh.shapes` (the scans are not
available). Units are metres; x is the long axis, +z points up; the ellipsoids are
centred on the origin and the steam bun's flat base lies on z = 0.

| file | shape | dimensions | vertices (Table I) | tetrahedra (Table I) | surface facets (Table I) |
|---|---|---|---|---|---|
{rows}

Vertex counts are within ±5 % of Table I (in parentheses). The meshes are graded to the
fingertips: spacing R/2 = 5 mm within 2R = 2 cm of the two points where the paper scenes'
placement rule (fingers at the height of the centre of mass, `fem_grasp.grasp.objects.PAPER_PLACEMENT_RULE`)
puts the fingers on a first, uniform mesh, and coarser elsewhere, so that each fingertip touches
several nodes (Table II reports 8–15 contact nodes at lift); see `fem_grasp.grasp.objects`.
Tetrahedron and facet counts follow from gmsh's sizing. Regenerate with `make meshes` (runs `scripts/make_meshes.py`, which needs
gmsh: Debian package `python3-gmsh`); the output is deterministic for a given gmsh
version (these were made with gmsh {gmsh_version}).
"""


def _describe(spec: shapes.PaperShape) -> tuple[str, str]:
    mm = [f"{1000 * d:g}" for d in spec.dimensions]
    if spec.kind == "dome":
        r, h, e = spec.dimensions
        if e == 0:
            return "dome: half spheroid, flat base", f"radius {mm[0]} mm, height {mm[1]} mm"
        return ("dome: spheroid cut flat below its equator",
                f"radius {mm[0]} mm, semi-axis {mm[1]} mm above the equator, equator {mm[2]} mm above the base "
                f"(height {1000 * (h + e):g} mm)")
    a, b, c = spec.dimensions
    if a == b == c:
        return "sphere", f"radius {mm[0]} mm"
    kind = "prolate spheroid" if a > b == c else "oblate spheroid" if a == b > c else "ellipsoid"
    return kind, "semi-axes " + " × ".join(mm) + " mm"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out-dir", type=Path, default=REPO / "fem_grasp" / "scenes" / "meshes",
                        help="where to write the .vtu files (default: the package data of the shipped scenes)")
    parser.add_argument(
        "--rel-tol", type=float, default=0.01, help="aimed relative tolerance on the vertex count (falls back to 0.05)"
    )
    parser.add_argument("--no-write", action="store_true", help="only mesh and print the table")
    parser.add_argument("-v", "--verbose", action="store_true", help="log the mesh-size search")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING, format="%(name)s: %(message)s")
    if args.verbose:
        logging.getLogger("fem_grasp.mesh.shapes").setLevel(logging.DEBUG)

    import gmsh  # only to record the version; shapes has already said how to install it

    header = (
        f"{'name':<10} {'vertices':>13} {'tets':>11} {'surf. facets':>12} "
        f"{'min dihedral':>12} {'min quality':>11} {'volume err':>10}"
    )
    print(header)
    print(f"{'':<10} {'(Table I)':>13} {'(Table I)':>11} {'(Table I)':>12} {'(deg)':>12} {'':>11} {'':>10}")
    print("-" * len(header))
    rows = []
    ok = True
    if not args.no_write:
        args.out_dir.mkdir(parents=True, exist_ok=True)
    for name, spec in shapes.PAPER_SHAPES.items():
        try:
            mesh = objects.graded_paper_mesh(name, rel_tol=args.rel_tol)
        except RuntimeError as exc:
            logging.warning("%s: %s; retrying with ±%g", name, exc, CONTRACT_TOL)
            mesh = objects.graded_paper_mesh(name, rel_tol=max(args.rel_tol, CONTRACT_TOL))
        n_faces = len(mesh.surface_faces)
        dmin = float(dihedral_angles(mesh.points, mesh.tets).min())
        vol_err = mesh.volume / spec.volume - 1.0
        within = abs(mesh.n_points - spec.vertices) <= CONTRACT_TOL * spec.vertices
        ok &= within
        print(
            f"{name:<10} {mesh.n_points:>5} ({spec.vertices:>5}) {mesh.n_tets:>4} ({spec.tetrahedra:>4}) "
            f"{n_faces:>4} ({spec.surface_facets:>4}) {dmin:>12.1f} {mesh.quality.min():>11.3f} "
            f"{vol_err:>+10.2%}"
        )
        shape, dims = _describe(spec)
        rows.append(
            f"| `{name}.vtu` | {shape} | {dims} | {mesh.n_points} ({spec.vertices}) "
            f"| {mesh.n_tets} ({spec.tetrahedra}) | {n_faces} ({spec.surface_facets}) |"
        )
        if not args.no_write:
            mesh.write(args.out_dir / f"{name}.vtu")
    if not args.no_write:
        text = README.format(rows="\n".join(rows), gmsh_version=gmsh.__version__)
        (args.out_dir / "README.md").write_text(text, encoding="utf-8")
        print(f"wrote {len(rows)} meshes and README.md to {args.out_dir}")
    if not ok:
        print("error: a vertex count is outside the tolerance", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
