"""A baseline that cannot fuse at a step (its solver fails) is recorded — method, step, reason —
and the run goes on: CMF, DMF and the other methods are exactly what they are without that
baseline, the check's record lists the failure once, and its verdict sentence says it."""

from pathlib import Path

import numpy as np
import pytest

import gpfverify.fusion.rcc_ci as rcc_ci_module
from gpfverify.contract.check import verdict_sentence
from gpfverify.errors import NumericalError, SolverError
from gpfverify.experiments import check
from gpfverify.model_fusion import run_fusion

ROOT = Path(__file__).resolve().parents[1]
TRACKER = f"{ROOT / 'examples' / 'three_sensor_system.py'}:tracker"
STEPS, FAILING_CALL = 5, 2
REASON = "RCC-CI primal ended with status unbounded_inaccurate"


@pytest.fixture
def rcc_ci_failing_once(monkeypatch):
    """RCC-CI as it is, except that its third call fails the way a solver does."""
    real, calls = rcc_ci_module.rcc_ci, []

    def flaky(*args, **kwargs):
        calls.append(None)
        if len(calls) == FAILING_CALL + 1:
            raise SolverError(REASON)
        return real(*args, **kwargs)

    monkeypatch.setattr(rcc_ci_module, "rcc_ci", flaky)


def test_a_failed_baseline_is_recorded_and_the_run_goes_on(rcc_ci_failing_once):
    params = check.params_for(TRACKER, steps=STEPS)
    model = check.load_system(params.system)
    _, ys = model.simulate(STEPS, np.random.default_rng(1))
    run = run_fusion(model, ys, methods=("cmf", "dmf", "cc", "rcc-ci"))
    without = run_fusion(model, ys, methods=("cmf", "dmf", "cc"))
    assert [dict(s.failed) for s in run.steps] == [{} if t != FAILING_CALL else {"rcc-ci": REASON}
                                                   for t in range(STEPS)]
    for method in ("cmf", "dmf", "cc"):  # one route, the same inputs: the same bits
        np.testing.assert_array_equal(run.means(method), without.means(method))
    failing = run.steps[FAILING_CALL]
    with pytest.raises(NumericalError, match=f"rcc-ci failed at step {failing.k}: {REASON}"):
        failing.estimate("rcc-ci")
    assert all("rcc-ci" in s.baselines for t, s in enumerate(run.steps) if t != FAILING_CALL)


def test_the_check_record_and_verdict_carry_the_failure(rcc_ci_failing_once):
    params = check.params_for(TRACKER, steps=STEPS, methods=("cmf", "dmf", "cc", "rcc-ci"))
    record = check.run_one(params, np.random.SeedSequence(3))
    results = {**check.summarize(params, [record]), "runs_ok": 1}
    k = record.steps[FAILING_CALL]["k"]
    assert results["failed_methods"] == ["rcc-ci"]
    assert results["method_failures"] == [{"run": 0, "k": k, "method": "rcc-ci", "reason": REASON}]
    assert "rcc-ci" not in record.steps[FAILING_CALL]["means"]
    assert set(results["rmse"]) == {"cmf", "dmf", "cc"}  # averages only over methods that fused everywhere
    assert f"rcc-ci failed at 1 of {STEPS} steps (first at k = {k}: {REASON})" in verdict_sentence(results)
