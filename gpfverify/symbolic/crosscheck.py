"""casadi against numpy: the second implementation must agree with the first to rounding on
random inputs (status "checked"), and the DMF sensitivity must match its closed form and bound.

Relative error = max |casadi − numpy| / max |numpy| over every output of a case; the tolerance
is :func:`~gpfverify.tolerances.algebra_rtol` of the case's condition number (stated per check).
"""

from __future__ import annotations

import time

import numpy as np

from gpfverify.filters.gp_adf import gp_adf_step
from gpfverify.filters.gp_ukf import gp_ukf_step
from gpfverify.filters.records import Gaussian
from gpfverify.fusion import cmf_update, dmf_update
from gpfverify.fusion.exactness import kernel_split
from gpfverify.fusion.synthetic import random_case, random_spd
from gpfverify.gp import GaussianProcess
from gpfverify.models import GPModel
from gpfverify.rng import generator
from gpfverify.symbolic.casadi_forms import (STEP_OUTPUTS, GPData, cmf_function, gp_adf_function,
                                             gp_ukf_function, moment_function)
from gpfverify.symbolic.certificate import NumericalCheck
from gpfverify.symbolic.sensitivity import dmf_jacobians, dmf_sensitivity
from gpfverify.tolerances import algebra_rtol

#: (D, E) of the random GPs; state dims of the filter steps; fusion (D, sizes)
GP_SHAPES = {"small": ((1, 1), (2, 2), (3, 2)), "large": ((1, 1), (1, 3), (2, 2), (3, 2), (3, 3), (4, 2))}
STEP_DIMS = {"small": ((1, 1), (2, 2)), "large": ((1, 1), (2, 2), (2, 3), (3, 2))}
FUSION_SHAPES = {"small": ((2, (1, 2)), (3, (2, 3, 1))), "large": ((2, (1, 2)), (3, (2, 3, 1)), (3, (3, 3)),
                                                                (4, (2, 4, 1, 3)))}
CASES_PER_SHAPE = {"small": 3, "large": 10}
CROSS_CONDITIONS = (1.0, 1e2, 1e4, 1e6)
TRAINING_POINTS = 25


def relative_error(got, expected) -> float:
    expected = np.asarray(expected, dtype=float)
    got = np.asarray(got, dtype=float).reshape(expected.shape)
    return float(np.abs(got - expected).max() / max(np.abs(expected).max(), np.finfo(float).tiny))


def random_gp(rng: np.random.Generator, input_dim: int, output_dim: int) -> GaussianProcess:
    """A GP with random hyperparameters on smooth random data (no fitting: fast, and any
    hyperparameters are valid inputs to both implementations)."""
    x = rng.uniform(-2.0, 2.0, size=(TRAINING_POINTS, input_dim))
    y = np.stack([np.sin(x @ rng.normal(size=input_dim)) + 0.5 * x[:, a % input_dim]
                  for a in range(output_dim)], axis=1)
    return GaussianProcess(x, y, lengthscales=rng.uniform(0.6, 2.0, (output_dim, input_dim)),
                           signal_var=rng.uniform(0.5, 2.0, output_dim),
                           noise_var=rng.uniform(0.01, 0.1, output_dim))


def _gram_condition(gp: GaussianProcess) -> float:
    return float(max(np.linalg.cond(k_inv) for k_inv in gp.K_inv))  # cond(K) = cond(K⁻¹)


def check_gp_moments(size: str = "small", seed: int = 1) -> NumericalCheck:
    start = time.perf_counter()
    rng = generator(seed)
    worst, ok, n = 0.0, True, 0
    for d, e in GP_SHAPES[size]:
        gp = random_gp(rng, d, e)
        fn = moment_function(GPData.of(gp))
        for _ in range(CASES_PER_SHAPE[size]):
            mu, sigma = rng.normal(scale=0.7, size=d), random_spd(rng, d, 0.05) * rng.uniform(0.1, 1.0)
            mm = gp.predict_uncertain(mu, sigma)
            errors = [relative_error(c, r) for c, r in zip(fn(mu, sigma), (mm.mean, mm.cov, mm.cross_cov))]
            tol = algebra_rtol(_gram_condition(gp) * np.linalg.cond(sigma))
            ok &= max(errors) <= tol
            worst, n = max(worst, max(errors)), n + 1
    detail = (f"{n} random (GP, μ, Σ) with (D, E) ∈ {GP_SHAPES[size]}, {TRAINING_POINTS} training points, random "
              "hyperparameters: casadi graph (determinants and direct solves, β and K⁻¹ recomputed in casadi) vs "
              f"GaussianProcess.predict_uncertain (scaled Cholesky forms): worst relative error {worst:.2e}, each "
              f"within algebra_rtol(cond(K)·cond(Σ)) ({'yes' if ok else 'NO'}).")
    return NumericalCheck("casadi-gp-moments", "casadi and numpy exact GP moment matching agree to rounding",
                       "casadi Function vs numpy on random inputs", ok, detail,
                       time.perf_counter() - start)


