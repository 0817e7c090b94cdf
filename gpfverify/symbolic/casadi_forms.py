"""The GP-ADF and GP-UKF steps and the CMF/DMF updates as casadi ``Function`` graphs: a second,
independent implementation of the same equations (no call into the numpy code), used to
cross-check it and to differentiate the fused mean by automatic differentiation.

The formulas are written the plain way, as in the paper — determinants, ``solve`` with the
matrices as written, kernel matrices from the training data and hyperparameters — not with the
numpy implementation's scaled Cholesky factorisations, so agreement is evidence for both.

* GP moments at x ~ N(μ, Σ) (seed 000 eq. 8–11, 20), Λ_a = diag(ℓ_a²), ν_i = x_i − μ:
  q_ai = α_a² |ΣΛ_a⁻¹ + I|^{-1/2} exp(−½ ν_iᵀ(Σ + Λ_a)⁻¹ν_i), M_a = β_aᵀq_a;
  Q^{ab}_ij = k_a(x_i, μ) k_b(x_j, μ) |R|^{-1/2} exp(½ z_ijᵀR⁻¹Σ z_ij), R = Σ(Λ_a⁻¹ + Λ_b⁻¹) + I;
  Cov_ab = β_aᵀQ^{ab}β_b + δ_ab(α_a² − tr(K_a⁻¹Q^{aa})) − M_aM_b; Cov[x, f_a] = Σ(Σ + Λ_a)⁻¹ Σ_i β_ai q_ai ν_i.
* GP-ADF (Lemma 1): moments of the transition GP at the posterior + its noise, moments of the
  measurement GP at the prediction + its noise, Gaussian update.
* GP-UKF (eq. 21–31): sigma points (α, β, κ) through the GP means; Q, R = diag(latent predictive
  variance + learned noise) at μ_e(k−1) and μ_p (the interpretation documented in
  :mod:`gpfverify.filters.gp_ukf`).
* CMF (eq. 15–16) and DMF (eq. 35) with (C_xy^m)⁺ = R⁻¹Qᵀ from the thin QR factorisation
  C_xy^m = QR, i.e. for full column rank (the same matrix as (C_xyᵀC_xy)⁻¹C_xyᵀ without squaring
  the condition number, which matters as σ_min(C_xy^m) → 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np


@dataclass(frozen=True)
class GPData:
    """What defines a trained SE-ARD GP: training inputs X (n, D), targets Y (n, E),
    lengthscales (E, D), signal_var (E,), noise_var (E,)."""

    X: np.ndarray
    Y: np.ndarray
    lengthscales: np.ndarray
    signal_var: np.ndarray
    noise_var: np.ndarray

    @classmethod
    def of(cls, gp) -> GPData:
        """From any object with these attributes (e.g. :class:`~gpfverify.gp.GaussianProcess`)."""
        y = np.asarray(gp.Y, dtype=float)
        return cls(np.asarray(gp.X, float), y.reshape(len(y), -1), np.asarray(gp.lengthscales, float),
                   np.asarray(gp.signal_var, float), np.asarray(gp.noise_var, float))

    @property
    def input_dim(self) -> int:
        return self.X.shape[1]

    @property
    def output_dim(self) -> int:
        return self.Y.shape[1]


def _kernel(a, b, ell: np.ndarray, signal: float):
    """SE-ARD kernel matrix between the rows of ``a`` (m, D) and ``b`` (n, D) (casadi or numpy)."""
    total = 0
    for d in range(len(ell)):
        diff = ca.repmat(a[:, d], 1, b.shape[0]) - ca.repmat(ca.transpose(b[:, d]), a.shape[0], 1)
        total = total + diff**2 / ell[d] ** 2
    return signal * ca.exp(-0.5 * total)


@dataclass(frozen=True)
class TrainedOutput:
    """β_a = (K_a + σ²I)⁻¹ y_a and (K_a + σ²I)⁻¹ for one output, computed in casadi (DM)."""

    beta: ca.DM
    k_inv: ca.DM


def train(gp: GPData) -> list[TrainedOutput]:
    x = ca.DM(gp.X)
    out = []
    for a in range(gp.output_dim):
        k = _kernel(x, x, gp.lengthscales[a], gp.signal_var[a]) + gp.noise_var[a] * ca.DM.eye(gp.X.shape[0])
        k_inv = ca.solve(k, ca.DM.eye(gp.X.shape[0]))
        out.append(TrainedOutput(ca.solve(k, ca.DM(gp.Y[:, a])), 0.5 * (k_inv + k_inv.T)))
    return out


def moment_function(gp: GPData, name: str = "gp_moments") -> ca.Function:
    """casadi Function (μ (D,1), Σ (D,D)) -> (mean (E,1), latent cov (E,E), cross_cov (D,E))."""
    d, e, n = gp.input_dim, gp.output_dim, gp.X.shape[0]
    trained = train(gp)
    mu, sigma = ca.SX.sym("mu", d), ca.SX.sym("Sigma", d, d)
    nu = ca.DM(gp.X) - ca.repmat(ca.transpose(mu), n, 1)  # (n, D)
    eye = ca.DM.eye(d)
    means, q, k_at_mu, cross_cols = [], [], [], []
    for a in range(e):
        lam = ca.diag(ca.DM(gp.lengthscales[a] ** 2))
        lam_inv = ca.diag(ca.DM(1.0 / gp.lengthscales[a] ** 2))
        s_inv_nu = ca.solve(sigma + lam, ca.transpose(nu))  # (D, n)
        maha = ca.sum1(ca.transpose(nu) * s_inv_nu)  # (1, n)
        q_a = gp.signal_var[a] * ca.det(sigma @ lam_inv + eye) ** -0.5 * ca.exp(-0.5 * ca.transpose(maha))
        q.append(q_a)
        means.append(ca.dot(trained[a].beta, q_a))
        k_at_mu.append(gp.signal_var[a] * ca.exp(-0.5 * ca.sum2((nu @ ca.sqrt(lam_inv)) ** 2)))  # (n, 1)
        weighted = ca.transpose(nu) @ (trained[a].beta * q_a)  # Σ_i β_ai q_ai ν_i, (D, 1)
        cross_cols.append(sigma @ ca.solve(sigma + lam, weighted))
    mean = ca.vertcat(*means)
    cov = ca.SX(e, e)
    for a in range(e):
        for b in range(a, e):
            xi = ca.diag(ca.DM(1.0 / gp.lengthscales[a] ** 2 + 1.0 / gp.lengthscales[b] ** 2))
            r = sigma @ xi + eye
            t = ca.solve(r, sigma)  # R⁻¹Σ
            za = nu @ ca.diag(ca.DM(1.0 / gp.lengthscales[a] ** 2))
            zb = nu @ ca.diag(ca.DM(1.0 / gp.lengthscales[b] ** 2))
            quad_a = ca.sum2((za @ t) * za)  # (n, 1)
            quad_b = ca.sum2((zb @ t) * zb)
            exponent = (ca.repmat(quad_a, 1, n) + ca.repmat(ca.transpose(quad_b), n, 1)
                        + za @ t @ ca.transpose(zb) + za @ ca.transpose(t) @ ca.transpose(zb))
            big_q = (k_at_mu[a] @ ca.transpose(k_at_mu[b])) * ca.det(r) ** -0.5 * ca.exp(0.5 * exponent)
            second = ca.transpose(trained[a].beta) @ big_q @ trained[b].beta
            if a == b:
                second = second + gp.signal_var[a] - ca.trace(trained[a].k_inv @ big_q)
            cov[a, b] = second - means[a] * means[b]
            cov[b, a] = cov[a, b]
    return ca.Function(name, [mu, sigma], [mean, cov, ca.horzcat(*cross_cols)],
                       ["mu", "Sigma"], ["mean", "cov", "cross_cov"])


def gaussian_update_graph(mu_p, c_p, mu_y, c_y, c_xy, y):
    """μ_e = μ_p + C_xy C_y⁻¹(y − μ_y), C_e = C_p − C_xy C_y⁻¹ C_xyᵀ (eq. 15–16)."""
    gain_t = ca.solve(c_y, ca.transpose(c_xy))  # (C_xy C_y⁻¹)ᵀ
    return mu_p + ca.transpose(gain_t) @ (y - mu_y), c_p - ca.transpose(gain_t) @ ca.transpose(c_xy)


STEP_OUTPUTS = ["mu_p", "C_p", "mu_y", "C_y", "C_xy", "mu_e", "C_e"]


def gp_adf_function(transition: GPData, measurement: GPData) -> ca.Function:
    """(μ_e(k−1), C_e(k−1), y) -> (μ_p, C_p, μ_y, C_y, C_xy, μ_e, C_e), Lemma 1."""
    d, l = transition.input_dim, measurement.output_dim
    mu, cov, y = ca.SX.sym("mu_e", d), ca.SX.sym("C_e", d, d), ca.SX.sym("y", l)
    mean_t, cov_t, _ = moment_function(transition, "transition_moments")(mu, cov)
    mu_p, c_p = mean_t, cov_t + ca.diag(ca.DM(transition.noise_var))
    mu_y, cov_y, c_xy = moment_function(measurement, "measurement_moments")(mu_p, c_p)
    c_y = cov_y + ca.diag(ca.DM(measurement.noise_var))
    mu_e, c_e = gaussian_update_graph(mu_p, c_p, mu_y, c_y, c_xy, y)
    return ca.Function("gp_adf_step", [mu, cov, y], [mu_p, c_p, mu_y, c_y, c_xy, mu_e, c_e],
                       ["mu_e_prev", "C_e_prev", "y"], STEP_OUTPUTS)


def _gp_mean_and_noise(gp: GPData, trained: list[TrainedOutput], x):
    """GP mean at the columns' points x (D, 1) -> (E, 1), and diag(latent var + noise) (E, E)."""
    row = ca.transpose(x)
    means, variances = [], []
    for a in range(gp.output_dim):
        k_star = _kernel(row, ca.DM(gp.X), gp.lengthscales[a], gp.signal_var[a])  # (1, n)
        means.append(k_star @ trained[a].beta)
        variances.append(gp.signal_var[a] - k_star @ trained[a].k_inv @ ca.transpose(k_star) + gp.noise_var[a])
    return ca.vertcat(*means), ca.diag(ca.vertcat(*variances))


