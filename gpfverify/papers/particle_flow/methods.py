"""Run the particle filters of the particle-flow paper's experiments (Zhou et al. 2020) over a
measurement sequence: bootstrap PF (resampling at every step, the SIR filter), UPF (likewise), EDH
and IE-PFF, each from the model's prior N(prior_mean, prior_cov), returning the per-step estimates
and the CPU time (and, for the weighted filters, N_eff/N per step). A filter that breaks down
(non-finite particles, every weight zero, a covariance that is not positive definite) is reported
as diverged instead of ending the run.

:func:`paired_comparison` is the decision rule of the experiments' claims (a paired t-test over
runs in which a divergence counts as a loss), :func:`ratio_comparison` its form for "within a factor
of"; :func:`divergence_health` and :func:`ess_health` are
the health checks (:mod:`gpfverify.health`) the claims apply before a verdict stands."""

from __future__ import annotations

import time
from collections.abc import Sequence
import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.stats import t as student_t

from gpfverify.contract.claims import Verdict, verdict_of
from gpfverify.contract.methods import Method
from gpfverify.papers.particle_flow.contract import EDH, FLOWS, IE_PFF, PF, UPF, Spacing
from gpfverify.errors import GpfverifyError
from gpfverify.filters.flows import edh_step, exponential_steps, ie_pff_step, uniform_steps
from gpfverify.filters.pf import pf_step
from gpfverify.filters.resampling import Particles
from gpfverify.filters.upf import upf_step
from gpfverify.health import HealthCheck, divergence_check, ess_check
from gpfverify.models import StateSpaceModel


@dataclass(frozen=True)
class MethodRun:
    """Estimates (T, D) (None when the filter diverged), the CPU seconds the filter took
    (process time: robust to other load on a shared machine; for runs filtered together, the
    batch's CPU seconds divided by its runs) and, for the PF and the UPF, N_eff/N of the weighted
    set per step (None for the flows, which do not weight, and when diverged)."""

    estimates: np.ndarray | None
    seconds: float
    ess_fraction: np.ndarray | None = None


def flow_steps(dlambda: float, spacing: Spacing, ratio: float, exponential_count: int = 0) -> np.ndarray:
    """The λ-steps of a flow: round(1/Δλ) equal steps (``uniform``, the paper's) or steps growing
    geometrically by ``ratio`` (``exponential``), as many as the uniform schedule has or, when
    ``exponential_count`` > 0, that many (Li & Coates 2017: 29 steps, ratio 1.2, whatever Δλ)."""
    count = max(1, int(round(1.0 / dlambda)))
    if spacing == "uniform":
        return uniform_steps(count)
    return exponential_steps(exponential_count if exponential_count > 0 else count, ratio)


def schedule_words(dlambda: float, spacing: Spacing, ratio: float, exponential_count: int = 0) -> str:
    """The λ schedule of :func:`flow_steps` in words ("Δλ = 0.1, uniform λ-steps")."""
    if spacing == "uniform":
        return f"Δλ = {dlambda:g}, uniform λ-steps"
    count = exponential_count if exponential_count > 0 else max(1, int(round(1.0 / dlambda)))
    first = float(flow_steps(dlambda, spacing, ratio, exponential_count)[0])
    return f"{count} exponential λ-steps (ratio {ratio:g}, first {first:.2g})"


#: how a run's CPU seconds are measured when runs are filtered together (every timing claim states it)
#: N_eff threshold of the PF and the UPF: resample at every step (SIR), as in seed 003
SIR_THRESHOLD = 1.0


def _prior_particles(model: StateSpaceModel, count: int, rngs: list[np.random.Generator], **extras) -> Particles:
    """``count`` equally weighted draws from the model's prior per run, (B, N, D) (``extras``:
    optional fields)."""
    mean, cov = np.asarray(model.prior_mean, dtype=float), np.asarray(model.prior_cov, dtype=float)
    return Particles.equally_weighted(np.stack([g.multivariate_normal(mean, cov, size=count, method="cholesky")
                                                for g in rngs]), **extras)


def _run(step, belief: Particles, model, ys, rngs, **params) -> tuple[np.ndarray, np.ndarray]:
    """The estimates (B, T, D) of ``step`` over the measurements ys (B, T, L) of B runs,
    k = 1 … T, and N_eff/N per step (B, T)."""
    out, ess = [], []
    for k in range(1, ys.shape[1] + 1):
        record = step(belief, model, ys[:, k - 1], k=k, rng=rngs, **params)
        belief = record.posterior
        out.append(record.mean)
        ess.append(np.asarray(record.ess) / record.weighted.size)
    return np.stack(out, axis=1), np.stack(ess, axis=1)


def _pf(model, ys, count, rngs, steps):
    return _run(pf_step, _prior_particles(model, count, rngs), model, ys, rngs, resample_threshold=SIR_THRESHOLD)


def _upf(model, ys, count, rngs, steps):
    belief = Particles.from_gaussian(model.prior_mean, model.prior_cov, count, rngs)
    return _run(upf_step, belief, model, ys, rngs, resample_threshold=SIR_THRESHOLD)


def _ie_pff(model, ys, count, rngs, steps):
    return _run(ie_pff_step, _prior_particles(model, count, rngs), model, ys, rngs, step_sizes=steps)


def _edh(model, ys, count, rngs, steps):
    prior_cov = np.broadcast_to(model.prior_cov, (len(rngs),) + np.shape(model.prior_cov)).copy()
    belief = _prior_particles(model, count, rngs, ekf_cov=prior_cov)
    return _run(edh_step, belief, model, ys, rngs, step_sizes=steps)


METHODS = {PF: _pf, UPF: _upf, EDH: _edh, IE_PFF: _ie_pff}


