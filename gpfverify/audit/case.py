"""Rank-condition audit of a fusion step (SPEC §3, use 3): which sensor's cross term C_xy^m lost
column rank, whether DMF is exact anyway, how large the gap is, and what repairs it.

For every sensor: the singular values of C_xy^m, the canonical correlations ρ of state and sensor
output, the rank under the *rank rule* (:class:`~gpfverify.fusion.exactness.RankRule`; default
``canonical``: ρ_i > τ = :data:`~gpfverify.tolerances.CANONICAL_RANK_TOL`, unit-free; a case's
``rank_tol`` or an explicit ``rank_tol`` means the ``absolute`` rule on singular values; ``numpy``:
σ_max · max(D, l_m) · eps), the tolerance that decided it (``tol``, in the rule's own units: τ for
canonical, a singular value otherwise), the condition number σ_max/σ_min of C_xy^m, the
necessary-and-sufficient exactness verdict (the gap gain in prior standard deviations per unit
whitened innovation against its rounding bound; :mod:`gpfverify.fusion.exactness`,
docs/fusion-definitions.md), and the repair dimension l_m − r_m with its basis N_m. DMF is eq. 35
with the Moore–Penrose inverse at the decided rank; when a sensor lost rank under the canonical rule
the audit also gives the unit-free variant's mean and its distance from DMF's (``unit_free_dmf_mean``,
``unit_dependence``, prior standard deviations) in a note.

JSON (:func:`audit_to_dict`): top-level ``"rank_rule"`` = {"name", "tol" (null for numpy, whose
tolerance is per matrix), "covariance" (whitening covariance of the canonical correlations:
"local C_p from C_e", "central C_p", "mixed" when the sensors differ, null when none could be
computed), "description"}; per sensor ``"rank_rule"`` = {"name", "tol" (the one used for this
matrix), "covariance"} and ``"canonical_correlations"`` (reported under every rule when the
whitening succeeds, else null).

With y: CMF, the observed gap DMF − CMF (also as ``gap_size`` in prior standard deviations, with
the step's rounding bound ``gap_bound`` and ``reproduced`` = within it), the closed-form gap,
each sensor's repair message
k_m = (I − P_m)(C_y^m)⁻¹(y^m − μ_y^m) (an l_m-vector, basis-free), the repaired DMF, and how far
each logged local posterior is from the local update with that y (when it is not, the observed and
predicted gaps may differ).
Without y the gap cannot be evaluated: μ_e^m − μ_p^m = C_xy^m w_m fixes w_m = (C_y^m)⁻¹(y^m − μ_y^m)
only on range(P_m); the kernel component (I − P_m) w_m = N_m Ñ_mᵀ w_m is lost, and the gap is
−Σ_m G_m C_y^m N_m Ñ_mᵀ w_m (so ``gap_gain_norm`` is the largest gap per unit of lost component).

:func:`audit_run` applies the same audit to every step of a filter run.

With y, each sensor's own share of the gap, 2π G_m n_m − G_m C_y^m k_m, says which sensor's
report drives it (``gap_contribution`` in state units, ``gap_contribution_size`` its size in prior
standard deviations, the unit of ``gap_size``). n_m are the *branch offsets* of its angle outputs
(:func:`~gpfverify.fusion.exactness.branch_offsets`): where the separately wrapped eq. 35 terms
wrap(μ_y^m − μ_y(m)) + wrap(y^m − μ_y^m) leave (−π, π], DMF's innovation differs from CMF's
wrap(y^m − μ_y(m)) by 2π; the audit reports them per sensor and in a note, and the predicted gap
includes them. Angle outputs are wrapped in every residual (the local consistency check too).

With ``sensitivity=True`` each sensor also gets the Jacobian norms of the fused mean with
respect to what it reports (casadi AD, :func:`gpfverify.symbolic.sensitivity.dmf_sensitivity`) and
the bound ‖G_m C_y^m‖₂ / σ_r(C_xy^m) on the μ_e^m Jacobian, which grows as C_xy^m nears rank loss.
"""

from __future__ import annotations