def _unscented(gp: GPData, trained, mean, cov, alpha: float, beta: float, kappa: float):
    """Sigma points of N(mean, cov) through the GP mean: (ȳ, C_y without noise, C_xy)."""
    d = mean.shape[0]
    lam = alpha**2 * (d + kappa) - d
    lower = ca.transpose(ca.chol((d + lam) * cov))  # columns are the sigma directions
    points = [mean] + [mean + lower[:, i] for i in range(d)] + [mean - lower[:, i] for i in range(d)]
    w_m = [lam / (d + lam)] + [0.5 / (d + lam)] * (2 * d)
    w_c = [w_m[0] + 1 - alpha**2 + beta] + w_m[1:]
    images = [_gp_mean_and_noise(gp, trained, p)[0] for p in points]
    y_bar = sum(w * y for w, y in zip(w_m, images))
    c_y = sum(w * (y - y_bar) @ ca.transpose(y - y_bar) for w, y in zip(w_c, images))
    c_xy = sum(w * (p - mean) @ ca.transpose(y - y_bar) for w, p, y in zip(w_c, points, images))
    return y_bar, c_y, c_xy


def gp_ukf_function(transition: GPData, measurement: GPData, alpha: float = 1.0, beta: float = 0.0,
                    kappa: float = 2.0) -> ca.Function:
    """(μ_e(k−1), C_e(k−1), y) -> (μ_p, C_p, μ_y, C_y, C_xy, μ_e, C_e), eq. 21–31."""
    d, l = transition.input_dim, measurement.output_dim
    mu, cov, y = ca.SX.sym("mu_e", d), ca.SX.sym("C_e", d, d), ca.SX.sym("y", l)
    trained_t, trained_m = train(transition), train(measurement)
    mu_p, c_p, _ = _unscented(transition, trained_t, mu, cov, alpha, beta, kappa)
    c_p = c_p + _gp_mean_and_noise(transition, trained_t, mu)[1]
    mu_y, c_y, c_xy = _unscented(measurement, trained_m, mu_p, c_p, alpha, beta, kappa)
    c_y = c_y + _gp_mean_and_noise(measurement, trained_m, mu_p)[1]
    mu_e, c_e = gaussian_update_graph(mu_p, c_p, mu_y, c_y, c_xy, y)
    return ca.Function("gp_ukf_step", [mu, cov, y], [mu_p, c_p, mu_y, c_y, c_xy, mu_e, c_e],
                       ["mu_e_prev", "C_e_prev", "y"], STEP_OUTPUTS)


