"""Manufactured-solution convergence: fem_grasp P1 against dolfinx P1 and P2.

A point-held body has no continuum limit (a point force has infinite energy), so convergence is
measured on a smooth displacement field prescribed on the whole boundary of
the unit box, with the body force that makes it an exact solution of
−div σ(u) = f.

The exact fields are sums of plane waves, ``u(x) = Σ_w c_w sin(k_w·x + φ_w)``,
for which the body force has the closed form

    f(x) = Σ_w sin(k_w·x + φ_w) [μ |k_w|² c_w + (λ + μ)(c_w·k_w) k_w]

used on the fem_grasp side, while the dolfinx side lets UFL differentiate the
exact field itself.  With every ``c_w ⟂ k_w`` the field is divergence-free
and f does not depend on λ: the right test for volumetric locking as ν → ½.
"""

from __future__ import annotations

import logging
import time
from dataclasses import asdict, dataclass

import numpy as np

from fem_grasp import Body, TetMesh, box_mesh

from .linalg import dirichlet_solve
from .quadrature import p1_errors, p1_load_vector
from .reference import ManufacturedResult, lame, max_edge_length, solve_clamped_gravity, solve_manufactured

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class PlaneWaveField:
    """``u(x) = Σ_w c_w sin(k_w·x + φ_w)``: a smooth exact displacement field.

    Attributes
    ----------
    amplitudes : (W, 3) c_w, metres
    wavevectors : (W, 3) k_w, 1/metres
    phases : (W,) φ_w
    """

    amplitudes: np.ndarray
    wavevectors: np.ndarray
    phases: np.ndarray

    def _arg(self, x: np.ndarray) -> np.ndarray:
        return x @ self.wavevectors.T + self.phases  # (N, W)

    def value(self, x: np.ndarray) -> np.ndarray:
        """(N, 3) displacement at (N, 3) points."""
        return np.sin(self._arg(np.asarray(x, dtype=float))) @ self.amplitudes

    def grad(self, x: np.ndarray) -> np.ndarray:
        """(N, 3, 3) gradient, ``[:, i, j] = ∂u_i/∂x_j``."""
        cos = np.cos(self._arg(np.asarray(x, dtype=float)))
        return np.einsum("nw,wi,wj->nij", cos, self.amplitudes, self.wavevectors)

    def divergence(self, x: np.ndarray) -> np.ndarray:
        return np.cos(self._arg(np.asarray(x, dtype=float))) @ np.einsum("wi,wi->w", self.amplitudes,
                                                                          self.wavevectors)

    def body_force(self, x: np.ndarray, lam: float, mu: float) -> np.ndarray:
        """(N, 3) f = −div σ(u) for Lamé parameters λ, μ (closed form)."""
        k, c = self.wavevectors, self.amplitudes
        coeff = mu * np.sum(k * k, axis=1)[:, None] * c + (lam + mu) * np.sum(c * k, axis=1)[:, None] * k
        return np.sin(self._arg(np.asarray(x, dtype=float))) @ coeff

    def ufl(self, x):
        """The field as a UFL expression of the spatial coordinate ``x``."""
        import ufl

        terms = [ufl.as_vector([float(ci) for ci in c]) * ufl.sin(ufl.dot(ufl.as_vector([float(ki) for ki in k]), x)
                                                                   + float(ph))
                 for c, k, ph in zip(self.amplitudes, self.wavevectors, self.phases)]
        out = terms[0]
        for t in terms[1:]:
            out = out + t
        return out


def _field(amplitudes, wavevectors, phases, solenoidal: bool) -> PlaneWaveField:
    c = np.asarray(amplitudes, dtype=float)
    k = np.asarray(wavevectors, dtype=float)
    if solenoidal:
        c = c - (np.sum(c * k, axis=1) / np.sum(k * k, axis=1))[:, None] * k
    return PlaneWaveField(1e-3 * c, k, np.asarray(phases, dtype=float))


_AMPLITUDES = [[1.0, 0.5, -0.3], [0.2, -0.8, 0.6], [-0.4, 0.3, 1.0]]
_WAVEVECTORS = np.pi * np.array([[1.0, 0.5, 0.3], [0.4, 1.2, -0.6], [-0.7, 0.2, 1.1]])
_PHASES = [0.3, 1.1, -0.5]

#: A compressible smooth field (div u ≠ 0) for the convergence study.
GENERAL_FIELD = _field(_AMPLITUDES, _WAVEVECTORS, _PHASES, solenoidal=False)
#: A divergence-free field for the locking study.
SOLENOIDAL_FIELD = _field(_AMPLITUDES, _WAVEVECTORS, _PHASES, solenoidal=True)


