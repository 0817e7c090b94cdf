"""Model functions (gpfverify.models.functions) at uneven points, and the Gaussian filters under
singular noise, against closed forms written here.

* the central-difference Jacobian of a cubic map f(x) = A x + C x³ (entrywise cube) is, in exact
  arithmetic, A + C diag(3x² + h²) with the documented step h_j = eps^(1/3) max(1, |x_j|): the
  difference quotient of a cubic carries exactly h² of truncation. Points whose components differ
  in size by up to 10⁴ (so the steps are uneven) pin the step rule and the quotient from both
  sides: a larger step moves the h² term beyond rounding, a smaller one the rounding eps |f| / h;
* KF, EKF and UKF with process noise of designed rank (exact zero eigenvalues; a measurement noise
  must be positive definite, and is) against the covariance-form Kalman filter written here with numpy's solve.
"""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gpfverify.errors import NumericalError
from gpfverify.filters.ekf import ekf_step
from gpfverify.filters.kalman import kf_step
from gpfverify.filters.ukf import ukf_step
from gpfverify.models import linear_model
from gpfverify.models.functions import NumpyFunction
from gpfverify.strategies import linear_gaussian_models, singular_covariances, uneven_points
from gpfverify.strategies.matrices import float_arrays
from gpfverify.tolerances import EPS, algebra_rtol

CUBE_ROOT_EPS = float(np.cbrt(EPS))


@given(point=uneven_points(spread=1e2), out_dim=st.integers(1, 3), data=st.data())
def test_central_difference_jacobian_of_a_cubic_is_its_closed_form(point, out_dim, data):
    d = point.size
    A = data.draw(float_arrays((out_dim, d), -2.0, 2.0), label="A")
    C = data.draw(float_arrays((out_dim, d), -1.0, 1.0), label="C")
    fn = NumpyFunction(lambda x: x @ A.T + (x**3) @ C.T, "f", d, out_dim)
    got = fn.jacobian(point[None, :])[0]
    h = CUBE_ROOT_EPS * np.maximum(1.0, np.abs(point))
    want = A + C * (3.0 * point**2 + h**2)
    # each difference quotient rounds f(x ± h e_j) (size |A||x ± h| + |C||x ± h|³) and the points
    magnitude = np.abs(A) @ (np.abs(point) + h) + np.abs(C) @ (np.abs(point) + h) ** 3
    tol = 8.0 * EPS * (magnitude[:, None] + np.abs(A) + np.abs(C) * point**2) / h[None, :] + 8.0 * EPS * np.abs(want)
    assert np.all(np.abs(got - want) <= tol), (got, want, tol)


@given(model=linear_gaussian_models(), data=st.data())
def test_gaussian_filters_are_the_kalman_filter_under_singular_noise(model, data):
    dim = model.F.shape[0]
    Q = data.draw(singular_covariances(dim), label="Q of designed rank")
    R = model.R  # the library requires a positive definite measurement noise (an InputError otherwise)
    system = linear_model(model.F, model.H, Q, R)
    mu, P = model.prior.mean, model.prior.cov
    C_p = model.F @ P @ model.F.T + Q
    C_y = model.H @ C_p @ model.H.T + R
    C_xy = C_p @ model.H.T
    gain = np.linalg.solve(C_y, C_xy.T).T
    mu_p = model.F @ mu
    want = {"mu_p": mu_p, "C_p": C_p, "mu_y": model.H @ mu_p, "C_y": C_y, "C_xy": C_xy,
            "mu_e": mu_p + gain @ (model.y - model.H @ mu_p), "C_e": C_p - gain @ C_xy.T}
    cond = np.linalg.cond(C_y) * np.linalg.cond(C_p)
    scale = max(np.abs(C_p).max(), np.abs(C_y).max(), np.abs(mu_p).max(), np.abs(model.y).max(), 1.0)
    # the UKF draws sigma points from C_p's factor: a singular C_p (F singular along Q's null space)
    # is refused with a NumericalError, as documented, rather than filtered
    definite = np.linalg.eigvalsh(C_p / np.sqrt(np.outer(np.diag(C_p), np.diag(C_p))))[0] > 1e-8 \
        if np.all(np.diag(C_p) > 0) else False
    for step in (kf_step, ekf_step, ukf_step):
        if step is ukf_step and not definite:
            with pytest.raises(NumericalError):
                step(model.prior, system, model.y, k=1)
            continue
        record = step(model.prior, system, model.y, k=1)
        for name, value in want.items():
            np.testing.assert_allclose(getattr(record, name), value, rtol=0, atol=algebra_rtol(cond) * scale ** 2,
                                       err_msg=f"{step.__name__} {name}")
