"""The rank rule of the audit and of eq. 35 (:class:`gpfverify.fusion.exactness.RankRule`).

(b) a range-bearing sensor: numpy's σ_max rule (and an absolute tolerance) change their verdict
when the bearing is in microradians instead of radians; the canonical rule does not.
(c) a tiny scalar cross term that numpy's rule calls full rank is uninformative (ρ ≤ τ) under the
canonical rule. (d) the repair message does not depend on the kernel basis (sign flips, rotations)
and the repaired DMF equals CMF. Plus the API: parser, precedence, reporting, model_fusion's
numpy default.
"""

import dataclasses

import numpy as np
import pytest

from gpfverify.audit.case import audit_case, audit_run, audit_to_dict, format_audit
from gpfverify.errors import InputError
from gpfverify.fusion.case import CentralPrediction, FusionCase, LocalReport
from gpfverify.fusion.centralized import cmf_update
from gpfverify.fusion.distributed import dmf_update
from gpfverify.fusion import exactness
from gpfverify.fusion.exactness import (COVARIANCE_CENTRAL, COVARIANCE_LOCAL, DEFAULT_RANK_RULE, RankRule,
                                        analyse_sensors, equivalence_tolerance, parse_rank_rule,
                                        repair_message, rescaled_case,
                                        resolve_rank_rule, sensor_split, whitened_innovation)
from gpfverify.fusion.synthetic import random_case
from gpfverify.linalg import canonical_correlations
from gpfverify.tolerances import CANONICAL_RANK_TOL, EPS, algebra_rtol

MICRO = 1e6  # radians -> microradians


def _range_condition(split) -> float:
    """σ_1/σ_r over the singular values of C_xy^m the split keeps (1 when it keeps none)."""
    s = split.rank.singular_values[: split.rank.rank]
    return float(s[0] / s[-1]) if s.size else 1.0



def linear_case(c_p, h, r, mu_p, mu_y_offset, z) -> FusionCase:
    """One sensor sharing the centre's prior: y = H x + v, v ~ N(0, R); y = μ_y + chol(C_y) z and
    the exact local update with that y."""
    c_p, h, r = (np.asarray(a, dtype=float) for a in (c_p, h, r))
    mu_p = np.asarray(mu_p, dtype=float)
    c_xy = c_p @ h.T
    c_y = h @ c_p @ h.T + r
    mu_y = h @ mu_p + np.asarray(mu_y_offset, dtype=float)
    y = mu_y + np.linalg.cholesky(c_y) @ np.asarray(z, dtype=float)
    gain = np.linalg.solve(c_y, c_xy.T).T
    local = LocalReport(mu_p, mu_y, c_y, c_xy, mu_p + gain @ (y - mu_y), c_p - gain @ c_xy.T)
    central = CentralPrediction(mu_p, c_p, mu_y, c_y, c_xy, (h.shape[0],))
    return FusionCase(central, (local,), y)


def range_bearing_case(range_m=1e6, radial_std=1e3, tangential_std=1e-2, range_noise=10.0, bearing_noise=1e-6):
    """A distant target on the x axis, state (x, y) in metres, prior much tighter across the line
    of sight than along it; outputs range (m) and bearing (rad), linearised: H = diag(1, 1/r)."""
    return linear_case(np.diag([radial_std ** 2, tangential_std ** 2]), np.diag([1.0, 1.0 / range_m]),
                       np.diag([range_noise ** 2, bearing_noise ** 2]), [range_m, 0.0], [0.0, 0.0], [0.3, -0.7])


def in_microradians(case):
    return rescaled_case(case, np.ones(case.state_dim), [1.0, MICRO])


# -- (b) units ------------------------------------------------------------------------------------