def _check_steps(claim: str, build, reference, label: str, size: str, seed: int) -> NumericalCheck:
    start = time.perf_counter()
    rng = generator(seed)
    worst, ok, n = 0.0, True, 0
    for d, l in STEP_DIMS[size]:
        transition, measurement = random_gp(rng, d, d), random_gp(rng, d, l)
        fn = build(GPData.of(transition), GPData.of(measurement))
        model = GPModel(transition, [measurement])
        for _ in range(CASES_PER_SHAPE[size]):
            mu, cov, y = rng.normal(scale=0.7, size=d), random_spd(rng, d, 0.05), rng.normal(size=l)
            record = reference(Gaussian(mu, cov), model, y, k=1)
            errors = [relative_error(out, getattr(record, k)) for out, k in zip(fn(mu, cov, y), STEP_OUTPUTS)]
            cond = max(_gram_condition(transition), _gram_condition(measurement)) * np.linalg.cond(record.C_y)
            ok &= max(errors) <= algebra_rtol(cond)
            worst, n = max(worst, max(errors)), n + 1
    detail = (f"{n} random steps, (D, l) ∈ {STEP_DIMS[size]}, random transition and measurement GPs: every field "
              f"of the casadi {label} step (μ_p, C_p, μ_y, C_y, C_xy, μ_e, C_e) vs the numpy step: worst relative "
              f"error {worst:.2e}, each within algebra_rtol(cond(K)·cond(C_y)) ({'yes' if ok else 'NO'}).")
    return NumericalCheck(claim, f"the casadi and numpy {label} steps agree to rounding",
                       "casadi Function vs numpy on random inputs", ok, detail,
                       time.perf_counter() - start)


def check_gp_adf_step(size: str = "small", seed: int = 1) -> NumericalCheck:
    return _check_steps("casadi-gp-adf-step", gp_adf_function, gp_adf_step, "GP-ADF", size, seed)


def check_gp_ukf_step(size: str = "small", seed: int = 1) -> NumericalCheck:
    return _check_steps("casadi-gp-ukf-step", gp_ukf_function, gp_ukf_step, "GP-UKF", size, seed)


def check_cmf_dmf(size: str = "small", seed: int = 1) -> NumericalCheck:
    start = time.perf_counter()
    rng = generator(seed)
    worst, ok, n = 0.0, True, 0
    for d, sizes in FUSION_SHAPES[size]:
        cmf = cmf_function(d, sum(sizes))
        for _ in range(CASES_PER_SHAPE[size]):
            case = random_case(rng, d, sizes)
            c = case.central
            jac = dmf_jacobians(case)
            assert case.y is not None  # random_case draws a measurement by default
            reference = cmf_update(c, case.y)
            mu, cov = cmf(c.mu_p, c.C_p, c.mu_y, c.C_y, c.C_xy, case.y)
            errors = [relative_error(mu, reference.mean), relative_error(cov, reference.cov),
                      relative_error(jac.function(*jac.values), dmf_update(case).mean)]
            cross = max(np.linalg.cond(local.C_xy) for local in case.locals)
            ok &= max(errors) <= algebra_rtol(np.linalg.cond(c.C_y) * cross)
            worst, n = max(worst, max(errors)), n + 1
    detail = (f"{n} random consistent fusion cases (gpfverify.fusion.synthetic.random_case), (D, l_m) ∈ "
              f"{FUSION_SHAPES[size]}, every C_xy^m of full column rank: casadi CMF (μ_e, C_e) vs cmf_update and "
              "casadi DMF (eq. 35, (C_xy^m)⁺ = R⁻¹Qᵀ from a QR) vs dmf_update (SVD pseudo-inverse): worst relative "
              f"error {worst:.2e}, each within algebra_rtol(cond(C_y)·cond(C_xy^m)) ({'yes' if ok else 'NO'}).")
    return NumericalCheck("casadi-cmf-dmf", "the casadi and numpy CMF and DMF updates agree to rounding",
                       "casadi Function vs numpy on random inputs", ok, detail,
                       time.perf_counter() - start)