def cmf_function(state_dim: int, total: int) -> ca.Function:
    """(μ_p, C_p, μ_y, C_y, C_xy, y) -> (μ_e, C_e), eq. 15–16 on the stacked measurement."""
    mu_p, c_p = ca.SX.sym("mu_p", state_dim), ca.SX.sym("C_p", state_dim, state_dim)
    mu_y, c_y = ca.SX.sym("mu_y", total), ca.SX.sym("C_y", total, total)
    c_xy, y = ca.SX.sym("C_xy", state_dim, total), ca.SX.sym("y", total)
    mu_e, c_e = gaussian_update_graph(mu_p, c_p, mu_y, c_y, c_xy, y)
    return ca.Function("cmf", [mu_p, c_p, mu_y, c_y, c_xy, y], [mu_e, c_e],
                       ["mu_p", "C_p", "mu_y", "C_y", "C_xy", "y"], ["mu_e", "C_e"])


#: what sensor m reports to the centre, in the order of the DMF Function's per-sensor inputs
REPORTED = ("mu_p", "mu_y", "C_y", "C_xy", "mu_e")


def dmf_function(state_dim: int, sizes: tuple[int, ...], given_pinv: tuple[int, ...] = ()) -> ca.Function:
    """Inputs: central μ_p, μ_y (L), C_y (L×L), C_xy (D×L), then per sensor m the reported
    μ_p^m, μ_y^m, C_y^m, C_xy^m, μ_e^m, and, for each sensor listed in ``given_pinv``, its
    pseudo-inverse (l_m×D) as one more input (a rank-deficient C_xy^m: the pseudo-inverse at a
    fixed numerical rank, computed outside, is a constant of the graph). Output: μ_DMF (eq. 35),
    with (C_xy^m)⁺ = R⁻¹Qᵀ from C_xy^m = QR for the other sensors."""
    d, total = state_dim, sum(sizes)
    mu_p, mu_y = ca.SX.sym("mu_p", d), ca.SX.sym("mu_y", total)
    c_y, c_xy = ca.SX.sym("C_y", total, total), ca.SX.sym("C_xy", d, total)
    gain = ca.transpose(ca.solve(c_y, ca.transpose(c_xy)))  # G = C_xy C_y⁻¹
    inputs, names, mean, start = [mu_p, mu_y, c_y, c_xy], ["mu_p", "mu_y", "C_y", "C_xy"], mu_p, 0
    for m, l in enumerate(sizes):
        local = {"mu_p": ca.SX.sym(f"mu_p{m}", d), "mu_y": ca.SX.sym(f"mu_y{m}", l),
                 "C_y": ca.SX.sym(f"C_y{m}", l, l), "C_xy": ca.SX.sym(f"C_xy{m}", d, l),
                 "mu_e": ca.SX.sym(f"mu_e{m}", d)}
        g_m = gain[:, start:start + l]
        inputs += [local[k] for k in REPORTED]
        names += [f"{k}{m}" for k in REPORTED]
        if m in given_pinv:
            a_pinv = ca.SX.sym(f"C_xy_pinv{m}", l, d)
            inputs.append(a_pinv)
            names.append(f"C_xy_pinv{m}")
        else:
            q, r = ca.qr(local["C_xy"])  # thin QR: q (D, l), r (l, l) upper triangular
            a_pinv = ca.solve(r, ca.transpose(q))
        mean = (mean + g_m @ (local["mu_y"] - mu_y[start:start + l])
                + g_m @ local["C_y"] @ a_pinv @ (local["mu_e"] - local["mu_p"]))
        start += l
    return ca.Function("dmf", inputs, [mean], names, ["mu_e"])
