"""Run the particle filters of seed 003's experiments over a measurement sequence: bootstrap PF
(resampling at every step, the SIR filter), UPF (likewise), EDH and IE-PFF, each from the model's
prior N(prior_mean, prior_cov), returning the per-step estimates and the CPU time. A filter that breaks down (non-finite particles, every weight zero, a covariance
that is not positive definite) is reported as diverged instead of ending the run."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from gpfverify.errors import GpfverifyError
from gpfverify.filters.flows import edh_step, exponential_steps, ie_pff_step, uniform_steps
from gpfverify.filters.pf import pf_step
from gpfverify.filters.resampling import Particles
from gpfverify.filters.upf import upf_step
from gpfverify.models import StateSpaceModel


@dataclass(frozen=True)
class MethodRun:
    """Estimates (T, D) (None when the filter diverged) and the CPU seconds the filter took
    (process time: robust to other load on a shared machine)."""

    estimates: np.ndarray | None
    seconds: float


def child_rng(seed_seq: np.random.SeedSequence, *key: int) -> np.random.Generator:
    """A generator for sub-stream ``key`` of a run: the same numbers however often it is asked for
    (unlike ``SeedSequence.spawn``, which advances a counter)."""
    return np.random.default_rng(np.random.SeedSequence(seed_seq.entropy,
                                                        spawn_key=(*seed_seq.spawn_key, *key)))


def flow_steps(dlambda: float, spacing: str) -> np.ndarray:
    """round(1/Δλ) λ-steps, uniform (the seed's) or exponentially spaced (ratio 1.2)."""
    count = max(1, int(round(1.0 / dlambda)))
    return uniform_steps(count) if spacing == "uniform" else exponential_steps(count)


#: N_eff threshold of the PF and the UPF: resample at every step (SIR), as in seed 003
SIR_THRESHOLD = 1.0


def _prior_particles(model: StateSpaceModel, count: int, rng: np.random.Generator, **extras) -> Particles:
    """``count`` equally weighted draws from the model's prior (``extras``: optional fields)."""
    return Particles.equally_weighted(rng.multivariate_normal(model.prior_mean, model.prior_cov, size=count,
                                                              method="cholesky"), **extras)


def _run(step, belief: Particles, model, ys, rng, **params) -> list[np.ndarray]:
    """The estimates of ``step`` over the measurements ys (T, L), k = 1 … T."""
    out = []
    for k, y in enumerate(ys, 1):
        record = step(belief, model, y, k=k, rng=rng, **params)
        belief = record.posterior
        out.append(record.mean)
    return out


def _pf(model, ys, count, rng, steps):
    return _run(pf_step, _prior_particles(model, count, rng), model, ys, rng, resample_threshold=SIR_THRESHOLD)


def _upf(model, ys, count, rng, steps):
    belief = Particles.from_gaussian(model.prior_mean, model.prior_cov, count, rng)
    return _run(upf_step, belief, model, ys, rng, resample_threshold=SIR_THRESHOLD)


def _ie_pff(model, ys, count, rng, steps):
    return _run(ie_pff_step, _prior_particles(model, count, rng), model, ys, rng, step_sizes=steps)


def _edh(model, ys, count, rng, steps):
    belief = _prior_particles(model, count, rng, ekf_cov=model.prior_cov)
    return _run(edh_step, belief, model, ys, rng, step_sizes=steps)


METHODS = {"PF": _pf, "UPF": _upf, "EDH": _edh, "IE-PFF": _ie_pff}


def run_method(method: str, model: StateSpaceModel, ys: np.ndarray, count: int, rng: np.random.Generator,
               steps: np.ndarray | None = None) -> MethodRun:
    """Filter ``ys`` (T, L) with ``count`` particles from the model's prior; ``steps`` are the
    λ-steps of the flows."""
    start = time.process_time()
    try:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            estimates = np.array(METHODS[method](model, ys, count, rng, steps))
        if not np.all(np.isfinite(estimates)):
            estimates = None
    except (GpfverifyError, np.linalg.LinAlgError):
        estimates = None
    return MethodRun(estimates, time.process_time() - start)
