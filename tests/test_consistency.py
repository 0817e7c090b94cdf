"""gpfverify.consistency: NEES/NIS χ² tests and the conservativeness check, each against a case that
must pass and one that must fail.

* the exact KF on a linear-Gaussian model passes the per-step two-sided ANEES/ANIS test at level
  0.95 in a fraction of seeds within a binomial tolerance (MONTE_CARLO_SIGMAS standard errors) of
  0.95 — the pass indicators of independent seeds at a fixed step are exactly Bernoulli(0.95);
  the same filter with its covariances shrunk fails (optimistic), inflated fails the lower bound;
* the time-averaged NIS of every run (white innovations: exactly χ²(T·L)/T) likewise;
* NEES with an angle state wraps the error (and is inconsistent without the wrap);
* covariance intersection of strongly correlated estimates is conservative, the convex combination
  (which ignores the correlation) is flagged; the statistic against an independent route;
* the record / fusion-run constructors against the array constructor; bad input raises InputError.
"""

import numpy as np
import pytest
import scipy.linalg as sla

from gpfverify.consistency import (
    STRICT_LEVEL,
    ChiSquareTest,
    Consistency,
    assert_consistent,
    chi2_interval,
    conservativeness,
    conservativeness_bound,
    estimation_errors,
)
from gpfverify.errors import InputError
from gpfverify.filters.kalman import kf_step
from gpfverify.filters.records import Gaussian
from gpfverify.models import linear_model
from gpfverify.tolerances import algebra_rtol, monte_carlo_atol

LEVEL = 0.95
SEEDS, RUNS, STEPS = 40, 50, 8
STRICT_ALPHA = 1.0 - STRICT_LEVEL


def _model():
    F = [[1.0, 0.5], [0.0, 0.9]]
    Q = [[0.05, 0.02], [0.02, 0.1]]
    return linear_model(F, [[1.0, 0.0]], Q, [[0.3]], prior_mean=[1.0, -0.5], prior_cov=[[1.0, 0.2], [0.2, 0.5]])


@pytest.fixture(scope="module")
def kf_runs():
    """SEEDS independent batches of RUNS runs of STEPS steps: truth, measurements and the exact KF's
    means, covariances, predicted measurements and innovation covariances, each (S, R, T, ...)."""
    model = _model()
    sims = [[model.simulate(STEPS, rng) for _ in range(RUNS)]
            for rng in (np.random.default_rng(seed) for seed in range(SEEDS))]
    truth = np.array([[x for x, _ in batch] for batch in sims])
    ys = np.array([[y for _, y in batch] for batch in sims])
    n = SEEDS * RUNS
    flat_y = ys.reshape(n, STEPS, -1)
    belief = Gaussian(np.tile(model.prior_mean, (n, 1)), np.tile(model.prior_cov, (n, 1, 1)))
    records = []
    for t in range(STEPS):
        record = kf_step(belief, model, flat_y[:, t], k=t + 1)
        belief = record.posterior
        records.append(record)

    def stack(name):  # (T, N, ...) -> (S, R, T, ...)
        arr = np.stack([getattr(r, name) for r in records], axis=1)
        return arr.reshape((SEEDS, RUNS) + arr.shape[1:])

    return {"truth": truth, "ys": ys, "means": stack("mu_e"), "covs": stack("C_e"), "mu_y": stack("mu_y"),
                "C_y": stack("C_y"), "records": records}


def _binomial_ok(fraction: float, n: int, p: float) -> bool:
    """|fraction − p| within MONTE_CARLO_SIGMAS standard errors of a Binomial(n, p) fraction."""
    return abs(fraction - p) <= monte_carlo_atol(np.sqrt(p * (1.0 - p)), n)


def _final_step_pass_fraction(tests: list[ChiSquareTest]) -> float:
    """Fraction of seeds whose per-step test passes at the last step (independent Bernoulli(level))."""
    return float(np.mean([t.inside[-1] for t in tests]))


# --- ANEES --------------------------------------------------------------------------------------

