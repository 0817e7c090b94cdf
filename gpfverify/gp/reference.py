"""Independent routes to the moments of a GP at a Gaussian input, used as oracles.

Both use only ``GaussianProcess.predict`` (deterministic inputs), never the closed forms:

* E[f_a] = E_x[m_a(x)],  Cov[f_a, f_b] = Cov_x[m_a(x), m_b(x)] + δ_ab E_x[σ_a²(x)],
  Cov[x, f_a] = Cov_x[x, m_a(x)]   (law of total (co)variance; independent outputs)

evaluated by tensor Gauss–Hermite quadrature or by Monte Carlo sampling of x.
"""

from __future__ import annotations

import itertools

import numpy as np

from gpfverify.gp.moments import MomentMatch


def _square_root(sigma: np.ndarray) -> np.ndarray:
    """A factor F with F Fᵀ = Σ that also works for singular Σ (eigen-decomposition)."""
    vals, vecs = np.linalg.eigh(0.5 * (sigma + sigma.T))
    return vecs * np.sqrt(np.clip(vals, 0.0, None))


def _moments_from_points(x: np.ndarray, w: np.ndarray, m: np.ndarray, v: np.ndarray) -> MomentMatch:
    """Weighted moments from points x with predictive means m and variances v."""
    mean_x = w @ x
    mean = w @ m
    dm = m - mean
    cov = (dm * w[:, None]).T @ dm + np.diag(w @ v)
    cross = ((x - mean_x) * w[:, None]).T @ dm
    return MomentMatch(mean=mean, cov=0.5 * (cov + cov.T), cross_cov=cross)


def quadrature_moments(gp, mu: np.ndarray, sigma: np.ndarray, order: int = 40) -> MomentMatch:
    """Tensor-product Gauss–Hermite quadrature with ``order`` nodes per dimension."""
    nodes, weights = np.polynomial.hermite_e.hermegauss(order)  # weight exp(−x²/2)
    weights = weights / weights.sum()
    d = mu.size
    grid = np.array(list(itertools.product(nodes, repeat=d)))
    w = np.prod(np.array(list(itertools.product(weights, repeat=d))), axis=1)
    x = mu + grid @ _square_root(sigma).T
    return _moments_from_points(x, w, *gp.predict(x))


def monte_carlo_moments(gp, mu: np.ndarray, sigma: np.ndarray, samples: int,
                        rng: np.random.Generator) -> tuple[MomentMatch, MomentMatch]:
    """Monte Carlo estimate of the moments and the standard error of each entry (delta method
    free: the standard errors are those of the sample means of the per-sample summands)."""
    x = mu + rng.standard_normal((samples, mu.size)) @ _square_root(sigma).T
    w = np.full(samples, 1.0 / samples)
    m, v = gp.predict(x)
    est = _moments_from_points(x, w, m, v)
    dm = m - est.mean
    dx = x - w @ x
    cov_terms = dm[:, :, None] * dm[:, None, :] + np.eye(m.shape[1]) * v[:, None, :]
    se = MomentMatch(mean=m.std(axis=0) / np.sqrt(samples),
                     cov=cov_terms.std(axis=0) / np.sqrt(samples),
                     cross_cov=(dx[:, :, None] * dm[:, None, :]).std(axis=0) / np.sqrt(samples))
    return est, se


def converged_quadrature_moments(gp, mu: np.ndarray, sigma: np.ndarray, rtol: float = 1e-10,
                                 max_nodes: int = 300_000) -> tuple[MomentMatch, float, int]:
    """Gauss–Hermite moments with the order raised (×1.5 from 10) until two successive rules agree
    to ``rtol`` relative, or the tensor grid would exceed ``max_nodes``.

    Returns (moments, relative change between the last two rules, last order): the change is the
    rule's own error estimate, so a caller can tell a converged oracle from an unconverged one."""
    order = 10
    previous = quadrature_moments(gp, mu, sigma, order)
    change = np.inf
    while True:
        nxt = int(np.ceil(order * 1.5))
        if nxt ** mu.size > max_nodes:
            return previous, change, order
        current = quadrature_moments(gp, mu, sigma, nxt)
        scale = max(np.abs(current.cov).max(), np.finfo(float).tiny)
        change = max(np.abs(getattr(current, k) - getattr(previous, k)).max()
                     for k in ("mean", "cov", "cross_cov")) / scale
        previous, order = current, nxt
        if change <= rtol:
            return current, change, order
