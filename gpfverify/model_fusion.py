"""Centralized and distributed fusion (seed 000 §3) for any user model and Gaussian filter family.

``model`` is a :class:`~gpfverify.models.StateSpaceModel` (families ``kf``, ``ekf``, ``ukf``) or
a :class:`~gpfverify.models.GPModel` (``gp-adf``, ``gp-ukf``); ``family`` a name from
:data:`~gpfverify.filters.families.FAMILY_NAMES`. A wrong pairing is an
:class:`~gpfverify.errors.InputError`. The centre's model is the whole system (all sensors
stacked, so its C_y carries the cross-sensor blocks); sensor m's local filter runs on
``model.sensor_model(m)``.

* :func:`central_prediction`: the family's prediction N(μ_p, C_p) from a fused belief (eq. 18–19
  / 21–24) and the stacked measurement moments μ_y, C_y, C_xy (eq. 17 / 25–29), with the sensors'
  ``sizes`` and the angle outputs ``circular`` of the stacked measurement;
* :func:`cmf_step`: centralized fusion, μ_e = μ_p + C_xy C_y⁻¹ (y ⊖ μ_y), C_e = C_p − C_xy C_y⁻¹ C_xyᵀ
  (eq. 15–16 / 30–31; ⊖ wraps the angle outputs to (−π, π]);
* :func:`dmf_step`: the centre's own prediction and stacked moments, then eq. 35 with each
  sensor's local record (μ_p^m, μ_y^m, C_y^m, C_xy^m, μ_e^m), C_e as in CMF
  (:mod:`gpfverify.fusion.distributed`);
* :func:`run_fusion`: a whole run — every sensor's local filter, CMF and DMF each with its own
  recursion, the baselines on the local posteriors (cc: convex combination, also spelled cw; ci:
  covariance intersection; rcc-ci: relaxed Chebyshev centre CI, ellipsoids enlarged when they do
  not intersect; ici, ei: inverse covariance / ellipsoidal intersection; names in
  :mod:`gpfverify.fusion.names`) and the per-step rank-condition audit
  (:func:`gpfverify.audit.case.audit_case`).

Angle state components (``model.circular_state``) travel in every fusion case
(``central.circular_state``): eq. 35's μ_e^m − μ_p^m is taken on the circle and the fused means
are wrapped, DMF's as CMF's.
The convex-solver baselines (ci, rcc-ci, ici: cvxpy) are imported only when requested.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import partial
from typing import TYPE_CHECKING, Any
from collections.abc import Callable, Sequence

import numpy as np

from gpfverify.errors import InputError, NumericalError
from gpfverify.filters.families import GP_FAMILIES, GaussianFamily, gaussian_family
from gpfverify.filters.records import Gaussian, StepRecord
from gpfverify.filters.sigma_points import SigmaParams, SigmaSettings
from gpfverify.fusion.case import CentralPrediction, FusionCase, LocalReport, sensor_blocks, split_circular
from gpfverify.fusion.distributed import DMFResult, dmf_update
from gpfverify.fusion.names import FUSION_RULES, canonical_rule, canonical_rules
from gpfverify.fusion.exactness import RankRule, resolve_rank_rule
from gpfverify.models.learned import GPModel
from gpfverify.models.system import StateSpaceModel, require_model
from gpfverify.validate import real_floats
from gpfverify.runtime import one_blas_thread
from gpfverify.views import HtmlView
from gpfverify.fusion.estimates import FusedEstimate

if TYPE_CHECKING:
    from gpfverify.audit.case import CaseAudit, RunAudit
    from gpfverify.fusion.rcc_ci import RccCiResult

#: the fusion rules :func:`run_fusion` can run: every rule (one list for every command)
METHODS: tuple[str, ...] = FUSION_RULES
#: what :func:`run_fusion` runs unless told otherwise
DEFAULT_METHODS: tuple[str, ...] = ("cmf", "dmf", "cc", "ci", "rcc-ci")


def model_family(name: str, model, params: SigmaParams | SigmaSettings = SigmaParams()) -> GaussianFamily:
    """The family ``name`` after checking that ``model`` is the kind it filters (InputError)."""
    family = gaussian_family(name, params)  # any case; family.name is the lower-case key
    require_model(model, GPModel if family.name in GP_FAMILIES else StateSpaceModel, f"the {name} family")
    return family


def central_prediction(belief: Gaussian, model, *, k: int = 1, family: str = "ukf",
                       params: SigmaParams | SigmaSettings = SigmaParams()) -> tuple[Gaussian, CentralPrediction]:
    """The centre's prediction N(μ_p, C_p) from the fused ``belief`` and its stacked measurement
    moments at step ``k``."""
    chosen = model_family(family, model, params)
    prediction = chosen.predict(belief, model, k=k)
    moments = chosen.measurement(prediction, model, k=k)
    return prediction, CentralPrediction(prediction.mean, prediction.cov, moments.mu_y, moments.C_y,
                                         moments.C_xy, tuple(model.sizes), tuple(model.circular),
                                         tuple(model.circular_state))


def cmf_step(belief: Gaussian, model, y, *, k: int = 1, family: str = "ukf",
             params: SigmaParams | SigmaSettings = SigmaParams()) -> StepRecord:
    """One centralized-fusion cycle with the stacked measurement ``y`` (L,)."""
    return model_family(family, model, params).step(belief, model, y, k=k)


@dataclass(frozen=True)
class DMFStep:
    """The fused ``record`` (central prediction and moments, DMF posterior), the fusion ``case``
    the centre saw, the eq. 35 ``result`` with per-sensor rank/exactness diagnostics (None for a
    step of :func:`run_fusion_batch`, whose audit carries them) and
    ``update_seconds``, the time of eq. 35 itself on :func:`dmf_step`'s ``clock`` (:func:`dmf_update`:
    what is left to do once the measurements arrive; a measurement, left out of comparisons)."""

    record: StepRecord
    case: FusionCase
    result: DMFResult | None
    update_seconds: float = field(default=0.0, compare=False)


def local_reports(local_records: Sequence[StepRecord], central: CentralPrediction) -> tuple[LocalReport, ...]:
    """What each sensor sends (eq. 32–34), from its step record; InputError when a record does
    not fit the centre's sizes."""
    if len(local_records) != len(central.sizes):
        raise InputError(f"{len(central.sizes)} sensors but {len(local_records)} local records")
    reports = []
    for m, (r, size, circular) in enumerate(zip(local_records, central.sizes,
                                                split_circular(central.circular, central.sizes))):
        expected = (central.mu_p.shape[0], size)
        if np.shape(r.C_xy) != expected:
            raise InputError(f"local record {m} has C_xy of shape {np.shape(r.C_xy)}, expected {expected}")
        reports.append(LocalReport(r.mu_p, r.mu_y, r.C_y, r.C_xy, r.mu_e, r.C_e, circular))
    return tuple(reports)


