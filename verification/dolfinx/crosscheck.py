"""Entry-by-entry comparison of fem_grasp with dolfinx on one mesh.

Each check returns plain floats (relative differences) so that the test-suite
can assert on them and the report can tabulate them:

* K: ``max |K_fg − K_dx| / max |K_dx|`` over all entries;
* G: ``max |G_fg − G_dx| / max |G_dx|`` and the §II-B identities
  G·t_z = −mg, G ⟂ t_x, t_y, r_x, r_y, r_z;
* strain energies of random fields (fem_grasp's ½ΔᵀKΔ against dolfinx's
  integral of eq. (2));
* the rigid modes: ``‖K r‖ / (‖K‖₂ ‖r‖)`` for both matrices, and optionally the
  six smallest eigenvalues by shift-invert Lanczos and λ₇, λ₈ of both matrices;
* contact solves: displacement field, contact forces and strain energy of both
  fem_grasp backends against a dolfinx/PETSc Dirichlet solve.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from fem_grasp import Body, solve_contact

from .reference import DolfinxModel

log = logging.getLogger(__name__)


def rel_max_diff(a, b) -> float:
    """``max |a − b| / max |b|`` for arrays or sparse matrices."""
    if sp.issparse(a) or sp.issparse(b):
        d = sp.csr_matrix(a) - sp.csr_matrix(b)
        num = float(abs(d).max()) if d.nnz else 0.0
        den = float(abs(sp.csr_matrix(b)).max())
    else:
        num = float(np.max(np.abs(np.asarray(a) - np.asarray(b))))
        den = float(np.max(np.abs(b)))
    return num / den if den > 0 else num


def rigid_fields(points: np.ndarray, center: np.ndarray) -> np.ndarray:
    """(3n, 6) translations and infinitesimal rotations about ``center`` (Theorem 1), built here."""
    n = len(points)
    d = points - center
    out = np.zeros((n, 3, 6))
    for i in range(3):
        out[:, i, i] = 1.0
        axis = np.eye(3)[i]
        out[:, :, 3 + i] = np.cross(axis, d)
    return out.reshape(3 * n, 6)


def norm2(matrix: sp.spmatrix) -> float:
    """Spectral norm (largest eigenvalue) of a symmetric positive semi-definite sparse matrix."""
    return float(spla.eigsh(matrix, k=1, which="LA", return_eigenvectors=False, tol=1e-6)[0])


def null_eigenvalues(matrix: sp.spmatrix) -> np.ndarray:
    """The six smallest eigenvalues of a symmetric PSD matrix by shift-invert Lanczos (ARPACK).

    The shift σ = −10⁻⁸ × mean diagonal is tiny and negative: K − σI is
    positive definite although K is singular, and the inverted operator
    magnifies the round-off splitting of the six-fold zero eigenvalue so that
    Lanczos, which from one start vector sees one copy of an exactly repeated
    eigenvalue, picks up all six (with a larger shift it can miss one).
    """
    shift = -1e-8 * float(matrix.diagonal().mean())
    vals = spla.eigsh(sp.csc_matrix(matrix), k=6, sigma=shift, which="LM", return_eigenvectors=False, ncv=40)
    return np.sort(vals)


def elastic_eigenvalues(matrix: sp.spmatrix, modes: np.ndarray, k: int = 2) -> np.ndarray:
    """The ``k`` smallest eigenvalues above the null space: λ₇, λ₈, … by deflated shift-invert Lanczos.

    The operator is ``P (K − σI)⁻¹ P`` with P the orthogonal projector off the
    rigid ``modes`` and σ = −10⁻² × mean diagonal, so the six zero eigenvalues
    are removed exactly and the elastic ones are resolved to round-off.
    """
    n = matrix.shape[0]
    q, _ = np.linalg.qr(modes)
    shift = -1e-2 * float(matrix.diagonal().mean())
    lu = spla.splu(sp.csc_matrix(matrix - shift * sp.identity(n)))

    def apply(x: np.ndarray) -> np.ndarray:
        x = np.asarray(x).ravel()
        y = lu.solve(x - q @ (q.T @ x))
        return y - q @ (q.T @ y)

    op = spla.LinearOperator((n, n), matvec=apply, dtype=float)
    # A fixed start off the null space: ARPACK's own random start depends on the calls before it, and on
    # the sliver mesh (λ₇ ≈ λ₈) one such start did not converge in 6481 iterations inside `make verify`.
    v0 = np.random.default_rng(0).standard_normal(n)
    v0 -= q @ (q.T @ v0)
    vals = spla.eigsh(matrix, k=k, sigma=shift, OPinv=op, which="LM", return_eigenvectors=False, tol=0,
                      v0=v0, ncv=max(20, 2 * k + 1))
    return np.sort(vals)


@dataclass
class ContactCase:
    """A contact problem: nodes held at prescribed displacements."""

    name: str
    nodes: np.ndarray
    displacements: np.ndarray


def contact_cases(body: Body, rng: np.random.Generator) -> list[ContactCase]:
    """Two contact problems on the surface of ``body``.

    ``grasp``: the six lowest surface nodes held still (a table), the
    surface nodes nearest (x_min, y_c, z_c) and (x_max, y_c, z_c), c the
    centre of mass, pushed inwards by 1 % of the width (two fingers).  ``random``: five random surface nodes with random
    displacements of 0.1 % of the diameter.
    """
    mesh = body.mesh
    surf = mesh.surface_nodes
    p = mesh.points
    low = surf[np.argsort(p[surf, 2], kind="stable")[:6]]
    c = body.center_of_mass
    lo, hi = mesh.bounds
    left = surf[np.argmin(np.linalg.norm(p[surf] - [lo[0], c[1], c[2]], axis=1))]
    right = surf[np.argmin(np.linalg.norm(p[surf] - [hi[0], c[1], c[2]], axis=1))]
    width = hi[0] - lo[0]
    nodes = np.concatenate([low, [left, right]])
    nodes = np.array(list(dict.fromkeys(nodes.tolist())))
    disp = np.zeros((len(nodes), 3))
    disp[nodes == left, 0] = 0.01 * width
    disp[nodes == right, 0] = -0.01 * width
    rnd = rng.choice(surf, size=5, replace=False)
    rdisp = 1e-3 * mesh.diameter * rng.standard_normal((5, 3))
    return [ContactCase("grasp", nodes, disp), ContactCase("random", np.sort(rnd), rdisp)]


def compare_operators(body: Body, model: DolfinxModel, rng: np.random.Generator, n_fields: int = 5,
                      eigen: bool = False) -> dict:
    """K, G, energies and rigid modes of ``body`` against ``model``.

    Parameters
    ----------
    body : fem_grasp Body
    model : DolfinxModel on the same mesh
    rng : random generator for the test fields
    n_fields : number of random fields for the energy check
    eigen : also compute the eight smallest eigenvalues of both matrices (small meshes only)

    Returns
    -------
    dict of floats (see module docstring); times in seconds under ``seconds_*``.
    """
    out: dict[str, float] = {}
    t0 = time.perf_counter()
    kf = body.stiffness
    out["seconds_fem_grasp_K"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    kd = model.stiffness(body.young, body.poisson)
    out["seconds_dolfinx_K"] = time.perf_counter() - t0
    out["K_rel_diff"] = rel_max_diff(kf, kd)
    out["K_nnz_fem_grasp"] = int(kf.nnz)
    out["K_symmetry"] = rel_max_diff(kf, kf.T)

    gf = body.gravity_loads
    gd = model.gravity_loads(body.density, body.gravity)
    out["G_rel_diff"] = rel_max_diff(gf, gd)
    modes = rigid_fields(body.mesh.points, body.center_of_mass)
    w, diam = body.weight, body.mesh.diameter
    out["G_tz_plus_mg_rel"] = abs(gf @ modes[:, 2] + w) / w
    out["G_other_modes_rel"] = float(max(abs(gf @ modes[:, j]) / (w * (diam if j >= 3 else 1.0))
                                         for j in (0, 1, 3, 4, 5)))
    out["rigid_modes_rel_diff"] = rel_max_diff(body.rigid_modes, modes)

    diffs = []
    for _ in range(n_fields):
        u = 1e-3 * diam * rng.standard_normal(3 * body.n_nodes)
        ef, ed = body.strain_energy(u), model.strain_energy(u, body.young, body.poisson)
        diffs.append(abs(ef - ed) / abs(ed))
    out["energy_rel_diff"] = float(max(diffs))

    knorm_d, knorm_f = norm2(kd), norm2(kf)
    out["K_norm2"] = knorm_f
    rn = np.linalg.norm(modes, axis=0)
    out["null_dolfinx"] = float(max(np.linalg.norm(kd @ modes, axis=0) / (knorm_d * rn)))
    out["null_fem_grasp"] = float(max(np.linalg.norm(kf @ modes, axis=0) / (knorm_f * rn)))
    if eigen:
        t0 = time.perf_counter()
        nf, nd = null_eigenvalues(kf), null_eigenvalues(kd)
        ef, ed = elastic_eigenvalues(kf, modes), elastic_eigenvalues(kd, modes)
        out["eig_seconds"] = time.perf_counter() - t0
        out["eig6_max_fem_grasp"] = float(np.abs(nf).max() / knorm_f)
        out["eig6_max_dolfinx"] = float(np.abs(nd).max() / knorm_d)
        out["eig7_fem_grasp"] = float(ef[0])
        out["eig7_rel_diff"] = float(np.max(np.abs(ef - ed) / ed))
        out["eig7_diff_over_norm"] = float(np.max(np.abs(ef - ed)) / knorm_d)
        out["eig7_over_norm"] = float(ef[0] / knorm_f)
        out["eig_smallest8_fem_grasp"] = np.concatenate([nf, ef]).tolist()
    return out


def compare_contact(body: Body, model: DolfinxModel, case: ContactCase, backends=("sparse", "spectral")) -> dict:
    """One contact problem solved by each fem_grasp backend and by dolfinx.

    Returns
    -------
    dict
        ``{backend: {"u_rel_diff", "f_rel_diff", "energy_rel_diff", "equilibrium_force",
        "equilibrium_torque", "seconds"}, "dolfinx_seconds": ..., "m": ...}``
    """
    ref = model.solve_contact(body.young, body.poisson, body.density, body.gravity, case.nodes,
                              case.displacements)
    out: dict = {"case": case.name, "m": int(len(case.nodes)), "dolfinx_seconds": ref.seconds,
                 "max_force": float(np.abs(ref.forces).max()), "max_displacement": float(np.abs(ref.displacements).max())}
    for backend in backends:
        t0 = time.perf_counter()
        sol = solve_contact(body, case.nodes, case.displacements, backend=backend)
        seconds = time.perf_counter() - t0
        fres, tres = sol.equilibrium_residual()
        out[backend] = {
            "u_rel_diff": rel_max_diff(sol.displacements, ref.displacements),
            "f_rel_diff": rel_max_diff(sol.forces, ref.forces),
            "energy_rel_diff": abs(sol.strain_energy - ref.strain_energy) / abs(ref.strain_energy),
            "equilibrium_force": fres,
            "equilibrium_torque": tres,
            "seconds": seconds,
        }
        log.debug("%s/%s: u %.2e f %.2e", case.name, backend, out[backend]["u_rel_diff"], out[backend]["f_rel_diff"])
    return out


def crosscheck_mesh(body: Body, rng: np.random.Generator, eigen: bool = False, spectral: bool = True,
                    sparse: bool = True) -> dict:
    """All comparisons on one body: operators, then each of :func:`contact_cases`.

    Parameters
    ----------
    body : Body
    rng : random generator
    eigen : compute the smallest eigenvalues (small meshes only)
    spectral, sparse : which fem_grasp backends to run for the contact problems
    """
    t0 = time.perf_counter()
    model = DolfinxModel(body.mesh)
    out = {"n_vertices": body.n_nodes, "n_tets": body.mesh.n_tets, "seconds_dolfinx_setup": time.perf_counter() - t0}
    out.update(compare_operators(body, model, rng, eigen=eigen))
    backends = tuple(b for b, on in (("sparse", sparse), ("spectral", spectral)) if on)
    out["contact"] = [compare_contact(body, model, c, backends) for c in contact_cases(body, rng)] if backends else []
    out["min_quality"] = float(body.mesh.quality.min())
    return out


def worst(result: dict, key: str) -> float:
    """The largest ``key`` over all contact cases and backends of a :func:`crosscheck_mesh` result."""
    vals = [c[b][key] for c in result.get("contact", []) for b in ("sparse", "spectral") if b in c]
    return float(max(vals)) if vals else float("nan")
