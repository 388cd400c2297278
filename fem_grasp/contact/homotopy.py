"""Homotopy continuation for square nonlinear systems ``P(x) = 0`` (paper footnote 2).

The paper solves its quadratic slip systems (6), (7), (8) with the homotopy used by
Maple's ``RootFinding[Homotopy]``:

    H(x, t) = (1 - (1 - t)^2) P(x) + (1 - t)^2 Q(x),    t in [0, 1],

so that ``H(., 0) = Q`` (a start system with a known root) and ``H(., 1) = P``.  The
default start system is ``Q(x) = x - x0`` whose root is the start guess ``x0``
(e.g. the previous slip state).  The root is followed from t = 0 to t = 1 with an
Euler predictor on ``dH/dx dx/dt = -dH/dt``, a Newton corrector and an adaptive step
in t, then polished at t = 1 with Newton's method on ``P``.  Real arithmetic is the
default; a complex ``gamma`` multiplying ``Q`` (the "gamma trick") makes the path avoid
real turning points, at the price of complex iterates (``fun``/``jac`` must accept them).
"""
from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np
import scipy.linalg as la

from .kernels import slip_homotopy

__all__ = ["SLIP_INITIAL_STEP", "SLIP_MAX_STEP", "HomotopyResult", "HomotopyError", "newton", "track"]

log = logging.getLogger(__name__)

Fun = Callable[[np.ndarray], np.ndarray]

_REASONS = {
    "diverged": "the iterate diverged (its norm blew up or became non-finite)",
    "singular_jacobian": "the Jacobian is singular (or numerically so)",
    "step_too_small": "the continuation step in t shrank below the minimum step",
    "max_steps": "the iteration budget was exhausted without convergence",
    "polish_failed": "Newton polishing of the end point at t = 1 failed",
}
# The limits the compiled homotopy shares (kernels cannot import this module).
_COND_MAX = slip_homotopy.COND_MAX
_CORRECTOR_TOL = slip_homotopy.CORRECTOR_TOL
_CORRECTOR_ITERS = slip_homotopy.CORRECTOR_ITERS
#: First and largest continuation steps in t for the slip systems of eqs. (6)–(8) (plane slip and mixed slip
#: alike): larger than :func:`track`'s defaults because their paths from the held state are short and smooth.
SLIP_INITIAL_STEP = 0.25
SLIP_MAX_STEP = 1.0
#: :func:`track`'s defaults: continuation steps, smallest step in t, Newton iterations of the final polish.
TRACK_MAX_STEPS = 2000
TRACK_MIN_STEP = 1e-10
TRACK_MAX_ITER = 50


@dataclass(frozen=True)
class HomotopyResult:
    """Outcome of :func:`track` (paper footnote 2).

    Attributes
    ----------
    x : ndarray, shape (N,)
        The root of ``P``.
    residual : float
        ``||P(x)||_2`` at the returned root.
    steps : int
        Accepted continuation steps (0 when plain Newton sufficed).
    newton_iterations : int
        Total Newton iterations (path correctors plus the final polish).
    path_length_t : float
        Length of the t interval tracked: 1.0 for a homotopy run, 0.0 for plain Newton.
    rejected_steps : int
        Continuation steps rejected and retried with a smaller step.
    method : str
        ``"homotopy"`` or ``"newton"``.
    """

    x: np.ndarray
    residual: float
    steps: int
    newton_iterations: int
    path_length_t: float
    rejected_steps: int = 0
    method: str = "homotopy"


class HomotopyError(RuntimeError):
    """Failure of :func:`newton` or :func:`track` (paper footnote 2).

    Attributes
    ----------
    reason : str
        ``"diverged"``, ``"singular_jacobian"``, ``"step_too_small"``, ``"max_steps"``
        or ``"polish_failed"``.
    t : float
        Homotopy parameter reached (1.0 for Newton on ``P`` itself).
    x : ndarray
        Last point reached.
    """

    def __init__(self, reason: str, *, t: float, x: np.ndarray, detail: str = "") -> None:
        self.reason, self.t, self.x = reason, float(t), np.array(x, copy=True)
        msg = f"{reason}: {_REASONS[reason]} at t = {self.t:.6g}"
        super().__init__(f"{msg} ({detail})" if detail else msg)


