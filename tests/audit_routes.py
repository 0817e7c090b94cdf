"""Comparing two routes to the same audit (``audit --json`` step objects): the per-step
:func:`gpfverify.audit.audit_case` and the block route of :mod:`gpfverify.blockaudit`, which round
differently.

Everything that is not a float must be equal: ranks, verdicts (exact, condition_holds,
reproduced, full_column_rank), rank rules, covariances used, shapes, notes. Floats agree to
``algebra_rtol(κ)`` relative, κ the largest condition number σ_1/σ_r of the step's full-rank
C_xy^m (the reconstruction A_m amplifies rounding by it). Three kinds of float are rounding noise
in both routes and are compared by what bounds them instead:

* the gap μ_DMF − μ_CMF and its norms (state units): each route subtracts its own two means, so the
  routes differ by at most the means' own differences, ``rtol · (‖μ_DMF‖₁ + ‖μ_CMF‖₁)``;
* the gap in prior standard deviations (gap_size, prediction_error): both routes' ``reproduced``
  verdicts (gap_size ≤ gap_bound) and notes must agree, and each value must lie within the other
  route's bound of it;
* the local consistency residual ‖μ_e^m − μ_p^m − C_xy^m w_m‖: each route rounds it at the level
  of a solve with C_y^m, ``algebra_rtol(κ(corr C_y^m)) · (‖μ_e^m − μ_p^m‖ + ‖μ_e^m‖ + ‖μ_p^m‖)``;
  the routes agree within twice that.
"""

from __future__ import annotations

import numpy as np

from gpfverify.fusion.case import FusionCase
from gpfverify.linalg import correlation_condition
from gpfverify.tolerances import algebra_rtol

GAP_FIELDS = ("gap", "gap_norm", "gap_residual")
PRIOR_SD_FIELDS = ("gap_size", "prediction_error")


def _leaves_equal(expected, got, path: str, rtol: float) -> None:
    if isinstance(expected, dict):
        assert isinstance(got, dict) and set(expected) == set(got), (path, set(expected) ^ set(got))
        for key in expected:
            _leaves_equal(expected[key], got[key], f"{path}.{key}", rtol)
    elif isinstance(expected, list):
        assert isinstance(got, list) and len(expected) == len(got), path
        for i, (a, b) in enumerate(zip(expected, got)):
            _leaves_equal(a, b, f"{path}[{i}]", rtol)
    elif isinstance(expected, float) and isinstance(got, float):
        assert abs(expected - got) <= rtol * max(abs(expected), abs(got)), (path, expected, got, rtol)
    else:
        assert type(expected) is type(got) and expected == got, (path, expected, got)


def step_rtol(step: dict) -> float:
    """algebra_rtol of the largest σ_1/σ_r among the step's full-rank cross covariances."""
    conditions = [s["condition_number"] for s in step["sensors"]
                  if s["full_column_rank"] and s["condition_number"] is not None]
    return algebra_rtol(max(conditions, default=1.0))


def consistency_slack(case: FusionCase, m: int) -> float:
    """Twice the rounding level of sensor m's local consistency residual (module docstring)."""
    local = case.locals[m]
    size = (np.linalg.norm(local.mu_e - local.mu_p) + np.linalg.norm(local.mu_e) + np.linalg.norm(local.mu_p))
    return 2.0 * algebra_rtol(correlation_condition(local.C_y)) * float(size)


def assert_same_audit(expected: dict, got: dict, case: FusionCase) -> None:
    """``got`` is the audit ``expected`` is of ``case``, to each field's rounding (module docstring)."""
    rtol = step_rtol(expected)
    skip = {*GAP_FIELDS, *PRIOR_SD_FIELDS}
    _leaves_equal({k: v for k, v in expected.items() if k not in skip and k != "sensors"},
                  {k: v for k, v in got.items() if k not in skip and k != "sensors"}, "", rtol)
    assert len(expected["sensors"]) == len(got["sensors"])
    for i, (a, b) in enumerate(zip(expected["sensors"], got["sensors"])):
        _leaves_equal({k: v for k, v in a.items() if k != "local_consistency_residual"},
                      {k: v for k, v in b.items() if k != "local_consistency_residual"}, f"sensors[{i}]", rtol)
        if "local_consistency_residual" in a:
            slack = consistency_slack(case, i)
            assert abs(a["local_consistency_residual"] - b["local_consistency_residual"]) <= slack, (i, a, b)
    if "gap" not in expected:
        assert not set(skip) & set(got)
        return
    means = float(np.abs(expected["dmf_mean"]).sum() + np.abs(expected["cmf_mean"]).sum())
    np.testing.assert_allclose(got["gap"], expected["gap"], rtol=0, atol=rtol * means)
    for key in ("gap_norm", "gap_residual"):
        assert abs(got[key] - expected[key]) <= rtol * means, (key, expected[key], got[key])
    for key in PRIOR_SD_FIELDS:
        assert abs(got[key] - expected[key]) <= max(expected["gap_bound"], got["gap_bound"]), (key, expected, got)