def run_method(method: Method, model: StateSpaceModel, ys: np.ndarray, count: int, rng: np.random.Generator,
               steps: np.ndarray | None = None) -> MethodRun:
    """Filter ``ys`` (T, L) with ``count`` particles from the model's prior; ``steps`` are the
    λ-steps of the flows (:func:`run_methods` of one run)."""
    return _run_batch(method, model, np.asarray(ys, dtype=float)[None], count, [rng], steps)[0]


def run_methods(method: Method, model: StateSpaceModel, ys: np.ndarray, count: int,
                seeds: Sequence[np.random.SeedSequence], steps: np.ndarray | None = None) -> list[MethodRun]:
    """:func:`run_method` of B runs at once: measurements ys (B, T, L), run b's filter drawing from
    ``default_rng(seeds[b])``. A run that breaks down is diverged alone; should the batch raise, its
    runs are filtered again one by one from their seeds (a run's numbers do not depend on its
    batch, so the result is the same). Each run's ``seconds`` is the batch's CPU time over B."""
    runs = _run_batch(method, model, ys, count, [np.random.default_rng(s) for s in seeds], steps)
    if runs is not None:
        return runs
    return [_run_batch(method, model, ys[b:b + 1], count, [np.random.default_rng(seed)], steps)[0]
            for b, seed in enumerate(seeds)]


def _run_batch(method, model, ys, count, rngs, steps):
    """The runs of :func:`run_methods`, or None when the batch of several runs raised (a batch of
    one that raises is one diverged run)."""
    start = time.process_time()
    try:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            means, fractions = METHODS[method](model, ys, count, rngs, steps)
    except (GpfverifyError, np.linalg.LinAlgError):
        if len(rngs) > 1:
            return None
        return [MethodRun(None, time.process_time() - start)]
    seconds = (time.process_time() - start) / len(rngs)
    out = []
    for estimates, ess in zip(means, fractions):
        if not np.all(np.isfinite(estimates)):
            out.append(MethodRun(None, seconds))
        else:
            out.append(MethodRun(estimates, seconds, None if method in FLOWS else np.clip(ess, 1.0 / count, 1.0)))
    return out


# ----------------------------------------------------------------------------- health checks

def divergence_health(subject: str, run_errors: list[tuple[float, ...] | None], steps: int,
                      bound: float) -> HealthCheck:
    """:func:`~gpfverify.health.divergence_check` of one filter over runs: per-run absolute errors
    per step (None where the filter broke down, counted as diverged), any error above ``bound``
    diverged too; healthy only when no run diverged."""
    errors = np.array([np.full(steps, np.nan) if e is None else np.asarray(e, float) for e in run_errors])
    return divergence_check(subject, errors.reshape(len(run_errors), -1), bound=bound)


def ess_health(subject: str, run_fractions: list[tuple[float, ...] | None], particles: int) -> HealthCheck | None:
    """:func:`~gpfverify.health.ess_check` of a weighted filter over its runs (N_eff/N per step;
    runs without a record are left out); None when no run recorded N_eff/N."""
    kept = [f for f in run_fractions if f is not None]
    return ess_check(subject, np.array(kept), particles) if kept else None


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

    @property
    def runs_to_decide(self) -> int | None:
        """For an undecided verdict, about how many paired runs would decide it were the observed
        mean difference and spread the true ones: t grows as √n, so n' = ⌈n (t* / |t|)²⌉ (None when
        decided, or when t is zero or unknown)."""
        if self.verdict != "undecided" or self.t is None or self.t == 0.0 or self.critical is None:
            return None
        return int(np.ceil(self.n * (self.critical / abs(self.t)) ** 2))


def _finite(values) -> list[float | None]:
    """Per-run values with every one that is not a finite number as None (diverged)."""
    return [None if v is None or not np.isfinite(v) else float(v) for v in values]


def paired_comparison(better: tuple[float | None, ...] | list[float | None],
                      worse: tuple[float | None, ...] | list[float | None], level: float) -> Comparison:
    """Is ``better`` (per-run RMSE, None = diverged) more accurate than ``worse``?

    NOT held when ``better`` diverged in a run where ``worse`` did not; otherwise a paired t-test on
    the runs where both are finite, d = mean(better − worse) with standard error se and
    t* = the (1 − level/2) quantile of Student's t with n − 1 degrees of freedom: held when
    d < −t*·se, NOT held when d > t*·se, undecided in between. A value that is not finite (an
    error that overflowed) counts as a divergence."""
    better, worse = _finite(better), _finite(worse)
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


def ratio_comparison(a: tuple[float | None, ...] | list[float | None], b: tuple[float | None, ...] | list[float | None],
                     bound: float, level: float) -> Comparison:
    """Is filter ``a``'s per-run RMSE at most ``bound`` times filter ``b``'s (None = diverged)? The
    paired t-test of :func:`paired_comparison` on log(a) − log(bound) against log(b): held when the
    mean log ratio lies below log(bound) beyond t*·se, NOT held when above it, undecided in between;
    NOT held when ``a`` diverged in a run where ``b`` did not."""
    def log(values, shift: float = 0.0) -> list[float | None]:
        return [None if v is None else float(np.log(v)) - shift for v in values]

    a, b = _finite(a), _finite(b)
    c = paired_comparison(log(a, float(np.log(bound))), log(b), level)
    pairs = [x / y for x, y in zip(a, b) if x is not None and y is not None]
    if c.lost or not pairs:
        return c
    ratio = float(np.exp(np.mean(np.log(pairs))))
    return dataclasses.replace(c, evidence=f"per-run RMSE ratio {ratio:.3g} (geometric mean over n = {len(pairs)} "
                                           f"runs; at most {bound:.3g} × for the claim)")