from dataclasses import dataclass
from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from gpfverify.angles import difference
from gpfverify.errors import NumericalError
from gpfverify.fusion.case import FusionCase
from gpfverify.fusion.caseblock import case_from_records
from gpfverify.fusion.centralized import cmf_update
from gpfverify.fusion.distributed import DMFResult, dmf_update, fused_mean
from gpfverify.fusion.exactness import (COVARIANCE_CENTRAL, COVARIANCE_LOCAL, DEFAULT_RANK_RULE,  # noqa: F401
                                        NUMPY_RANK_RULE, RankRule, analyse_sensors, branch_offsets, canonical_split,
                                        equivalence_tolerance, gap_size,
                                        local_consistency_residual, parse_rank_rule, predicted_gap,
                                        resolve_rank_rule, sensor_gap, sensor_prior_covariance,
                                        whitened_innovation)
from gpfverify.linalg import correlation_condition
from gpfverify.runtime import one_blas_thread
from gpfverify.tolerances import algebra_rtol
from gpfverify.views import HtmlView

if TYPE_CHECKING:  # casadi is imported only when sensitivities are asked for
    from gpfverify.symbolic.sensitivity import SensorSensitivity

RANK_RULE_DEFAULT = DEFAULT_RANK_RULE.describe() + "; a case's rank_tol means the absolute rule"

NOTE_NO_Y = ("y not given: the gap cannot be evaluated. mu_e^m - mu_p^m = C_xy^m w_m determines the "
             "whitened local innovation w_m = (C_y^m)^-1 (y^m - mu_y^m) only on range(P_m) (the rank "
             "rule's split); its kernel component (I - P_m) w_m (repair_dim dimensions per sensor) is "
             "lost, and the gap is -sum_m G_m C_y^m (I - P_m) w_m (gap_gain_norm = largest gap per unit "
             "of that component).")


@dataclass(frozen=True)
class SensorAudit:
    """Evidence for one sensor (fields as in the ``audit --json`` output)."""

    index: int
    rows: int
    cols: int
    rank: int
    singular_values: np.ndarray
    tol: float
    condition_number: float
    gap_gain_norm: float
    exactness_tol: float
    exact: bool
    repair_basis: np.ndarray
    repair_message: np.ndarray | None = None
    local_consistency_residual: float | None = None
    consistency_tol: float | None = None
    gap_contribution: np.ndarray | None = None
    gap_contribution_size: float | None = None
    sensitivity: SensorSensitivity | None = None
    branch_offsets: np.ndarray | None = None
    rank_rule: RankRule | None = None
    canonical_correlations: np.ndarray | None = None
    covariance: str | None = None

    @property
    def full_column_rank(self) -> bool:
        return self.rank == self.cols

    @property
    def repair_dim(self) -> int:
        return self.cols - self.rank


