"""Stability studies: Young's-modulus scaling, near-collinear contacts, sliver meshes, ν → ½.

* **E scaling.** With contact displacements prescribed, the contact forces
  are ``F̄ = C Δ̄ + F̄₀`` with C ∝ E and F̄₀ (gravity with the contacts held)
  independent of E; the displacement field under gravity alone scales as
  1/E.  Checked from E = 10² to 10¹² Pa for both backends and dolfinx.
* **Near-collinear contacts.** Three contact nodes, the middle one moved off
  the line of the other two by an angle θ: the condition number of M
  (eq. 3) against θ, agreement with dolfinx, and the θ at which
  :class:`~fem_grasp.CollinearContactError` is first raised.
* **Slivers.** A Delaunay tetrahedralisation of a slightly jittered grid
  is full of near-flat tetrahedra; K and contact solves are compared with
  dolfinx there.
* **Poisson's ratio.** K against dolfinx for ν up to 0.4999; locking itself
  is measured by :func:`verification.dolfinx.manufactured.locking_study`.
"""

from __future__ import annotations

import logging

import numpy as np
from scipy.spatial import Delaunay

from fem_grasp import Body, CollinearContactError, TetMesh, box_mesh
from fem_grasp.elastic.response import ContactResponse

from .crosscheck import contact_cases, crosscheck_mesh, rel_max_diff
from .reference import DolfinxModel

log = logging.getLogger(__name__)

BACKENDS = ("sparse", "spectral")


def young_scaling(body: Body, youngs: list[float], reference: float = 1e6, seed: int = 7) -> dict:
    """Check the exact E-scaling of forces and displacements for a grasp-like contact set.

    Returns
    -------
    dict
        ``rows``: for each E, the largest relative deviations from exact
        scaling of (a) ``F̄(Δ̄) − F̄(0)`` (∝ E), (b) ``F̄(0)`` (E-independent),
        (c) the gravity-only displacement field (∝ 1/E), for each backend, and
        the agreement of each backend with dolfinx at that E;
        ``max_deviation``: the worst of (a)–(c) over all E and backends.
    """
    case = contact_cases(body, np.random.default_rng(seed))[0]
    model = DolfinxModel(body.mesh)

    def run(young: float, backend: str):
        b = body.with_material(young=young)
        resp = ContactResponse(b, case.nodes, backend=backend)
        with_d = resp.solve(case.displacements)
        zero = resp.solve(np.zeros_like(case.displacements))
        return with_d, zero

    ref = {bk: run(reference, bk) for bk in BACKENDS}
    rows, worst = [], 0.0
    for young in youngs:
        row: dict = {"young": young}
        dref = model.solve_contact(young, body.poisson, body.density, body.gravity, case.nodes, case.displacements)
        for bk in BACKENDS:
            with_d, zero = run(young, bk)
            r_with, r_zero = ref[bk]
            s = young / reference
            dev_c = rel_max_diff((with_d.forces - zero.forces) / s, r_with.forces - r_zero.forces)
            dev_0 = rel_max_diff(zero.forces, r_zero.forces)
            dev_u = rel_max_diff(zero.displacements * s, r_zero.displacements)
            row[bk] = {"C_scaling": dev_c, "F0_invariance": dev_0, "u_gravity_scaling": dev_u,
                       "f_vs_dolfinx": rel_max_diff(with_d.forces, dref.forces),
                       "u_vs_dolfinx": rel_max_diff(with_d.displacements, dref.displacements)}
            worst = max(worst, dev_c, dev_0, dev_u)
        rows.append(row)
    return {"reference_young": reference, "rows": rows, "max_deviation": worst,
            "max_vs_dolfinx": max(max(r[bk]["f_vs_dolfinx"], r[bk]["u_vs_dolfinx"]) for r in rows for bk in BACKENDS)}