def _anees(data, scale):
    return [Consistency.from_estimates(data["truth"][s], data["means"][s], scale * data["covs"][s])
            .average_over_runs(LEVEL) for s in range(SEEDS)]


def test_consistent_kf_passes_anees_in_about_level_of_seeds(kf_runs):
    tests = _anees(kf_runs, 1.0)
    assert tests[0].dof == RUNS * 2 and tests[0].samples == RUNS and tests[0].values.shape == (STEPS,)
    lo, hi = chi2_interval(RUNS * 2, RUNS, LEVEL)
    assert (tests[0].lower, tests[0].upper) == (lo, hi) and lo < 2.0 < hi
    fraction = _final_step_pass_fraction(tests)
    assert _binomial_ok(fraction, SEEDS, LEVEL), f"pass fraction {fraction} over {SEEDS} seeds"


def test_overconfident_filter_fails_anees(kf_runs):
    tests = _anees(kf_runs, 0.5)  # covariances shrunk: ANEES ≈ 2 D
    fraction = _final_step_pass_fraction(tests)
    assert not _binomial_ok(fraction, SEEDS, LEVEL), f"pass fraction {fraction}"
    assert all(t.verdict() == "optimistic" for t in tests)
    with pytest.raises(AssertionError, match=r"ANEES: optimistic .* inside \["):
        assert_consistent(tests[0], what="KF x 0.5")


def test_underconfident_filter_fails_the_lower_bound(kf_runs):
    tests = _anees(kf_runs, 2.0)  # covariances inflated: ANEES ≈ D / 2
    fraction = _final_step_pass_fraction(tests)
    assert not _binomial_ok(fraction, SEEDS, LEVEL), f"pass fraction {fraction}"
    assert all(t.n_above == 0 and t.n_below > 0 and t.verdict() == "pessimistic" for t in tests)


# --- NIS ----------------------------------------------------------------------------------------

def _nis(data, scale, seed=None):
    if seed is None:  # every run of every seed
        shape = (SEEDS * RUNS, STEPS)
        return Consistency.nis(data["ys"].reshape(shape + (-1,)), data["mu_y"].reshape(shape + (-1,)),
                               scale * data["C_y"].reshape(shape + (1, 1)))
    return Consistency.nis(data["ys"][seed], data["mu_y"][seed], scale * data["C_y"][seed])


def test_consistent_kf_passes_anis(kf_runs):
    tests = [_nis(kf_runs, 1.0, s).average_over_runs(LEVEL) for s in range(SEEDS)]
    fraction = _final_step_pass_fraction(tests)
    assert _binomial_ok(fraction, SEEDS, LEVEL), f"pass fraction {fraction}"
    assert tests[0].name == "ANIS" and tests[0].dim == 1


def test_time_averaged_nis_of_every_run(kf_runs):
    """Innovations of the exact KF are white: each run's time average is exactly χ²(T·L)/T, the runs
    independent, so the fraction inside is Binomial and the verdict is a valid test."""
    ok = _nis(kf_runs, 1.0).average_over_time(LEVEL)
    assert ok.values.shape == (SEEDS * RUNS,) and ok.dof == STEPS
    assert _binomial_ok(ok.fraction_inside, ok.values.size, LEVEL), ok.summary()
    assert_consistent(ok, alpha=STRICT_ALPHA)
    bad = _nis(kf_runs, 0.5).average_over_time(LEVEL)
    assert not _binomial_ok(bad.fraction_inside, bad.values.size, LEVEL)
    assert bad.verdict(STRICT_ALPHA) == "optimistic"
    with pytest.raises(AssertionError, match="time-averaged NIS: optimistic"):
        assert_consistent(bad, alpha=STRICT_ALPHA)


