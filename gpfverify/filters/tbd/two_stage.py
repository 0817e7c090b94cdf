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

from collections.abc import Sequence
from dataclasses import dataclass
from typing import cast

import numpy as np

from gpfverify.filters import runs
from gpfverify.filters.records import StepRecord
from gpfverify.filters.resampling import Particles, ParticleStep, first_run, weighted_sum
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
    (first_x, first_y), (last_x, last_y) = _patch_bounds(model, config, estimate[None])
    return np.arange(first_x[0], last_x[0] + 1), np.arange(first_y[0], last_y[0] + 1)


def _patch_bounds(model: TbdModel, config: TbdConfig, estimates: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """First and last cells, (2, B) each (rows x, y), of each run's second-stage patch: the cell
    nearest to the run's estimate (B, 5) ± r, clipped to the image (last < first: empty)."""
    centres = model.nearest_cell(estimates[:, list(POS)].T)
    r = config.second_stage_radius
    return np.maximum(centres - r, 0), np.minimum(centres + r, model.grid_size - 1)


def second_stage_update(merged: np.ndarray, log_weights: np.ndarray, model: TbdModel, config: TbdConfig,
                        image: np.ndarray, estimate: np.ndarray,
                        spread: PatchSpread | None = None) -> tuple[StepRecord, np.ndarray, np.ndarray]:
    """Eq. 11–20 on the patch C around ``estimate`` for one run (:func:`second_stage_runs` on a
    batch of one); returns (record, cells_x, cells_y), the patch's cells flattened row-major (the
    order of μ_y). ``log_weights`` are normalised; ``spread``, when given, is
    ``model.patch_spread(merged)`` (the PF stage's, reused)."""
    spread = model.patch_spread(merged) if spread is None else spread
    return second_stage_runs(merged[None], log_weights[None], model, config, image[None], estimate[None], spread)[0]


def second_stage_runs(merged: np.ndarray, log_weights: np.ndarray, model: TbdModel, config: TbdConfig,
                      images: np.ndarray, estimates: np.ndarray,
                      spread: PatchSpread) -> list[tuple[StepRecord, np.ndarray, np.ndarray]]:
    """Eq. 11–20 for B runs: merged (B, N, 5) with normalised log weights (B, N), images
    (B, n, n), the patch C_b around each run's estimate (B, 5); ``spread`` is
    ``model.patch_spread`` of all runs' merged particles in order (B·N rows). One (record,
    cells_x, cells_y) per run, the cells flattened row-major (the order of μ_y).

    Only the particles whose own patch overlaps C (the set O) have h_C ≠ 0; every other particle
    has h_C = 0, so with D = [√w^i (s^i − ŝ)] (all particles) and E = [√w^i (h_C(s^i) − ẑ)] (i ∈ O),
    w_Ō = Σ_{i ∉ O} w^i and d_Ō = Σ_{i ∉ O} w^i (s^i − ŝ), the sums of the module docstring are

        ẑ = Σ_{i ∈ O} w^i h_C(s^i),   P = D Dᵀ,   P_xz = D_O Eᵀ − d_Ō ẑᵀ,   Cov(h_C) = E Eᵀ + w_Ō ẑ ẑᵀ,

    (on average under a third of the particles are in O). Batched over the runs: ŝ, D, P, D 1_w
    (stacked products, one BLAS call per run), the overlap sets of every run (flat, run after
    run) and their h on each run's own patch (:meth:`~gpfverify.filters.tbd.model.TbdModel.measurement_on_patch`
    with a patch per particle, (2r+1)² cells each, a clipped patch's extra cells dropped after).
    Run by run (each run's |C| and |O| differ): the products with E and D_O and the update, the
    Gram products BLAS ``syrk`` (exactly symmetric), so the update is
    :func:`~gpfverify.filters.update.condition`'s. A run's products are the BLAS calls it makes
    alone, so its numbers do not depend on the batch. The products are BLAS's: the command line
    and the Monte Carlo workers run BLAS on one thread (:mod:`gpfverify.runtime`), as it should be
    at these sizes.
    """
    runs_, count = log_weights.shape
    (first_x, first_y), (last_x, last_y) = _patch_bounds(model, config, estimates)
    size_x, size_y = np.maximum(last_x - first_x + 1, 0), np.maximum(last_y - first_y + 1, 0)
    weights = np.exp(log_weights)
    root_w = np.sqrt(weights)
    s_hat = weighted_sum(weights, merged)
    dev = np.subtract(merged.swapaxes(-1, -2), s_hat[:, :, None], out=np.empty((runs_, merged.shape[-1], count)))
    dev *= root_w[:, None, :]  # particles last
    P = dev @ dev.swapaxes(-1, -2)
    measured = (size_x > 0) & (size_y > 0)
    inside = _overlapping_runs(model, spread, first_x, last_x, first_y, last_y, measured, count)
    run_of = inside // count
    ends = np.cumsum(np.bincount(run_of, minlength=runs_)).tolist()
    width = 2 * config.second_stage_radius + 1
    offsets = np.arange(width)[:, None]
    patches = model.measurement_on_patch(spread, first_x[run_of] + offsets, first_y[run_of] + offsets,
                                         inside).reshape(width, width, inside.size)
    flat_w, flat_root = weights.reshape(-1), root_w.reshape(-1)
    w_inside, root_inside = flat_w[inside], flat_root[inside]
    # D_O of every run, (5, Σ|O|) in Fortran order (as dev[:, O] of one run): entry (k, q) is dev at run
    # run_of[q], row k, particle inside[q] − run_of[q]·N
    rows = np.arange(dev.shape[1]) * count
    dev_inside = dev.reshape(-1)[(inside + run_of * ((dev.shape[1] - 1) * count))[:, None] + rows].T
    dev_total = (dev @ root_w[:, :, None])[:, :, 0]
    w_total = weights.sum(axis=-1)
    out = []
    for b in range(runs_):
        if not measured[b]:  # the patch lies off the image: nothing is measured
            empty = np.zeros(0, dtype=np.int64)
            out.append((StepRecord(s_hat[b], P[b], np.zeros(0), np.zeros((0, 0)), np.zeros((merged.shape[-1], 0)),
                                   s_hat[b], P[b]), empty, empty))
            continue
        start, end = (ends[b - 1] if b else 0), ends[b]
        nx, ny = int(size_x[b]), int(size_y[b])
        H = patches[:nx, :ny, start:end].reshape(nx * ny, end - start)  # (|C|, |O|)
        w_in, root_in, dev_in = w_inside[start:end], root_inside[start:end], dev_inside[:, start:end]
        z_hat = H @ w_in
        H -= z_hat[:, None]
        H *= root_in
        # the particles outside O: d_Ō = Σ_all − Σ_O, and w_Ō likewise
        d_out = dev_total[b] - dev_in @ root_in
        w_out = float(w_total[b] - w_in.sum())
        P_xz = dev_in @ H.T - np.outer(d_out, z_hat)
        S = H @ H.T + w_out * np.outer(z_hat, z_hat) + model.noise_std**2 * np.eye(nx * ny)
        z = images[b, first_x[b]:last_x[b] + 1, first_y[b]:last_y[b] + 1].reshape(-1)
        cells_x, cells_y = np.indices((nx, ny)).reshape(2, -1)
        cells_x += first_x[b]
        cells_y += first_y[b]
        out.append((condition(s_hat[b], P[b], z_hat, S, P_xz, z), cells_x, cells_y))
    return out


def overlapping(model: TbdModel, spread: PatchSpread, axis_x: np.ndarray, axis_y: np.ndarray) -> np.ndarray:
    """Indices of the particles whose own patch (centre ± p) meets the cells axis_x × axis_y
    (contiguous, non-empty ranges): the only ones whose h on those cells is not zero."""
    first_x, last_x, first_y, last_y = (np.array([cell]) for cell in (axis_x[0], axis_x[-1], axis_y[0], axis_y[-1]))
    return _overlapping_runs(model, spread, first_x, last_x, first_y, last_y, np.ones(1, dtype=bool),
                             spread.amplitude.size)


def _overlapping_runs(model: TbdModel, spread: PatchSpread, first_x: np.ndarray, last_x: np.ndarray,
                      first_y: np.ndarray, last_y: np.ndarray, measured: np.ndarray, count: int) -> np.ndarray:
    """:func:`overlapping` for B runs of ``count`` particles each (``spread`` of all of them in
    order), run b's patch the cells first_x[b] … last_x[b] × first_y[b] … last_y[b]: the indices
    into the B·count particles, run after run; none of a run that is not ``measured``."""
    p = model.patch_radius
    meets = measured[:, None]
    for centre, first, last in ((spread.centre_x, first_x, last_x), (spread.centre_y, first_y, last_y)):
        offset = (centre.reshape(-1, count) - (first - p)[:, None]).view(np.uint64)  # below 0 wraps to huge
        meets = meets & (offset <= (last - first + 2 * p).astype(np.uint64)[:, None])
    return np.flatnonzero(meets)


def transfer_particles(particles: np.ndarray, posterior_mean: np.ndarray, posterior_cov: np.ndarray,
                       zeta: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 21 for one run (:func:`transfer_runs` on a batch of one): particle i becomes a draw
    from N(mean, cov) when e_i > ζ, e_i ~ U[0, 1). Returns (new particles, boolean mask of the
    replaced ones)."""
    out, replaced = transfer_runs(particles[None], posterior_mean[None], posterior_cov[None], zeta, [rng])
    return out[0], replaced[0]


def transfer_runs(particles: np.ndarray, posterior_mean: np.ndarray, posterior_cov: np.ndarray, zeta: float,
                  rng: Sequence[np.random.Generator]) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 21 for B runs: particles (B, N, 5), each run's N(mean, cov) (B, 5) and (B, 5, 5), one
    Generator per run. Each run draws its e_i (N uniforms), then n_b = #{e_i > ζ} standard normal
    rows, as alone; the draws x = mean + L ε (L the Cholesky factor of the run's cov) of all runs
    are written at once. Returns (new particles, replaced mask (B, N))."""
    replaced = runs.random(rng, particles.shape[1:2]) > zeta
    out = particles.copy()
    counts = np.count_nonzero(replaced, axis=1).tolist()
    draws = [posterior_mean[b] + stream.standard_normal((n, particles.shape[-1]))
             @ cholesky(posterior_cov[b], "second-stage posterior covariance").factor.T
             for b, (stream, n) in enumerate(zip(rng, counts)) if n]
    if draws:
        out[replaced] = np.concatenate(draws)
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
    (particles (B, N_c, 5), images (B, n, n), one Generator per run in each stream) the PF stage,
    the second stage (:func:`second_stage_runs`: a patch and an overlapping set of particles of each
    run's own size, as flat arrays) and the transfer (:func:`transfer_runs`) run on all runs at once;
    each run's numbers are those it gets alone."""
    if belief.particles.ndim == 2:  # one run: a batch of one
        batch = Particles(belief.particles[None], belief.log_weights[None], existence=np.array([belief.existence]))
        step = tpf_tbd_step(batch, model, image[None], rng=[cast(np.random.Generator, rng)], config=config,
                            second_rng=[cast(np.random.Generator, second_rng)])
        one = first_run(step)
        return TwoStageStep(one.posterior, one.weighted, one.mean, one.cov, one.ess, one.resampled,
                            step.second_stage[0] if isinstance(step.second_stage, tuple) else step.second_stage)
    runs.check_streams(second_rng, belief.particles.shape[:-2])
    stage, spread = pf_tbd_stage(belief, model, image, rng=rng, config=config)
    merged = stage.weighted
    updates = second_stage_runs(merged.particles, merged.log_weights, model, config, image, stage.mean, spread)
    mu_e, C_e = np.stack([record.mu_e for record, _, _ in updates]), np.stack([record.C_e for record, _, _ in updates])
    transferred, replaced = transfer_runs(stage.posterior.particles, mu_e, C_e, config.zeta,
                                          cast(Sequence[np.random.Generator], second_rng))
    stages = tuple(SecondStage(record, cells_x, cells_y, replaced[b])
                   for b, (record, cells_x, cells_y) in enumerate(updates))
    zeta, gap = config.zeta, stage.mean - mu_e
    mean = zeta * stage.mean + (1.0 - zeta) * mu_e
    cov = symmetrize(zeta * stage.cov + (1.0 - zeta) * C_e + zeta * (1.0 - zeta) * gap[:, :, None] * gap[:, None, :])
    posterior = Particles.equally_weighted(transferred, existence=stage.posterior.existence)
    return TwoStageStep(posterior, stage.weighted, mean, cov, stage.ess, stage.resampled, tuple(stages))
