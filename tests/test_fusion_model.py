"""run_fusion for any model: a GPModel learned from the three-sensor tracker (gp-adf, gp-ukf) and
the known model (ukf), against independent routes — CMF by the family's own update from the
belief DMF started from, the baselines called directly on the local posteriors, and each local
filter run on its own; wrong family/model pairings and missing priors are InputErrors."""

import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from gpfverify.errors import InputError
from gpfverify.filters.families import gaussian_family
from gpfverify.filters.records import Gaussian
from gpfverify.fusion.ci import covariance_intersection
from gpfverify.fusion.convex import convex_combination
from gpfverify.fusion.exactness import equivalence_tolerance
from gpfverify.model_fusion import cmf_step, dmf_step, run_fusion
from gpfverify.models import learn_gp_model
from gpfverify.scenarios.three_sensor import three_sensor_model

STEPS = 6


@pytest.fixture(scope="module")
def learned():
    """A GPModel learned from 60 samples of the tracker with the bearing sensor moved west of the
    track (the bearing stays near 0, away from the cut a GP cannot learn across)."""
    system = three_sensor_model(range_bearing_at=(-100.0, 0.0))
    model = learn_gp_model(system, 60, np.random.default_rng(1), restarts=1, fit_points=60)
    _, ys = system.simulate(STEPS, np.random.default_rng(2))
    return system, model, ys, Gaussian(system.prior_mean, system.prior_cov)


@pytest.mark.parametrize("family", ["gp-adf", "gp-ukf"])
def test_dmf_equals_cmf_on_a_learned_model(learned, family):
    system, model, ys, prior = learned
    run = run_fusion(model, ys, family=family, methods=("cmf", "dmf", "cc"), local_priors=[prior] * 3,
                     fused_prior=prior)
    assert run.family == family and [s.k for s in run.steps] == list(range(1, STEPS + 1))
    belief, full_rank_steps = prior, 0
    for step in run.steps:
        y = ys[step.k - 1]
        same_start = cmf_step(belief, model, y, k=step.k, family=family)
        tol = equivalence_tolerance(step.dmf.case, step.dmf.result.gain, step.dmf.result.sensors)
        if step.dmf.result.condition_holds:
            full_rank_steps += 1
            np.testing.assert_allclose(step.dmf.record.mu_e, same_start.mu_e, rtol=0, atol=tol)
        np.testing.assert_allclose(step.audit.gap, step.audit.predicted_gap, rtol=0, atol=tol)
        assert np.abs(step.dmf.case.central.C_y[:2, 2:]).max() > 0  # the stack's cross-sensor blocks
        assert step.dmf.case.central.circular == model.circular == (3,)
        belief = step.dmf.record.posterior
    assert full_rank_steps >= STEPS // 2
    np.testing.assert_allclose(run.audit.gap_norm, [np.linalg.norm(s.audit.gap) for s in run.steps])


def test_run_parts_match_their_direct_computation():
    """Locals: each sensor's filter on its own; cw and ci: the rules on the local posteriors."""
    model = three_sensor_model()
    _, ys = model.simulate(4, np.random.default_rng(5))
    run = run_fusion(model, ys, methods=("cmf", "dmf", "cc", "ci"), first_k=3)
    family = gaussian_family("ukf")
    for m in range(3):
        belief = Gaussian(model.prior_mean, model.prior_cov)
        for step in run.steps:
            record = family.step(belief, model.sensor_model(m), ys[step.k - 3][model.blocks[m]], k=step.k)
            np.testing.assert_array_equal(step.local[m].mu_e, record.mu_e)
            belief = record.posterior
    for step in run.steps:
        posteriors = [r.posterior for r in step.local]
        np.testing.assert_array_equal(step.estimate("cc").mean, convex_combination(posteriors).mean)
        np.testing.assert_array_equal(step.estimate("ci").cov, covariance_intersection(posteriors).cov)
        assert set(step.seconds) == {"local", "cmf", "dmf", "cc", "ci"} and len(step.local_seconds) == 3
        # eq. 35's own time is part of the DMF step's, and a measurement: not compared
        assert 0 < step.dmf.update_seconds < step.seconds["dmf"]
        assert step.dmf == replace(step.dmf, update_seconds=step.dmf.update_seconds + 1.0)
    assert run.means("dmf").shape == (4, 4) and run.local_means(2).shape == (4, 4)


def test_rcc_ci_baseline_runs_and_reports_enlargement():
    model = three_sensor_model()
    _, ys = model.simulate(2, np.random.default_rng(6))
    run = run_fusion(model, ys, methods=("dmf", "rcc-ci"))
    for step in run.steps:
        result = step.baselines["rcc-ci"]
        assert isinstance(result.enlarged, bool) and result.mean.shape == (4,)
        assert step.cmf is None


def test_importing_model_fusion_does_not_import_cvxpy():
    code = "import sys, gpfverify.model_fusion; print('cvxpy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_wrong_pairings_and_missing_inputs_are_input_errors(learned):
    system, model, ys, prior = learned
    with pytest.raises(InputError, match="gp-adf family needs a GPModel"):
        run_fusion(system, ys, family="gp-adf")
    with pytest.raises(InputError, match="ukf family needs a StateSpaceModel"):
        run_fusion(model, ys, family="ukf", local_priors=[prior] * 3, fused_prior=prior)
    with pytest.raises(InputError, match="ekf family needs a StateSpaceModel"):
        cmf_step(prior, model, ys[0], family="ekf")
    with pytest.raises(InputError, match="gp-ukf family needs a GPModel"):
        dmf_step(prior, system, ys[0], local_records=[], family="gp-ukf")
    with pytest.raises(InputError, match="filter family"):
        run_fusion(system, ys, family="pf")
    with pytest.raises(InputError, match="no prior"):
        run_fusion(model, ys, family="gp-adf")
    with pytest.raises(InputError, match="local_priors needs 3"):
        run_fusion(system, ys, local_priors=[prior])
    with pytest.raises(InputError, match="methods"):
        run_fusion(system, ys, methods=("cmf", "ei"))
    with pytest.raises(InputError, match="audit"):
        run_fusion(system, ys, methods=("cmf",))
    with pytest.raises(InputError, match="ys"):
        run_fusion(system, ys[:, :4])