def test_numpy_rule_flips_with_bearing_units_canonical_does_not():
    radians = range_bearing_case()
    micro = in_microradians(radians)
    s_rad = np.linalg.svd(radians.locals[0].C_xy, compute_uv=False)
    s_mic = np.linalg.svd(micro.locals[0].C_xy, compute_uv=False)
    # σ_min/σ_max moves by the unit factor alone (1e-16 -> 1e-10), across numpy's 2·eps threshold
    assert s_rad[-1] / s_rad[0] < 2 * EPS < s_mic[-1] / s_mic[0]
    assert (s_mic[-1] / s_mic[0]) / (s_rad[-1] / s_rad[0]) == pytest.approx(MICRO, rel=algebra_rtol())
    numpy_rad, numpy_mic = (audit_case(c, rank_rule="numpy") for c in (radians, micro))
    assert not numpy_rad.condition_holds and numpy_mic.condition_holds
    canon_rad, canon_mic = audit_case(radians), audit_case(micro)
    assert canon_rad.rank_rule == canon_mic.rank_rule == DEFAULT_RANK_RULE
    assert canon_rad.condition_holds and canon_mic.condition_holds and canon_rad.exact and canon_mic.exact
    np.testing.assert_allclose(canon_rad.sensors[0].canonical_correlations,
                               canon_mic.sensors[0].canonical_correlations, rtol=algebra_rtol(), atol=0)
    # the bearing really is informative: ρ ≈ (σ_t / r) / sqrt(σ_t² / r² + σ_b²) ≈ 1e-2
    assert min(canon_rad.sensors[0].canonical_correlations) == pytest.approx(1e-2, rel=1e-3)
    # and eq. 35 under the canonical rule equals CMF in both units
    for case, audit in ((radians, canon_rad), (micro, canon_mic)):
        dmf = dmf_update(case)
        np.testing.assert_allclose(audit.gap, 0.0, atol=equivalence_tolerance(case, dmf.gain, dmf.sensors))


def test_absolute_rule_flips_with_bearing_units():
    """An absolute singular-value tolerance has the units of C_xy^m: 1e-3 m·rad is not 1e-3 m·µrad."""
    radians = range_bearing_case(range_m=1e6, radial_std=1e3, tangential_std=10.0, bearing_noise=1e-4)
    micro = in_microradians(radians)
    rule = parse_rank_rule("absolute:1e-3")
    assert not audit_case(radians, rank_rule=rule).condition_holds
    assert audit_case(micro, rank_rule=rule).condition_holds
    assert audit_case(radians).condition_holds and audit_case(micro).condition_holds


# -- (c) a tiny cross term ------------------------------------------------------------------------

def test_tiny_scalar_cross_term_is_rank_under_numpy_but_not_canonical():
    """C_p = C_y = 1, C_xy = 1e-10: numpy's rule keeps it (σ = 1e-10 > 1e-10 · eps). Its canonical
    correlation ρ = 1e-10 is below τ = sqrt(eps): the measurement removes a fraction ρ² = 1e-20 of
    the prior variance, which double precision cannot even represent — the local posterior
    covariance C_e = 1 − ρ² is exactly C_p. The canonical rule calls it rank 0; DMF then drops the
    sensor, which leaves a gap of ρ prior standard deviations per unit innovation (not exact), and
    the repair message (the whole w, 1 number) restores CMF."""
    case = linear_case([[1.0]], [[1e-10]], [[1.0]], [0.0], [0.0], [2.0])
    assert case.locals[0].C_e[0, 0] == case.central.C_p[0, 0]  # 1 − 1e-20 == 1 in double precision
    numpy_audit = audit_case(case, rank_rule="numpy")
    assert numpy_audit.condition_holds and numpy_audit.exact
    audit = audit_case(case)
    (s,) = audit.sensors
    assert s.canonical_correlations == pytest.approx([1e-10], rel=algebra_rtol())
    assert s.rank == 0 and not s.full_column_rank and s.tol == CANONICAL_RANK_TOL
    assert not s.exact and s.gap_gain_norm == pytest.approx(1e-10, rel=algebra_rtol())
    tol = equivalence_tolerance(case, dmf_update(case).gain, dmf_update(case).sensors)
    np.testing.assert_allclose(audit.repaired_dmf_mean, audit.cmf_mean, rtol=0, atol=tol)
    np.testing.assert_allclose(audit.gap, audit.predicted_gap, rtol=0, atol=tol)
    # the threshold itself: a correlation just above τ is kept
    kept = linear_case([[1.0]], [[3 * CANONICAL_RANK_TOL]], [[1.0]], [0.0], [0.0], [2.0])
    assert audit_case(kept).condition_holds


def test_canonical_threshold_is_selectable():
    case = linear_case(np.eye(2), [[1.0, 0.0], [0.0, 1e-4]], np.eye(2), [0.0, 0.0], [0.0, 0.0], [1.0, 1.0])
    assert audit_case(case).condition_holds
    strict = audit_case(case, rank_rule="canonical:1e-3")
    assert not strict.condition_holds and strict.sensors[0].tol == 1e-3 and strict.sensors[0].rank == 1


