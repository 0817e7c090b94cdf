"""GPSR-UPF (Meng, Gao & Wang 2015, seed 001 §1.4): the unscented particle filter of
:mod:`gpfverify.filters.upf` whose per-particle proposal is a square-root UKF
(:mod:`gpfverify.filters.sr_ukf`) on the approximate model corrected by GP residuals
(:mod:`gpfverify.gp.residual`, seed 001 eq. 18–19):

    x_k = f̂(x_{k−1}, k) + GP_f(ξ_{k−1}) + ε_k,   ε_k ~ N(0, Q(x_{k−1}))
    z_k = ĥ(x_k, k) + GP_h(ζ_k) + δ_k,          δ_k ~ N(0, R_k)

Q(x) is the nominal Q with the rows and columns of the GP-corrected outputs replaced by the GP
predictive variances at ξ = (x[state_inputs], u_{k−1}) (Ko & Fox: the learned noise replaces the
nominal one); R_k likewise from the measurement GP at ζ_k = u^h_k. The same Q(x^i_{k−1}) is used
in the SR-UKF proposal of particle i and in its transition density p(x_k | x^i_{k−1}) in the
weights, so the importance weights are exact for the learned model.

Exogenous inputs: row k−1 of ``transition_inputs`` drives the step k−1 → k (inputs at the start
of the interval), row k of ``measurement_inputs`` the measurement at k. The measurement GP must use
exogenous inputs only: the UPF weights need one R per step.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import numpy as np

from gpfverify.errors import InputError
from gpfverify.filters.likelihoods import LOG_2PI
from gpfverify.filters.models import NonlinearModel
from gpfverify.filters.resampling import ParticleStepInfo
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.filters.sr_ukf import SqrtGaussian, noise_sqrt, sr_ukf_predict, sr_ukf_update
from gpfverify.linalg import cholesky_batched
from gpfverify.filters.upf import ParticleCloud, upf_step
from gpfverify.gp.residual import ResidualGP


def sr_ukf_proposal(particles: np.ndarray, sqrt_covs: np.ndarray, model: NonlinearModel, y: np.ndarray,
                    k: int, process_sqrt=None, params: SigmaParams = SigmaParams()):
    """One SR-UKF step per particle from N(x^i, S^i S^iᵀ): the UPF proposal (means (N, D), lower
    factors (N, D, D)). ``process_sqrt(particles, k) -> (N, D, D)`` gives per-particle square roots
    of a state-dependent Q; without it √Q of ``model.Q`` is shared."""
    sqrt_q = noise_sqrt(model.Q) if process_sqrt is None else process_sqrt(particles, k)
    prior, _ = sr_ukf_predict(SqrtGaussian(particles, sqrt_covs), model.f, sqrt_q, k, params)
    record = sr_ukf_update(prior, model.h, noise_sqrt(model.R), y, k, params)
    return record.mu_e, record.S_e


def batched_gaussian_logpdf(residuals: np.ndarray, covs: np.ndarray, name: str) -> np.ndarray:
    """log N(r_i; 0, C_i) for residuals (N, D) and one covariance per row (N, D, D)."""
    chol = cholesky_batched(covs, name)
    white = np.linalg.solve(chol, residuals[..., None])[..., 0]
    log_det = 2.0 * np.sum(np.log(np.diagonal(chol, axis1=-2, axis2=-1)), axis=-1)
    return -0.5 * (np.sum(white * white, axis=-1) + log_det + residuals.shape[-1] * LOG_2PI)


@dataclass(frozen=True)
class GPResidualModel:
    """Approximate model + GP residuals (either may be ``None``: no correction).

    transition_inputs (K+1, U) / measurement_inputs (K+1, U'): exogenous inputs per time index
    (``None`` when the residual uses none); extra_noise (D, D): a covariance added to Q(x) after
    the GP variances are put in (a filter tuning shared with a baseline filter), or ``None``."""

    approx: NonlinearModel
    transition: ResidualGP | None = None
    measurement: ResidualGP | None = None
    transition_inputs: np.ndarray | None = None
    measurement_inputs: np.ndarray | None = None
    extra_noise: np.ndarray | None = None

    def __post_init__(self):
        if self.measurement is not None and self.measurement.state_inputs:
            raise InputError("the measurement residual GP must use exogenous inputs only "
                             "(the UPF weights need one R per step)")

    def _u(self, table, index):
        return None if table is None else table[index]

    def f(self, x: np.ndarray, k: int) -> np.ndarray:
        out = self.approx.f(x, k)
        if self.transition is None:
            return out
        return self.transition.add_to(out, x, self._u(self.transition_inputs, k - 1))

    def h(self, x: np.ndarray, k: int) -> np.ndarray:
        out = self.approx.h(x, k)
        if self.measurement is None:
            return out
        u = self._u(self.measurement_inputs, k)
        out = np.array(out, dtype=float, copy=True)
        out[:, list(self.measurement.outputs)] += self.measurement.mean(x[:1], u)
        return out

    def process_cov(self, x_prev: np.ndarray, k: int) -> np.ndarray:
        """Q(x^i_{k−1}) per particle, (N, D, D)."""
        q = np.broadcast_to(self.approx.Q, (x_prev.shape[0],) + self.approx.Q.shape)
        if self.transition is not None:
            q = _replace_block(q, self.transition.outputs,
                               self.transition.noise_var(x_prev, self._u(self.transition_inputs, k - 1)))
        return q if self.extra_noise is None else q + self.extra_noise

    def process_sqrt(self, x_prev: np.ndarray, k: int) -> np.ndarray:
        return cholesky_batched(self.process_cov(x_prev, k), "GP process covariance")

    def measurement_cov(self, k: int) -> np.ndarray:
        """R_k, (L, L)."""
        if self.measurement is None:
            return self.approx.R
        state = np.zeros((1, self.approx.state_dim))
        var = self.measurement.noise_var(state, self._u(self.measurement_inputs, k))
        return _replace_block(self.approx.R[None], self.measurement.outputs, var)[0]

    def transition_logpdf(self, x_new: np.ndarray, x_prev: np.ndarray, k: int) -> np.ndarray:
        return batched_gaussian_logpdf(x_new - self.f(x_prev, k), self.process_cov(x_prev, k),
                                       "GP process covariance")

    def sample_transition(self, x_prev: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
        noise = np.einsum("nij,nj->ni", self.process_sqrt(x_prev, k), rng.standard_normal(x_prev.shape))
        return self.f(x_prev, k) + noise

    def at_step(self, k: int) -> NonlinearModel:
        """The model of step k as a :class:`NonlinearModel` for :func:`~gpfverify.filters.upf.upf_step`
        (R = R_k; Q the nominal summary, the exact state-dependent density in the hooks)."""
        q = self.approx.Q if self.extra_noise is None else self.approx.Q + self.extra_noise
        return NonlinearModel(self.f, self.h, q, self.measurement_cov(k),
                              transition_sampler=self.sample_transition,
                              transition_logpdf=self.transition_logpdf)


def _replace_block(covs: np.ndarray, outputs: tuple[int, ...], variances: np.ndarray) -> np.ndarray:
    """Covariances (N, D, D) with rows/columns ``outputs`` zeroed and ``variances`` (N, E) on their
    diagonal."""
    out = np.array(covs, dtype=float, copy=True)
    idx = list(outputs)
    out[:, idx, :] = 0.0
    out[:, :, idx] = 0.0
    out[:, idx, idx] = variances
    return out


def gpsr_upf_step(cloud: ParticleCloud, model: GPResidualModel, y: np.ndarray, k: int,
                  rng: np.random.Generator, params: SigmaParams = SigmaParams(),
                  resample_threshold: float = 0.5) -> tuple[ParticleCloud, ParticleStepInfo]:
    """One GPSR-UPF step: :func:`~gpfverify.filters.upf.upf_step` with the SR-UKF proposal on the
    GP-corrected model and the GP process noise of each particle."""
    proposal = partial(sr_ukf_proposal, process_sqrt=model.process_sqrt, params=params)
    return upf_step(cloud, model.at_step(k), y, k, rng, proposal=proposal,
                    resample_threshold=resample_threshold)