def dmf_step(belief: Gaussian, model, y=None, *, local_records: Sequence[StepRecord], k: int = 1,
             family: str = "ukf", params: SigmaParams | SigmaSettings = SigmaParams(),
             rank_tol: float | None = None, rank_rule: RankRule | str | None = None,
             clock: Callable[[], float] = time.perf_counter, reported: Sequence[bool] | None = None) -> DMFStep:
    """One distributed-fusion cycle (eq. 35) from the fused ``belief``: ``local_records[m]`` is
    sensor m's step record from its own filter; ``y`` (stacked, optional) is kept in the case for
    the gap diagnostics only. ``reported`` (one flag per sensor; default: the sensors whose block
    of ``y`` is not NaN, else every one) says which sensors sent a report: eq. 35 sums over them
    (:meth:`~gpfverify.fusion.case.FusionCase.of_reports`). The rank rule is ``rank_rule``, else
    the absolute ``rank_tol``
    (also stored as the case's ``rank_tol``), else the canonical rule (the default of every entry
    point, :data:`~gpfverify.fusion.exactness.DEFAULT_RANK_RULE`); ``result.rank_rule`` says which
    decided. ``clock`` times eq. 35 (wall-clock by default; the experiments pass a CPU clock)."""
    _, central = central_prediction(belief, model, k=k, family=family, params=params)
    stacked = None if y is None else real_floats(y, "y").reshape(-1)
    if stacked is not None and stacked.shape != (int(sum(central.sizes)),):
        raise InputError(f"y must have {int(sum(central.sizes))} entries, got shape {np.shape(y)}")
    if reported is None:
        reported = [True] * len(central.sizes) if stacked is None else list(model.reported(stacked, "y"))
    reports = local_reports(local_records, central)
    case = FusionCase.of_reports(central, [r if here else None for r, here in zip(reports, reported)], stacked,
                                 rank_tol)
    rule = resolve_rank_rule(None, rank_rule, rank_tol)
    result, seconds = _timed(dmf_update, case, rank_rule=rule, clock=clock)
    record = StepRecord(central.mu_p, central.C_p, central.mu_y, central.C_y, central.C_xy, result.mean, result.cov)
    return DMFStep(record, case, result, seconds)


