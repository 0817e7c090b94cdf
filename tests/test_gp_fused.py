"""The fused moment kernel (gpfverify.gp.fused) against independent routes: its expm1 (compiled and
in numpy) against mpmath at 40 digits; its sums against the numpy reference path of moment
matching on drawn GP stacks in every regime."""

import mpmath
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gpfverify.gp import expm1, fused
from gpfverify.gp.moments import _first_moments, moment_match_stack
from gpfverify.strategies import gp_stacks
from gpfverify.tolerances import algebra_rtol

needs_numba = pytest.mark.skipif(not fused.AVAILABLE, reason="the fused kernel needs numba (the fast extra)")

EPS = np.finfo(float).eps
#: the reduction's boundaries ±½ ln 2 and their neighbours, zeros, the clamp and the largest argument
EDGES = np.array([0.0, -0.0, 5e-324, -5e-324, 1e-300, 1e-17, -1e-17, 0.5 * np.log(2), -0.5 * np.log(2),
                  np.nextafter(0.5 * np.log(2), 1), np.nextafter(-0.5 * np.log(2), -1), np.log(2), -np.log(2),
                  1.0, -1.0, 36.0, -36.0, -60.0, -61.0, -1000.0, 700.0, fused.EXPM1_SAFE])


def _arguments(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    magnitudes = 10.0 ** rng.uniform(-300, np.log10(fused.EXPM1_SAFE), 20_000)
    return np.concatenate([EDGES, magnitudes * rng.choice([-1.0, 1.0], magnitudes.size),
                           rng.normal(0.0, 0.5, 5_000)])


def _ulps(got: np.ndarray, exact: np.ndarray) -> np.ndarray:
    return np.abs(got - exact) / np.spacing(np.abs(exact))


def test_reference_expm1_is_within_two_ulp_of_mpmath():
    x = _arguments()[::7]
    mpmath.mp.dps = 40
    exact = np.array([float(mpmath.expm1(mpmath.mpf(float(v)))) for v in x])
    ulps = _ulps(expm1.expm1_reference(x), exact)
    assert np.all(ulps <= 2.0), (x[np.argmax(ulps)], ulps.max())


def test_polynomial_coefficients_are_the_chebyshev_fit_they_claim():
    """The reduced-argument polynomial's coefficients fitted again at 50 digits (mpmath's Chebyshev
    fit of (expm1(r) − r)/r² on |r| ≤ ½ ln 2 · (1 + 2⁻³⁰), degree 9), each within an ulp of the
    constant in the code; and r + r²P(r) with those doubles, evaluated exactly at 2001 points of the
    interval, within a quarter of an ulp of expm1(r): the polynomial's part of the 2-ulp budget."""
    with mpmath.workdps(50):
        half_width = mpmath.log(2) / 2 * (1 + mpmath.mpf(2) ** -30)

        def target(r):  # a series where (expm1(r) − r)/r² would cancel at 50 digits
            return mpmath.mpf(1) / 2 + r / 6 if abs(r) < 1e-20 else (mpmath.expm1(r) - r) / r ** 2

        highest_first = mpmath.chebyfit(target, [-half_width, half_width], len(expm1._P))
        fitted = np.array([float(c) for c in reversed(highest_first)])
        worst = max(abs(r + r ** 2 * mpmath.polyval([mpmath.mpf(c) for c in reversed(expm1._P)], r)
                        - mpmath.expm1(r)) / abs(mpmath.expm1(r))
                    for r in mpmath.linspace(-half_width, half_width, 2001) if r)
    assert np.all(np.abs(fitted - np.array(expm1._P)) <= np.spacing(np.abs(fitted))), fitted
    assert float(worst) < 0.25 * EPS, float(worst)


def test_reference_expm1_keeps_every_digit_near_zero():
    """expm1(x) = x(1 + x/2 + …): for |x| below eps the result is x itself, where exp(x) − 1 is 0."""
    x = np.array([1e-20, -3e-18, 2.5e-300])
    np.testing.assert_array_equal(expm1.expm1_reference(x), x)


@needs_numba
def test_compiled_expm1_is_within_two_ulp_of_mpmath():
    """The compiled expm1 may fuse multiplies and adds (FMA), so it is its own route: checked
    against mpmath like the reference, and against the reference to the same 2 ulp each."""
    x = _arguments(1)
    from gpfverify.gp.fused_kernels import expm1_compiled

    got = expm1_compiled(x)
    sample = slice(None, None, 7)
    mpmath.mp.dps = 40
    exact = np.array([float(mpmath.expm1(mpmath.mpf(float(v)))) for v in x[sample]])
    ulps = _ulps(got[sample], exact)
    assert np.all(ulps <= 2.0), (x[sample][np.argmax(ulps)], ulps.max())
    reference = expm1.expm1_reference(x)
    assert np.all(np.abs(got - reference) <= 4.0 * np.spacing(np.abs(reference)))
    np.testing.assert_array_equal(expm1_compiled(np.array([1e-20, -3e-18, 2.5e-300])), [1e-20, -3e-18, 2.5e-300])


def _both_paths(case):
    saved = fused.enabled
    try:
        fused.enabled = True
        got = moment_match_stack(list(case.gps), case.mu, case.sigma)
        fused.enabled = False
        ref = moment_match_stack(list(case.gps), case.mu, case.sigma)
    finally:
        fused.enabled = saved
    return got, ref


def _first_moment_scales(gp, mu, sigma) -> tuple[np.ndarray, np.ndarray]:
    """Per output a, the rounding scales of M_a = Σ_i β_ai q_ai and of Cov[x, f_a] =
    Σ(Σ + Λ_a)⁻¹ Σ_i β_ai q_ai ν_i: algebra_rtol(κ_a) times Σ_i |β_ai| q_ai and times
    ‖Σ‖ Σ_i |β_ai| q_ai ‖ν_i‖ / min ℓ_a², with κ_a = (1 + |log α_a²| + log|B_a + I| + max_i |log q_ai|) ·
    |B_a + I| — the size of the terms in each exponent times cond(B_a + I) ≤ |B_a + I|."""
    first = _first_moments(gp, mu, sigma)
    weights = np.abs(gp.beta) * np.exp(first.log_q)  # (E, n)
    kappa = ((1.0 + np.abs(np.log(gp.signal_var)) + first.b_logdet + np.abs(first.log_q).max(axis=1))
             * np.exp(first.b_logdet))
    rtol = np.array([algebra_rtol(k) for k in kappa])
    mean = rtol * weights.sum(axis=1)
    nu_norm = np.linalg.norm(gp.X - mu, axis=1)
    cross = rtol * np.linalg.norm(sigma, 2) * (weights @ nu_norm) / np.min(gp.lengthscales ** 2, axis=1)
    return mean, cross


@needs_numba
@settings(max_examples=40)
@given(case=gp_stacks(regime=st.sampled_from(("ordinary", "near-linear", "wide", "far"))))
def test_fused_moments_equal_the_numpy_path(case):
    """Same algebra, different rounding (summation order, expm1, the D × D eigendecompositions):
    the first moments equal to the rounding of their sums (:func:`_first_moment_scales`), the
    covariance to the rounding of the centred sums, whose size is bounded by Σ|β_a q_a||E||β_b q_b| ≤
    the moments' scale below."""
    got, ref = _both_paths(case)
    scales = [_first_moment_scales(gp, case.mu, case.sigma) for gp in case.gps]
    mean_tol, cross_tol = (np.concatenate([s[k] for s in scales]) for k in (0, 1))
    assert np.all(np.abs(got.mean - ref.mean) <= mean_tol + 1e-300), np.abs(got.mean - ref.mean) / mean_tol
    assert np.all(np.abs(got.cross_cov - ref.cross_cov) <= cross_tol + 1e-300)
    kappa = max(np.linalg.cond(k) for gp in case.gps for k in gp.K_inv)
    tol = algebra_rtol(kappa)
    scale = np.sqrt(np.outer(np.diag(np.abs(ref.cov)), np.diag(np.abs(ref.cov)))) + np.abs(ref.cov)
    assert np.all(np.abs(got.cov - ref.cov) <= tol * scale + 1e-300), np.max(np.abs(got.cov - ref.cov) / scale)


@needs_numba
def test_an_exponent_beyond_the_limit_takes_the_numpy_path(monkeypatch):
    """Where an exponent is above EXPM1_SAFE the kernel is not called."""
    rng = np.random.default_rng(9)
    from gpfverify.gp import GaussianProcess

    x = np.concatenate([rng.uniform(-10, 10, size=(30, 1)), rng.uniform(250, 400, size=(30, 1))])
    gp = GaussianProcess(x, np.sin(3 * x[:, 0]), lengthscales=[[0.5]], signal_var=[1.0], noise_var=[0.01])
    from gpfverify.gp import fused_kernels

    calls = []
    monkeypatch.setattr(fused_kernels, "centred_sums", lambda *a: calls.append(a))
    monkeypatch.setattr(fused, "enabled", True)
    gp.predict_uncertain(np.array([0.5]), np.array([[30.0]]))
    assert calls == []
    gp.predict_uncertain(np.array([0.5]), np.array([[1e-4]]))
    assert len(calls) == 1


@needs_numba
def test_an_input_the_bound_does_not_clear_is_summed_by_the_kernel_when_its_exponents_allow(monkeypatch):
    """The Cauchy–Schwarz bound is loose in two dimensions: inputs above it whose largest exponent is
    below EXPM1_SAFE (formed by largest_exponents) go through the kernel, and get the numpy path's
    moments to rounding."""
    from gpfverify.gp import GaussianProcess, fused_kernels

    largest = []
    original = fused_kernels.largest_exponents
    monkeypatch.setattr(fused_kernels, "largest_exponents", lambda *a: largest.append(original(*a)) or largest[-1])
    rng = np.random.default_rng(36)
    x = rng.uniform(-10, 10, size=(30, 2))
    gp = GaussianProcess(x, np.sin(x[:, 0]) * np.cos(x[:, 1]), lengthscales=[rng.uniform(0.2, 3, 2)],
                         signal_var=[1.0], noise_var=[0.01])
    for scale in (1.0, 3.0, 10.0, 30.0, 100.0, 300.0):
        a = rng.normal(size=(2, 2))
        mu, sigma = rng.normal(size=2) * 5, scale * (a @ a.T + 0.1 * np.eye(2))
        got, ref = _both_paths(type("Case", (), {"gps": (gp,), "mu": mu, "sigma": sigma}))
        np.testing.assert_allclose(got.mean, ref.mean, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(got.cov, ref.cov, rtol=1e-10, atol=1e-12)
    assert any(v[0] <= fused.EXPM1_SAFE for v in largest)


def test_importing_the_package_does_not_import_numba():
    """numba costs about half a second to import: only the first moment-matching call loads it."""
    import subprocess
    import sys

    code = "import sys, gpfverify.cli, gpfverify.models, gpfverify.gp; print('numba' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


_WIDTH_SCRIPT = """
import json, sys
import numba, numpy as np
from gpfverify.gp import GaussianProcess
from gpfverify.gp.moments import moment_match_batch
rng = np.random.default_rng(0)
n, d, e = 301, 3, 3
x = rng.uniform(-3, 3, (n, d))
gp = GaussianProcess(x, np.sin(x @ rng.normal(size=(d, e))), rng.uniform(0.5, 2, (e, d)), rng.uniform(0.5, 2, e),
                     np.full(e, 0.01))
mu, a = rng.normal(size=(5, d)), rng.normal(size=(5, d, d))
mm = moment_match_batch(gp, mu, 0.1 * a @ a.transpose(0, 2, 1) + 0.01 * np.eye(d))
widened = bool(numba.config.CPU_FEATURES) and "-prefer-256-bit" in numba.config.CPU_FEATURES
print(json.dumps({"widened": widened, "cov": mm.cov.tolist(), "mean": mm.mean.tolist(),
                  "kappa": max(float(np.linalg.cond(k)) for k in gp.K_inv)}))
"""


def _moments_in_a_process(env_features: str | None) -> dict:
    import json
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CPU_NAME", "NUMBA_CPU_FEATURES")}
    if env_features is not None:
        env["NUMBA_CPU_FEATURES"] = env_features
    out = subprocess.run([sys.executable, "-c", _WIDTH_SCRIPT], capture_output=True, text=True, check=True, env=env)
    return json.loads(out.stdout)


@pytest.mark.slow
@needs_numba
def test_the_vector_width_setting_changes_speed_not_results():
    """On a processor with AVX-512 gpfverify turns LLVM's 256-bit preference off for its kernels,
    unless the user chose numba's CPU features (here: the processor's own, preference kept); the
    moments agree to the rounding of the algebra either way (elsewhere neither run widens)."""
    from gpfverify import numba_target

    wider = numba_target.wider_vectors_features()
    own = _moments_in_a_process(None)
    kept = _moments_in_a_process(wider.removesuffix(",-prefer-256-bit") if wider else "")
    assert own["widened"] is (wider is not None)
    assert kept["widened"] is False
    tol = algebra_rtol(own["kappa"])
    for key in ("cov", "mean"):
        a, b = np.array(own[key]), np.array(kept[key])
        assert np.all(np.abs(a - b) <= tol * np.abs(b).max()), key


@pytest.mark.slow
@needs_numba
def test_the_vector_width_setting_leaves_a_users_numba_alone():
    """Once numba has compiled code in the process (its code generator is fixed), or when the user
    set numba's CPU features, :func:`configure` changes nothing."""
    import subprocess
    import sys

    code = ("import numba\n"
            "numba.njit(lambda v: v + 1)(1)\n"
            "from gpfverify import numba_target\n"
            "print(numba_target.configure(), numba.config.CPU_FEATURES)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False", "None"]
