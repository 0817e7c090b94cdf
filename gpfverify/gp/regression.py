"""Independent SE-ARD Gaussian-process regression per output (seed 000 §2.2, eq. 3–6).

For output a with training data (X, y_a), K_a = k_a(X, X) + σ_εa² I and β_a = K_a⁻¹ y_a:

* predictive mean   m_a(x*) = k_a(x*, X) β_a                          (eq. 5)
* predictive var    σ_a²(x*) = k_a(x*, x*) − k_a(x*, X) K_a⁻¹ k_a(X, x*)  (eq. 6, latent f)
* log evidence      −½ y_aᵀ β_a − ½ log|K_a| − n/2 log 2π

The prior mean is zero (as in Deisenroth et al. 2009 and scikit-learn with ``normalize_y=False``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from gpfverify.errors import InputError, NumericalError
from gpfverify.gp.kernels import se_ard
from gpfverify.linalg import Cholesky, all_finite, cholesky
from gpfverify.rng import generator
from gpfverify.validate import as_array, as_covariance, as_positive, as_vector
from gpfverify.runtime import one_blas_thread

_LOG_2PI = float(np.log(2.0 * np.pi))
_potrf, _potrs, _potri = sla.lapack.dpotrf, sla.lapack.dpotrs, sla.lapack.dpotri


@dataclass(frozen=True)
class FitBounds:
    """Box bounds of evidence maximisation, relative to the data (all in natural units).

    lengthscale ∈ [min_lengthscale, max_lengthscale] × (range of x_d): beyond 100 ranges an input
    is irrelevant anyway, and the bound keeps ℓ → ∞ from wandering off. signal variance ∈
    [1e-4, 1e4] × mean(y²). noise variance ≥ min_noise × mean(y²) (floor 1e-10), keeping the
    degenerate interpolating optimum σ_ε → 0 out of reach; ≤ 10 × mean(y²).
    """

    min_lengthscale: float = 1e-3
    max_lengthscale: float = 1e2
    min_signal: float = 1e-4
    max_signal: float = 1e4
    min_noise: float = 1e-8
    max_noise: float = 10.0

    def log_box(self, x: np.ndarray, y: np.ndarray) -> list[tuple[float, float]]:
        """Bounds on (log ℓ_1..log ℓ_D, log α², log σ_ε²) for one output."""
        span = np.ptp(x, axis=0)
        span = np.where(span > 0, span, 1.0)
        power = max(float(np.mean(y * y)), 1e-12)
        box = [(np.log(self.min_lengthscale * s), np.log(self.max_lengthscale * s)) for s in span]
        box.append((np.log(self.min_signal * power), np.log(self.max_signal * power)))
        box.append((np.log(max(self.min_noise * power, 1e-10)), np.log(self.max_noise * power)))
        return box


def _neg_log_evidence(theta: np.ndarray, x: np.ndarray, y: np.ndarray,
                      sq_diff: np.ndarray) -> tuple[float, np.ndarray]:
    """Negative log marginal likelihood of one output and its gradient in log parameters.

    ∂(−log p)/∂θ = −½ tr((ββᵀ − K⁻¹) ∂K/∂θ) with ∂K/∂log ℓ_d = K_f ∘ Δ_d²/ℓ_d²,
    ∂K/∂log α² = K_f, ∂K/∂log σ_ε² = σ_ε² I. ``sq_diff`` is (n, n, D) of (x_i,d − x_j,d)².

    Every n × n array is formed once, in place where it can be (this runs some fifty times per
    fit): K = ½(K_f + K_fᵀ) + σ_ε² I (the symmetrised K that :func:`~gpfverify.linalg.cholesky`
    factors, the same bits) is factored by LAPACK ``potrf`` in place, K⁻¹ by ``potri`` in place
    on the factor (its lower triangle; the upper stays the zeros ``potrf`` cleaned), and
    W = ββᵀ − K⁻¹ subtracts the lower triangle and its transpose (each entry the same IEEE
    operations as the full K⁻¹ of :meth:`~gpfverify.linalg.Cholesky.inverse` gives, x − 0 = x), the
    diagonal once. With one input dimension the scaled distances Δ²/ℓ² are a product, the one term of
    the matrix–vector product taken otherwise (the same bits). tests/test_gp_regression.py holds
    the value and gradient to the bits of the plain formulas.
    """
    n, d = x.shape
    ell2 = np.exp(2.0 * theta[:d])
    signal, noise = np.exp(theta[d]), np.exp(theta[d + 1])
    kf = sq_diff[..., 0] * (1.0 / ell2[0]) if d == 1 else sq_diff @ (1.0 / ell2)
    np.multiply(kf, -0.5, out=kf)
    np.exp(kf, out=kf)
    np.multiply(kf, signal, out=kf)  # K_f = α² exp(−½ Σ_d Δ_d²/ℓ_d²)
    k = np.add(kf, kf.T)
    k *= 0.5
    k.flat[::n + 1] += noise
    factor, info = _potrf(k.T, lower=1, clean=1, overwrite_a=1)  # k is symmetric: its transpose is it, F-ordered
    if info != 0 or not all_finite(factor):  # not positive definite at θ: a wall for the optimiser
        return 1e25, np.zeros_like(theta)
    beta, _ = _potrs(factor, y, lower=1)
    nll = 0.5 * float(y @ beta) + 0.5 * (2.0 * float(np.log(factor.diagonal()).sum())) + 0.5 * n * _LOG_2PI
    k_inv, info = _potri(factor, lower=1, overwrite_c=1)
    if info != 0:
        raise NumericalError(f"inverse from the Cholesky factor of K failed (potri info={info})")
    w = np.multiply.outer(beta, beta)  # W = ββᵀ − K⁻¹ from the lower triangle of K⁻¹
    w -= k_inv
    w -= k_inv.T
    w.flat[::n + 1] = beta * beta - k_inv.diagonal()
    wk = np.multiply(w, kf, out=kf)
    grad = np.empty_like(theta)
    grad[:d] = -0.5 * np.einsum("ij,ijd->d", wk, sq_diff) / ell2
    grad[d] = -0.5 * float(wk.sum())
    grad[d + 1] = -0.5 * noise * float(w.trace())
    return nll, grad


def _initial_guess(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Data-driven start: ℓ_d = std(x_d) (or 1), α² = mean(y²), σ_ε² = 1 % of α²."""
    std = np.std(x, axis=0)
    std = np.where(std > 0, std, 1.0)
    power = max(float(np.mean(y * y)), 1e-12)
    return np.concatenate([np.log(std), [np.log(power), np.log(0.01 * power)]])