@dataclass(frozen=True)
class FusionStep:
    """Step ``k`` of a run: ``local`` the sensors' step records, ``cmf`` the CMF record, ``dmf``
    the DMF step (None for a method not run), ``baselines`` method → fused estimate (``mean``,
    ``cov``; rcc-ci gives the :class:`~gpfverify.fusion.rcc_ci.RccCiResult` with ``enlarged``),
    ``audit`` the :class:`~gpfverify.audit.case.CaseAudit` of ``dmf.case`` (None without audit) and
    ``seconds`` the wall-clock time per method (``"local"``: the sensors' filters, one entry each
    in ``local_seconds``); ``failed`` baseline → why it could not fuse at this step (a solver
    failure or an estimate that is not a covariance: :class:`~gpfverify.errors.NumericalError`),
    the run going on with the other methods."""

    k: int
    local: tuple[StepRecord, ...]
    cmf: StepRecord | None
    dmf: DMFStep | None
    baselines: dict
    audit: CaseAudit | None
    seconds: dict
    local_seconds: tuple[float, ...]
    failed: dict = field(default_factory=dict)

    def estimate(self, method: str) -> Gaussian:
        """The fused posterior of ``method`` (one of the run's methods, any accepted spelling)."""
        method = canonical_rule(method)
        if method == "cmf" and self.cmf is not None:
            return self.cmf.posterior
        if method == "dmf" and self.dmf is not None:
            return self.dmf.record.posterior
        if method in self.failed:
            raise NumericalError(f"{method} failed at step {self.k}: {self.failed[method]}")
        if method in self.baselines:
            return Gaussian(self.baselines[method].mean, self.baselines[method].cov)
        raise InputError(f"method {method!r} was not run at step {self.k}")


@dataclass(frozen=True)
class FusionRun(HtmlView):
    """A fusion run: the ``family``, the ``methods`` run and one :class:`FusionStep` per measurement;
    ``model`` and ``ys`` what it ran on, ``ci_criterion`` CI's weight criterion, ``params`` the
    sigma points of the unscented families. In a notebook it shows as ``gpfverify check``'s page
    (:func:`gpfverify.notebook.fusion_run_html`)."""

    family: str
    methods: tuple[str, ...]
    steps: tuple[FusionStep, ...]
    model: object = field(default=None, repr=False, compare=False)
    ys: np.ndarray | None = field(default=None, repr=False, compare=False)
    ci_criterion: str = "trace"
    params: SigmaSettings = SigmaSettings()
    rcc_metric: str = "euclidean"

    def means(self, method: str) -> np.ndarray:
        """Fused means of ``method`` at every step, (T, D)."""
        return np.array([s.estimate(method).mean for s in self.steps])

    def local_means(self, m: int) -> np.ndarray:
        """Sensor m's local posterior means at every step, (T, D)."""
        return np.array([s.local[m].mu_e for s in self.steps])

    @property
    def audit(self) -> RunAudit | None:
        """The per-step audits as a :class:`~gpfverify.audit.case.RunAudit` (None without audit)."""
        from gpfverify.audit.case import RunAudit

        if self.steps[0].audit is None:
            return None
        audits = []
        for s in self.steps:
            assert s.audit is not None  # run_fusion audits every step or none
            audits.append(s.audit)
        return RunAudit(tuple(audits))


