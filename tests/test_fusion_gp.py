"""GP-ADF / GP-UKF versions of CMF and DMF (gpfverify.model_fusion on a GPModel) on a small
two-sensor GP model: DMF = CMF to rounding when every C_xy^m has full column rank; otherwise the
observed gap equals the closed-form gap and the repaired DMF equals CMF. Oracle: CMF on the
GaussianProcessStack (the centralized route)."""

import numpy as np
import pytest

from gpfverify.errors import InputError
from gpfverify.filters.gp_adf import gp_adf_step
from gpfverify.filters.gp_ukf import gp_ukf_step
from gpfverify.filters.records import Gaussian
from gpfverify.fusion.exactness import equivalence_tolerance, predicted_gap, repair_message
from gpfverify.fusion.distributed import dmf_update
from gpfverify.model_fusion import cmf_step, dmf_step
from gpfverify.gp import GaussianProcess
from gpfverify.models import GPModel

LOCAL_STEP = {"gp-adf": gp_adf_step, "gp-ukf": gp_ukf_step}


def _gp(rng, d, fn, n=25):
    x = rng.uniform(-2, 2, size=(n, d))
    y = fn(x)
    e = y.shape[1]
    return GaussianProcess(x, y, lengthscales=np.full((e, d), 1.2), signal_var=np.full(e, 1.5),
                           noise_var=np.full(e, 0.02))


def _model(d, seed):
    rng = np.random.default_rng(seed)
    if d == 2:
        transition = _gp(rng, 2, lambda x: np.stack([0.9 * x[:, 0] + 0.3 * np.sin(x[:, 1]),
                                                       0.8 * x[:, 1] - 0.2 * x[:, 0]], 1))
        sensors = [_gp(rng, 2, lambda x: (x[:, 0] + 0.5 * np.sin(x[:, 1]))[:, None]),
                   _gp(rng, 2, lambda x: np.stack([x[:, 1], np.cos(x[:, 0]) + 0.3 * x[:, 1]], 1))]
    else:  # one state, two outputs per sensor: C_xy^m is 1 x 2, never full column rank
        transition = _gp(rng, 1, lambda x: 0.5 * x + np.sin(x))
        sensors = [_gp(rng, 1, lambda x: np.hstack([np.sin(x), x])),
                   _gp(rng, 1, lambda x: np.hstack([np.cos(x), x**2 / 4]))]
    return GPModel(transition, sensors)


def _beliefs(d, rng):
    def one():
        a = rng.normal(size=(d, d))
        return Gaussian(rng.uniform(-0.5, 0.5, size=d), 0.2 * (a @ a.T / d + 0.3 * np.eye(d)))
    return one(), [one(), one()]


@pytest.mark.parametrize("method", ["gp-adf", "gp-ukf"])
@pytest.mark.parametrize("seed", [0, 1])
def test_dmf_equals_cmf_with_full_column_rank(method, seed):
    model = _model(2, seed)
    rng = np.random.default_rng(seed + 100)
    central_belief, local_beliefs = _beliefs(2, rng)
    ys = [rng.normal(size=size) for size in model.sizes]
    local = [LOCAL_STEP[method](b, model.sensor_model(m), y) for m, (b, y) in enumerate(zip(local_beliefs, ys))]
    y = np.concatenate(ys)
    cmf = cmf_step(central_belief, model, y, family=method)
    dmf = dmf_step(central_belief, model, y, local_records=local, family=method)
    assert dmf.result.condition_holds and dmf.result.exact
    assert np.abs(cmf.C_y[:1, 1:]).max() > 0  # the stack's cross-sensor block is present
    tol = equivalence_tolerance(dmf.case, dmf.result.gain, dmf.result.sensors)
    np.testing.assert_allclose(dmf.record.mu_e, cmf.mu_e, rtol=0, atol=tol)
    np.testing.assert_allclose(dmf.record.C_e, cmf.C_e, rtol=0, atol=tol * np.abs(cmf.C_e).max())


