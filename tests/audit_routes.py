"""Comparing two routes to the same audit (``audit --json`` step objects): the per-step
:func:`gpfverify.audit.case.audit_case` and the block route of :mod:`gpfverify.audit.block`, which round
differently.

Everything that is not a float must be equal: ranks, verdicts (exact, condition_holds,
reproduced, full_column_rank), rank rules, covariances used, shapes, branch offsets, notes (with
the numbers they render read as the fields' names; those fields are compared as below).
Floats agree to ``algebra_rtol(κ)`` relative, κ the largest condition number σ_1/σ_r of the step's
C_xy^m on the range its rank rule keeps (r its decided rank; the generalised inverse A_m amplifies
rounding by it). Some floats are rounding noise in both routes, or carry an error that is not
relative to their own size, and are compared by what bounds them instead (computed here from the
case, by numpy, not by the code under test):

* the means where there is a y (CMF's, DMF's, the repaired one): to ``rtol`` times the sizes they
  are summed from, |μ_p| + |C_xy| |C_y⁻¹ (y ⊖ μ_y)| + Σ_m |g_m| (g_m sensor m's share of the gap),
  or relative (a mean that cancels to 1e-33 is rounding noise of those sizes);
* the means without a y, and the unit-free variant's mean: to ``rtol`` times the sizes eq. 35
  combines, ‖μ_p‖₁ + Σ_m ‖μ_e^m‖₁ + ‖μ_DMF‖₁ + ‖μ_CMF‖₁, or relative (a mean that cancels to zero
  is rounding noise of the local estimates it is combined from);
* the gap μ_DMF − μ_CMF, its norms and the predicted gap (state units): each route subtracts its
  own two means (or sums the sensors' shares of their difference), so the routes differ by at most
  the means' own rounding, ``rtol · (‖μ_DMF‖₁ + ‖μ_CMF‖₁)`` plus the sizes the means are summed from
  (above: two means that cancel to 1e-34 differ by rounding noise of those), or agree relative (the
  means may vanish where a share does not); each sensor's share of the gap, made from the local estimates and the
  local update's correction C_xy^m w_m, to ``rtol`` times the sizes eq. 35 combines (as the means
  without a y) plus ‖ |C_xy^m| |(C_y^m)⁻¹| |y^m ⊖ μ_y^m| ‖₁, or relative;
* sizes in prior standard deviations of what is rounding noise where it vanishes — a sensor's
  share of the gap, the distance of the unit-free variant's mean from DMF's — to ``rtol`` times the
  whitened size of the means they are differences of, ‖ |L_p⁻¹| (|μ| + |μ'|) ‖ (L_p the Cholesky
  factor of C_p), a share also to its own bound above whitened, ‖L_p⁻¹‖₁ times it;
* the gap in prior standard deviations (gap_size, prediction_error): both routes' ``reproduced``
  verdicts (gap_size ≤ gap_bound) and notes must agree, and each value must lie within the larger
  route's bound of the other, or within ``rtol`` of it where it is far above the bound; the note
  that compares the prediction error with the bound may differ only when an error lies within the
  larger bound of a bound (each route's error rounds by that much, so either side may be taken);
* the local consistency residual ‖μ_e^m − μ_p^m − C_xy^m w_m‖: each route rounds it at the level
  of a solve with C_y^m, ``algebra_rtol(κ(corr C_y^m)) · (‖μ_e^m − μ_p^m‖ + ‖μ_e^m‖ + ‖μ_p^m‖
  + ‖ |C_xy^m| |(C_y^m)⁻¹| |y^m ⊖ μ_y^m| ‖)``;
  the routes agree within twice that;
* what an SVD gives normwise: singular values and canonical correlations to ``rtol`` times the
  largest (a lost direction's is rounding noise of that size); a sensor's condition number
  σ_1/σ_min, whose relative error is ``rtol · σ_1/σ_min`` (beyond 1/rtol both routes only say
  "unresolved"); the kernel basis N_m, defined up to an orthogonal rotation, as its projector
  N_m N_mᵀ;
* the repair message k_m = N_m N_mᵀ w_m, a projection of the whitened innovation
  w_m = (C_y^m)⁻¹(y^m ⊖ μ_y^m): to ``rtol · ‖w_m‖_∞``;
* the gap gain R_m, which is rounding noise up to its bound τ_m when the sensor is exact: to
  ``rtol · R_m`` plus the larger of the two routes' τ_m.
"""

