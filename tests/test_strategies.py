"""The public strategies keep their documented guarantees on every draw (checked by independent
computations: eigenvalues, SVDs, the case-file validator and the audit command)."""

import json
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gpfverify.errors import InputError
from gpfverify.fusion.caseblock import case_from_dict
from gpfverify.strategies import (KINDS, gp_stacks, correlated_estimates, fusion_case_files, fusion_cases,
                                  joint_gaussians, matrices_with_singular_values,
                                  orthonormal_matrices, psd_matrices, saving_case_on_failure,
                                  sigma_params, spd_matrices)
from gpfverify.strategies.matrices import log_uniform
from gpfverify.strategies.counterexamples import ENVIRONMENT_VARIABLE
from gpfverify.tolerances import algebra_rtol

FEW = settings(max_examples=40, deadline=None)


@given(leak=log_uniform(1e-8, 1.0), data=st.data())
def test_a_decoupling_leak_keeps_the_joint_definite_and_correlates_by_at_most_its_size(leak, data):
    """With decoupled_leak ε the joint stays positive definite, a decoupled component keeps its zero
    cross column, and it correlates with every other measurement component by at most ε (R's
    entries in its row scaled by ε, or ε² towards another decoupled component)."""
    joint = data.draw(joint_gaussians(kinds=st.sampled_from(("full", "decoupled")), decoupled_leak=leak))
    assert np.linalg.eigvalsh(joint.cov)[0] > 0
    std = np.sqrt(np.diag(joint.cov_y))
    correlation = joint.cov_y / np.outer(std, std)
    for design, block in zip(joint.sensors, joint.blocks):
        for j in design.decoupled:
            np.testing.assert_array_equal(joint.cross_cov[:, block.start + j], 0.0)
            others = np.delete(correlation[block.start + j], block.start + j)
            assert np.all(np.abs(others) <= leak * (1 + algebra_rtol())), (leak, others)


@settings(max_examples=1, deadline=None)
@given(data=st.data())
def test_a_decoupling_leak_outside_zero_to_one_is_an_input_error(data):
    for leak in (-0.1, 1.5, float("nan")):
        with pytest.raises(InputError, match="decoupled_leak must lie in"):
            data.draw(joint_gaussians(kinds="decoupled", decoupled_leak=leak))


@FEW
@given(q=orthonormal_matrices(4, 3))
def test_orthonormal_columns(q):
    np.testing.assert_allclose(q.T @ q, np.eye(3), rtol=0, atol=algebra_rtol())


@FEW
@given(a=spd_matrices(st.integers(1, 5), max_condition=1e4, scale=0.5))
def test_spd_matrices_have_bounded_spectrum(a):
    eig = np.linalg.eigvalsh(a)
    np.testing.assert_array_equal(a, a.T)
    assert eig[0] >= 0.5 * (1 - algebra_rtol(1e4)) and eig[-1] <= 0.5 * 1e4 * (1 + algebra_rtol())


@FEW
@given(data=st.data())
def test_singular_values_are_as_designed(data):
    s = np.array([3.0, 1.0, 1e-3])
    a = data.draw(matrices_with_singular_values(4, 5, s))
    np.testing.assert_allclose(np.linalg.svd(a, compute_uv=False)[:3], s, rtol=0, atol=algebra_rtol() * 3.0)
    assert np.linalg.matrix_rank(a) == 3


@FEW
@given(joint=joint_gaussians())
def test_joint_gaussians_are_positive_definite_with_designed_cross_terms(joint):
    assert np.linalg.eigvalsh(joint.cov)[0] > 0
    for design, block in zip(joint.sensors, joint.blocks):
        cross = joint.cross_cov[:, block]
        s = np.linalg.svd(cross, compute_uv=False)
        want = np.zeros(len(s))
        want[:design.rank] = design.singular_values
        np.testing.assert_allclose(s, want, rtol=0, atol=algebra_rtol() * max(1.0, s.max(initial=0.0)))
        for j in design.decoupled:
            np.testing.assert_array_equal(cross[:, j], 0.0)
            row = joint.cov_y[block.start + j]
            assert np.count_nonzero(row) == 1


@FEW
@given(kind=st.sampled_from(KINDS), data=st.data())
def test_each_kind_respects_its_size_rule(kind, data):
    joint = data.draw(joint_gaussians(state_dim=3, kinds=kind, sensors=2))
    for design in joint.sensors:
        if kind in ("full", "nearly"):
            assert design.size <= 3 and design.full_column_rank
        elif kind == "deficient":
            assert 1 <= design.rank < design.size
        elif kind == "zero":
            assert design.rank == 0
        else:
            assert design.rank == design.size - len(design.decoupled) and design.decoupled