@pytest.mark.parametrize("method", ["gp-adf", "gp-ukf"])
def test_gap_equals_predicted_gap_under_rank_deficiency(method):
    model = _model(1, 3)
    rng = np.random.default_rng(7)
    central_belief, local_beliefs = _beliefs(1, rng)
    ys = [rng.normal(size=2) for _ in model.sizes]
    local = [LOCAL_STEP[method](b, model.sensor_model(m), y) for m, (b, y) in enumerate(zip(local_beliefs, ys))]
    y = np.concatenate(ys)
    cmf = cmf_step(central_belief, model, y, family=method)
    dmf = dmf_step(central_belief, model, y, local_records=local, family=method)
    assert not dmf.result.condition_holds and [s.repair_dim for s in dmf.result.sensors] == [1, 1]
    tol = equivalence_tolerance(dmf.case, dmf.result.gain, dmf.result.sensors)
    gap = dmf.record.mu_e - cmf.mu_e
    assert np.linalg.norm(gap) > 1e3 * tol
    np.testing.assert_allclose(gap, predicted_gap(dmf.case, dmf.result.sensors), rtol=0, atol=tol)
    messages = [repair_message(r, y_m) for r, y_m in zip(dmf.case.locals, ys)]
    np.testing.assert_allclose(dmf_update(dmf.case, messages).mean, cmf.mu_e, rtol=0, atol=tol)


def test_mismatched_inputs_are_input_errors():
    model = _model(2, 0)
    central_belief, local_beliefs = _beliefs(2, np.random.default_rng(0))
    local = [gp_adf_step(b, model.sensor_model(m), np.zeros(size))
             for m, (b, size) in enumerate(zip(local_beliefs, model.sizes))]
    with pytest.raises(InputError, match="local records"):
        dmf_step(central_belief, model, local_records=local[:1], family="gp-adf")
    with pytest.raises(InputError, match="C_xy of shape"):
        dmf_step(central_belief, model, local_records=local[::-1], family="gp-adf")
    with pytest.raises(InputError, match="filter family"):
        cmf_step(central_belief, model, np.zeros(3), family="gp-ekf")
    with pytest.raises(InputError, match="needs a StateSpaceModel"):
        cmf_step(central_belief, model, np.zeros(3), family="ukf")


def test_audit_of_a_short_run_matches_the_dmf_steps():
    """audit_run over cases_from_run (CMF records as the centre's prediction, local records) gives
    per step and sensor the same ranks and gaps as dmf_step's own diagnostics."""
    from gpfverify.audit.case import audit_run, cases_from_run

    model = _model(1, 5)
    rng = np.random.default_rng(9)
    central, local_beliefs = _beliefs(1, rng)
    cmf_records, local_runs, ys, dmf_gaps = [], [], [], []
    for _ in range(3):
        y_parts = [rng.normal(size=2) for _ in model.sizes]
        local = [gp_adf_step(b, model.sensor_model(m), y) for m, (b, y) in enumerate(zip(local_beliefs, y_parts))]
        y = np.concatenate(y_parts)
        cmf = cmf_step(central, model, y, family="gp-adf")
        dmf = dmf_step(central, model, y, local_records=local, family="gp-adf")
        cmf_records.append(cmf)
        local_runs.append(local)
        ys.append(y)
        dmf_gaps.append(np.linalg.norm(dmf.record.mu_e - cmf.mu_e))
        central, local_beliefs = cmf.posterior, [r.posterior for r in local]
    cases = cases_from_run(cmf_records, local_runs, [2, 2], ys)
    run = audit_run(cases, rank_rule="numpy")  # dmf_step's default rule
    assert run.rank.shape == (3, 2) and not run.full_column_rank.any()
    np.testing.assert_array_equal(run.repair_dim, np.ones((3, 2), dtype=int))
    tol = [equivalence_tolerance(c, dmf_update(c).gain, dmf_update(c).sensors) for c in cases]
    np.testing.assert_allclose(run.gap_norm, dmf_gaps, rtol=0, atol=max(tol))
    np.testing.assert_allclose(run.gap_norm, run.predicted_gap_norm, rtol=0, atol=max(tol))