@dataclass(frozen=True)
class CaseAudit(HtmlView):
    """Audit of one fusion case: ``rank_rule`` the :class:`RankRule` that decided,
    ``condition_holds`` (Proposition 1: every C_xy^m full column rank), ``exact`` (the
    necessary-and-sufficient condition for every sensor that reported); the y-dependent fields
    are None without y; ``missing`` the run's sensors that did not report at this step (the audit
    is of the others: each :class:`SensorAudit`'s ``index`` is the sensor's among the run's). In a
    notebook it shows as the text ``gpfverify audit CASE.json`` prints
    (:func:`gpfverify.notebook.case_audit_html`)."""

    sensors: tuple[SensorAudit, ...]
    rank_rule: RankRule
    condition_holds: bool
    exact: bool
    dmf_mean: np.ndarray
    cmf_mean: np.ndarray | None = None
    gap: np.ndarray | None = None
    predicted_gap: np.ndarray | None = None
    repaired_dmf_mean: np.ndarray | None = None
    gap_size: float | None = None
    gap_bound: float | None = None
    prediction_error: float | None = None
    unit_free_dmf_mean: np.ndarray | None = None
    unit_dependence: float | None = None
    missing: tuple[int, ...] = ()

    @property
    def sensor_count(self) -> int:
        """N, the run's sensors (those audited and those that did not report)."""
        return len(self.sensors) + len(self.missing)

    @property
    def reproduced(self) -> bool | None:
        """Whether DMF equals CMF to the rounding bound of the step (``gap_size`` ≤ ``gap_bound``,
        both in prior standard deviations); None without y."""
        if self.gap_size is None or self.gap_bound is None:
            return None
        return self.gap_size <= self.gap_bound

    @property
    def covariance(self) -> str | None:
        """Whitening covariance of the canonical correlations: the sensors' common one, "mixed", or
        None when none was computed."""
        used = {s.covariance for s in self.sensors if s.covariance is not None}
        return None if not used else used.pop() if len(used) == 1 else "mixed"

    @property
    def notes(self) -> list[str]:
        notes = []
        if self.cmf_mean is None:
            notes.append(NOTE_NO_Y)
        if self.missing:
            notes.append(f"sensor(s) {list(self.missing)} did not report at this step: eq. 35, CMF and the rank "
                         "condition are over the sensors that did")
        if self.exact and not self.condition_holds:
            notes.append("the rank condition of Proposition 1 fails but DMF is exact: every lost "
                         "kernel direction lies in ker G_m C_y^m")
        lost = [s.index for s in self.sensors if not s.full_column_rank]
        if lost and self.unit_dependence is not None:
            notes.append(f"sensor(s) {lost} lost rank: DMF's Moore-Penrose inverse (eq. 35) then depends on the "
                         f"units of state and outputs; the unit-free variant (whitened truncation) gives a mean "
                         f"{self.unit_dependence:.3g} prior standard deviations away (unit_free_dmf_mean)")
        elif lost and self.rank_rule.name != "canonical":
            notes.append(f"sensor(s) {lost} lost rank under the {self.rank_rule.name} rule, whose decision "
                         f"depends on units (singular values of C_xy^m); the canonical rule decides without them")
        bad = [s.index for s in self.sensors if s.local_consistency_residual is not None
               and s.consistency_tol is not None and s.local_consistency_residual > s.consistency_tol]
        if bad:
            notes.append(f"the logged local posterior of sensor(s) {bad} is not the local update with "
                         f"the logged y: the observed gap need not equal the predicted gap")
        elif (self.prediction_error is not None and self.gap_bound is not None
              and self.prediction_error > self.gap_bound):
            notes.append(f"the observed gap differs from the predicted one by {self.prediction_error:.3g} prior "
                         f"standard deviations, beyond the step's rounding bound {self.gap_bound:.3g}")
        branched = [f"sensor {s.index} output {j} (n = {n:+d})" for s in self.sensors
                    if s.branch_offsets is not None for j, n in enumerate(s.branch_offsets) if n]
        if branched:
            notes.append("branch offset on angle output(s) " + ", ".join(branched) + ": wrap(mu_y^m - mu_y(m)) "
                         "+ wrap(y^m - mu_y^m) leaves (-pi, pi], so DMF's innovation there differs from CMF's "
                         "wrap(y^m - mu_y(m)) by 2 pi n and the gap gains 2 pi n G_m e_j (included in "
                         "predicted_gap and gap_contribution; repair messages do not remove it)")
        return notes


def _consistency_tol(case: FusionCase, m: int) -> float:
    """Rounding level of μ_e^m − μ_p^m − C_xy^m w_m for a consistent record: w_m = (C_y^m)⁻¹(…) is
    a Cholesky solve, whose rounding follows the condition of C_y^m's correlation matrix (units do
    not change it)."""
    local = case.locals[m]
    scale = np.linalg.norm(local.mu_e - local.mu_p) + np.linalg.norm(local.mu_e) + np.linalg.norm(local.mu_p)
    return float(algebra_rtol(correlation_condition(local.C_y)) * scale)


