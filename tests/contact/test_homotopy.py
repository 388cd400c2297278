"""Tests for fem_grasp.contact.homotopy (paper footnote 2: H = (1-(1-t)^2) P + (1-t)^2 Q)."""
from __future__ import annotations

import numpy as np
import pytest

from fem_grasp.contact.homotopy import HomotopyError, HomotopyResult, _Homotopy, newton, track

SQRT2 = np.sqrt(2.0)
CUBIC_ROOT = -1.7692923542386314  # the only real root of x^3 - 2x + 2


def _scalar(p, dp):
    return (lambda x: np.array([p(x[0])]), lambda x: np.array([[dp(x[0])]]))


SQUARE = _scalar(lambda x: x * x - 4.0, lambda x: 2.0 * x)
CUBIC = _scalar(lambda x: x**3 - 2.0 * x + 2.0, lambda x: 3.0 * x * x - 2.0)
ATAN = _scalar(np.arctan, lambda x: 1.0 / (1.0 + x * x))
NO_ROOT = _scalar(lambda x: x * x + 1.0, lambda x: 2.0 * x)


def circle_line(x):
    return np.array([x[0] ** 2 + x[1] ** 2 - 4.0, x[0] - x[1]])


def circle_line_jac(x):
    return np.array([[2.0 * x[0], 2.0 * x[1]], [1.0, -1.0]])


# --- paper eq. (6): (1+mu^2)(f_k.z)^2 = f_k.f_k with f_k affine in the slips d -------------
MU_P, Z = 0.4, np.array([0.0, 0.0, 1.0])
_rng = np.random.default_rng(7)
A6 = _rng.normal(size=(2, 3, 2))                       # df_k/dd, two sliding nodes
D_STAR = np.array([0.3, -0.2])                         # the root built into the system
_phi, _mag = np.array([0.7, 2.5]), np.array([2.0, 1.5])
F_STAR = _mag[:, None] * np.stack([MU_P * np.cos(_phi), MU_P * np.sin(_phi), np.ones(2)], 1)
B6 = F_STAR - A6 @ D_STAR                              # so that f_k(D_STAR) is on the cone


def cone6(d):
    f = A6 @ d + B6
    return (1.0 + MU_P**2) * f[:, 2] ** 2 - np.einsum("ki,ki->k", f, f)


def cone6_jac(d):
    f = A6 @ d + B6
    return 2.0 * (1.0 + MU_P**2) * f[:, 2:3] * A6[:, 2, :] - 2.0 * np.einsum("ki,kij->kj", f, A6)


# --- paper eqs. (7)+(8): fingertip slip in (c, s) = (cos theta, sin theta) ------------------
MU_F, N_HAT, THETA_STAR = 0.5, np.array([0.0, 0.0, 1.0]), -0.3
CS_STAR = np.array([np.cos(THETA_STAR), np.sin(THETA_STAR)])
U78 = 2.0 * np.array([[1.0, 0.2], [-0.3, 0.8], [0.5, -0.4]])
F0_78 = 1.5 * np.array([MU_F * np.cos(0.7), MU_F * np.sin(0.7), 1.0]) - U78 @ CS_STAR
THETA_OTHER = -1.1217031124971577  # the other real root of this system


def cone78(x):
    f = F0_78 + U78 @ x
    return np.array([(1.0 + MU_F**2) * (f @ N_HAT) ** 2 - f @ f, x @ x - 1.0])


def cone78_jac(x):
    f = F0_78 + U78 @ x
    return np.array([2.0 * (1.0 + MU_F**2) * (f @ N_HAT) * (N_HAT @ U78) - 2.0 * f @ U78, 2.0 * x])


# ------------------------------------------------------------------------------------------
def test_newton_scalar_root():
    x, its = newton(*SQUARE, [0.1])
    assert x == pytest.approx([2.0], abs=1e-12)
    assert 1 <= its <= 15


def test_track_scalar_root():
    res = track(*SQUARE, [0.1])
    assert isinstance(res, HomotopyResult)
    assert res.x == pytest.approx([2.0], abs=1e-12)
    assert res.residual <= 1e-12
    assert res.path_length_t == 1.0 and res.steps > 0 and res.newton_iterations >= res.steps


@pytest.mark.parametrize(
    "system, x0, newton_reason, root",
    [
        (SQUARE, 0.0, "singular_jacobian", 2.0),    # P'(x0) = 0
        (CUBIC, 0.0, "max_steps", CUBIC_ROOT),      # Newton cycles 0 -> 1 -> 0
        (ATAN, 3.0, "diverged", 0.0),               # Newton overshoots to infinity
    ],
)
def test_newton_fails_but_track_succeeds(system, x0, newton_reason, root):
    with pytest.raises(HomotopyError) as info:
        newton(*system, [x0])
    assert info.value.reason == newton_reason
    res = track(*system, [x0])
    assert res.x == pytest.approx([root], abs=1e-12)
    assert res.residual <= 1e-12


def test_circle_line_from_singular_start():
    with pytest.raises(HomotopyError, match="singular") as info:
        newton(circle_line, circle_line_jac, [0.0, 0.0])
    assert info.value.reason == "singular_jacobian"
    res = track(circle_line, circle_line_jac, [0.0, 0.0])
    # lambda P(x) + x = 0 passes x = (0, -2) at lambda = 1 and ends on the lower root
    assert res.x == pytest.approx([-SQRT2, -SQRT2], abs=1e-12)
    assert np.linalg.norm(circle_line(res.x)) <= 1e-12