def kernel_error(reason: int, detail: int, t: float, value: float, x: np.ndarray, *, tol: float, min_step: float,
                 max_steps: int, max_iter: int) -> HomotopyError:
    """The :class:`HomotopyError` :func:`track` would raise for a failed outcome of the compiled
    :func:`~fem_grasp.contact.kernels.slip_homotopy.homotopy` run with these limits (its reason and detail codes, the
    t it reached, the value its message quotes, the last point)."""
    name = slip_homotopy.HOMOTOPY_REASONS[reason]
    if name == "polish_failed":
        inner = slip_homotopy.HOMOTOPY_REASONS[detail]
        extra = {"diverged": "non-finite residual" if value < 0 else f"||x|| > {value:.3g}",
                 "singular_jacobian": slip_homotopy.SINGULAR_DETAILS[int(value)],
                 "max_steps": f"Newton: {max_iter} iterations, ||P|| = {value:.3g} > {tol:.3g}"}[inner]
        return HomotopyError(name, t=1.0, x=x, detail=str(HomotopyError(inner, t=1.0, x=x, detail=extra)))
    extra = {"diverged": f"||x|| > {value:.3g}", "singular_jacobian": slip_homotopy.SINGULAR_DETAILS[detail],
             "step_too_small": f"step {value:.3g} < {min_step:.3g}, turning point?",
             "max_steps": f"{max_steps} continuation steps"}[name]
    return HomotopyError(name, t=t, x=x, detail=extra)


class _Singular(Exception):
    """Internal signal: a linear solve met a (numerically) singular matrix."""