def _timed(fn: Callable, *args, clock: Callable[[], float] = time.perf_counter, **kwargs):
    start = clock()
    out = fn(*args, **kwargs)
    return out, clock() - start


def _attempt(rule: Callable, beliefs: Sequence) -> tuple[object, str | None, float]:
    """``(fused estimate or None, why it failed or None, seconds)`` of one baseline at one step."""
    start = time.perf_counter()
    try:
        return rule(beliefs), None, time.perf_counter() - start
    except NumericalError as exc:
        return None, str(exc), time.perf_counter() - start


def _baselines(methods: Sequence[str], rcc_size: float | None,
               circular_state: Sequence[int], ci_criterion: str = "trace",
               rcc_metric: str = "euclidean") -> dict[str, Callable]:
    """The requested baselines as functions of the local posteriors, averaging the angle state
    components ``circular_state`` on the circle, CI and ICI with the weight criterion
    ``ci_criterion`` (convex solvers imported only when requested)."""
    out: dict[str, Callable[[Sequence], FusedEstimate | RccCiResult]] = {}
    if "cc" in methods:
        from gpfverify.fusion.convex import convex_combination
        out["cc"] = partial(convex_combination, circular_state=circular_state)
    if "ci" in methods:
        from gpfverify.fusion.ci import covariance_intersection
        out["ci"] = partial(covariance_intersection, criterion=ci_criterion, circular_state=circular_state)
    if "rcc-ci" in methods:
        from gpfverify.fusion.rcc_ci import rcc_ci
        out["rcc-ci"] = partial(rcc_ci, c=rcc_size, on_empty="enlarge", circular_state=circular_state,
                                metric=rcc_metric)
    if "ici" in methods:
        from gpfverify.fusion.ci import inverse_covariance_intersection
        out["ici"] = partial(inverse_covariance_intersection, criterion=ci_criterion, circular_state=circular_state)
    if "ei" in methods:
        from gpfverify.fusion.ellipsoidal import ellipsoidal_intersection
        out["ei"] = partial(ellipsoidal_intersection, circular_state=circular_state)
    return out


def _checked_methods(methods: Sequence[str], audit: bool) -> tuple[str, ...]:
    if isinstance(methods, str) or not methods:
        raise InputError(f"methods must be a non-empty sequence of rule names among {', '.join(METHODS)}, "
                         f"got {methods!r}")
    methods = canonical_rules(methods)
    if audit and "dmf" not in methods:
        raise InputError("audit=True audits the DMF step: include 'dmf' in methods or pass audit=False")
    return methods


def _priors(model, local_priors, fused_prior) -> tuple[list[Gaussian], Gaussian]:
    """The sensors' and the centre's starting beliefs (default: the model's prior)."""
    n = len(model.sizes)
    if isinstance(model, StateSpaceModel):
        default = Gaussian(model.prior_mean, model.prior_cov)
    elif local_priors is None or fused_prior is None:
        raise InputError("a GPModel has no prior: pass local_priors (one belief per sensor) and fused_prior")
    local = [default] * n if local_priors is None else list(local_priors)
    if len(local) != n:
        raise InputError(f"local_priors needs {n} beliefs (one per sensor), got {len(local)}")
    return local, default if fused_prior is None else fused_prior