def test_nis_from_records_equals_arrays(kf_runs):
    records = kf_runs["records"]
    one = [[type(r)(*(getattr(r, f)[i] for f in ("mu_p", "C_p", "mu_y", "C_y", "C_xy", "mu_e", "C_e")))
            for r in records] for i in range(3)]
    got = Consistency.nis_from_records(kf_runs["ys"][0, :3], one)
    want = _nis(kf_runs, 1.0, 0).values[:3]
    np.testing.assert_allclose(got.values, want, rtol=algebra_rtol(10.0))
    single = Consistency.nis_from_records(kf_runs["ys"][0, 0], one[0])
    np.testing.assert_allclose(single.values, want[:1], rtol=algebra_rtol(10.0))
    nees = Consistency.from_records(kf_runs["truth"][0, :3], one)  # StepRecord → posterior
    np.testing.assert_allclose(nees.values, Consistency.from_estimates(
        kf_runs["truth"][0, :3], kf_runs["means"][0, :3], kf_runs["covs"][0, :3]).values,
        rtol=algebra_rtol(10.0))


# --- angles -------------------------------------------------------------------------------------

def test_nees_wraps_angle_state_components():
    P = np.diag([0.04, 1.0])
    got = Consistency.from_estimates([[np.pi - 0.1, 0.3]], [[-np.pi + 0.1, 0.3]], [P], circular_state=[0])
    np.testing.assert_allclose(got.values, [[0.2 ** 2 / 0.04]], rtol=algebra_rtol())
    # Monte Carlo: estimates of a heading near ±π, errors drawn from P and wrapped
    rng = np.random.default_rng(7)
    n = 400
    truth = np.column_stack([np.full(n, np.pi - 0.05), rng.normal(size=n)])
    means = truth + rng.multivariate_normal(np.zeros(2), P, size=n)
    means[:, 0] = np.pi - np.mod(np.pi - means[:, 0], 2 * np.pi)  # estimates reported in (−π, π]
    assert np.mean(means[:, 0] < 0) > 0.2  # the wrap matters for a good share of runs
    covs = np.broadcast_to(P, (n, 1, 2, 2))
    wrapped = Consistency.from_estimates(truth[:, None], means[:, None], covs, circular_state=(0,))
    assert_consistent(wrapped.average_over_runs(STRICT_LEVEL))
    plain = Consistency.from_estimates(truth[:, None], means[:, None], covs)
    assert plain.average_over_runs(STRICT_LEVEL).verdict() == "optimistic"


def test_nis_wraps_angle_outputs():
    S = np.array([[0.01]])
    got = Consistency.nis([[np.pi - 0.05]], [[-np.pi + 0.05]], [S], circular=[0])
    np.testing.assert_allclose(got.values, [[0.1 ** 2 / 0.01]], rtol=algebra_rtol())
    assert Consistency.nis([[np.pi - 0.05]], [[-np.pi + 0.05]], [S]).values[0, 0] > 1e3


# --- conservativeness -----------------------------------------------------------------------------

def _correlated_estimates(rng, n, rho):
    """n runs of two estimates of x ∈ R² with covariances P1, P2 and error cross-covariance
    ρ P1^{1/2} P2^{1/2} (diagonal): truth (n, 2) and the local estimates."""
    P1, P2 = np.diag([1.0, 2.0]), np.diag([2.0, 1.0])
    cross = rho * np.sqrt(P1) @ np.sqrt(P2)
    joint = np.block([[P1, cross], [cross.T, P2]])
    truth = rng.normal(size=(n, 2))
    errors = rng.multivariate_normal(np.zeros(4), joint, size=n)
    return truth, [[Gaussian(x + e[:2], P1), Gaussian(x + e[2:], P2)] for x, e in zip(truth, errors)]