def solve_fem_grasp_p1(mesh: TetMesh, field: PlaneWaveField, young: float, poisson: float) -> ManufacturedResult:
    """The manufactured problem with fem_grasp's K and a NumPy consistent load.

    Boundary nodes (every surface node) take the exact field's values; the
    load is ``∫ f φ_a`` by a degree-5 quadrature; the linear solve is MUMPS.
    Timing covers K, the load and the solve.
    """
    lam, mu = lame(young, poisson)
    t0 = time.perf_counter()
    k = Body(mesh, young, poisson, density=1.0).stiffness
    load = p1_load_vector(mesh.points, mesh.tets, lambda x: field.body_force(x, lam, mu))
    boundary = mesh.surface_nodes
    fixed = (3 * boundary[:, None] + np.arange(3)).ravel()
    u = dirichlet_solve(k, load, fixed, field.value(mesh.points[boundary]).ravel())
    seconds = time.perf_counter() - t0
    err = p1_errors(mesh.points, mesh.tets, u.reshape(-1, 3), field.value, field.grad, lam, mu)
    return ManufacturedResult(degree=1, n_dofs=3 * mesh.n_points, h=max_edge_length(mesh), seconds=seconds, **err)


def fitted_rate(h: list[float] | np.ndarray, err: list[float] | np.ndarray) -> float:
    """Least-squares slope of log(err) against log(h)."""
    h, err = np.asarray(h, dtype=float), np.asarray(err, dtype=float)
    if len(h) < 2:
        return float("nan")
    return float(np.polyfit(np.log(h), np.log(err), 1)[0])


METHODS = ("fem_grasp P1", "dolfinx P1", "dolfinx P2")


def convergence_study(levels: list[int], p2_levels: list[int], young: float = 1e5, poisson: float = 0.3,
                      field: PlaneWaveField = GENERAL_FIELD) -> dict:
    """Errors, times and fitted rates on unit-box meshes with ``N`` cells per side for N in ``levels``.

    Parameters
    ----------
    levels : divisions per side for the P1 runs (fem_grasp and dolfinx)
    p2_levels : divisions per side for the dolfinx P2 runs
    young, poisson : material

    Returns
    -------
    dict
        ``runs[method]`` is a list of :class:`ManufacturedResult` dicts (with
        ``N``), ``rates[method]`` the fitted L2 and energy rates (cell size
        h = 1/N), ``max_rel_diff_p1`` the largest relative difference between
        fem_grasp's and dolfinx's P1 errors.
    """
    from fem_grasp.progress import progress

    runs: dict[str, list[dict]] = {m: [] for m in METHODS}
    sizes = sorted(set(levels) | set(p2_levels))
    for n in progress(sizes, total=len(sizes), desc="convergence (mesh sizes)", unit="mesh"):
        mesh = box_mesh(divisions=(n, n, n))
        todo = []
        if n in levels:
            todo += [("fem_grasp P1", lambda: solve_fem_grasp_p1(mesh, field, young, poisson)),
                     ("dolfinx P1", lambda: solve_manufactured(mesh, field, young, poisson, 1))]
        if n in p2_levels:
            todo.append(("dolfinx P2", lambda: solve_manufactured(mesh, field, young, poisson, 2)))
        for name, job in todo:
            res = job()
            runs[name].append(dict(asdict(res), N=n, cell_size=1.0 / n))
            log.info("%-13s N=%-3d dofs=%-8d L2 %.3e  energy %.3e  %.2f s", name, n, res.n_dofs,
                     res.l2_error / res.l2_norm, res.energy_error / res.energy_norm, res.seconds)
    rates = {}
    for name, rows in runs.items():
        h = [r["cell_size"] for r in rows]
        rates[name] = {"l2": fitted_rate(h, [r["l2_error"] for r in rows]),
                       "energy": fitted_rate(h, [r["energy_error"] for r in rows]),
                       "l2_last": fitted_rate(h[-2:], [r["l2_error"] for r in rows[-2:]]),
                       "energy_last": fitted_rate(h[-2:], [r["energy_error"] for r in rows[-2:]])}
    diffs = [max(abs(a["l2_error"] / b["l2_error"] - 1), abs(a["energy_error"] / b["energy_error"] - 1))
             for a, b in zip(runs["fem_grasp P1"], runs["dolfinx P1"])]
    return {"young": young, "poisson": poisson, "runs": runs, "rates": rates,
            "p1_error_max_rel_diff": float(max(diffs)) if diffs else float("nan")}


