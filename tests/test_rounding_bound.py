"""The step's rounding bound (docs/fusion-definitions.md, "Rounding bound") and the verdicts it
decides, in prior standard deviations: tight on well-conditioned steps (within 10³ of the rounding
gap actually observed), small enough that a planted DMF error of 1e-8 of the state scale is beyond
it, and the exactness verdict judged against the fused estimate's scale (a sensor whose gain is
1e-12 of the others' is exact, whatever its units)."""

import dataclasses

import numpy as np

from gpfverify.audit.case import audit_case
from gpfverify.fusion.centralized import cmf_update
from gpfverify.fusion.distributed import dmf_update
from gpfverify.fusion.exactness import equivalence_tolerance, gap_size, rescaled_case
from gpfverify.fusion.synthetic import random_case


def _whitened(case, v) -> float:
    """‖L_p⁻¹ v‖ with numpy's own Cholesky (independent of the code's whitening)."""
    return float(np.linalg.norm(np.linalg.solve(np.linalg.cholesky(case.central.C_p), v)))


def _full_rank_cases(count: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        dim = int(rng.integers(2, 6))
        sizes = tuple(int(rng.integers(1, dim + 1)) for _ in range(int(rng.integers(1, 4))))
        yield random_case(rng, dim, sizes)


def test_the_bound_holds_and_is_within_a_thousand_of_the_observed_rounding_gap():
    ratios = []
    for case in _full_rank_cases(60):
        dmf = dmf_update(case)
        assert dmf.exact and dmf.condition_holds
        observed = _whitened(case, dmf.mean - cmf_update(case.central, case.y, dmf.gain).mean)
        bound = equivalence_tolerance(case, dmf.gain, dmf.sensors)
        assert observed <= bound
        if observed > 0:
            ratios.append(bound / observed)
    assert len(ratios) >= 30  # most steps round to a nonzero gap
    assert np.median(ratios) <= 1e3, np.percentile(ratios, [10, 50, 90])


def test_a_planted_dmf_error_of_1e_8_of_the_state_scale_is_beyond_rounding():
    for case in _full_rank_cases(20, seed=1):
        dmf = dmf_update(case)
        cmf = cmf_update(case.central, case.y, dmf.gain).mean
        bound = equivalence_tolerance(case, dmf.gain, dmf.sensors)
        state_scale = np.sqrt(np.diag(case.central.C_p))
        direction = np.random.default_rng(2).choice([-1.0, 1.0], case.state_dim)
        planted = dmf.mean + 1e-8 * state_scale * direction
        assert gap_size(case, planted - cmf) > bound
        assert gap_size(case, dmf.mean - cmf) <= bound


def test_the_audit_reports_a_planted_report_error_beyond_the_bound():
    """A logged local posterior off by 1e-8 prior standard deviations: DMF moves by about that, and
    the audit says the gap is beyond rounding (while the sensors stay exact)."""
    case = random_case(np.random.default_rng(3), 3, (2, 3))
    clean = audit_case(case)
    assert clean.exact and clean.reproduced
    local = case.locals[0]
    shifted = dataclasses.replace(local, mu_e=local.mu_e + 1e-8 * np.sqrt(np.diag(local.C_e)))
    bad = audit_case(dataclasses.replace(case, locals=(shifted, case.locals[1])))
    assert bad.exact and bad.reproduced is False
    assert bad.gap_size > 1e3 * bad.gap_bound
    assert any("not the local update" in note for note in bad.notes)


def _with_third_sensor_noise(factor: float, offset: float):
    """Three sensors, the third with l = 3 > D = 2 (it loses rank) and its outputs' noise standard
    deviations ×``factor`` (its gain about 1/factor of what it was), every state mean shifted by
    ``offset`` (the fused estimate's magnitude; covariances unchanged)."""
    rng = np.random.default_rng(4)
    base = random_case(rng, 2, (2, 2, 3))
    c, local = base.central, base.locals[2]
    extra = (factor ** 2 - 1) * np.diag(local.C_y)
    c_y = c.C_y.copy()
    c_y[4:, 4:] += np.diag((factor ** 2 - 1) * np.diag(c.C_y)[4:])
    local_c_y = local.C_y + np.diag(extra)
    y = base.y.copy()
    y[4:] = local.mu_y + factor * np.sqrt(np.diag(local.C_y)) * rng.normal(size=3)
    k = np.linalg.solve(local_c_y, local.C_xy.T).T
    prior = local.C_e + local.C_xy @ np.linalg.solve(local.C_y, local.C_xy.T)
    local = dataclasses.replace(local, C_y=local_c_y, mu_e=local.mu_p + k @ (y[4:] - local.mu_y),
                                C_e=prior - k @ local.C_xy.T)
    shift = np.full(2, offset)
    moved = [dataclasses.replace(r, mu_p=r.mu_p + shift, mu_e=r.mu_e + shift) for r in (*base.locals[:2], local)]
    central = dataclasses.replace(c, C_y=c_y, mu_p=c.mu_p + shift)
    return dataclasses.replace(base, central=central, locals=tuple(moved), y=y)


def test_a_saturated_sensor_is_exact_and_a_weak_one_is_not():
    """Gain 1e-14 of what it was, on an estimate of size 1e3 prior standard deviations: its gap per
    unit innovation is below the estimate's own rounding, so it is exact (in any units); gain 1e-6
    of what it was leaves a real gap: not exact."""
    saturated = _with_third_sensor_noise(1e14, 1e3)
    for case in (saturated, rescaled_case(saturated, [1e-4, 1.0], [1e6, 1, 1, 1, 1, 1, 1])):
        audit = audit_case(case)
        assert not audit.sensors[2].full_column_rank
        assert all(s.exact for s in audit.sensors), [(s.gap_gain_norm, s.exactness_tol) for s in audit.sensors]
        assert audit.reproduced
    weak = audit_case(_with_third_sensor_noise(1e6, 1e3))
    assert not weak.sensors[2].full_column_rank and not weak.sensors[2].exact


def test_verdicts_do_not_depend_on_units():
    """State ×1e-4 on one component and one output ×1e6: the same ranks, exactness and reproduction
    verdicts, and the gap in prior standard deviations the same to rounding."""
    for case in list(_full_rank_cases(10, seed=5)) + [random_case(np.random.default_rng(6), 3, (5, 2))]:
        outputs = np.ones(case.central.mu_y.size)
        outputs[0] = 1e6
        states = np.ones(case.state_dim)
        states[-1] = 1e-4
        a, b = audit_case(case), audit_case(rescaled_case(case, states, outputs))
        assert [s.rank for s in a.sensors] == [s.rank for s in b.sensors]
        assert [s.exact for s in a.sensors] == [s.exact for s in b.sensors]
        assert a.reproduced == b.reproduced