def _correlations(case: FusionCase, m: int, split) -> tuple[np.ndarray | None, str | None]:
    """Canonical correlations of sensor m (from its split under the canonical rule, else computed
    for the report) and the covariance that whitened the state; (None, None) if not computable."""
    if split.correlations is not None:
        return split.correlations, split.covariance
    local = case.locals[m]
    try:
        prior, which = sensor_prior_covariance(local, case.central.C_p)
        try:
            return canonical_split(local.C_xy, prior, local.C_y, covariance=which).correlations, which
        except NumericalError:
            if which != COVARIANCE_LOCAL:
                raise
            return canonical_split(local.C_xy, case.central.C_p, local.C_y).correlations, COVARIANCE_CENTRAL
    except (NumericalError, np.linalg.LinAlgError):
        return None, None


def _unit_free_variant(case: FusionCase, rule: RankRule, dmf: DMFResult) -> tuple[np.ndarray | None, float | None]:
    """(the unit-free variant's mean, its distance from DMF's in prior standard deviations) when a
    sensor lost rank under the canonical rule (the variant needs it), else (None, None)."""
    if rule.name != "canonical" or dmf.condition_holds:
        return None, None
    # the variant's splits under the same central gain and scale DMF already computed
    sensors = analyse_sensors(case, dmf.gain, rank_rule=rule, unit_free=True, scale=dmf.scale)
    variant = fused_mean(case, dmf.gain, sensors)
    return variant, gap_size(case, difference(dmf.mean, variant, case.circular_state), dmf.scale)


@one_blas_thread
def audit_case(case: FusionCase, rank_tol: float | None = None, sensitivity: bool = False,
               rank_rule: RankRule | str | None = None, dmf: DMFResult | None = None) -> CaseAudit:
    """The rank-condition audit of one case under ``rank_rule`` (a :class:`RankRule` or its string,
    :func:`parse_rank_rule`), else the absolute ``rank_tol``, else the case's ``rank_tol``
    (absolute), else the canonical rule; ``sensitivity`` adds the per-sensor Jacobian norms
    (imports casadi; their pseudo-inverse follows the absolute/numpy rule — the canonical rule's
    split is not available to the casadi forms, so under it they use numpy's rule).

    ``dmf``: the caller's :func:`~gpfverify.fusion.distributed.dmf_update` of this same ``case``
    (a fusion run's step has it already), used instead of computing it again when it was made under
    the rule the audit resolves (and is not the unit-free variant); otherwise it is computed here.
    The audit is the same either way: ``dmf_update`` is a function of the case and the rule alone."""
    rule = resolve_rank_rule(case, rank_rule, rank_tol)
    if dmf is None or dmf.rank_rule != rule or dmf.unit_free:
        dmf = dmf_update(case, rank_rule=rule)
    has_y = case.y is not None
    jacobians: list[SensorSensitivity | None] = [None] * len(dmf.sensors)
    if sensitivity:
        from gpfverify.symbolic.sensitivity import dmf_sensitivity

        jacobians = list(dmf_sensitivity(case, rule.tol if rule.name == "absolute" else None))
    offsets = branch_offsets(case) if has_y else []
    sensors, messages = [], []
    for s in dmf.sensors:
        rank = s.split.rank
        message = contribution = offset = contribution_size = None
        residual = None
        if has_y:
            y_m = case.local_measurement(s.index)
            message = s.split.kernel_component(whitened_innovation(case.locals[s.index], y_m))
            messages.append(message)
            residual = float(np.linalg.norm(local_consistency_residual(case, s.index)))
            offset = offsets[s.index]
            contribution = sensor_gap(case, s, dmf.gain, offset)
            contribution_size = gap_size(case, contribution, dmf.scale)
        rho, covariance = _correlations(case, s.index, s.split)
        sensors.append(SensorAudit(
            index=case.sensor_ids[s.index], rows=rank.shape[0], cols=rank.shape[1], rank=rank.rank,
            singular_values=rank.singular_values, tol=rank.tol, condition_number=rank.condition_number,
            gap_gain_norm=s.residual, exactness_tol=s.tol, exact=s.exact,
            repair_basis=s.split.kernel_basis, repair_message=message,
            local_consistency_residual=residual,
            consistency_tol=_consistency_tol(case, s.index) if has_y else None,
            gap_contribution=contribution, gap_contribution_size=contribution_size, sensitivity=jacobians[s.index],
            branch_offsets=offset, rank_rule=rule, canonical_correlations=rho,
            covariance=covariance))
    unit_free_mean, unit_dependence = _unit_free_variant(case, rule, dmf)
    missing = tuple(sorted(set(range(case.sensor_count)) - set(case.sensor_ids)))
    if case.y is None:
        return CaseAudit(tuple(sensors), rule, dmf.condition_holds, dmf.exact, dmf.mean,
                         unit_free_dmf_mean=unit_free_mean, unit_dependence=unit_dependence, missing=missing)
    cmf = cmf_update(case.central, case.y, dmf.gain)
    repaired = fused_mean(case, dmf.gain, dmf.sensors, messages)
    gap = difference(dmf.mean, cmf.mean, case.circular_state)
    predicted = predicted_gap(case, dmf.sensors, dmf.gain)
    return CaseAudit(tuple(sensors), rule, dmf.condition_holds, dmf.exact, dmf.mean, cmf.mean, gap, predicted,
                     repaired, gap_size=gap_size(case, gap, dmf.scale),
                     gap_bound=equivalence_tolerance(case, dmf.gain, dmf.sensors, dmf.scale),
                     prediction_error=gap_size(case, difference(gap, predicted, case.circular_state), dmf.scale),
                     unit_free_dmf_mean=unit_free_mean, unit_dependence=unit_dependence, missing=missing)