def fit_one_output(x: np.ndarray, y: np.ndarray, restarts: int, rng: np.random.Generator,
                   bounds: FitBounds) -> np.ndarray:
    """Best log-parameters (log ℓ, log α², log σ_ε²) over ``restarts`` L-BFGS-B runs: the first
    from the data-driven guess, the others from it perturbed by N(0, 1) in log space (clipped)."""
    import scipy.optimize as sopt  # only fitting needs the optimiser (0.3 s to import)

    box = bounds.log_box(x, y)
    lo, hi = np.array([b[0] for b in box]), np.array([b[1] for b in box])
    sq_diff = (x[:, None, :] - x[None, :, :]) ** 2
    start = np.clip(_initial_guess(x, y), lo, hi)
    best_theta, best_val = start, np.inf
    for r in range(max(1, restarts)):
        theta0 = start if r == 0 else np.clip(start + rng.standard_normal(start.size), lo, hi)
        res = sopt.minimize(_neg_log_evidence, theta0, args=(x, y, sq_diff), jac=True,
                            method="L-BFGS-B", bounds=box)
        if res.fun < best_val:
            best_theta, best_val = res.x, float(res.fun)
    return best_theta


def _per_output(value, name: str, shape: tuple[int, ...]) -> np.ndarray:
    """A strictly positive hyperparameter array of ``shape``; with one output (E = 1) the leading
    axis may be omitted (``lengthscales`` (D,), a scalar variance)."""
    arr = np.asarray(value, dtype=float) if not isinstance(value, np.ndarray) else value
    if shape[0] == 1 and arr.shape == shape[1:]:
        arr = arr.reshape(shape)
    return as_positive(arr, name, shape=shape)