def test_paper_eq6_coupled_cone_system():
    assert np.linalg.norm(cone6(D_STAR)) < 1e-14
    res = track(cone6, cone6_jac, np.zeros(2))        # start: previous slip state d = 0
    assert res.x == pytest.approx(D_STAR, abs=1e-12)
    f = A6 @ res.x + B6
    assert (1 + MU_P**2) * f[:, 2] ** 2 == pytest.approx(np.einsum("ki,ki->k", f, f), rel=1e-12)


def test_paper_eq7_eq8_track_reaches_built_root_where_newton_goes_elsewhere():
    x0 = np.array([np.cos(-2 * np.pi / 3), np.sin(-2 * np.pi / 3)])
    xn, _ = newton(cone78, cone78_jac, x0)
    assert np.arctan2(xn[1], xn[0]) == pytest.approx(THETA_OTHER, abs=1e-10)
    res = track(cone78, cone78_jac, x0)
    assert res.x == pytest.approx(CS_STAR, abs=1e-12)
    assert res.x @ res.x == pytest.approx(1.0, abs=1e-14)
    # and from the no-slip state (c, s) = (1, 0)
    assert track(cone78, cone78_jac, [1.0, 0.0]).x == pytest.approx(CS_STAR, abs=1e-12)


def test_user_start_system():
    start = (lambda x: x * x - 1.0, lambda x: np.diag(2.0 * x))   # root x0 = 1
    res = track(*SQUARE, [1.0], start=start[0], start_jac=start[1])
    assert res.x == pytest.approx([2.0], abs=1e-12)             # path x(t) = sqrt(4 - 3(1-t)^2)
    with pytest.raises(ValueError):
        track(*SQUARE, [1.0], start=start[0])
    with pytest.raises(ValueError):
        track(*SQUARE, [0.5], start=start[0], start_jac=start[1])


def test_complex_gamma_trick_finds_complex_root():
    res = track(*NO_ROOT, [0.5], gamma=np.exp(0.9j))
    assert np.iscomplexobj(res.x)
    assert abs(res.x[0] ** 2 + 1.0) <= 1e-12 and abs(res.x[0].imag) == pytest.approx(1.0)


def test_no_real_root_reports_turning_point():
    with pytest.raises(HomotopyError, match="step") as info:
        track(*NO_ROOT, [0.5])
    err = info.value
    assert err.reason == "step_too_small"
    # lambda (x^2 + 1) + x - 0.5 = 0 (lambda = a/b) folds at lambda* = (0.5 + sqrt(1.25)) / 2
    lam = (0.5 + np.sqrt(1.25)) / 2
    assert err.t == pytest.approx(1.0 - np.sqrt(1.0 / (1.0 + lam)), abs=1e-4)
    assert err.x == pytest.approx([-1.0 / (2.0 * lam)], abs=1e-3)
    with pytest.raises(HomotopyError) as info:
        newton(*NO_ROOT, [0.5])
    assert info.value.reason == "max_steps" and np.all(np.isfinite(info.value.x))


def test_other_failure_reasons():
    shifted = _scalar(lambda x: np.arctan(x) + 2.0, lambda x: 1.0 / (1.0 + x * x))  # no root
    with pytest.raises(HomotopyError, match="diverged") as info:
        track(*shifted, [0.0])
    assert info.value.reason == "diverged" and 0.99 < info.value.t < 1.0
    with pytest.raises(HomotopyError) as info:
        track(*SQUARE, [0.1], max_steps=3)
    assert info.value.reason == "max_steps" and 0.0 < info.value.t < 1.0
    with pytest.raises(HomotopyError, match="polish") as info:
        track(lambda x: x * x - 2.0, lambda x: np.diag(2.0 * x), [1.0], tol=1e-300)
    assert info.value.reason == "polish_failed" and info.value.x == pytest.approx([SQRT2])
    with pytest.raises(HomotopyError) as info:                     # never a raw LinAlgError
        newton(lambda x: x - 1.0, lambda x: np.zeros((2, 2)), [0.0, 0.0])
    assert info.value.reason == "singular_jacobian"
    with pytest.raises(HomotopyError) as info:
        newton(lambda x: np.full(2, np.nan), lambda x: np.eye(2), [0.0, 0.0])
    assert info.value.reason == "diverged"


@pytest.mark.parametrize("gamma", [1.0, 0.3 - 0.8j])
def test_homotopy_derivatives_finite_difference(gamma):
    q = (lambda x: x**3 - np.array([0.5, -1.0]), lambda x: np.diag(3.0 * x**2))
    hom = _Homotopy(cone6, cone6_jac, q[0], q[1], gamma)
    x, t, eps = np.array([0.2, 0.7]), 0.37, 1e-6
    assert hom.value(x, 0.0) == pytest.approx(gamma * q[0](x), rel=1e-14)
    assert hom.value(x, 1.0) == pytest.approx(cone6(x), rel=1e-14)
    fd_t = (hom.value(x, t + eps) - hom.value(x, t - eps)) / (2 * eps)
    assert hom.jac_t(x, t) == pytest.approx(fd_t, rel=1e-8, abs=1e-9)
    fd_x = np.column_stack([(hom.value(x + eps * e, t) - hom.value(x - eps * e, t)) / (2 * eps)
                            for e in np.eye(2)])
    assert hom.jac_x(x, t) == pytest.approx(fd_x, rel=1e-8, abs=1e-9)


def test_track_tolerance_is_relative_to_the_callers_scale():
    """A large-magnitude system: the residual tolerance is relative to the caller's scale."""
    big = (lambda d: 1e6 * cone6(d), lambda d: 1e6 * cone6_jac(d))
    res = track(*big, np.zeros(2), tol=1e-12, scale=1e6)
    assert res.residual <= 1e-6 and res.x == pytest.approx(D_STAR, abs=1e-12)