@one_blas_thread
def run_fusion(model, ys, *, family: str = "ukf", methods: Sequence[str] = DEFAULT_METHODS, first_k: int = 1,
               params: SigmaParams | SigmaSettings = SigmaParams(), rank_tol: float | None = None,
               local_priors: Sequence[Gaussian] | None = None, fused_prior: Gaussian | None = None,
               audit: bool = True, rcc_size: float | None = None,
               rank_rule: RankRule | str | None = None, ci_criterion: str = "trace",
               rcc_metric: str = "euclidean", reported=None) -> FusionRun:
    """Filter the stacked measurements ``ys`` (T, L) — ``ys[t]`` at step k = first_k + t — with
    every sensor's local filter, CMF and DMF (each its own recursion from ``fused_prior``) and the
    chosen baselines (a baseline that fails at a step is recorded in ``FusionStep.failed`` and the run
    goes on); ``rcc_size`` is RCC-CI's ellipsoid size c (default χ²_D(0.99)) and ``rcc_metric`` the
    norm of its Chebyshev centre's error ("euclidean", the paper's, or "scaled": each component in
    its own scale, unit-free; :mod:`gpfverify.fusion.rcc_ci`); ``ci_criterion`` the
    weight criterion of CI and ICI: "trace" (the default; minimises the trace of the fused bound,
    which depends on the units of the state components) or "det" (its determinant: unit-free).
    Priors default to the model's (a GPModel has none: then both are required). ``rank_rule``/``rank_tol`` as in
    :func:`dmf_step` (default the canonical rule); the per-step audit uses the same rule.

    Missing measurements: a sensor that did not report at a step has NaN in its whole block of
    ``ys[t]``, or False in the mask ``reported`` (T, N). Its local filter then only predicts, CMF
    updates with the sensors that reported, eq. 35 sums over them and the audit judges the rank
    condition over them (:meth:`~gpfverify.fusion.case.FusionCase.of_reports`); the baselines fuse
    the posteriors of the sensors that reported. Every step needs at least one sensor."""
    chosen = model_family(family, model, params)
    methods = _checked_methods(methods, audit)
    ys, reported = with_missing(model, ys, reported)
    local_beliefs, fused = _priors(model, local_priors, fused_prior)
    sensor_models = [model.sensor_model(m) for m in range(len(model.sizes))]
    if ci_criterion not in ("trace", "det"):
        raise InputError(f"ci_criterion must be 'trace' or 'det', got {ci_criterion!r}")
    baselines = _baselines(methods, rcc_size, model.circular_state, ci_criterion, rcc_metric)
    cmf_belief = dmf_belief = fused
    steps = []
    for t, (y, here) in enumerate(zip(ys, reported)):
        k = first_k + t
        timed = [_timed(chosen.step, b, sm, y[block], k=k)
                 for b, sm, block in zip(local_beliefs, sensor_models, sensor_blocks(model.sizes))]
        local = tuple(r for r, _ in timed)
        local_beliefs = [r.posterior for r in local]
        seconds, cmf, dmf, fused_estimates = {"local": sum(s for _, s in timed)}, None, None, {}
        failed: dict[str, str] = {}
        if "cmf" in methods:
            cmf, seconds["cmf"] = _timed(cmf_step, cmf_belief, model, y, k=k, family=family, params=params)
            cmf_belief = cmf.posterior
        if "dmf" in methods:
            dmf, seconds["dmf"] = _timed(dmf_step, dmf_belief, model, y, local_records=local, k=k,
                                         family=family, params=params, rank_tol=rank_tol,
                                         rank_rule=rank_rule, reported=here)
            dmf_belief = dmf.record.posterior
        for name, rule in baselines.items():
            estimate, why, seconds[name] = _attempt(rule, [b for b, r in zip(local_beliefs, here) if r])
            if why is None:
                fused_estimates[name] = estimate
            else:
                failed[name] = why
        step_audit = None
        if audit:
            assert dmf is not None  # _checked_methods requires dmf when auditing
            step_audit = _audit(dmf)
        steps.append(FusionStep(k, local, cmf, dmf, fused_estimates, step_audit,
                                seconds, tuple(s for _, s in timed), failed))
    return FusionRun(family, methods, tuple(steps), model, ys, ci_criterion, SigmaSettings.of(params), rcc_metric)