def rank_rule_to_dict(rule: RankRule, covariance: str | None = None, tol: float | None = None) -> dict:
    """{"name", "tol", "covariance"}: ``tol`` overrides the rule's own (numpy's is per matrix)."""
    return {"name": rule.name, "tol": rule.tol if tol is None else float(tol), "covariance": covariance}


def _finite_or_none(x: float):
    return float(x) if np.isfinite(x) else None


def _measured(audit: CaseAudit) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """(CMF mean, gap, predicted gap, repaired DMF mean) of an audit with the measurement y, else None."""
    if (audit.cmf_mean is None or audit.gap is None or audit.predicted_gap is None
            or audit.repaired_dmf_mean is None):
        return None
    return audit.cmf_mean, audit.gap, audit.predicted_gap, audit.repaired_dmf_mean


def _measurement_fields(s: SensorAudit) -> dict:
    """A sensor's fields that need the measurement y (empty without it)."""
    if s.repair_message is None or s.gap_contribution is None or s.branch_offsets is None:
        return {}
    return {"repair_message": s.repair_message.tolist(),
            "local_consistency_residual": s.local_consistency_residual,
            "gap_contribution": s.gap_contribution.tolist(),
            "gap_contribution_size": s.gap_contribution_size,
            "branch_offsets": s.branch_offsets.tolist()}


def audit_to_dict(audit: CaseAudit) -> dict:
    """The ``audit --json`` object (CONTRACT.md fields plus documented extras)."""
    out = {
        "sensors": [{
            "index": s.index, "rows": s.rows, "cols": s.cols, "rank": s.rank,
            "rank_rule": rank_rule_to_dict(audit.rank_rule, s.covariance, s.tol),
            "canonical_correlations": None if s.canonical_correlations is None
            else s.canonical_correlations.tolist(),
            "full_column_rank": s.full_column_rank, "singular_values": s.singular_values.tolist(),
            "tol": s.tol, "exact": s.exact, "repair_dim": s.repair_dim,
            "condition_number": _finite_or_none(s.condition_number),
            "gap_gain_norm": s.gap_gain_norm, "exactness_tol": s.exactness_tol,
            "repair_basis": s.repair_basis.tolist(),
            **_measurement_fields(s),
            **({} if s.sensitivity is None else {"sensitivity": {
                "jacobian_norms": s.sensitivity.jacobian_norms, "sigma_r": s.sensitivity.sigma_r,
                "mu_e_bound": _finite_or_none(s.sensitivity.mu_e_bound),
                "rank_rule": "absolute" if audit.rank_rule.name == "absolute" else "numpy"}}),
        } for s in audit.sensors],
        "rank_rule": {**rank_rule_to_dict(audit.rank_rule, audit.covariance),
                      "description": audit.rank_rule.describe()},
        "condition_holds": audit.condition_holds,
        "exact": audit.exact,
        "dmf_mean": audit.dmf_mean.tolist(),
    }
    if audit.missing:
        out["missing_sensors"] = list(audit.missing)
    measured = _measured(audit)
    if measured is not None:
        cmf_mean, gap, predicted, repaired = measured
        out.update({"cmf_mean": cmf_mean.tolist(), "gap": gap.tolist(),
                    "predicted_gap": predicted.tolist(),
                    "gap_norm": float(np.linalg.norm(gap)),
                    "gap_residual": float(np.linalg.norm(gap - predicted)),
                    "gap_size": audit.gap_size, "gap_bound": audit.gap_bound, "reproduced": audit.reproduced,
                    "prediction_error": audit.prediction_error,
                    "repaired_dmf_mean": repaired.tolist()})
    if audit.unit_free_dmf_mean is not None:
        out.update({"unit_free_dmf_mean": audit.unit_free_dmf_mean.tolist(),
                    "unit_dependence": audit.unit_dependence})
    out["notes"] = audit.notes
    return out