# -- (d) repair message ---------------------------------------------------------------------------

def _flipped(split, q):
    return dataclasses.replace(split, kernel_basis=split.kernel_basis @ q,
                               cokernel=None if split.cokernel is None else split.cokernel @ q)


@pytest.mark.parametrize("rule", ["canonical", "numpy"])
def test_repair_message_does_not_depend_on_the_kernel_basis(rule):
    case = random_case(np.random.default_rng(21), 2, (4, 2))  # sensor 0: rank 2 of 4, a 2-dim kernel
    local, y_m = case.locals[0], case.local_measurement(0)
    split = sensor_split(local, parse_rank_rule(rule), case.central.C_p)
    assert split.kernel_basis.shape == (4, 2)
    message = repair_message(local, y_m, rank_rule=rule)
    w = whitened_innovation(local, y_m)
    rotation = np.array([[np.cos(0.7), -np.sin(0.7)], [np.sin(0.7), np.cos(0.7)]])
    for q in (np.diag([-1.0, 1.0]), -np.eye(2), rotation):
        other = _flipped(split, q)
        np.testing.assert_allclose(repair_message(local, y_m, split=other), message, rtol=0,
                                   atol=algebra_rtol(np.linalg.cond(local.C_y)) * np.linalg.norm(w))
        # the basis coordinates themselves do move: that is why they are not what is sent
        assert not np.allclose(other.dual_basis.T @ w, split.dual_basis.T @ w)
    messages = [repair_message(r, case.local_measurement(m), rank_rule=rule) for m, r in enumerate(case.locals)]
    dmf = dmf_update(case, rank_rule=rule)
    repaired = dmf_update(case, messages, rank_rule=rule)
    assert not dmf.exact and repaired.repaired
    np.testing.assert_allclose(repaired.mean, cmf_update(case.central, case.y).mean, rtol=0,
                               atol=equivalence_tolerance(case, dmf.gain, dmf.sensors))
    # the centre projects the message: the whole w_m works as well as its kernel component
    whole = [whitened_innovation(r, case.local_measurement(m)) for m, r in enumerate(case.locals)]
    np.testing.assert_allclose(dmf_update(case, whole, rank_rule=rule).mean, repaired.mean, rtol=0,
                               atol=equivalence_tolerance(case, dmf.gain, dmf.sensors))


def test_repair_message_shape_is_checked():
    case = random_case(np.random.default_rng(22), 2, (3, 2))
    with pytest.raises(InputError, match="kernel component"):
        dmf_update(case, [np.zeros(1), np.zeros(2)])


def test_unit_free_split_is_an_oblique_projector_with_the_gap_formula():
    """The unit-free variant: A_m C_xy^m = P_m idempotent, C_y^m P_m symmetric, I − P_m = N_m Ñ_mᵀ,
    Ñ_m = C_y^m N_m; and its DMF's observed gap is the predicted one."""
    case = random_case(np.random.default_rng(23), 3, (5,))
    local = case.locals[0]
    split = sensor_split(local, DEFAULT_RANK_RULE, case.central.C_p, unit_free=True)
    p = split.pinv @ local.C_xy
    rho, r = split.correlations, split.rank.rank
    tol = algebra_rtol(rho[0] / rho[r - 1] * split.whitening.whitening_condition * np.linalg.cond(local.C_y))
    np.testing.assert_allclose(p @ p, p, atol=tol)
    np.testing.assert_allclose(local.C_y @ p, (local.C_y @ p).T, atol=tol * np.linalg.norm(local.C_y))
    np.testing.assert_allclose(np.eye(5) - p, split.kernel_basis @ split.cokernel.T, atol=tol)
    np.testing.assert_allclose(split.cokernel, local.C_y @ split.kernel_basis, atol=tol * np.linalg.norm(local.C_y))
    assert not np.allclose(p, p.T)  # oblique
    dmf = dmf_update(case, unit_free=True)
    cmf = cmf_update(case.central, case.y, dmf.gain)
    sensors = analyse_sensors(case, dmf.gain, unit_free=True)
    observed, predicted = dmf.mean - cmf.mean, exactness.predicted_gap(case, sensors, dmf.gain)
    assert exactness.gap_size(case, observed - predicted) <= equivalence_tolerance(case, dmf.gain, dmf.sensors)