def test_ci_conservative_and_naive_convex_combination_flagged():
    from gpfverify.fusion.ci import covariance_intersection
    from gpfverify.fusion.convex import convex_combination

    rng = np.random.default_rng(3)
    truth, locals_ = _correlated_estimates(rng, 600, rho=0.95)
    results = {}
    for name, rule in (("ci", covariance_intersection), ("cc", convex_combination)):
        fused = [rule(pair) for pair in locals_]
        errors = estimation_errors(truth, np.array([f.mean for f in fused]))
        results[name] = conservativeness(errors, np.array([f.cov for f in fused]), STRICT_LEVEL)
        common = conservativeness(errors, fused[0].cov, STRICT_LEVEL)  # the same P in every run
        np.testing.assert_allclose(common.eigenvalues, results[name].eigenvalues, rtol=algebra_rtol(10.0))
        # independent route: generalised eigenvalues of (Ê, P)
        second_moment = errors.T @ errors / len(errors)
        np.testing.assert_allclose(common.statistic, sla.eigh(second_moment, fused[0].cov, eigvals_only=True)[-1],
                                   rtol=algebra_rtol(10.0))
    assert results["ci"].verdict() == "conservative", results["ci"].summary()
    assert_consistent(results["ci"])
    cw = results["cc"]
    assert cw.verdict() == "not conservative", cw.summary()
    assert cw.bound == conservativeness_bound(600, 2, STRICT_LEVEL)
    with pytest.raises(AssertionError, match="not conservative"):
        assert_consistent(cw, what="convex combination")


def test_conservativeness_bound_holds_at_the_boundary():
    """Errors drawn exactly from the claimed P (Σ = P, the worst case of H0): the statistic may
    exceed the level-0.95 bound in at most 5 % of repetitions (up to the binomial tolerance); a
    covariance claimed half the truth along one eigendirection is detected."""
    rng = np.random.default_rng(11)
    P = np.array([[2.0, 0.6], [0.6, 0.5]])
    reps, runs = 200, 50
    passed = [conservativeness(rng.multivariate_normal(np.zeros(2), P, size=runs), P).passed
              for _ in range(reps)]
    false_alarms = 1.0 - np.mean(passed)
    assert false_alarms <= 0.05 + monte_carlo_atol(np.sqrt(0.05 * 0.95), reps)
    values, vectors = np.linalg.eigh(P)
    shrunk = vectors @ np.diag(values * [1.0, 0.5]) @ vectors.T  # λ_max(shrunk⁻¹ P) = 2
    result = conservativeness(rng.multivariate_normal(np.zeros(2), P, size=runs), shrunk)
    assert result.verdict() == "not conservative", result.summary()
    # errors whose second moment is exactly P: the statistic is 2 along the shrunk eigendirection
    basis, _ = np.linalg.qr(rng.normal(size=(runs, 2)))
    exact = np.sqrt(runs) * basis @ np.linalg.cholesky(P).T
    result = conservativeness(exact, shrunk)
    rtol = algebra_rtol(np.linalg.cond(P))
    np.testing.assert_allclose(result.eigenvalues, [1.0, 2.0], rtol=rtol)
    np.testing.assert_allclose(result.direction, vectors[:, 1] * np.sign(vectors[np.argmax(np.abs(vectors[:, 1])), 1]),
                               rtol=rtol, atol=rtol)


# --- fusion-run and particle constructors -----------------------------------------------------------

def test_from_fusion_and_from_records_equal_arrays():
    from gpfverify.filters.resampling import ParticleStep
    from gpfverify.model_fusion import run_fusion

    model = linear_model([[1.0, 0.5], [0.0, 0.9]], [[1.0, 0.0], [0.0, 1.0]], np.diag([0.05, 0.1]),
                         np.diag([0.3, 0.2]), sizes=(1, 1))
    rng = np.random.default_rng(5)
    sims = [model.simulate(4, rng) for _ in range(3)]
    truth = np.array([x for x, _ in sims])
    runs = [run_fusion(model, y, family="kf", methods=("cmf", "cc"), audit=False) for _, y in sims]
    for method in ("cmf", "cc"):
        got = Consistency.from_fusion(truth, runs, method)
        means = np.array([run.means(method) for run in runs])
        covs = np.array([[s.estimate(method).cov for s in run.steps] for run in runs])
        np.testing.assert_array_equal(got.values, Consistency.from_estimates(truth, means, covs).values)
    single = Consistency.from_fusion(truth[0], runs[0], "cmf")
    np.testing.assert_array_equal(single.values, Consistency.from_fusion(truth, runs, "cmf").values[:1])
    particles = [[ParticleStep(None, None, s.estimate("cmf").mean, s.estimate("cmf").cov, 1.0, False)
                  for s in run.steps] for run in runs]
    np.testing.assert_array_equal(Consistency.from_records(truth, particles).values,
                                  Consistency.from_fusion(truth, runs, "cmf").values)
    cmf_nis = Consistency.nis_from_records(np.array([y for _, y in sims]),
                                           [[s.cmf for s in run.steps] for run in runs])
    assert cmf_nis.values.shape == (3, 4) and cmf_nis.dim == 2


