"""Health checks of a filter in one experiment configuration: a verdict about a paper's claim
stands only when the filters it compares work there.

Three checks, each a :class:`~gpfverify.contract.health_records.HealthCheck` record (name, passed,
statistic, threshold, detail); the first two are gates, the third a consistency finding:

* **weight collapse** (:func:`ess_check`) — the effective sample size of a particle filter,
  N_eff = 1 / Σ_i w_i² (Kong, Liu & Wong 1994), as a fraction of N, per step; the filter has
  collapsed when the median over steps of N_eff/N is at most ``min_fraction`` (default
  :data:`MIN_ESS_FRACTION`): then most steps carry their posterior on a handful of particles and its
  errors measure the proposal, not the filter. N_eff/N = 1/N is total collapse (one particle).
* **divergence** (:func:`divergence_check`) — runs whose estimate left the finite numbers or whose
  error exceeded ``bound`` at some step; passes when the fraction of diverged runs is at most
  ``max_fraction`` (default 0: one diverged run fails it).
* **NEES** (:func:`nees_check`) — where the truth is known: the ANEES per step against its
  two-sided χ² interval (:class:`gpfverify.consistency.Consistency`, binomial verdict on the count
  of steps outside). A filter outside the band is optimistic or pessimistic: its error bars are not
  what its errors show. That is a consistency finding, reported apart on every page; it does not
  withhold a verdict on the filter's errors (:data:`~gpfverify.contract.health_records.CONSISTENCY_CHECKS`).

A claim record carries the checks of every filter it compares and applies the gates itself
(:meth:`gpfverify.contract.claims.ClaimRecord.checked`): a failed gate turns its verdict into
``"not decidable"``, keeping the verdict the runs gave, so a page never reports a comparison of
filters that did not work as a finding about the method.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gpfverify.contract.health_records import HealthCheck
from gpfverify.errors import InputError

__all__ = ["MIN_EFFECTIVE_PARTICLES", "MIN_ESS_FRACTION", "HealthCheck", "divergence_check", "ess_check",
           "nees_check", "nees_values_check"]

#: median N_eff / N at or below which a particle filter counts as collapsed
MIN_ESS_FRACTION = 0.05
#: ... or, with so few particles that 1/N exceeds that fraction, this many particles' worth
#: (capped at half the set), so that a total collapse is flagged at any N
MIN_EFFECTIVE_PARTICLES = 2.0


def ess_check(subject: str, ess_fraction, n_particles: int, *,
              min_fraction: float = MIN_ESS_FRACTION) -> HealthCheck:
    """Weight collapse from N_eff/N per step (any shape: runs × steps or steps), N particles: the
    median at or below max(``min_fraction``, :data:`MIN_EFFECTIVE_PARTICLES` / N) (at most ½)."""
    fractions = np.asarray(ess_fraction, dtype=float)
    if fractions.size == 0 or not np.all(np.isfinite(fractions)):
        raise InputError(f"{subject}: N_eff/N must be a non-empty array of finite numbers")
    if np.any(fractions <= 0) or np.any(fractions > 1 + 1e-12):
        raise InputError(f"{subject}: N_eff/N must lie in (0, 1]")
    if not 0 < min_fraction < 1:
        raise InputError(f"min_fraction must lie in (0, 1), got {min_fraction}")
    threshold = min(max(min_fraction, MIN_EFFECTIVE_PARTICLES / n_particles), 0.5)
    median = float(np.median(fractions))
    passed = median > threshold
    total = median <= 1.5 / n_particles
    detail = (f"median N_eff/N {median:.3g} over {fractions.size} step(s) at N = {n_particles}"
              + (" — collapsed to about one particle" if total and not passed else
                 " — collapsed" if not passed else "")
              + f" (healthy above {threshold:.3g})")
    return HealthCheck("weight collapse", subject, passed, median, threshold, detail)


def divergence_check(subject: str, errors, *, bound: float, max_fraction: float = 0.0) -> HealthCheck:
    """Divergence from estimation errors (runs × steps [× D]): a run diverged when an error is not
    finite or its norm exceeds ``bound`` at some step."""
    e = np.asarray(errors, dtype=float)
    if e.ndim < 2 or e.shape[0] == 0:
        raise InputError(f"{subject}: errors must have shape (runs, steps[, D])")
    if not bound > 0:
        raise InputError(f"bound must be positive, got {bound}")
    norms = np.linalg.norm(e, axis=-1) if e.ndim == 3 else np.abs(e)
    with np.errstate(invalid="ignore"):
        diverged = np.any(~np.isfinite(norms) | (norms > bound), axis=1)
    fraction = float(np.mean(diverged))
    passed = fraction <= max_fraction
    allowed = "when no run diverges" if max_fraction == 0 else f"when at most {max_fraction:.0%} of the runs diverge"
    detail = (f"{int(diverged.sum())} of {diverged.size} run(s) diverged (error not finite or above {bound:g})"
              f"; the check passes {allowed}")
    return HealthCheck("divergence", subject, passed, fraction, max_fraction, detail)


def nees_check(subject: str, truth, means, covs, *, circular_state: Sequence[int] = (),
               level: float = 0.95) -> HealthCheck:
    """NEES consistency over Monte Carlo runs (truth, means (R, T, D), covs (R, T, D, D))."""
    from gpfverify.consistency import Consistency

    nees = Consistency.from_estimates(truth, means, covs, circular_state=circular_state)
    return nees_values_check(subject, nees.values, nees.dim, level)


def nees_values_check(subject: str, nees, dim: int, level: float = 0.95) -> HealthCheck:
    """NEES consistency from normalised errors already computed (R, T) — e.g. the squared
    Mahalanobis distances a run records — in state dimension ``dim``: the ANEES per step against
    its two-sided χ² interval; a run with a non-finite NEES fails it."""
    from gpfverify.consistency import Consistency

    values = np.asarray(nees, dtype=float)
    if not np.all(np.isfinite(values)):
        bad = int(np.sum(~np.all(np.isfinite(values), axis=1)))
        return HealthCheck("NEES", subject, False, float("inf"), float(dim), f"NEES not finite in {bad} run(s)")
    test = Consistency("NEES", values, dim).average_over_runs(level)
    verdict = test.verdict()
    return HealthCheck("NEES", subject, verdict == "consistent", float(np.mean(test.values)), float(dim),
                       f"{verdict}: {test.summary()}")