def _vec(v) -> str:
    return "[" + ", ".join(f"{x:.6g}" for x in v) + "]"


def format_audit(audit: CaseAudit) -> str:
    """Human-readable audit report."""
    rule = audit.rank_rule
    decided = "canonical correlations (tau)" if rule.name == "canonical" else "singular values (tol)"
    lines = [f"rank rule ({rule.spec}): {rule.describe()}"
             + (f"; whitened with {audit.covariance}" if audit.covariance else ""),
             f"the rank is decided by the {decided}", ""]
    header = f"{'sensor':>6} {'D x l':>7} {'rank':>4} {'full col':>8} {'cond':>10} {'exact':>5} " \
             f"{'gap gain':>10} {'repair':>6}  {decided}; other"
    lines.append(header)
    for s in audit.sensors:
        cond = "inf" if not np.isfinite(s.condition_number) else f"{s.condition_number:.3g}"
        rho = "n/a" if s.canonical_correlations is None else _vec(s.canonical_correlations)
        if rule.name == "canonical":
            evidence = f"rho {rho} ({s.tol:.3g}); singular values {_vec(s.singular_values)}"
        else:
            evidence = f"singular values {_vec(s.singular_values)} ({s.tol:.3g}); rho {rho}"
        lines.append(f"{s.index:>6} {f'{s.rows}x{s.cols}':>7} {s.rank:>4} {str(s.full_column_rank):>8} "
                     f"{cond:>10} {str(s.exact):>5} {s.gap_gain_norm:>10.3g} {s.repair_dim:>6}  {evidence}")
    lines += ["", f"Proposition 1 condition (every C_xy^m full column rank): {audit.condition_holds}",
              f"DMF exact for every measurement (ker C_xy^m in ker G_m C_y^m): {audit.exact}",
              f"DMF mean: {_vec(audit.dmf_mean)} (eq. 35, Moore-Penrose inverse at the decided rank)"]
    if audit.unit_free_dmf_mean is not None:
        lines.append(f"unit-free variant's mean: {_vec(audit.unit_free_dmf_mean)}")
    measured = _measured(audit)
    if measured is not None:
        cmf_mean, gap, predicted, repaired = measured
        lines += [f"CMF mean: {_vec(cmf_mean)}",
                  f"gap DMF - CMF: {_vec(gap)} (norm {np.linalg.norm(gap):.3g})",
                  f"predicted gap: {_vec(predicted)} "
                  f"(|observed - predicted| = {np.linalg.norm(gap - predicted):.3g})",
                  f"gap in prior standard deviations: {audit.gap_size:.3g}, "
                  f"{'within' if audit.reproduced else 'beyond'} the step's rounding bound {audit.gap_bound:.3g}",
                  f"repaired DMF mean: {_vec(repaired)}"]
        for s in audit.sensors:
            if s.repair_dim:
                lines.append(f"sensor {s.index} repair message (kernel component of w_m, {s.repair_dim} "
                             f"dimension(s)): {_vec(s.repair_message)}; "
                             f"its share of the gap: {_vec(s.gap_contribution)}")
    for s in audit.sensors:
        if s.sensitivity is not None:
            norms = ", ".join(f"{k} {'n/a' if v is None else f'{v:.3g}'}"
                              for k, v in s.sensitivity.jacobian_norms.items())
            lines.append(f"sensor {s.index} sensitivity |d mu_DMF / d report|: {norms}; bound on the mu_e "
                         f"term |G_m C_y^m| / sigma_r = {s.sensitivity.mu_e_bound:.3g} "
                         f"(sigma_r = {s.sensitivity.sigma_r:.3g})")
    lines += [f"note: {n}" for n in audit.notes]
    return "\n".join(lines)


