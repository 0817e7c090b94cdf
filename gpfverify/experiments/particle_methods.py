"""Run the particle filters of the particle-flow paper's experiments (Zhou et al. 2020) over a
measurement sequence: bootstrap PF (resampling at every step, the SIR filter), UPF (likewise), EDH
and IE-PFF, each from the model's prior N(prior_mean, prior_cov), returning the per-step estimates
and the CPU time. A filter that breaks down (non-finite particles, every weight zero, a covariance
that is not positive definite) is reported as diverged instead of ending the run.

:func:`paired_comparison` is the decision rule of the experiments' claims (a paired t-test over
runs in which a divergence counts as a loss)."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy.stats import t as student_t

from gpfverify.contract.claims import Verdict, verdict_of
from gpfverify.contract.methods import Method
from gpfverify.contract.particle_flow import EDH, IE_PFF, PF, UPF, Spacing
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


def flow_steps(dlambda: float, spacing: Spacing, ratio: float) -> np.ndarray:
    """round(1/Δλ) λ-steps, uniform (the paper's) or growing geometrically by ``ratio``."""
    count = max(1, int(round(1.0 / dlambda)))
    return uniform_steps(count) if spacing == "uniform" else exponential_steps(count, ratio)


#: N_eff threshold of the PF and the UPF: resample at every step (SIR), as in seed 003
SIR_THRESHOLD = 1.0


def _prior_particles(model: StateSpaceModel, count: int, rng: np.random.Generator, **extras) -> Particles:
    """``count`` equally weighted draws from the model's prior (``extras``: optional fields)."""
    mean, cov = np.asarray(model.prior_mean, dtype=float), np.asarray(model.prior_cov, dtype=float)
    return Particles.equally_weighted(rng.multivariate_normal(mean, cov, size=count, method="cholesky"), **extras)


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


METHODS = {PF: _pf, UPF: _upf, EDH: _edh, IE_PFF: _ie_pff}


def run_method(method: Method, model: StateSpaceModel, ys: np.ndarray, count: int, rng: np.random.Generator,
               steps: np.ndarray | None = None) -> MethodRun:
    """Filter ``ys`` (T, L) with ``count`` particles from the model's prior; ``steps`` are the
    λ-steps of the flows."""
    start = time.process_time()
    estimates: np.ndarray | None
    try:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            estimates = np.array(METHODS[method](model, ys, count, rng, steps))
        if not np.all(np.isfinite(estimates)):
            estimates = None
    except (GpfverifyError, np.linalg.LinAlgError):
        estimates = None
    return MethodRun(estimates, time.process_time() - start)


# ----------------------------------------------------------------------------- decisions

@dataclass(frozen=True)
class Comparison:
    """Is one filter (``better``) more accurate than another, over paired runs?

    ``t`` = mean(better − worse) / its standard error over the runs where both stayed finite
    (None when undecidable or lost by divergence), ``critical`` the two-sided Student quantile it is
    compared with (held when t < −critical), ``lost`` the runs in which only ``better`` diverged."""

    verdict: Verdict
    t: float | None
    critical: float | None
    n: int
    lost: int
    evidence: str


def paired_comparison(better: tuple[float | None, ...] | list[float | None],
                      worse: tuple[float | None, ...] | list[float | None], level: float) -> Comparison:
    """Is ``better`` (per-run RMSE, None = diverged) more accurate than ``worse``?

    NOT held when ``better`` diverged in a run where ``worse`` did not; otherwise a paired t-test on
    the runs where both are finite, d = mean(better − worse) with standard error se and
    t* = the (1 − level/2) quantile of Student's t with n − 1 degrees of freedom: held when
    d < −t*·se, NOT held when d > t*·se, undecided in between."""
    lost = sum(b is None and w is not None for b, w in zip(better, worse))
    pairs = np.array([(b, w) for b, w in zip(better, worse) if b is not None and w is not None], float)
    if lost:
        return Comparison("NOT held", None, None, len(pairs), lost,
                          f"diverged in {lost} of {len(better)} runs where the other did not")
    if len(pairs) < 2:
        return Comparison("undecided", None, None, len(pairs), 0,
                          "fewer than two runs where both filters stayed finite")
    diff = pairs[:, 0] - pairs[:, 1]
    d, se = float(diff.mean()), float(diff.std(ddof=1) / np.sqrt(len(diff)))
    critical = float(student_t.ppf(1.0 - level / 2, len(diff) - 1))
    text = (f"mean per-run RMSE {pairs[:, 0].mean():.4g} vs {pairs[:, 1].mean():.4g} "
            f"(difference {d:+.3g} ± {se:.2g}, n = {len(diff)})")
    if se == 0.0:
        held = None if d == 0.0 else d < 0.0
        return Comparison(verdict_of(held), None, critical, len(diff), 0, text)
    t = d / se
    held = True if t < -critical else False if t > critical else None
    return Comparison(verdict_of(held), t, critical, len(diff), 0, text)
