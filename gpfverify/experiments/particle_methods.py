"""Run the particle filters of seed 003's experiments over a measurement sequence: bootstrap PF,
UPF, EDH and IE-PFF, each from N(prior mean, prior cov), returning the per-step estimates and the
CPU time. A filter that breaks down (non-finite particles, every weight zero, a covariance
that is not positive definite) is reported as diverged instead of ending the run."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from gpfverify.errors import GpfverifyError
from gpfverify.filters.flows import EDHBelief, edh_step, exponential_steps, ie_pff_step, uniform_steps
from gpfverify.filters.models import NonlinearModel
from gpfverify.filters.pf import pf_step
from gpfverify.filters.resampling import ParticleSet
from gpfverify.filters.upf import ParticleCloud, upf_step


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


def _prior_particles(mean, cov, count, rng):
    return rng.multivariate_normal(mean, cov, size=count, method="cholesky")


def _pf(model, mean, cov, ys, count, rng, **_):
    belief = ParticleSet.equally_weighted(_prior_particles(mean, cov, count, rng))
    out = []
    for k, y in enumerate(ys, 1):
        belief, info = pf_step(belief, model, y, k, rng)
        out.append(info.mean)
    return out


def _upf(model, mean, cov, ys, count, rng, **_):
    cloud = ParticleCloud.from_gaussian(mean, cov, count, rng)
    out = []
    for k, y in enumerate(ys, 1):
        cloud, info = upf_step(cloud, model, y, k, rng, resample_threshold=1.0)
        out.append(info.mean)
    return out


def _ie_pff(model, mean, cov, ys, count, rng, steps):
    x = _prior_particles(mean, cov, count, rng)
    out = []
    for k, y in enumerate(ys, 1):
        x, est = ie_pff_step(x, model, y, k, rng, steps)
        out.append(est.mean)
    return out


def _edh(model, mean, cov, ys, count, rng, steps):
    belief = EDHBelief(_prior_particles(mean, cov, count, rng), np.asarray(cov, dtype=float))
    out = []
    for k, y in enumerate(ys, 1):
        belief, est = edh_step(belief, model, y, k, rng, steps)
        out.append(est.mean)
    return out


METHODS = {"PF": _pf, "UPF": _upf, "EDH": _edh, "IE-PFF": _ie_pff}


def run_method(method: str, model: NonlinearModel, prior_mean, prior_cov, ys: np.ndarray, count: int,
               rng: np.random.Generator, steps: np.ndarray | None = None) -> MethodRun:
    """Filter ``ys`` (T, L) with ``count`` particles; ``steps`` are the λ-steps of the flows."""
    start = time.process_time()
    try:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            estimates = np.array(METHODS[method](model, np.asarray(prior_mean, float), prior_cov, ys,
                                                 count, rng, steps=steps))
        if not np.all(np.isfinite(estimates)):
            estimates = None
    except (GpfverifyError, np.linalg.LinAlgError):
        estimates = None
    return MethodRun(estimates, time.process_time() - start)