def _lin_solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve ``a y = b``; raise :class:`_Singular` if ``a`` is singular or non-finite.

    One LU factorisation with LAPACK's condition estimate (gecon) instead of
    an SVD: slip systems can have hundreds of unknowns.
    """
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise _Singular("non-finite matrix or right-hand side")
    anorm = np.abs(a).sum(axis=0).max()
    if anorm == 0.0:
        raise _Singular("zero matrix")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", la.LinAlgWarning)
        lu, piv = la.lu_factor(a, check_finite=False)
    gecon = la.lapack.get_lapack_funcs("gecon", (lu,))
    rcond, info = gecon(lu, anorm, norm="1")
    if info != 0 or not rcond * _COND_MAX > 1.0:
        raise _Singular(f"condition number > {_COND_MAX:.0e}")
    return la.lu_solve((lu, piv), b, check_finite=False)


class _Homotopy:
    """``H(x, t) = (1-(1-t)^2) P(x) + (1-t)^2 Q(x)`` and its partial derivatives."""

    def __init__(self, fun: Fun, jac: Fun, start: Fun, start_jac: Fun,
                 gamma: complex = 1.0) -> None:
        self.fun, self.jac, self.start, self.start_jac = fun, jac, start, start_jac
        self.gamma = gamma
        self.dtype = complex if np.iscomplexobj(gamma) else float

    def _p(self, f: Fun, x: np.ndarray, g: complex = 1.0) -> np.ndarray:
        return g * np.asarray(f(x), dtype=self.dtype)

    def value(self, x: np.ndarray, t: float) -> np.ndarray:
        b = (1.0 - t) ** 2
        return (1.0 - b) * self._p(self.fun, x) + b * self._p(self.start, x, self.gamma)

    def jac_x(self, x: np.ndarray, t: float) -> np.ndarray:
        b = (1.0 - t) ** 2
        return (1.0 - b) * self._p(self.jac, x) + b * self._p(self.start_jac, x, self.gamma)

    def jac_t(self, x: np.ndarray, t: float) -> np.ndarray:
        # d/dt (1-(1-t)^2) = 2(1-t) = -d/dt (1-t)^2
        return 2.0 * (1.0 - t) * (self._p(self.fun, x) - self._p(self.start, x, self.gamma))


def _vector(x0: np.ndarray, divergence: float, dtype: type = float) -> tuple[np.ndarray, float]:
    """Copy ``x0`` as a float (or complex) vector; return it and the divergence bound."""
    x = np.array(x0, dtype=np.result_type(np.asarray(x0), dtype)).reshape(-1)
    return x, divergence * max(1.0, float(np.linalg.norm(x)))


@np.errstate(over="ignore", invalid="ignore")
def _newton(fun: Fun, jac: Fun, x: np.ndarray, thresh: float, max_iter: int,
            limit: float) -> tuple[np.ndarray, int, float]:
    """Newton on ``fun`` until ``||fun(x)|| <= thresh``; returns (x, iterations, residual)."""
    for it in range(max_iter + 1):
        r = np.asarray(fun(x), dtype=x.dtype)
        if not np.all(np.isfinite(r)):
            raise HomotopyError("diverged", t=1.0, x=x, detail="non-finite residual")
        res = float(np.linalg.norm(r))
        if res <= thresh:
            return x, it, res
        if it == max_iter:
            break
        try:
            x = x + _lin_solve(np.asarray(jac(x), dtype=x.dtype), -r)
        except _Singular as exc:
            raise HomotopyError("singular_jacobian", t=1.0, x=x, detail=str(exc)) from None
        if not np.all(np.isfinite(x)) or np.linalg.norm(x) > limit:
            raise HomotopyError("diverged", t=1.0, x=x, detail=f"||x|| > {limit:.3g}")
    raise HomotopyError("max_steps", t=1.0, x=x,
                        detail=f"Newton: {max_iter} iterations, ||P|| = {res:.3g} > {thresh:.3g}")


def newton(fun: Fun, jac: Fun, x0: np.ndarray, *, tol: float = 1e-12, max_iter: int = 50,
           scale: float = 1.0, divergence: float = 1e8) -> tuple[np.ndarray, int]:
    """Plain Newton's method for ``P(x) = 0`` (the polishing step of paper footnote 2).

    Parameters
    ----------
    fun, jac : callable
        ``P(x) -> (N,)`` and its Jacobian ``(N, N)``.
    x0 : array_like, shape (N,)
        Start point.
    tol, scale : float
        Converged when ``||P(x)||_2 <= tol * scale``.
    max_iter : int
        Maximum number of Newton steps.
    divergence : float
        Fail once ``||x|| > divergence * max(1, ||x0||)``.

    Returns
    -------
    (x, iterations) : tuple of ndarray and int

    Raises
    ------
    HomotopyError
        ``reason`` is ``"diverged"``, ``"singular_jacobian"`` or ``"max_steps"``.
    """
    x, limit = _vector(x0, divergence)
    x, it, _ = _newton(fun, jac, x, tol * scale, max_iter, limit)
    return x, it


@np.errstate(over="ignore", invalid="ignore")
def _correct(hom: _Homotopy, x: np.ndarray, t: float) -> Optional[tuple[np.ndarray, int]]:
    """Newton corrector on ``H(., t)``; ``None`` unless it contracts and converges quickly."""
    prev = np.inf
    for k in range(1, _CORRECTOR_ITERS + 1):
        dx = _lin_solve(hom.jac_x(x, t), -hom.value(x, t))
        x = x + dx
        step = float(np.linalg.norm(dx))
        if not np.isfinite(step):
            return None
        if step <= _CORRECTOR_TOL * (1.0 + float(np.linalg.norm(x))):
            return x, k
        if step > 0.5 * prev:
            return None
        prev = step
    return None


@np.errstate(over="ignore", invalid="ignore")
def track(fun: Fun, jac: Fun, x0: np.ndarray, *, start: Optional[Fun] = None,
          start_jac: Optional[Fun] = None, tol: float = 1e-12, scale: float = 1.0,
          max_steps: int = TRACK_MAX_STEPS, min_step: float = TRACK_MIN_STEP, divergence: float = 1e8,
          initial_step: float = 0.05, max_step: float = 0.25, max_iter: int = TRACK_MAX_ITER,
          gamma: complex = 1.0) -> HomotopyResult:
    """Track the root of ``H(x, t)`` from ``x0`` at t = 0 to a root of ``P`` at t = 1.

    Implements paper footnote 2: ``H = (1-(1-t)^2) P + (1-t)^2 Q`` with Euler predictor
    (tangent from ``dH/dx dx/dt = -dH/dt``), Newton corrector, adaptive step in t
    (halved when the corrector fails, doubled when it converges in <= 3 iterations) and
    a Newton polish of ``P`` at t = 1.

    Parameters
    ----------
    fun, jac : callable
        Target system ``P(x) -> (N,)`` and its Jacobian ``(N, N)``.
    x0 : array_like, shape (N,)
        Known root of the start system (default start ``Q(x) = x - x0``).
    start, start_jac : callable, optional
        User start system ``Q`` and its Jacobian (both or neither); ``Q(x0)`` must be ~0.
    tol, scale : float
        Polish until ``||P(x)||_2 <= tol * scale``.
    max_steps : int
        Budget of continuation steps (accepted plus rejected).
    min_step : float
        Fail when the step in t falls below this.
    divergence : float
        Fail once ``||x|| > divergence * max(1, ||x0||)``.
    initial_step, max_step : float
        First and largest step in t.
    max_iter : int
        Newton iterations allowed in the final polish.
    gamma : float or complex
        Factor on ``Q`` (1 = paper footnote 2).  A complex value (gamma trick) tracks in
        complex arithmetic, avoiding real turning points; ``result.x`` is then complex.

    Returns
    -------
    HomotopyResult

    Raises
    ------
    HomotopyError
        With ``reason`` in ``"diverged"``, ``"singular_jacobian"``, ``"step_too_small"``,
        ``"max_steps"``, ``"polish_failed"``; ``.t`` and ``.x`` give where it stopped.
    """
    if (start is None) != (start_jac is None):
        raise ValueError("pass both start and start_jac, or neither")
    x, limit = _vector(x0, divergence, complex if np.iscomplexobj(gamma) else float)
    if start is None or start_jac is None:
        x_start = x.copy()
        start, start_jac = (lambda y: y - x_start), (lambda y: np.eye(y.size))
    elif np.linalg.norm(start(x)) > 1e-8 * max(1.0, float(np.linalg.norm(x))):
        raise ValueError("x0 is not a root of the start system")
    hom = _Homotopy(fun, jac, start, start_jac, gamma)
    t, h, steps, rejected, iters = 0.0, initial_step, 0, 0, 0
    while t < 1.0:
        if steps + rejected >= max_steps:
            raise HomotopyError("max_steps", t=t, x=x, detail=f"{max_steps} continuation steps")
        try:
            xdot = _lin_solve(hom.jac_x(x, t), -hom.jac_t(x, t))
        except _Singular as exc:
            raise HomotopyError("singular_jacobian", t=t, x=x, detail=str(exc)) from None
        h = min(h, 1.0 - t)
        t_new = 1.0 if h >= 1.0 - t else t + h
        try:
            out = _correct(hom, x + h * xdot, t_new)
        except _Singular:
            out = None
        if out is None:
            rejected += 1
            h *= 0.5
            if h < min_step:
                raise HomotopyError("step_too_small", t=t, x=x,
                                    detail=f"step {h:.3g} < {min_step:.3g}, turning point?")
            continue
        x, t = out[0], t_new
        steps, iters = steps + 1, iters + out[1]
        if np.linalg.norm(x) > limit:
            raise HomotopyError("diverged", t=t, x=x, detail=f"||x|| > {limit:.3g}")
        if out[1] <= 3:
            h = min(2.0 * h, max_step)
    try:
        x, it, res = _newton(fun, jac, x, tol * scale, max_iter, limit)
    except HomotopyError as exc:
        raise HomotopyError("polish_failed", t=1.0, x=exc.x, detail=str(exc)) from None
    log.debug("homotopy: %d steps (%d rejected), %d Newton iterations, |P| = %.3g",
              steps, rejected, iters + it, res)
    return HomotopyResult(x, res, steps, iters + it, 1.0, rejected, "homotopy")
