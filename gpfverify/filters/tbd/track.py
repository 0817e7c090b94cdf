"""Run PF-TBD or TPFTBD over an image sequence (a thin iterator over the step functions)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gpfverify.errors import InputError
from gpfverify.filters.resampling import ParticleStep
from gpfverify.filters.tbd.model import STATE_DIM, TbdModel
from gpfverify.filters.tbd.pf import TbdConfig, initial_belief, pf_tbd_step
from gpfverify.filters.tbd.two_stage import tpf_tbd_step
from gpfverify.rng import generator


@dataclass(frozen=True)
class TbdTrack:
    """Per frame: existence probability P_k (K,), estimate ŝ_k (K, 5) (conditional on existence)
    and the effective sample size of the weighted set as a fraction of its size, N_eff/N (K,); with
    a leading run axis (B, K), (B, K, 5), (B, K) for a batch of runs."""

    existence: np.ndarray
    estimates: np.ndarray
    ess_fraction: np.ndarray


def filter_sequence(images, model: TbdModel, config: TbdConfig, rng, second_rng=None) -> TbdTrack:
    """Filter ``images`` (K, n, n) from P_0 = 0; or the sequences (B, K, n, n) of B runs together,
    with one Generator (or seed) per run in ``rng`` and ``second_rng`` (:mod:`gpfverify.filters.runs`).

    ``rng`` drives the PF part (initial set, births, propagation, resampling); ``second_rng`` the
    transfer of TPFTBD (``config.two_stage``). Keeping the streams apart makes TPFTBD with ζ = 1
    reproduce PF-TBD exactly for the same ``rng``.
    """
    n = model.grid_size
    images = np.asarray(images, dtype=float)
    if images.ndim not in (3, 4) or images.shape[-2:] != (n, n):
        raise InputError(f"images must have shape (K, {n}, {n}) or (runs, K, {n}, {n}), got {images.shape}")
    if not np.all(np.isfinite(images)):
        raise InputError("images contain NaN or inf")
    batch = images.ndim == 4
    rng = _streams(rng, batch, images.shape[0], "rng")
    if config.two_stage:
        if second_rng is None:
            raise InputError("second_rng is required when config.two_stage is set")
        second_rng = _streams(second_rng, batch, images.shape[0], "second_rng")
    belief = initial_belief(model, config, rng)
    frames = images.shape[-3]
    lead = images.shape[:-3]
    existence = np.empty(lead + (frames,))
    estimates = np.empty(lead + (frames, STATE_DIM))
    ess_fraction = np.empty(lead + (frames,))
    for k in range(frames):
        image = images[..., k, :, :]
        step: ParticleStep
        if config.two_stage:
            step = tpf_tbd_step(belief, model, image, k=k + 1, rng=rng, config=config, second_rng=second_rng)
        else:
            step = pf_tbd_step(belief, model, image, k=k + 1, rng=rng, config=config)
        belief = step.posterior
        existence[..., k] = belief.existence
        estimates[..., k, :] = step.mean
        ess_fraction[..., k] = np.asarray(step.ess) / step.weighted.size
    return TbdTrack(existence, estimates, ess_fraction)


def _streams(rng, batch: bool, runs: int, name: str):
    """One Generator (from a seed or Generator) for one run; one per run for a batch."""
    if not batch:
        return generator(rng)
    streams = [generator(g) for g in rng]
    if len(streams) != runs:
        raise InputError(f"{name}: {runs} image sequences need {runs} generators, got {len(streams)}")
    return streams