def check_dmf_sensitivity(size: str = "small", seed: int = 1) -> NumericalCheck:
    """casadi's AD Jacobians of μ_DMF against their closed forms (∂/∂μ_e^m = G_m C_y^m (C_xy^m)⁺,
    ∂/∂μ_p^m = −that, ∂/∂μ_y^m = G_m) and the bound ‖G_m C_y^m‖₂/σ_min, as σ_min → 0."""
    start = time.perf_counter()
    rng = generator(seed)
    ok, rows = True, []
    settings = [(cond, None) for cond in CROSS_CONDITIONS] + [(None, (1, 2))]  # last: rank-deficient sensors
    for cond, ranks in settings:
        case = random_case(rng, 3, (2, 3), ranks=ranks, cross_condition=cond)
        jacobians = dmf_jacobians(case).by_name
        gain = np.linalg.solve(case.central.C_y, case.central.C_xy.T).T
        begin = 0
        for m, local in enumerate(case.locals):
            l = local.C_y.shape[0]
            g_m = gain[:, begin:begin + l]
            closed = g_m @ local.C_y @ kernel_split(local.C_xy).pinv  # SVD, at the numerical rank
            jac = {k: jacobians[f"{k}{m}"] for k in ("mu_p", "mu_y", "mu_e")}
            tol = algebra_rtol(np.linalg.cond(local.C_xy) * np.linalg.cond(case.central.C_y))
            ok &= relative_error(jac["mu_e"], closed) <= tol and relative_error(jac["mu_p"], -closed) <= tol
            ok &= relative_error(jac["mu_y"], g_m) <= tol
            begin += l
        for s in dmf_sensitivity(case):
            mu_e_norm = s.jacobian_norms["mu_e"]
            assert mu_e_norm is not None  # only the C_xy entry is undefined (at a fixed rank)
            ok &= mu_e_norm <= s.mu_e_bound * (1 + algebra_rtol(1.0 / s.sigma_r))
            ok &= (s.jacobian_norms["C_xy"] is None) == (ranks is not None)
            label = f"cond {cond:g}" if ranks is None else f"ranks {ranks}"
            cxy = "undefined (fixed rank)" if s.jacobian_norms["C_xy"] is None else f"{s.jacobian_norms['C_xy']:.2e}"
            rows.append(f"{label}, sensor {s.index}: rank {s.rank}, σ_r {s.sigma_r:.1e}, ‖∂μ/∂μ_e‖ "
                        f"{s.jacobian_norms['mu_e']:.2e} ≤ bound {s.mu_e_bound:.2e}, ‖∂μ/∂C_xy‖ {cxy}")
    detail = ("Random consistent cases, D = 3, sensors with l_m = 2 and 3, C_xy^m with condition number "
              f"{', '.join(f'{c:g}' for c in CROSS_CONDITIONS)}, and one case with ranks (1, 2) (pseudo-inverse at the "
              "numerical rank held fixed): casadi AD Jacobians of μ_DMF equal the closed forms "
              "∂/∂μ_e^m = G_m C_y^m (C_xy^m)⁺, ∂/∂μ_p^m = −G_m C_y^m (C_xy^m)⁺, ∂/∂μ_y^m = G_m within "
              "algebra_rtol(cond(C_xy^m)·cond(C_y)), and ‖∂μ/∂μ_e^m‖₂ ≤ ‖G_m C_y^m‖₂/σ_r(C_xy^m) "
              f"({'yes' if ok else 'NO'}). " + "; ".join(rows) + ".")
    return NumericalCheck("dmf-sensitivity-bound",
                       "the DMF mean's sensitivity to sensor m's μ_e^m is G_m C_y^m (C_xy^m)⁺, bounded by "
                       "‖G_m C_y^m‖/σ_min(C_xy^m)",
                       "casadi automatic differentiation vs closed form", ok, detail,
                       time.perf_counter() - start)


