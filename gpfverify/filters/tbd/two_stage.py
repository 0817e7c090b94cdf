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
from typing import cast

import numpy as np

from gpfverify.filters import runs
from gpfverify.filters.records import StepRecord
from gpfverify.filters.resampling import Particles, ParticleStep, first_run
from gpfverify.filters.tbd.model import POS, PatchSpread, TbdModel
from gpfverify.filters.tbd.pf import TbdConfig, pf_tbd_stage
from gpfverify.filters.update import condition
from gpfverify.linalg import cholesky, symmetrize


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
    along x and along y (contiguous ranges, possibly empty)."""
    r, last = config.second_stage_radius, model.grid_size - 1
    axes = []
    for coordinate in (estimate[POS[0]], estimate[POS[1]]):
        centre = int(model.nearest_cell(coordinate))
        axes.append(np.arange(max(centre - r, 0), min(centre + r, last) + 1))
    return axes[0], axes[1]


def second_stage_update(merged: np.ndarray, log_weights: np.ndarray, model: TbdModel, config: TbdConfig,
                        image: np.ndarray, estimate: np.ndarray,
                        spread: PatchSpread | None = None) -> tuple[StepRecord, np.ndarray, np.ndarray]:
    """Eq. 11–20 on the patch C around ``estimate``; returns (record, cells_x, cells_y), the
    patch's cells flattened row-major (the order of μ_y). ``log_weights`` are normalised;
    ``spread``, when given, is ``model.patch_spread(merged)`` (the PF stage's, reused).

    Only the particles whose own patch overlaps C (the set O) have h_C ≠ 0; every other particle
    has h_C = 0, so with D = [√w^i (s^i − ŝ)] (all particles) and E = [√w^i (h_C(s^i) − ẑ)] (i ∈ O),
    w_Ō = Σ_{i ∉ O} w^i and d_Ō = Σ_{i ∉ O} w^i (s^i − ŝ), the sums of the module docstring are

        ẑ = Σ_{i ∈ O} w^i h_C(s^i),   P = D Dᵀ,   P_xz = D_O Eᵀ − d_Ō ẑᵀ,   Cov(h_C) = E Eᵀ + w_Ō ẑ ẑᵀ,

    (on average under a third of the particles are in O). The Gram products are BLAS ``syrk``
    (exactly symmetric), so the update is :func:`~gpfverify.filters.update.condition`'s. The
    products are BLAS's: the command line and the Monte Carlo workers run BLAS on one thread
    (:mod:`gpfverify.runtime`), as it should be at these sizes.
    """
    axis_x, axis_y = second_stage_axes(model, config, estimate)
    cells_x, cells_y = np.repeat(axis_x, axis_y.size), np.tile(axis_y, axis_x.size)
    z = image[cells_x, cells_y]
    weights = np.exp(log_weights)
    root_w = np.sqrt(weights)
    s_hat = weights @ merged
    dev = np.subtract(merged.T, s_hat[:, None], out=np.empty(merged.shape[::-1]))  # particles last
    dev *= root_w
    P = dev @ dev.T
    if not z.size:  # the patch lies off the image: nothing is measured
        empty = np.zeros((merged.shape[1], 0))
        return StepRecord(s_hat, P, z, np.zeros((0, 0)), empty, s_hat, P), cells_x, cells_y
    spread = model.patch_spread(merged) if spread is None else spread
    inside = overlapping(model, spread, axis_x, axis_y)
    H = model.measurement_on_patch(spread, axis_x, axis_y, inside)  # (|C|, |O|)
    z_hat = H @ weights[inside]
    H -= z_hat[:, None]
    H *= root_w[inside]
    dev_inside = dev[:, inside]
    # the particles outside O: d_Ō = Σ_all − Σ_O, and w_Ō likewise
    d_out = dev @ root_w - dev_inside @ root_w[inside]
    w_out = float(weights.sum() - weights[inside].sum())
    P_xz = dev_inside @ H.T - np.outer(d_out, z_hat)
    S = H @ H.T + w_out * np.outer(z_hat, z_hat) + model.noise_std**2 * np.eye(z.size)
    return condition(s_hat, P, z_hat, S, P_xz, z), cells_x, cells_y


def overlapping(model: TbdModel, spread: PatchSpread, axis_x: np.ndarray, axis_y: np.ndarray) -> np.ndarray:
    """Indices of the particles whose own patch (centre ± p) meets the cells axis_x × axis_y
    (contiguous, non-empty ranges): the only ones whose h on those cells is not zero."""
    p = model.patch_radius
    meets = [(centre - (axis[0] - p)).view(np.uint64) <= axis[-1] - axis[0] + 2 * p  # below 0 wraps to huge
             for centre, axis in ((spread.centre_x, axis_x), (spread.centre_y, axis_y))]
    return np.flatnonzero(meets[0] & meets[1])


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
    mixture moments of the module docstring) and the second stage that produced it (one per run,
    a tuple, for a batch of runs)."""

    second_stage: SecondStage | tuple[SecondStage, ...]


def tpf_tbd_step(belief: Particles, model: TbdModel, image: np.ndarray, *, k: int = 1,
                 rng: runs.Streams, config: TbdConfig, second_rng: runs.Streams) -> TwoStageStep:
    """PF-TBD with ``rng``, then the second stage and the transfer with ``second_rng`` (separate
    streams: with ζ = 1 the step reproduces PF-TBD exactly for the same ``rng``). For B runs
    (particles (B, N_c, 5), images (B, n, n), one Generator per run in each stream) the PF stage
    runs on all runs at once and the second stage (a patch and an overlapping set of particles of
    each run's own size) run by run."""
    if belief.particles.ndim == 2:  # one run: a batch of one
        batch = Particles(belief.particles[None], belief.log_weights[None], existence=np.array([belief.existence]))
        step = tpf_tbd_step(batch, model, image[None], rng=[cast(np.random.Generator, rng)], config=config,
                            second_rng=[cast(np.random.Generator, second_rng)])
        one = first_run(step)
        return TwoStageStep(one.posterior, one.weighted, one.mean, one.cov, one.ess, one.resampled,
                            step.second_stage[0] if isinstance(step.second_stage, tuple) else step.second_stage)
    runs.check_streams(second_rng, belief.particles.shape[:-2])
    stage, spread = pf_tbd_stage(belief, model, image, rng=rng, config=config)
    size = stage.weighted.size
    stages, transferred = [], []
    for b, stream in enumerate(cast(list, second_rng)):
        merged = stage.weighted
        record, cells_x, cells_y = second_stage_update(merged.particles[b], merged.log_weights[b], model, config,
                                                       image[b], stage.mean[b], spread.run(b, size))
        particles, replaced = transfer_particles(stage.posterior.particles[b], record.mu_e, record.C_e,
                                                 config.zeta, stream)
        stages.append(SecondStage(record, cells_x, cells_y, replaced))
        transferred.append(particles)
    mu_e, C_e = np.stack([s.record.mu_e for s in stages]), np.stack([s.record.C_e for s in stages])
    zeta, gap = config.zeta, stage.mean - mu_e
    mean = zeta * stage.mean + (1.0 - zeta) * mu_e
    cov = symmetrize(zeta * stage.cov + (1.0 - zeta) * C_e + zeta * (1.0 - zeta) * gap[:, :, None] * gap[:, None, :])
    posterior = Particles.equally_weighted(np.stack(transferred), existence=stage.posterior.existence)
    return TwoStageStep(posterior, stage.weighted, mean, cov, stage.ess, stage.resampled, tuple(stages))