# --- verdict mechanics and bad input ------------------------------------------------------------------

def test_single_value_verdict_is_the_interval_test():
    lo, hi = chi2_interval(4, 2, LEVEL)
    make = lambda v: ChiSquareTest("ANEES", np.array([v]), lo, hi, 2, 2, 4, LEVEL)
    assert make(2.0).verdict() == "consistent"
    assert make(hi * 1.01).verdict() == "optimistic"
    assert make(lo * 0.99).verdict() == "pessimistic"


GOOD_TRUTH = np.zeros((3, 2))
GOOD_COVS = np.tile(np.eye(2), (3, 1, 1))


@pytest.mark.parametrize("kwargs, name", [
    ({"truth": np.zeros(2), "means": np.zeros(2), "covs": np.eye(2)}, "truth"),
    ({"truth": GOOD_TRUTH, "means": np.zeros((3, 3)), "covs": GOOD_COVS}, "means"),
    ({"truth": GOOD_TRUTH, "means": GOOD_TRUTH, "covs": np.eye(2)}, "covs"),
    ({"truth": GOOD_TRUTH, "means": GOOD_TRUTH, "covs": np.tile(np.diag([1.0, -1.0]), (3, 1, 1))},
     "covs is not positive definite"),
    ({"truth": GOOD_TRUTH, "means": GOOD_TRUTH, "covs": np.tile([[1.0, 0.5], [0.0, 1.0]], (3, 1, 1))},
     "covs is not symmetric"),
    ({"truth": GOOD_TRUTH, "means": GOOD_TRUTH * np.nan, "covs": GOOD_COVS}, "means contains NaN"),
    ({"truth": GOOD_TRUTH, "means": GOOD_TRUTH, "covs": GOOD_COVS, "circular_state": [2]}, "circular_state"),
])
def test_bad_estimates_raise_input_error(kwargs, name):
    with pytest.raises(InputError, match=name):
        Consistency.from_estimates(**kwargs)


@pytest.mark.parametrize("level", [0.0, 1.0, 1.5, -0.1, float("nan"), "high"])
def test_level_outside_open_unit_interval(level):
    nees = Consistency.from_estimates(GOOD_TRUTH, GOOD_TRUTH, GOOD_COVS)
    for call in (nees.average_over_runs, nees.average_over_time,
                 lambda lv: conservativeness(np.zeros((3, 2)), np.eye(2), lv)):
        with pytest.raises(InputError, match="level"):
            call(level)


def test_other_bad_input():
    with pytest.raises(InputError, match="innovation_covs is not positive definite at index"):
        Consistency.nis(np.zeros((2, 1)), np.zeros((2, 1)), np.array([[[1.0]], [[0.0]]]))
    with pytest.raises(InputError, match="errors"):
        conservativeness(np.zeros(3), np.eye(3))
    with pytest.raises(InputError, match="claimed_cov"):
        conservativeness(np.zeros((4, 2)), np.eye(3))
    with pytest.raises(InputError, match="claimed_cov is not positive definite"):
        conservativeness(np.zeros((4, 2)), np.diag([1.0, 0.0]))
    with pytest.raises(InputError, match=r"records\[0\]\[1\]"):
        Consistency.from_records(np.zeros((1, 2, 2)), [[Gaussian(np.zeros(2), np.eye(2)), object()]])
    with pytest.raises(InputError, match="alpha"):
        Consistency.from_estimates(GOOD_TRUTH, GOOD_TRUTH, GOOD_COVS).average_over_runs().verdict(alpha=2.0)
    with pytest.raises(InputError, match="result"):
        assert_consistent("not a test")
