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
from functools import cached_property, partial

import numpy as np

from gpfverify.errors import InputError
from gpfverify.filters.likelihoods import batched_gaussian_logpdf
from gpfverify.filters.resampling import RESAMPLE_THRESHOLD, Particles, ParticleStep
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.filters.sr_ukf import SqrtGaussian, noise_sqrt, sr_ukf_predict, sr_ukf_update
from gpfverify.filters.upf import upf_step
from gpfverify.gp.residual import ResidualGP
from gpfverify.linalg import cholesky_batched
from gpfverify.models import Sensor, StateSpaceModel


def sr_ukf_proposal(belief: Particles, model, y: np.ndarray, *, k: int = 1, process_sqrt=None,
                    params: SigmaParams = SigmaParams()) -> tuple[np.ndarray, np.ndarray]:
    """One SR-UKF step per particle from N(x^i, S^i S^iᵀ): the UPF proposal (means (N, D), lower
    factors (N, D, D)). ``process_sqrt(particles, k) -> (N, D, D)`` gives per-particle square roots
    of a state-dependent Q; without it √Q of ``model.Q`` is shared. Angle outputs and state
    components of the model are handled as in the SR-UKF."""
    if belief.sqrt_covs is None:
        raise InputError("belief.sqrt_covs: the SR-UKF proposal needs each particle's covariance factor "
                         "(Particles.from_gaussian gives the prior's)")
    sqrt_q = noise_sqrt(model.Q) if process_sqrt is None else process_sqrt(belief.particles, k)
    prior, _ = sr_ukf_predict(SqrtGaussian(belief.particles, belief.sqrt_covs), model.f, sqrt_q, k, params,
                              model.circular_state)
    record = sr_ukf_update(prior, model.h, noise_sqrt(model.R), y, k, params, model.circular,
                           model.circular_state)
    return record.mu_e, record.S_e


@dataclass(frozen=True)
class GPResidualModel:
    """Approximate model + GP residuals (either may be ``None``: no correction).

    transition_inputs (K+1, U) / measurement_inputs (K+1, U'): exogenous inputs per time index
    (``None`` when the residual uses none); extra_noise (D, D): a covariance added to Q(x) after
    the GP variances are put in (a filter tuning shared with a baseline filter), or ``None``."""

    approx: StateSpaceModel
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

    @cached_property
    def model(self) -> StateSpaceModel:
        """The GP-corrected model as one :class:`~gpfverify.models.StateSpaceModel` (built and
        probed once): f and h above, the nominal summary Q (+ extra_noise) and R of step 1, the
        approximate model's prior and angle components, the exact state-dependent transition
        density in the sampler and log-density hooks."""
        q = self.approx.Q if self.extra_noise is None else self.approx.Q + self.extra_noise
        sensor = Sensor(self.h, self.measurement_cov(1), circular=self.approx.circular)
        return StateSpaceModel(self.f, q, [sensor], self.approx.prior_mean, self.approx.prior_cov,
                               circular_state=self.approx.circular_state,
                               transition_sampler=self.sample_transition,
                               transition_logpdf=self.transition_logpdf, name="GP-corrected model")

    def at_step(self, k: int) -> StateSpaceModel:
        """The model of step k for :func:`~gpfverify.filters.upf.upf_step`: :attr:`model` with
        R = R_k (:meth:`~gpfverify.models.StateSpaceModel.with_noise`, no new probing)."""
        if self.measurement is None:
            return self.model
        return self.model.with_noise(noise_covs=[self.measurement_cov(k)])


def _replace_block(covs: np.ndarray, outputs: tuple[int, ...], variances: np.ndarray) -> np.ndarray:
    """Covariances (N, D, D) with rows/columns ``outputs`` zeroed and ``variances`` (N, E) on their
    diagonal."""
    out = np.array(covs, dtype=float, copy=True)
    idx = list(outputs)
    out[:, idx, :] = 0.0
    out[:, :, idx] = 0.0
    out[:, idx, idx] = variances
    return out


def gpsr_upf_step(belief: Particles, model: GPResidualModel, y: np.ndarray, *, k: int = 1,
                  rng: np.random.Generator, params: SigmaParams = SigmaParams(),
                  resample_threshold: float = RESAMPLE_THRESHOLD) -> ParticleStep:
    """One GPSR-UPF step: :func:`~gpfverify.filters.upf.upf_step` with the SR-UKF proposal on the
    GP-corrected model and the GP process noise of each particle. One run at a time: its cost is the
    GP's predictive variance at every particle, which advancing runs together would not reduce."""
    if np.ndim(belief.particles) != 2:
        raise InputError("GPSR-UPF takes one run at a time: particles (N, D) (the GP-corrected model's functions "
                         "take particles as rows of one run)")
    proposal = partial(sr_ukf_proposal, process_sqrt=model.process_sqrt, params=params)
    return upf_step(belief, model.at_step(k), y, k=k, rng=rng, proposal=proposal,
                    resample_threshold=resample_threshold)