@dataclass(frozen=True)
class RunAudit(HtmlView):
    """Audit of every step (T) and sensor (N) of a run: per-step :class:`CaseAudit` plus arrays
    rank, full_column_rank, exact, condition_number, repair_dim (T, N) and gap_norm,
    predicted_gap_norm (T,) (NaN where a step has no y); ``reported`` (T, N) where each sensor
    reported — where it did not, the per-sensor arrays hold a fill value (rank and repair_dim 0,
    full_column_rank and exact True, condition_number NaN: nothing was audited, nothing failed). In a
    notebook it shows as the page of ``gpfverify audit RUN --out DIR``
    (:func:`gpfverify.notebook.run_audit_html`)."""

    steps: tuple[CaseAudit, ...]

    def _per_sensor(self, attr: str, dtype=float, fill=np.nan) -> np.ndarray:
        count = max(step.sensor_count for step in self.steps)
        out = np.full((len(self.steps), count), fill, dtype=dtype)
        for t, step in enumerate(self.steps):
            for s in step.sensors:
                out[t, s.index] = getattr(s, attr)
        return out

    @property
    def reported(self) -> np.ndarray:
        out = np.ones((len(self.steps), max(step.sensor_count for step in self.steps)), dtype=bool)
        for t, step in enumerate(self.steps):
            out[t, list(step.missing)] = False
        return out

    @property
    def rank(self) -> np.ndarray:
        return self._per_sensor("rank", int, 0)

    @property
    def full_column_rank(self) -> np.ndarray:
        return self._per_sensor("full_column_rank", bool, True)

    @property
    def exact(self) -> np.ndarray:
        return self._per_sensor("exact", bool, True)

    @property
    def condition_number(self) -> np.ndarray:
        return self._per_sensor("condition_number")

    @property
    def repair_dim(self) -> np.ndarray:
        return self._per_sensor("repair_dim", int, 0)

    @property
    def gap_norm(self) -> np.ndarray:
        return np.array([np.nan if s.gap is None else np.linalg.norm(s.gap) for s in self.steps])

    @property
    def predicted_gap_norm(self) -> np.ndarray:
        return np.array([np.nan if s.predicted_gap is None else np.linalg.norm(s.predicted_gap)
                         for s in self.steps])


def audit_run(cases: Iterable[FusionCase], rank_tol: float | None = None,
              rank_rule: RankRule | str | None = None) -> RunAudit:
    """The audit of every step of a run (rule as in :func:`audit_case`)."""
    rule = None if rank_rule is None else resolve_rank_rule(None, rank_rule, rank_tol)
    return RunAudit(tuple(audit_case(c, rank_tol, rank_rule=rule) if rule is None
                          else audit_case(c, rank_rule=rule) for c in cases))


def cases_from_run(central_records: Sequence, local_records: Sequence[Sequence], sizes: Sequence[int],
                   ys: Sequence | None = None, circular: Sequence[int] = ()) -> list[FusionCase]:
    """Fusion cases from a run's records: ``central_records[k]`` holds the centre's prediction at step
    k (e.g. the CMF :class:`~gpfverify.filters.records.StepRecord`), ``local_records[k][m]`` sensor
    m's step record, ``ys[k]`` the stacked measurement, ``circular`` its angle outputs."""
    return [case_from_records(central, locals_k, sizes, None if ys is None else ys[k], circular=circular)
            for k, (central, locals_k) in enumerate(zip(central_records, local_records))]