def collinear_study(angles: list[float], divisions: int = 4, size: float = 0.04, young: float = 1e5,
                    poisson: float = 0.3, weight: float = 1.0) -> dict:
    """Three contact nodes on the top edge of a cube, the middle one turned off their line by θ.

    The cube's top-face edge y = 0 carries nodes A = (0, 0, s), B = (s, 0, s)
    and the middle node P; P is moved into the face by ``(s/2) tan θ`` in y.
    The contacts hold A, B, P at zero displacement (the body hangs from them
    under gravity) — as θ → 0 it becomes free to swing about the line AB.

    Returns
    -------
    dict with a row per θ: ``cond`` (2-norm condition number of M) per
    backend or the error message, the agreement of forces and displacements
    with dolfinx, and ``first_error_angle``, the largest θ at which either
    backend refused the contact set.
    """
    base = box_mesh((0, 0, 0), (size,) * 3, (divisions,) * 3)
    p0 = base.points
    top = np.isclose(p0[:, 2], size) & np.isclose(p0[:, 1], 0.0)
    a = int(np.flatnonzero(top & np.isclose(p0[:, 0], 0.0))[0])
    b = int(np.flatnonzero(top & np.isclose(p0[:, 0], size))[0])
    mid = int(np.flatnonzero(top & np.isclose(p0[:, 0], size / 2))[0])
    nodes = np.array([a, mid, b])
    rows, first_error = [], None
    for theta in angles:
        pts = p0.copy()
        pts[mid, 1] += 0.5 * size * np.tan(theta)
        body = Body(TetMesh(pts, base.tets), young, poisson, weight=weight)
        row: dict = {"angle": float(theta)}
        ref = None
        try:
            ref = DolfinxModel(body.mesh).solve_contact(young, poisson, body.density, body.gravity, nodes,
                                                        np.zeros((3, 3)))
            row["dolfinx_max_force"] = float(np.abs(ref.forces).max())
            row["dolfinx_axis_moment"] = axis_moment_residual(body, nodes, ref.forces)
        except Exception as exc:  # PETSc may report a singular factorisation
            row["dolfinx_error"] = str(exc)
        for bk in BACKENDS:
            try:
                resp = ContactResponse(body, nodes, backend=bk)
                sol = resp.solve(np.zeros((3, 3)))
                entry = {"cond": resp.condition_number(), "max_force": float(np.abs(sol.forces).max()),
                         "equilibrium": max(sol.equilibrium_residual()),
                         "axis_moment": axis_moment_residual(body, nodes, sol.forces)}
                if ref is not None:
                    entry["f_vs_dolfinx"] = rel_max_diff(sol.forces, ref.forces)
                    entry["u_vs_dolfinx"] = rel_max_diff(sol.displacements, ref.displacements)
                row[bk] = entry
            except CollinearContactError as exc:
                row[bk] = {"error": str(exc)}
                if first_error is None or theta > first_error:
                    first_error = float(theta)
        rows.append(row)
        log.info("collinear theta=%.1e: %s", theta, {bk: row[bk].get("cond", "error") for bk in BACKENDS})
    return {"rows": rows, "first_error_angle": first_error}


def axis_moment_residual(body: Body, nodes: np.ndarray, forces: np.ndarray) -> float:
    """Moment balance about the line through the first and last contact node, relative to gravity's moment.

    Only the middle node's force has a lever arm about that line, so this is
    the statics identity that fixes the (large) middle force exactly:
    ``ê · Σ (p_k − p_a) × f_k = −ê · Σ (p_i − p_a) × G_i``.
    """
    p = body.mesh.points
    a, b = p[nodes[0]], p[nodes[-1]]
    e = (b - a) / np.linalg.norm(b - a)
    g = body.gravity_loads.reshape(-1, 3)
    m_grav = float(e @ np.cross(p - a, g).sum(axis=0))
    m_contact = float(e @ np.cross(p[nodes] - a, forces).sum(axis=0))
    return abs(m_contact + m_grav) / abs(m_grav)


def sliver_mesh(divisions: int = 5, jitter: float = 1e-3, seed: int = 3, size: float = 0.04) -> TetMesh:
    """Delaunay tetrahedralisation of a jittered ``divisions``³ grid of a cube.

    The eight points of every grid cell are almost co-spherical, so Delaunay
    splits cells with flat "sliver" tetrahedra whose volume is of the order
    of the jitter.
    """
    rng = np.random.default_rng(seed)
    g = np.linspace(0.0, size, divisions + 1)
    pts = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
    pts = pts + jitter * (size / divisions) * rng.uniform(-1, 1, pts.shape)
    tets = Delaunay(pts).simplices
    return TetMesh(pts, tets)


def sliver_study(divisions: int = 5, jitter: float = 1e-3, young: float = 1e5, poisson: float = 0.3) -> dict:
    """Quality statistics of :func:`sliver_mesh` and the full dolfinx cross-check on it."""
    mesh = sliver_mesh(divisions, jitter)
    body = Body(mesh, young, poisson, weight=1.0)
    q = mesh.quality
    res = crosscheck_mesh(body, np.random.default_rng(5), eigen=True)
    res.update({"jitter": jitter, "min_quality": float(q.min()), "median_quality": float(np.median(q)),
                "n_below_0.01": int((q < 0.01).sum()), "n_below_0.1": int((q < 0.1).sum())})
    return res


def poisson_operator_table(poissons: list[float], divisions: int = 3, young: float = 1e5) -> list[dict]:
    """K and a contact solve against dolfinx for each ν (a small box mesh)."""
    mesh = box_mesh((0, 0, 0), (0.04, 0.03, 0.02), (divisions,) * 3)
    model = DolfinxModel(mesh)
    rows = []
    for nu in poissons:
        body = Body(mesh, young, nu, weight=1.0)
        case = contact_cases(body, np.random.default_rng(11))[0]
        ref = model.solve_contact(young, nu, body.density, body.gravity, case.nodes, case.displacements)
        row = {"poisson": nu, "K_rel_diff": rel_max_diff(body.stiffness, model.stiffness(young, nu))}
        for bk in BACKENDS:
            sol = ContactResponse(body, case.nodes, backend=bk).solve(case.displacements)
            row[bk] = {"f_vs_dolfinx": rel_max_diff(sol.forces, ref.forces),
                       "u_vs_dolfinx": rel_max_diff(sol.displacements, ref.displacements)}
        rows.append(row)
    return rows