from __future__ import annotations

import re

import numpy as np

from gpfverify.angles import difference
from gpfverify.fusion.case import FusionCase
from gpfverify.linalg import correlation_condition
from gpfverify.tolerances import algebra_rtol

GAP_FIELDS = ("gap", "predicted_gap", "gap_norm", "gap_residual")
PRIOR_SD_FIELDS = ("gap_size", "prediction_error")
#: fields whose values the notes render (to 3 significant digits)
NOTE_FIELDS = ("unit_dependence", "prediction_error", "gap_bound")
#: means compared by the sizes they are summed from where there is a y (relative without one)
MEAN_FIELDS = ("cmf_mean", "dmf_mean", "repaired_dmf_mean")
OWN_RULE_FIELDS = (*MEAN_FIELDS, *GAP_FIELDS, *PRIOR_SD_FIELDS, "unit_free_dmf_mean", "unit_dependence", "notes",
                   "sensors")
OWN_RULE_SENSOR_FIELDS = ("singular_values", "canonical_correlations", "condition_number", "repair_basis",
                          "repair_message", "gap_gain_norm", "local_consistency_residual", "gap_contribution",
                          "gap_contribution_size")


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


def _within(expected, got, atol, path: str, rtol: float = 0.0) -> None:
    """Elementwise within ``atol`` plus ``rtol`` times the larger of the two values."""
    a, b = np.asarray(expected, dtype=float), np.asarray(got, dtype=float)
    slack = atol + rtol * np.maximum(np.abs(a), np.abs(b))
    assert a.shape == b.shape and bool(np.all(np.abs(a - b) <= slack)), (path, expected, got, atol, rtol)


def step_rtol(step: dict) -> float:
    """algebra_rtol of the largest σ_1/σ_r among the step's cross covariances, r the decided rank."""
    conditions = [s["singular_values"][0] / s["singular_values"][s["rank"] - 1] for s in step["sensors"]
                  if s["rank"] and s["singular_values"][s["rank"] - 1] > 0]
    return algebra_rtol(max(conditions, default=1.0))


def consistency_slack(case: FusionCase, m: int) -> float:
    """Twice the rounding level of sensor m's local consistency residual (module docstring)."""
    local = case.locals[m]
    innovation = np.abs(difference(case.local_measurement(m), local.mu_y, local.circular))
    correction = np.abs(local.C_xy) @ (np.abs(np.linalg.inv(local.C_y)) @ innovation)
    size = (np.linalg.norm(local.mu_e - local.mu_p) + np.linalg.norm(local.mu_e) + np.linalg.norm(local.mu_p)
            + np.linalg.norm(correction))
    return 2.0 * algebra_rtol(correlation_condition(local.C_y)) * float(size)