def checked_batch(mus, Sigmas, dim: int) -> tuple[np.ndarray, np.ndarray]:
    """Means (B, D) and covariances (B, D, D) of a batch of Gaussian inputs, each checked."""
    m = as_array(mus, "mus", shape=(None, dim))
    s = as_array(Sigmas, "Sigmas", shape=(m.shape[0], dim, dim))
    return m, np.stack([as_covariance(c, f"Sigmas[{b}]", dim) for b, c in enumerate(s)]) if len(s) else s


class GaussianProcess:
    """Independent SE-ARD GPs, one per output column of ``Y``, with fixed hyperparameters.

    Parameters
    ----------
    X : (n, D) training inputs.
    Y : (n, E) or (n,) training targets.
    lengthscales : (E, D) ℓ_a per output and input dimension.
    signal_var : (E,) α_a².
    noise_var : (E,) σ_εa².

    The Cholesky factors and K_a⁻¹ are computed once here; prediction never factorises again.
    """

    def __init__(self, X, Y, lengthscales, signal_var, noise_var):
        self.X = as_array(X, "X", ndim=2)
        n, d = self.X.shape
        if n == 0 or d == 0:
            raise InputError(f"X must have at least one row and one column, got shape {self.X.shape}")
        y = as_array(Y, "Y")
        if y.ndim == 1:
            y = y[:, None]
        if y.ndim != 2 or y.shape[0] != n:
            raise InputError(f"Y must have shape ({n},) or ({n}, E), got {np.shape(Y)}")
        self.Y = y
        e = y.shape[1]
        self.lengthscales = _per_output(lengthscales, "lengthscales", (e, d))
        self.signal_var = _per_output(signal_var, "signal_var", (e,))
        self.noise_var = _per_output(noise_var, "noise_var", (e,))
        kernels = se_ard(self.X, self.X, self.lengthscales, self.signal_var)
        kernels += self.noise_var[:, None, None] * np.eye(n)
        factors = [cholesky(kernels[a], f"K[{a}]") for a in range(e)]
        #: the factors' transposes L_aᵀ stacked, shape (E, n, n), C-ordered: column i of L_a below the
        #: diagonal is a contiguous row (how the fused moment kernel whitens); the Cholesky factors
        #: below are views of it
        self.factors_t = np.stack([c.factor.T for c in factors])
        self._chol: list[Cholesky] = [Cholesky(self.factors_t[a].T, c.jitter) for a, c in enumerate(factors)]
        #: β_a = K_a⁻¹ y_a, shape (E, n)
        self.beta = np.stack([c.solve(y[:, a]) for a, c in enumerate(self._chol)])
        #: K_a⁻¹ cached once for the trace terms of moment matching, shape (E, n, n)
        self.K_inv = np.stack([c.inverse() for c in self._chol])

    # -- construction by evidence maximisation ---------------------------------------------------
    @classmethod
    @one_blas_thread
    def fit(cls, X, Y, restarts: int = 3, seed=0, bounds: FitBounds | None = None) -> GaussianProcess:
        """Maximise the log evidence of each output independently (log-parameterised L-BFGS-B with
        analytic gradients, ``restarts`` starts, deterministic for a given ``seed``)."""
        x = as_array(X, "X", ndim=2)
        y = as_array(Y, "Y")
        y2 = y[:, None] if y.ndim == 1 else y
        if y2.ndim != 2 or y2.shape[0] != x.shape[0]:
            raise InputError(f"Y must have shape ({x.shape[0]},) or ({x.shape[0]}, E), got {y.shape}")
        if x.shape[0] < 2:
            raise InputError("fit needs at least two training points")
        bounds = bounds or FitBounds()
        rng = generator(seed)
        d = x.shape[1]
        thetas = np.stack([fit_one_output(x, y2[:, a], restarts, rng, bounds)
                           for a in range(y2.shape[1])])
        return cls(x, y2, np.exp(thetas[:, :d]), np.exp(thetas[:, d]), np.exp(thetas[:, d + 1]))

    # -- basic facts ------------------------------------------------------------------------------
    @property
    def input_dim(self) -> int:
        return self.X.shape[1]

    @property
    def output_dim(self) -> int:
        return self.Y.shape[1]

    @property
    def choleskys(self) -> tuple[Cholesky, ...]:
        """The Cholesky factorisation L_a of each K_a (+ jitter), computed once at construction."""
        return tuple(self._chol)

    @property
    def jitter(self) -> np.ndarray:
        """Jitter added to each K_a to factorise it (zeros when none was needed)."""
        return np.array([c.jitter for c in self._chol])

    def log_marginal_likelihood(self) -> float:
        """Σ_a log p(y_a | X) at the current hyperparameters."""
        n = self.X.shape[0]
        total = 0.0
        for a, c in enumerate(self._chol):
            total += -0.5 * float(self.Y[:, a] @ self.beta[a]) - 0.5 * c.logdet() - 0.5 * n * _LOG_2PI
        return total

    # -- prediction -------------------------------------------------------------------------------
    def predict(self, Xs) -> tuple[np.ndarray, np.ndarray]:
        """Latent predictive mean and variance at deterministic inputs (eq. 5–6): each (m, E)."""
        xs = as_array(Xs, "Xs")
        if xs.ndim == 1:
            xs = xs[None, :]
        if xs.ndim != 2 or xs.shape[1] != self.input_dim:
            raise InputError(f"Xs must have shape (m, {self.input_dim}), got {np.shape(Xs)}")
        ks = se_ard(xs, self.X, self.lengthscales, self.signal_var)  # (E, m, n)
        mean = np.einsum("emn,en->me", ks, self.beta)
        var = np.empty_like(mean)
        for a, c in enumerate(self._chol):
            v = c.whiten(ks[a].T)  # L⁻¹k*ᵀ
            var[:, a] = self.signal_var[a] - np.einsum("ij,ij->j", v, v)
        return mean, np.maximum(var, 0.0)

    def predict_mean(self, Xs: np.ndarray) -> np.ndarray:
        """Predictive mean only, without argument checks: the hot path of sigma-point filters.
        ``Xs`` is (m, D); returns (m, E)."""
        return np.einsum("emn,en->me", se_ard(Xs, self.X, self.lengthscales, self.signal_var), self.beta)

    def predict_uncertain(self, mu, Sigma):
        """Exact moments of f(x) for x ~ N(mu, Sigma) (eq. 8–11, 20); see
        :func:`gpfverify.gp.moments.moment_match`."""
        from gpfverify.gp.moments import moment_match

        m = as_vector(mu, "mu", self.input_dim)
        s = as_covariance(Sigma, "Sigma", self.input_dim)
        return moment_match(self, m, s)

    def predict_uncertain_batch(self, mus, Sigmas):
        """:meth:`predict_uncertain` at many inputs N(mus[b], Sigmas[b]) in one call: mus (B, D),
        Sigmas (B, D, D); the moments carry a leading batch axis (mean (B, E), cov (B, E, E),
        cross_cov (B, D, E)) and equal the single calls to rounding, at a lower cost per input."""
        from gpfverify.gp.moments import moment_match_batch

        m, s = checked_batch(mus, Sigmas, self.input_dim)
        return moment_match_batch(self, m, s)