def test_moore_penrose_split_is_the_orthogonal_projector_at_the_decided_rank():
    """The default (DMF) split under the canonical rule: the rank the canonical correlations
    decide, and A_m = (C_xy^m)⁺ truncated there in C_xy^m's own SVD, so P_m = A_m C_xy^m is the
    orthogonal projector onto the top-r right singular vectors (symmetric, idempotent)."""
    case = random_case(np.random.default_rng(23), 3, (5,))
    local = case.locals[0]
    split = sensor_split(local, DEFAULT_RANK_RULE, case.central.C_p)
    r = int(np.sum(split.correlations > DEFAULT_RANK_RULE.tol))
    assert split.rank.rank == r
    _, _, vt = np.linalg.svd(local.C_xy)
    p = split.pinv @ local.C_xy
    tol = algebra_rtol(_range_condition(split))
    np.testing.assert_allclose(p, vt[:r].T @ vt[:r], atol=tol)
    np.testing.assert_allclose(np.eye(5) - p, split.kernel_basis @ split.kernel_basis.T, atol=tol)
    dmf = dmf_update(case)
    audit = audit_case(case)
    assert exactness.gap_size(case, audit.gap - audit.predicted_gap) <= equivalence_tolerance(
        case, dmf.gain, dmf.sensors)


# -- covariance used, API -------------------------------------------------------------------------

def test_local_prior_is_recovered_from_c_e_else_the_central_one_is_used():
    case = random_case(np.random.default_rng(24), 2, (2, 3))
    split = sensor_split(case.locals[0], DEFAULT_RANK_RULE, case.central.C_p)
    assert split.covariance == COVARIANCE_LOCAL
    # random_case's local prior is the sensor's own: C_e + C_xy C_y⁻¹ C_xyᵀ gives back its correlations
    local = case.locals[0]
    c_p = local.C_e + local.C_xy @ np.linalg.solve(local.C_y, local.C_xy.T)
    np.testing.assert_allclose(split.correlations, canonical_correlations(c_p, local.C_y, local.C_xy).correlations,
                               atol=algebra_rtol(np.linalg.cond(c_p)))
    assert np.all(split.correlations <= 1 + algebra_rtol(np.linalg.cond(c_p)))
    bare = dataclasses.replace(case, locals=tuple(dataclasses.replace(r, C_e=None) for r in case.locals))
    out = audit_to_dict(audit_case(bare))
    assert out["rank_rule"]["covariance"] == COVARIANCE_CENTRAL
    assert all(s["rank_rule"]["covariance"] == COVARIANCE_CENTRAL for s in out["sensors"])
    mixed = dataclasses.replace(case, locals=(bare.locals[0], case.locals[1]))
    assert audit_to_dict(audit_case(mixed))["rank_rule"]["covariance"] == "mixed"
    with pytest.raises(InputError, match="prior covariance"):
        repair_message(bare.locals[0], case.local_measurement(0))


@pytest.mark.parametrize("text, rule", [("canonical", RankRule("canonical", CANONICAL_RANK_TOL)),
                                        ("canonical:1e-6", RankRule("canonical", 1e-6)),
                                        ("absolute:1e-9", RankRule("absolute", 1e-9)),
                                        (" Numpy ", RankRule("numpy"))])
def test_parse_rank_rule(text, rule):
    assert parse_rank_rule(text) == rule
    assert parse_rank_rule(rule.spec) == rule


@pytest.mark.parametrize("text", ["", "svd", "absolute", "absolute:-1", "absolute:nan", "canonical:1.5",
                                  "canonical:x", "numpy:1e-9", "absolute:inf"])
def test_parse_rank_rule_rejects(text):
    with pytest.raises(InputError):
        parse_rank_rule(text)


def test_rule_precedence():
    case = random_case(np.random.default_rng(25), 2, (2, 2))
    assert resolve_rank_rule(case) == DEFAULT_RANK_RULE
    with_tol = dataclasses.replace(case, rank_tol=0.5)
    assert resolve_rank_rule(with_tol) == RankRule("absolute", 0.5)  # a case's rank_tol is absolute
    assert resolve_rank_rule(with_tol, rank_tol=0.1) == RankRule("absolute", 0.1)
    assert resolve_rank_rule(with_tol, "numpy") == RankRule("numpy")  # an explicit rule wins
    with pytest.raises(InputError, match="not both"):
        resolve_rank_rule(case, "numpy", 0.1)
    assert audit_case(with_tol).rank_rule == RankRule("absolute", 0.5)