@settings(max_examples=1, deadline=None)
@given(data=st.data())
def test_incompatible_fixed_sizes_are_refused(data):
    with pytest.raises(InputError, match="full"):
        data.draw(joint_gaussians(state_dim=2, kinds="full", sizes=(3,)))


@FEW
@given(data=fusion_case_files())
def test_case_files_validate_and_local_posteriors_are_the_local_update(data):
    case = case_from_dict(json.loads(json.dumps(data)))
    for m, local in enumerate(case.locals):
        innovation = np.linalg.solve(local.C_y, case.local_measurement(m) - local.mu_y)
        np.testing.assert_allclose(local.mu_e, local.mu_p + local.C_xy @ innovation,
                                   rtol=0, atol=algebra_rtol(np.linalg.cond(local.C_y)) * (1 + np.abs(local.mu_e).max()))


@pytest.mark.slow
@settings(max_examples=3, deadline=None)
@given(drawn=fusion_cases(kinds="deficient"))
def test_the_audit_command_reads_drawn_case_files(drawn, tmp_path_factory):
    path = tmp_path_factory.mktemp("case") / "case.json"
    path.write_text(json.dumps(drawn.to_dict()))
    proc = subprocess.run([sys.executable, "-m", "gpfverify", "audit", str(path), "--json"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    audit = json.loads(proc.stdout)
    assert [s["rank"] for s in audit["sensors"]] == list(drawn.ranks)
    assert audit["condition_holds"] is False


@FEW
@given(drawn=correlated_estimates())
def test_correlated_estimates_are_admissible(drawn):
    d = drawn.state_dim
    assert np.linalg.eigvalsh(drawn.joint_cov)[0] >= -algebra_rtol() * np.abs(drawn.joint_cov).max()
    for m, e in enumerate(drawn.estimates):
        np.testing.assert_array_equal(drawn.joint_cov[m * d:(m + 1) * d, m * d:(m + 1) * d], e.cov)
        assert np.linalg.eigvalsh(e.cov)[0] > 0


@FEW
@given(dim=st.integers(1, 5), data=st.data())
def test_sigma_params_are_valid_and_psd_matrices_psd(dim, data):
    params = data.draw(sigma_params(dim))
    wm, wc = params.weights(dim)
    assert abs(wm.sum() - 1.0) <= algebra_rtol() * np.abs(wm).sum()
    sigma = data.draw(psd_matrices(dim, 1e-3, 10.0))
    assert np.linalg.eigvalsh(sigma)[0] >= -algebra_rtol() * 10.0


@pytest.mark.slow
def test_failing_property_saves_its_shrunk_case(tmp_path, monkeypatch):
    monkeypatch.setenv(ENVIRONMENT_VARIABLE, str(tmp_path))

    @settings(max_examples=50, deadline=None, database=None, derandomize=True)
    @given(drawn=fusion_cases(state_dim=1, sensors=1, kinds="full"))
    def prop(drawn):
        with saving_case_on_failure(drawn.case, "two-sensors"):
            assert len(drawn.case.locals) > 1

    with pytest.raises(AssertionError):
        prop()
    saved = json.loads((tmp_path / "two-sensors.json").read_text())
    assert len(case_from_dict(saved).locals) == 1


@settings(max_examples=20)
@given(case=gp_stacks(regime="far"))
def test_far_gp_stacks_reach_the_log_space_branch(case):
    """The ``far`` regime puts a training point where exp(d_ij) would overflow, so the centred
    second moments take the log-space branch (the exponent exceeds the expm1 limit)."""
    from gpfverify.gp import moments

    calls = []
    original = moments._log_space_centred

    def spy(*args):
        calls.append(args)
        return original(*args)

    moments._log_space_centred = spy
    try:
        moments.moment_match_stack(list(case.gps), case.mu, case.sigma)
    finally:
        moments._log_space_centred = original
    assert calls


@settings(max_examples=20)
@given(case=gp_stacks(regime=st.sampled_from(("ordinary", "near-linear", "wide")), count=st.just(2)))
def test_gp_stacks_have_their_own_training_sets(case):
    first, second = case.gps
    assert first.X.shape[0] != second.X.shape[0] or not np.array_equal(first.X, second.X) or first.X.size == 1
    if case.regime == "near-linear":
        assert min(gp.lengthscales.min() for gp in case.gps) >= 1e3 * 3.0