EVIDENCE_DIMS = {"small": (1, 2), "large": (1, 2, 3)}


def check_gp_evidence(size: str = "small", seed: int = 1) -> NumericalCheck:
    """The analytic evidence gradient of ``fit`` against casadi AD, and ``fit``'s optimum against
    IPOPT started from the same point within the same box."""
    from gpfverify.gp.regression import FitBounds, _initial_guess, _neg_log_evidence, fit_one_output
    from gpfverify.symbolic.evidence import maximise_evidence, neg_log_evidence_function
    from gpfverify.tolerances import SOLVER_TOL

    start_time = time.perf_counter()
    rng = generator(seed)
    grad_ok, optimum_ok, rows = True, True, []
    for d in EVIDENCE_DIMS[size]:
        x = rng.uniform(-3.0, 3.0, size=(TRAINING_POINTS, d))
        y = np.sin(x @ rng.normal(size=d)) + 0.1 * rng.normal(size=TRAINING_POINTS)
        sq_diff = (x[:, None, :] - x[None, :, :]) ** 2
        box = FitBounds().log_box(x, y)
        lo, hi = np.array([b[0] for b in box]), np.array([b[1] for b in box])
        theta = np.clip(_initial_guess(x, y) + 0.3 * rng.normal(size=d + 2), lo, hi)
        value, grad = neg_log_evidence_function(x, y)(theta)
        ref_value, ref_grad = _neg_log_evidence(theta, x, y, sq_diff)
        grad_err = relative_error(grad, ref_grad)
        gram = (np.exp(theta[d]) * np.exp(-0.5 * sq_diff @ np.exp(-2 * theta[:d]))
                + np.exp(theta[d + 1]) * np.eye(len(y)))
        tol = algebra_rtol(np.linalg.cond(gram))
        grad_ok &= grad_err <= tol and abs(float(value) - ref_value) <= tol * abs(ref_value)
        start = np.clip(_initial_guess(x, y), lo, hi)
        ipopt = maximise_evidence(x, y, start, box)
        fitted = fit_one_output(x, y, 1, rng, FitBounds())
        fit_nll = _neg_log_evidence(fitted, x, y, sq_diff)[0]
        optimum_ok &= fit_nll <= ipopt.nll + SOLVER_TOL * max(1.0, abs(ipopt.nll))
        rows.append(f"D={d}: gradient rel. err {grad_err:.1e}; −log evidence fit {fit_nll:.6f}, IPOPT "
                    f"{ipopt.nll:.6f} ({ipopt.status})")
    ok = grad_ok and optimum_ok
    detail = (f"{TRAINING_POINTS} noisy sine points per case. (a) −log evidence and its gradient written in casadi "
              "(Cholesky log-determinant, AD gradient) vs gpfverify.gp.regression's value and analytic gradient "
              f"at a random θ: within algebra_rtol(cond(K)) relative ({'yes' if grad_ok else 'NO'}). (b) IPOPT "
              "from the same data-driven start within the same box vs fit (L-BFGS-B, one start): fit's optimum is "
              f"no worse than IPOPT's by more than SOLVER_TOL relative ({'yes' if optimum_ok else 'NO'}). "
              + "; ".join(rows) + ".")
    return NumericalCheck("casadi-gp-evidence",
                       "GP evidence maximisation (fit) agrees with casadi + IPOPT, and its analytic gradient with AD",
                       "casadi AD + IPOPT vs numpy/L-BFGS-B", ok, detail,
                       time.perf_counter() - start_time)


#: cross-check id -> function(size, seed)
CROSSCHECKS = {
    "casadi-gp-moments": check_gp_moments,
    "casadi-gp-adf-step": check_gp_adf_step,
    "casadi-gp-ukf-step": check_gp_ukf_step,
    "casadi-cmf-dmf": check_cmf_dmf,
    "dmf-sensitivity-bound": check_dmf_sensitivity,
    "casadi-gp-evidence": check_gp_evidence,
}


def run_crosschecks(size: str = "small", seed: int = 1, progress=None) -> list[NumericalCheck]:
    out = []
    for name, check in CROSSCHECKS.items():
        if progress:
            progress(f"[prove] {name} ({size}) ...")
        out.append(check(size, seed))
    return out