class _Scales:
    """The case's sizes the comparisons are relative to (module docstring)."""

    def __init__(self, case: FusionCase, expected: dict, rtol: float):
        self.case, self.rtol = case, rtol
        self.inverse = np.abs(np.linalg.inv(np.linalg.cholesky(case.central.C_p)))   # |L_p⁻¹|
        self.has_y = "cmf_mean" in expected
        self.means = np.abs(expected["dmf_mean"]) + (np.abs(expected["cmf_mean"]) if self.has_y else 0.0)

    def state(self) -> float:
        """rtol · (‖μ_DMF‖₁ + ‖μ_CMF‖₁)."""
        return self.rtol * float(self.means.sum())

    def estimates(self) -> float:
        """rtol · (‖μ_p‖₁ + Σ_m ‖μ_e^m‖₁ + ‖μ_DMF‖₁ + ‖μ_CMF‖₁): the sizes eq. 35 and its unit-free
        variant combine, which a mean that cancels to zero is rounded relative to."""
        local = sum(float(np.abs(r.mu_e).sum()) for r in self.case.locals)
        return self.state() + self.rtol * (float(np.abs(self.case.central.mu_p).sum()) + local)

    def mean_terms(self, sensors: list) -> np.ndarray:
        """rtol · (|μ_p| + |C_xy| |C_y⁻¹| |y ⊖ μ_y| + Σ_m |g_m|): the sizes CMF's mean is summed
        from (the solve's weights C_y⁻¹(y ⊖ μ_y) are rounded relative to |C_y⁻¹| |y ⊖ μ_y|, not to
        themselves: a weight that cancels to zero carries that rounding), and the sensors' shares
        g_m of the gap that DMF's and the repaired mean differ from it by."""
        c = self.case.central
        weights = np.abs(np.linalg.inv(c.C_y)) @ np.abs(difference(self.case.y, c.mu_y, c.circular))
        shares = sum((np.abs(np.asarray(s["gap_contribution"], dtype=float)) for s in sensors),
                     np.zeros(len(c.mu_p)))
        return self.rtol * (np.abs(c.mu_p) + np.abs(c.C_xy) @ weights + shares)

    def share(self, m: int) -> float:
        """rtol · (the sizes eq. 35 combines + ‖ |C_xy^m| |(C_y^m)⁻¹| |y^m ⊖ μ_y^m| ‖₁): what sensor m's
        share of the gap is made from, its local estimates and its update's correction C_xy^m w_m, whose
        weights w_m are rounded relative to |(C_y^m)⁻¹| |y^m ⊖ μ_y^m| (as in :meth:`mean_terms`; a share
        that cancels to zero is rounding noise of those)."""
        local, y = self.case.locals[m], self.case.local_measurement(m)
        weights = np.abs(np.linalg.inv(local.C_y)) @ np.abs(difference(y, local.mu_y, local.circular))
        return self.estimates() + self.rtol * float((np.abs(local.C_xy) @ weights).sum())

    def whitened_share(self, m: int) -> float:
        """:meth:`share` in prior standard deviations: ‖ |L_p⁻¹| v ‖₂ ≤ ‖L_p⁻¹‖₁ ‖v‖₁."""
        return float(self.inverse.sum(axis=0).max()) * self.share(m)

    def whitened(self, magnitudes: np.ndarray) -> float:
        """rtol · ‖ |L_p⁻¹| m ‖."""
        return self.rtol * float(np.linalg.norm(self.inverse @ magnitudes))

    def innovation(self, m: int) -> float:
        """rtol · ‖w_m‖_∞, w_m = (C_y^m)⁻¹(y^m ⊖ μ_y^m)."""
        local, y = self.case.locals[m], self.case.local_measurement(m)
        return self.rtol * float(np.abs(np.linalg.solve(local.C_y, difference(y, local.mu_y, local.circular))).max())


def _normwise(expected: list, got: list, path: str, rtol: float) -> None:
    scale = max(np.abs(np.asarray(expected, dtype=float)).max(initial=0.0),
                np.abs(np.asarray(got, dtype=float)).max(initial=0.0))
    _within(expected, got, rtol * scale, path)


def _condition_numbers(expected: float | None, got: float | None, path: str, rtol: float) -> None:
    """σ_1/σ_min (None: infinite) to its relative error rtol · σ_1/σ_min."""
    a, b = (np.inf if x is None else x for x in (expected, got))
    if a == b:
        return
    larger = max(a, b)
    assert abs(a - b) <= rtol * larger * larger or rtol * min(a, b) >= 1.0, (path, expected, got, rtol)


def _same_sensor(m: int, a: dict, b: dict, scales: _Scales) -> None:
    path, rtol = f"sensors[{m}]", scales.rtol
    _leaves_equal({k: v for k, v in a.items() if k not in OWN_RULE_SENSOR_FIELDS},
                  {k: v for k, v in b.items() if k not in OWN_RULE_SENSOR_FIELDS}, path, rtol)
    assert set(a) == set(b), (path, set(a) ^ set(b))
    for key in ("singular_values", "canonical_correlations"):
        if a[key] is not None or b[key] is not None:
            _normwise(a[key], b[key], f"{path}.{key}", rtol)
    _condition_numbers(a["condition_number"], b["condition_number"], f"{path}.condition_number", rtol)
    bases = [np.asarray(s["repair_basis"], dtype=float).reshape(s["cols"], -1) for s in (a, b)]
    assert bases[0].shape == bases[1].shape, path
    _within(bases[0] @ bases[0].T, bases[1] @ bases[1].T, rtol, f"{path}.repair_basis")
    gain_slack = rtol * max(a["gap_gain_norm"], b["gap_gain_norm"]) + max(a["exactness_tol"], b["exactness_tol"])
    assert abs(a["gap_gain_norm"] - b["gap_gain_norm"]) <= gain_slack, (path, a["gap_gain_norm"], b["gap_gain_norm"])
    if "repair_message" not in a:
        return
    _within(a["repair_message"], b["repair_message"], scales.innovation(m), f"{path}.repair_message", rtol)
    _within(a["gap_contribution"], b["gap_contribution"], scales.share(m), f"{path}.gap_contribution", rtol)
    share_slack = (scales.whitened(scales.means) + scales.whitened_share(m)
                   + rtol * max(a["gap_contribution_size"], b["gap_contribution_size"]))
    assert abs(a["gap_contribution_size"] - b["gap_contribution_size"]) <= share_slack, (path, a, b)
    assert abs(a["local_consistency_residual"] - b["local_consistency_residual"]) <= consistency_slack(
        scales.case, m), (path, a, b)