def with_missing(model, ys, reported=None) -> tuple[np.ndarray, np.ndarray]:
    """(ys, reported): the stacked measurements (..., T, L) with NaN in the blocks of the sensors
    that did not report, and which did (..., T, N) — from ``reported`` (a boolean mask of that
    shape) or, without it, from the NaN blocks of ``ys`` (:meth:`~gpfverify.models.StateSpaceModel.reported`,
    which refuses a block NaN in part, an inf, or a step where no sensor reported)."""
    ys = real_floats(ys, "ys")
    if ys.ndim < 2 or ys.shape[-1] != model.measurement_dim or not ys.shape[-2]:
        raise InputError(f"ys must have shape (T, {model.measurement_dim}) with T >= 1, got {ys.shape}")
    if reported is not None:
        mask = np.asarray(reported)
        if mask.dtype != bool or mask.shape != ys.shape[:-1] + (len(model.sizes),):
            raise InputError(f"reported must be a boolean mask of shape {ys.shape[:-1] + (len(model.sizes),)} "
                             f"(steps × sensors), got {mask.dtype} {mask.shape}")
        rows = np.concatenate([np.repeat(mask[..., m:m + 1], size, axis=-1) for m, size in enumerate(model.sizes)],
                              axis=-1)
        ys = np.where(rows, ys, np.nan)
    return ys, model.reported(ys, "ys")


def _audit(dmf: DMFStep) -> CaseAudit:
    from gpfverify.audit.case import audit_case

    assert dmf.result is not None  # dmf_step's
    return audit_case(dmf.case, rank_rule=dmf.result.rank_rule, dmf=dmf.result)  # the step's eq. 35, not again


def _per_run(belief: Gaussian | None, runs: int, dim: int) -> Gaussian:
    """A belief for every run: one with a leading run axis as it is, one belief repeated."""
    assert belief is not None
    mean, cov = np.asarray(belief.mean, dtype=float), np.asarray(belief.cov, dtype=float)
    if mean.shape == (runs, dim):
        return Gaussian(mean, cov)
    return Gaussian(np.broadcast_to(mean, (runs, dim)).copy(), np.broadcast_to(cov, (runs, dim, dim)).copy())


def _batch_baselines(methods: Sequence[str], rcc_size: float | None, circular_state: Sequence[int],
                     ci_criterion: str, rcc_metric: str = "euclidean") -> dict[str, Callable]:
    """The requested baselines over a batch: ``rule(means (B, N, D), covs (B, N, D, D))`` →
    (means, covs, why each run failed or None). CC, CI and RCC-CI on arrays; ICI and EI run by run
    (pairwise rules, each a scalar root). A rule that cannot fuse every run at once fuses each run
    alone (:func:`_attempt`), so that one run's failure is its own."""
    singles = _baselines(methods, rcc_size, circular_state, ci_criterion, rcc_metric)
    out: dict[str, Callable] = {}
    for name, single in singles.items():
        if name == "cc":
            from gpfverify.fusion.batched import convex_combination_batch
            batched: Callable | None = partial(convex_combination_batch, circular_state=circular_state)
        elif name == "ci":
            from gpfverify.fusion.ci import covariance_intersection_batch
            batched = partial(covariance_intersection_batch, criterion=ci_criterion, circular_state=circular_state)
        elif name == "rcc-ci":
            from gpfverify.fusion.rcc_ci import rcc_ci_batch
            batched = partial(rcc_ci_batch, c=rcc_size, on_empty="enlarge", circular_state=circular_state,
                              metric=rcc_metric)
        else:
            batched = None
        out[name] = partial(_fuse_runs, batched, single)
    return out