def locking_study(poissons: list[float], divisions: int, p2_divisions: int | None = None,
                  young: float = 1e5, field: PlaneWaveField = SOLENOIDAL_FIELD) -> dict:
    """Relative L2 and energy errors against ν for a divergence-free exact field.

    The exact field and its load do not depend on ν, so any growth of the
    error as ν → ½ is volumetric locking of the discretisation.
    """
    rows = []
    mesh = box_mesh(divisions=(divisions,) * 3)
    mesh2 = box_mesh(divisions=(p2_divisions or divisions,) * 3)
    for nu in poissons:
        row = {"poisson": nu}
        for name, job in (("fem_grasp P1", lambda: solve_fem_grasp_p1(mesh, field, young, nu)),
                          ("dolfinx P1", lambda: solve_manufactured(mesh, field, young, nu, 1)),
                          ("dolfinx P2", lambda: solve_manufactured(mesh2, field, young, nu, 2))):
            res = job()
            row[name] = {"l2_rel": res.l2_error / res.l2_norm, "energy_rel": res.energy_error / res.energy_norm,
                         "n_dofs": res.n_dofs}
        rows.append(row)
        log.info("locking nu=%g: P1 L2 %.3e, P2 L2 %.3e", nu, row["fem_grasp P1"]["l2_rel"],
                 row["dolfinx P2"]["l2_rel"])
    ref = rows[0]
    growth = {m: rows[-1][m]["l2_rel"] / ref[m]["l2_rel"] for m in METHODS}
    return {"divisions": divisions, "p2_divisions": p2_divisions or divisions, "young": young, "rows": rows,
            "l2_growth": growth}


def beam_locking_study(poissons: list[float], divisions: tuple[int, int, int] = (10, 2, 2),
                       reference_divisions: tuple[int, int, int] = (20, 4, 4), length: float = 0.1,
                       width: float = 0.02, young: float = 1e7, density: float = 1000.0) -> dict:
    """Tip deflection of a cantilever sagging under its own weight, against ν.

    A box ``length × width × width`` clamped at x = 0 bends under gravity.
    fem_grasp's K and G (the partitioned solve of a clamped face) and dolfinx
    P1 on the same mesh are compared with dolfinx P2 on a finer mesh (the
    reference).  As ν → ½ the P1 deflection collapses (volumetric locking);
    P2 much less so.

    Returns
    -------
    dict with, per ν, the vertical tip deflection (centre of the free end) of
    each method and its ratio to the reference, and the gravity work ∫ρg·u.
    """
    mesh = box_mesh((0, 0, 0), (length, width, width), divisions)
    ref_mesh = box_mesh((0, 0, 0), (length, width, width), reference_divisions)
    probe = np.array([length, width / 2, width / 2])
    tip = int(np.argmin(np.linalg.norm(mesh.points - probe, axis=1)))
    clamp = np.flatnonzero(mesh.points[:, 0] <= 1e-12)
    fixed = (3 * clamp[:, None] + np.arange(3)).ravel()
    rows = []
    for nu in poissons:
        body = Body(mesh, young, nu, density=density)
        u = dirichlet_solve(body.stiffness, body.gravity_loads, fixed, np.zeros(len(fixed)))
        fg = {"tip": float(u[3 * tip + 2]), "work": float(body.gravity_loads @ u)}
        d1 = solve_clamped_gravity(mesh, 1, young, nu, density, probe)
        d2 = solve_clamped_gravity(mesh, 2, young, nu, density, probe)
        ref = solve_clamped_gravity(ref_mesh, 2, young, nu, density, probe)
        row = {"poisson": nu, "reference_tip": float(ref["probe_displacement"][2]), "reference_work": ref["work"]}
        for name, tip_z, work in (("fem_grasp P1", fg["tip"], fg["work"]),
                                  ("dolfinx P1", float(d1["probe_displacement"][2]), d1["work"]),
                                  ("dolfinx P2", float(d2["probe_displacement"][2]), d2["work"])):
            row[name] = {"tip": tip_z, "tip_ratio": tip_z / row["reference_tip"], "work_ratio": work / ref["work"]}
        rows.append(row)
        log.info("beam nu=%g: tip ratio P1 %.3f, P2 %.3f", nu, row["fem_grasp P1"]["tip_ratio"],
                 row["dolfinx P2"]["tip_ratio"])
    # Euler–Bernoulli: w = q L⁴ / (8 E I), q = ρ g A, I = a⁴ / 12 (no shear, no ν).
    euler_bernoulli = density * 9.8 * width**2 * length**4 / (8.0 * young * width**4 / 12.0)
    return {"divisions": list(divisions), "reference_divisions": list(reference_divisions), "length": length,
            "width": width, "young": young, "density": density, "euler_bernoulli_tip": -euler_bernoulli,
            "rows": rows,
            "max_fem_grasp_vs_dolfinx_p1": max(abs(r["fem_grasp P1"]["tip"] / r["dolfinx P1"]["tip"] - 1)
                                               for r in rows)}
