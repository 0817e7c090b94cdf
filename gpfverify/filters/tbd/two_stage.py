"""TPFTBD: PF-TBD followed by a Kalman-type second measurement update (seed 004 §2, steps ⑦–⑪).

After the PF step (:func:`~gpfverify.filters.tbd.pf.pf_tbd_step`), from the merged weighted set
{s^i, w^i} of step ④ (eq. 11–17):

    ŝ = Σ w^i s^i,                          ẑ = Σ w^i h_C(s^i),
    P = Σ w^i (s^i − ŝ)(s^i − ŝ)ᵀ,          P_xz = Σ w^i (s^i − ŝ)(h_C(s^i) − ẑ)ᵀ,
    S = Σ w^i (h_C(s^i) − ẑ)(h_C(s^i) − ẑ)ᵀ + σ² I,

where h_C is the point-spread measurement on the fixed patch C of the image centred on the cell
nearest to the PF estimate (``TbdConfig.second_stage_radius``); then (eq. 18–20)

    K = P_xz S⁻¹,   ŝ⁺ = ŝ + K (z_C − ẑ),   P⁺ = P − K S Kᵀ.

Finally (eq. 21) each resampled particle i is replaced by a draw from N(ŝ⁺, P⁺) when its uniform
draw e_i ~ U[0, 1) exceeds ζ; ζ = 1 leaves the PF unchanged. The transferred set is thus drawn
from the mixture ζ p_PF + (1 − ζ) N(ŝ⁺, P⁺), whose mean and covariance are the step's estimate:

    x̂ = ζ ŝ + (1 − ζ) ŝ⁺,   P̂ = ζ P + (1 − ζ) P⁺ + ζ (1 − ζ) (ŝ − ŝ⁺)(ŝ − ŝ⁺)ᵀ.

P⁺ is the Schur complement of a weighted sample covariance plus σ²I, hence positive semidefinite
by construction (it is symmetrised against rounding).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gpfverify.filters.records import StepRecord
from gpfverify.filters.resampling import Particles, ParticleStep
from gpfverify.filters.tbd.model import POS, PatchSpread, TbdModel
from gpfverify.filters.tbd.pf import TbdConfig, pf_tbd_stage
from gpfverify.linalg import cholesky, right_solve_spd, symmetrize


@dataclass(frozen=True)
class SecondStage:
    """The Kalman-type update (``record``: μ_p = ŝ, C_p = P, μ_y = ẑ, C_y = S, C_xy = P_xz,
    μ_e = ŝ⁺, C_e = P⁺), the image cells it used, and which particles were replaced."""

    record: StepRecord
    cells_x: np.ndarray
    cells_y: np.ndarray
    replaced: np.ndarray


def second_stage_axes(model: TbdModel, config: TbdConfig, estimate: np.ndarray):
    """Cells of the (2r+1)² patch around the cell nearest to the estimate, clipped to the image,
    along x and along y."""
    offsets = np.arange(-config.second_stage_radius, config.second_stage_radius + 1)
    axes = []
    for coordinate in (estimate[POS[0]], estimate[POS[1]]):
        cells = model.nearest_cell(coordinate) + offsets
        axes.append(cells[(cells >= 0) & (cells < model.grid_size)])
    return axes[0], axes[1]


def second_stage_update(merged: np.ndarray, log_weights: np.ndarray, model: TbdModel, config: TbdConfig,
                        image: np.ndarray, estimate: np.ndarray,
                        spread: PatchSpread | None = None) -> tuple[StepRecord, np.ndarray, np.ndarray]:
    """Eq. 11–20 on the patch around ``estimate``; returns (record, cells_x, cells_y), the patch's
    cells flattened row-major (the order of μ_y). ``spread``, when given, is
    ``model.patch_spread(merged)`` (the PF stage's, reused).

    The weighted moments of the joint sample [s^i, h_C(s^i)] give ŝ, ẑ, P, P_xz and Cov(h_C):
    with the deviations scaled by √w^i in place, the covariance is one Gram product DᵀD (BLAS
    ``syrk``, exactly symmetric). The product is BLAS's: the command line and the Monte Carlo
    workers run BLAS on one thread (:mod:`gpfverify.runtime`), as it should be at these sizes.
    """
    axis_x, axis_y = second_stage_axes(model, config, estimate)
    cells_x, cells_y = (c.ravel() for c in np.meshgrid(axis_x, axis_y, indexing="ij"))
    z = image[cells_x, cells_y]
    weights = np.exp(log_weights)
    d = merged.shape[1]
    joint = np.empty((d + z.size, merged.shape[0]))  # particles last: rows [s; h_C]
    joint[:d] = merged.T
    model.measurement_on_patch(merged, axis_x, axis_y, spread, out=joint[d:])
    joint_mean = joint @ weights
    joint -= joint_mean[:, None]
    joint *= np.sqrt(weights)
    joint_cov = joint @ joint.T
    s_hat, z_hat = joint_mean[:d], joint_mean[d:]
    P, P_xz = joint_cov[:d, :d], joint_cov[:d, d:]
    S = joint_cov[d:, d:] + model.noise_std**2 * np.eye(z.size)
    K = right_solve_spd(P_xz, S, "second-stage innovation covariance S")
    mean = s_hat + K @ (z - z_hat)
    cov = symmetrize(P - K @ P_xz.T)
    return StepRecord(s_hat, P, z_hat, S, P_xz, mean, cov), cells_x, cells_y


def transfer_particles(particles: np.ndarray, posterior_mean: np.ndarray, posterior_cov: np.ndarray,
                       zeta: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 21: particle i becomes a draw from N(mean, cov) when e_i > ζ, e_i ~ U[0, 1).
    Returns (new particles, boolean mask of the replaced ones)."""
    replaced = np.asarray(rng.random(particles.shape[0]) > zeta)
    out = particles.copy()
    n = int(replaced.sum())
    if n:
        factor = cholesky(posterior_cov, "second-stage posterior covariance").factor
        out[replaced] = posterior_mean + rng.standard_normal((n, particles.shape[1])) @ factor.T
    return out, replaced


@dataclass(frozen=True)
class TwoStageStep(ParticleStep):
    """A TPFTBD step: the :class:`~gpfverify.filters.resampling.ParticleStep` (``weighted`` the
    merged set of the PF stage, ``posterior`` the transferred particles, ``mean``/``cov`` the
    mixture moments of the module docstring) and the second stage that produced it."""

    second_stage: SecondStage


def tpf_tbd_step(belief: Particles, model: TbdModel, image: np.ndarray, *, k: int = 1,
                 rng: np.random.Generator, config: TbdConfig, second_rng: np.random.Generator) -> TwoStageStep:
    """PF-TBD with ``rng``, then the second stage and the transfer with ``second_rng`` (separate
    streams: with ζ = 1 the step reproduces PF-TBD exactly for the same ``rng``)."""
    step, spread = pf_tbd_stage(belief, model, image, rng=rng, config=config)
    record, cells_x, cells_y = second_stage_update(step.weighted.particles, step.weighted.log_weights, model,
                                                   config, image, step.mean, spread)
    particles, replaced = transfer_particles(step.posterior.particles, record.mu_e, record.C_e,
                                             config.zeta, second_rng)
    zeta, gap = config.zeta, step.mean - record.mu_e
    mean = zeta * step.mean + (1.0 - zeta) * record.mu_e
    cov = symmetrize(zeta * step.cov + (1.0 - zeta) * record.C_e + zeta * (1.0 - zeta) * np.outer(gap, gap))
    posterior = Particles.equally_weighted(particles, existence=step.posterior.existence)
    return TwoStageStep(posterior, step.weighted, mean, cov, step.ess, step.resampled,
                        SecondStage(record, cells_x, cells_y, replaced))
