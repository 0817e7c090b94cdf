"""Health checks flag collapsed, diverged and inconsistent filters; a claim record withholds its
verdict when a filter it compares failed a gate (tests/test_claim_records.py)."""

from __future__ import annotations

import numpy as np
import pytest

from gpfverify.errors import InputError
from gpfverify.health import MIN_ESS_FRACTION, divergence_check, ess_check, nees_check
from gpfverify.rng import generator


def _ess_fraction(log_weights: np.ndarray) -> float:
    w = np.exp(log_weights - log_weights.max())
    w /= w.sum()
    return float(1.0 / np.sum(w**2) / w.size)


def test_a_bootstrap_filter_with_a_far_too_narrow_likelihood_is_flagged_as_collapsed():
    # particles from N(0, 1), likelihood N(y; x, r²): N_eff/N ≈ r / sqrt(1 + r²) shrinks with r
    rng = generator(7)
    n = 500
    narrow, broad = [], []
    for _ in range(40):
        x = rng.normal(size=n)
        y = rng.normal()
        narrow.append(_ess_fraction(-0.5 * (y - x) ** 2 / 1e-6))
        broad.append(_ess_fraction(-0.5 * (y - x) ** 2 / 1.0))
    collapsed, healthy = ess_check("narrow", narrow, n), ess_check("broad", broad, n)
    assert not collapsed.passed and "collapsed" in collapsed.detail
    assert healthy.passed and healthy.statistic > MIN_ESS_FRACTION
    total = ess_check("one particle", np.full(30, 1 / n), n)
    assert not total.passed and "about one particle" in total.detail
    # with so few particles that 1/N exceeds MIN_ESS_FRACTION, total collapse is still flagged
    few = ess_check("ten particles", np.full(30, 1 / 10), 10)
    assert not few.passed and few.threshold == pytest.approx(0.2)
    assert ess_check("ten particles", np.full(30, 0.6), 10).passed


def test_divergence_counts_runs_with_non_finite_or_huge_errors():
    errors = np.zeros((10, 5, 2))
    assert divergence_check("ok", errors, bound=1.0).passed
    errors[3, 4, 0] = np.nan
    errors[7, 1, 1] = 5.0
    check = divergence_check("two bad runs", errors, bound=1.0)
    assert not check.passed and check.statistic == pytest.approx(0.2)
    assert divergence_check("tolerant", errors, bound=1.0, max_fraction=0.2).passed


def test_nees_passes_a_calibrated_estimate_and_flags_an_overconfident_one():
    rng = generator(3)
    runs, steps, d = 200, 20, 2
    truth = rng.normal(size=(runs, steps, d))
    cov = np.broadcast_to(np.eye(d), (runs, steps, d, d))
    means = truth + rng.normal(size=truth.shape)  # errors ~ N(0, I): calibrated
    assert nees_check("calibrated", truth, means, cov).passed
    overconfident = nees_check("overconfident", truth, means, 0.25 * cov)
    assert not overconfident.passed and not overconfident.is_gate  # a consistency finding, never a gate


@pytest.mark.parametrize("values", [[], [0.0, 0.5], [np.nan], [1.5]])
def test_ess_check_rejects_impossible_fractions(values):
    with pytest.raises(InputError):
        ess_check("x", values, 100)