def _fuse_runs(batched: Callable | None, single: Callable, means: np.ndarray, covs: np.ndarray,
               reported: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, list[str | None]]:
    """(fused means, covs, failures) of every run: ``batched`` on all, else ``single`` run by run;
    a run where some sensor did not report (``reported`` (B, N) False) fuses the others' estimates
    alone."""
    runs = means.shape[0]
    if reported is not None and not reported.all():
        complete = reported.all(axis=1)
        dim = means.shape[-1]
        out_mean, out_cov = np.full((runs, dim), np.nan), np.full((runs, dim, dim), np.nan)
        failures: list[str | None] = [None] * runs
        if complete.any():
            whole = np.flatnonzero(complete)
            part = _fuse_runs(batched, single, means[whole], covs[whole])
            out_mean[whole], out_cov[whole] = part[0], part[1]
            for b, why in zip(whole.tolist(), part[2]):
                failures[b] = why
        for b in np.flatnonzero(~complete).tolist():
            estimate, why, _ = _attempt(single, [Gaussian(m, c) for m, c, here in zip(means[b], covs[b], reported[b])
                                                 if here])
            failures[b] = why
            if why is None:
                some: Any = estimate
                out_mean[b], out_cov[b] = some.mean, some.cov
        return out_mean, out_cov, failures
    if batched is not None:
        try:
            fused = batched(means, covs)
        except (NumericalError, np.linalg.LinAlgError):
            pass
        else:
            failures = list(getattr(fused, "failures", [None] * runs))
            return fused.mean, fused.cov, failures
    dim = means.shape[-1]
    out_mean, out_cov, failures = np.full((runs, dim), np.nan), np.full((runs, dim, dim), np.nan), []
    for b in range(runs):
        estimate, why, _ = _attempt(single, [Gaussian(m, c) for m, c in zip(means[b], covs[b])])
        failures.append(why)
        if why is None:
            alone: Any = estimate  # a FusedEstimate or an RccCiResult: both have mean and cov
            out_mean[b], out_cov[b] = alone.mean, alone.cov
    return out_mean, out_cov, failures