def test_audit_reports_the_rule_top_level_and_per_sensor():
    case = random_case(np.random.default_rng(26), 3, (2, 4))
    for rule, name in ((None, "canonical"), ("numpy", "numpy"), ("absolute:1e-9", "absolute")):
        out = audit_to_dict(audit_case(case, rank_rule=rule))
        assert out["rank_rule"]["name"] == name and {"name", "tol", "covariance"} <= set(out["rank_rule"])
        for s in out["sensors"]:
            assert {"index", "rows", "cols", "rank", "full_column_rank", "singular_values", "tol", "exact",
                    "repair_dim", "rank_rule", "canonical_correlations"} <= set(s)
            assert s["rank_rule"]["name"] == name and s["rank_rule"]["tol"] == s["tol"]
            assert len(s["canonical_correlations"]) == min(s["rows"], s["cols"])
            assert len(s["repair_message"]) == s["cols"]
        text = format_audit(audit_case(case, rank_rule=rule))
        assert text.startswith(f"rank rule ({parse_rank_rule(rule or 'canonical').spec})")
        decided = "canonical correlations (tau)" if name == "canonical" else "singular values (tol)"
        assert f"the rank is decided by the {decided}" in text
    assert audit_to_dict(audit_case(case, rank_rule="numpy"))["rank_rule"]["tol"] is None


def test_audit_run_takes_the_rule():
    rng = np.random.default_rng(27)
    cases = [random_case(rng, 2, (2, 3)) for _ in range(3)]
    assert all(s.rank_rule.name == "numpy" for s in audit_run(cases, rank_rule="numpy").steps)
    assert all(s.rank_rule.name == "absolute" for s in audit_run(cases, rank_tol=1e-9).steps)
    assert all(s.rank_rule == DEFAULT_RANK_RULE for s in audit_run(cases).steps)


def test_model_fusion_defaults_to_the_canonical_rule_and_the_experiments_pass_theirs():
    """dmf_step/run_fusion default to the canonical rule, the one default of every entry point; a
    rule can be chosen (numpy's, the experiments' reference rule), and run_fusion's audit uses the
    DMF step's rule; both rules fuse this full-rank linear system alike."""
    from gpfverify.model_fusion import run_fusion
    from gpfverify.models import linear_model

    model = linear_model(np.eye(2), np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]), 0.1 * np.eye(2),
                         np.diag([0.5, 0.3, 0.4]), prior_mean=[1.0, 0.5], prior_cov=np.eye(2), sizes=(2, 1))
    ys = np.random.default_rng(28).normal(size=(3, 3))
    default = run_fusion(model, ys, family="kf", methods=("cmf", "dmf"))
    assert all(s.dmf.result.rank_rule == DEFAULT_RANK_RULE and s.audit.rank_rule == DEFAULT_RANK_RULE
               for s in default.steps)
    chosen = run_fusion(model, ys, family="kf", methods=("cmf", "dmf"), rank_rule="numpy")
    assert all(s.dmf.result.rank_rule.name == "numpy" and s.audit.rank_rule.name == "numpy" for s in chosen.steps)
    np.testing.assert_allclose(chosen.means("dmf"), default.means("dmf"), rtol=0,
                               atol=algebra_rtol(1e3) * np.abs(default.means("cmf")).max())


@pytest.mark.parametrize("options, expected", [({}, DEFAULT_RANK_RULE),
                                               ({"rank_tol": 1e-9}, RankRule("absolute", 1e-9)),
                                               ({"rank_rule": "numpy"}, RankRule("numpy"))])
def test_the_experiments_give_eq_35_their_own_rule(monkeypatch, options, expected):
    """The papers' experiments name the rule eq. 35 uses (the canonical rule by default, numpy's as
    the interpretation numpy-rank, absolute with --rank-tol), passed explicitly to every step."""
    from gpfverify.papers.fusion import run as fusion_run
    from gpfverify.papers.fusion import ungm1d_experiment as ungm1d
    from gpfverify.model_fusion import dmf_step

    seen = []

    def spy(*args, **kwargs):
        seen.append(kwargs.get("rank_rule"))
        return dmf_step(*args, **kwargs)

    monkeypatch.setattr(fusion_run, "dmf_step", spy)
    ungm1d.run_one(ungm1d.Params(train=15, test_steps=2, sweep=(), **options), np.random.SeedSequence(3))
    assert seen and all(rule == expected for rule in seen), seen