#: how the note that compares the prediction error with the step's rounding bound begins
PREDICTION_NOTE = "the observed gap differs from the predicted one"


def _at_the_bound(step: dict, other: dict) -> bool:
    """Whether either route's prediction error lies within the larger bound of either route's bound:
    there the two routes, each within the other's bound of the error, may fall on either side of it."""
    bounds = [s.get("gap_bound") for s in (step, other)]
    errors = [s.get("prediction_error") for s in (step, other)]
    if None in bounds or None in errors:
        return False
    slack = max(bounds)
    return any(abs(e - b) <= slack for e in errors for b in bounds)


def _notes_read(step: dict, other: dict) -> list[str]:
    """The step's notes with the numbers they render read as the fields' names; the note comparing
    the prediction error with the rounding bound left out when the error sits at the bound in
    either route (``_at_the_bound``)."""
    notes = step["notes"]
    if _at_the_bound(step, other):
        notes = [n for n in notes if not n.startswith(PREDICTION_NOTE)]
    for key in NOTE_FIELDS:
        if step.get(key) is not None:
            rendered = re.compile(rf"(?<= ){re.escape(f'{step[key]:.3g}')}(?= |$)")
            notes = [rendered.sub(f"<{key}>", n) for n in notes]
    return notes


def assert_same_audit(expected: dict, got: dict, case: FusionCase) -> None:
    """``got`` is the audit ``expected`` is of ``case``, to each field's rounding (module docstring)."""
    rtol = step_rtol(expected)
    scales = _Scales(case, expected, rtol)
    _leaves_equal({k: v for k, v in expected.items() if k not in OWN_RULE_FIELDS},
                  {k: v for k, v in got.items() if k not in OWN_RULE_FIELDS}, "", rtol)
    assert set(expected) == set(got), set(expected) ^ set(got)
    assert _notes_read(expected, got) == _notes_read(got, expected), (expected["notes"], got["notes"])
    if "unit_dependence" in expected:
        slack = scales.whitened(np.abs(expected["dmf_mean"]) + np.abs(expected["unit_free_dmf_mean"]))
        assert abs(expected["unit_dependence"] - got["unit_dependence"]) <= slack, (expected, got)
    assert len(expected["sensors"]) == len(got["sensors"])
    for m, (a, b) in enumerate(zip(expected["sensors"], got["sensors"])):
        _same_sensor(m, a, b, scales)
    if "unit_free_dmf_mean" in expected:
        _within(expected["unit_free_dmf_mean"], got["unit_free_dmf_mean"], scales.estimates(), "unit_free_dmf_mean",
                rtol)
    if not scales.has_y:
        assert set(MEAN_FIELDS) & set(expected) == set(MEAN_FIELDS) & set(got)
        for key in set(MEAN_FIELDS) & set(expected):
            _within(expected[key], got[key], scales.estimates(), key, rtol)
        return
    terms = scales.mean_terms(expected["sensors"])
    for key in MEAN_FIELDS:
        if key in expected:
            _within(expected[key], got[key], terms, key, rtol)
    for key in ("gap", "predicted_gap"):
        _within(expected[key], got[key], scales.state() + terms, key, rtol)
    for key in ("gap_norm", "gap_residual"):
        slack = scales.state() + float(terms.sum()) + rtol * max(abs(got[key]), abs(expected[key]))
        assert abs(got[key] - expected[key]) <= slack, (key, expected[key], got[key])
    for key in PRIOR_SD_FIELDS:  # within the larger bound, or relative where the value is far above it
        slack = max(expected["gap_bound"], got["gap_bound"]) + rtol * max(abs(got[key]), abs(expected[key]))
        assert abs(got[key] - expected[key]) <= slack, (key, expected, got)