@one_blas_thread
def run_fusion_batch(model, ys, *, family: str = "ukf", methods: Sequence[str] = DEFAULT_METHODS,
                     first_k: int = 1, params: SigmaParams | SigmaSettings = SigmaParams(),
                     rank_tol: float | None = None,
                     local_priors: Sequence[Gaussian] | None = None, fused_prior: Gaussian | None = None,
                     audit: bool = True, rcc_size: float | None = None, rank_rule: RankRule | str | None = None,
                     ci_criterion: str = "trace", rcc_metric: str = "euclidean",
                     reported=None) -> list[FusionRun]:
    """:func:`run_fusion` of B Monte Carlo runs at once: ``ys`` (B, T, L), run b's measurements at
    b; ``model`` the system every run filters (a :class:`~gpfverify.models.StateSpaceModel`, its
    functions then applied run by run, :meth:`~gpfverify.models.StateSpaceModel.for_runs`) or the
    runs' own GP models (:func:`~gpfverify.models.batch_gp_models`); priors one belief for every run
    or beliefs with a leading run axis. Every sensor's local filter, CMF and DMF step all runs
    together; eq. 35 and the audit by the block route (:func:`gpfverify.audit.block.dmf_runs`); CC,
    CI and RCC-CI on arrays, ICI and EI run by run. Returns one :class:`FusionRun` per run, as
    :func:`run_fusion` would (its DMF steps carry no ``result``: their ``audit`` has the evidence),
    a run's numbers independent of the other runs and of B; ``seconds`` of a step is the batch's
    wall-clock time per run. Missing measurements as in :func:`run_fusion` (NaN blocks of ``ys`` or
    ``reported`` (B, T, N)): a run and step where a sensor did not report is fused by the per-step
    route (eq. 35 and the audit over the sensors that did), the others together."""
    from gpfverify.audit.block import case_block, dmf_runs

    chosen = model_family(family, model, params)
    methods = _checked_methods(methods, audit)
    ys = real_floats(ys, "ys")
    if ys.ndim != 3 or ys.shape[2] != model.measurement_dim or not ys.shape[0] or not ys.shape[1]:
        raise InputError(f"ys must have shape (B, T, {model.measurement_dim}) with B, T >= 1, got {ys.shape}")
    ys, reported = with_missing(model, ys, reported)
    if ci_criterion not in ("trace", "det"):
        raise InputError(f"ci_criterion must be 'trace' or 'det', got {ci_criterion!r}")
    runs, dim = ys.shape[0], model.state_dim
    stepped = model.for_runs(runs) if isinstance(model, StateSpaceModel) else model
    local_priors, fused_prior = _priors(model, local_priors, fused_prior)
    local_beliefs = [_per_run(b, runs, dim) for b in local_priors]
    cmf_belief = dmf_belief = _per_run(fused_prior, runs, dim)
    sensor_models = [stepped.sensor_model(m) for m in range(len(model.sizes))]
    blocks = sensor_blocks(model.sizes)
    rule = resolve_rank_rule(None, rank_rule, rank_tol)
    baselines = _batch_baselines(methods, rcc_size, model.circular_state, ci_criterion, rcc_metric)
    per_run: list[list[FusionStep]] = [[] for _ in range(runs)]
    for t in range(ys.shape[1]):
        k, y = first_k + t, ys[:, t]
        timed = [_timed(chosen.step, b, sm, y[:, block], k=k)
                 for b, sm, block in zip(local_beliefs, sensor_models, blocks)]
        local = [r for r, _ in timed]
        local_beliefs = [r.posterior for r in local]
        seconds: dict[str, float] = {"local": sum(s for _, s in timed) / runs}
        cmf = dmf = None
        if "cmf" in methods:
            cmf, elapsed = _timed(chosen.step, cmf_belief, stepped, y, k=k)
            seconds["cmf"] = elapsed / runs
            cmf_belief = cmf.posterior
        if "dmf" in methods:
            start = time.perf_counter()
            _, central = central_prediction(dmf_belief, stepped, k=k, family=family, params=params)
            block = case_block(central, local, y, central.sizes, central.circular, central.circular_state,
                               reported[:, t])
            dmf = dmf_runs(block, rule)
            seconds["dmf"] = (time.perf_counter() - start - dmf.audit_seconds) / runs
            dmf_belief = Gaussian(dmf.mean, dmf.cov)
        means = np.stack([b.mean for b in local_beliefs], axis=1)
        covs = np.stack([b.cov for b in local_beliefs], axis=1)
        fused = {}
        for name, rule_of in baselines.items():
            fused[name], elapsed = _timed(rule_of, means, covs, reported[:, t])
            seconds[name] = elapsed / runs
        for b in range(runs):
            step_dmf = None
            if dmf is not None:
                record = StepRecord(block.mu_p[b], block.C_p[b], block.mu_y[b], block.C_y[b], block.C_xy[b],
                                    dmf.mean[b], dmf.cov[b])
                step_dmf = DMFStep(record, block.case(b), None, dmf.online)
            estimates = {name: FusedEstimate(f[0][b], f[1][b]) for name, f in fused.items() if f[2][b] is None}
            failed = {name: f[2][b] for name, f in fused.items() if f[2][b] is not None}
            per_run[b].append(FusionStep(k, tuple(_run_record(r, b) for r in local),
                                         None if cmf is None else _run_record(cmf, b), step_dmf,
                                         estimates, dmf.audits[b] if audit and dmf is not None else None, seconds,
                                         tuple(s / runs for _, s in timed), failed))
    return [FusionRun(family, methods, tuple(steps), model, ys[b], ci_criterion, SigmaSettings.of(params),
                      rcc_metric)
            for b, steps in enumerate(per_run)]


def _run_record(record: StepRecord, b: int) -> StepRecord:
    """Run b's record of a batched step record (views)."""
    return StepRecord(record.mu_p[b], record.C_p[b], record.mu_y[b], record.C_y[b], record.C_xy[b], record.mu_e[b],
                      record.C_e[b])
