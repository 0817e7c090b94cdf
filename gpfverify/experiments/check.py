"""``gpfverify check``: does distributed fusion reproduce centralized fusion on *your* system, at
every step, and if not, why (SPEC §6).

One run: the measurements y_1..y_T — simulated from the system (truth known) or the user's logged
``y`` (T, L) with optional truth ``x`` (T, D) — are filtered by every sensor's local filter, the
centre's CMF and DMF (seed 000 eq. 35; each with its own recursion from the prior) and the chosen
baselines (:func:`gpfverify.model_fusion.run_fusion`), and every DMF step is audited
(:func:`gpfverify.audit.case.audit_case`): the one-step gap μ_DMF − μ_CMF from the same central
prediction against its rounding bound (:func:`~gpfverify.fusion.exactness.equivalence_tolerance`,
both in prior standard deviations), each sensor's rank verdict, exactness, share of the gap and
repair size. With the truth, every estimate's squared error and NEES, and the NIS of CMF and of
each local filter.

The GP families (``gp-adf``, ``gp-ukf``) first learn the system from ``train`` samples drawn from it
(:func:`gpfverify.models.learn_gp_model`) or from the user's training file (``x`` (n, D) states,
``y`` (n, L) their stacked measurements). Each run draws its training data and its measurements
from independent child streams of its seed.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any
from pathlib import Path

import numpy as np

from gpfverify.angles import difference
from gpfverify.consistency import Consistency
from gpfverify.contract.check import CiCriterion, FilterName, Params, RccMetric, RunRecord
from gpfverify.errors import CaseFileError, InputError
from gpfverify.adapters.local_filters import LocalFilters
from gpfverify.filters.families import GP_FAMILIES, SIGMA_POINT_FAMILIES
from gpfverify.filters.sigma_points import SigmaSettings
from gpfverify.filters.records import Gaussian
from gpfverify.audit.case import rank_rule_to_dict
from gpfverify.fusion.case import cases_to_dicts
from gpfverify.fusion.caseblock import case_from_dict
from gpfverify.fusion.exactness import gap_size, parse_rank_rule
from gpfverify.model_fusion import run_fusion, run_fusion_batch
from gpfverify.audit.runfile import write_run
from gpfverify.models import batch_gp_models, fit_gp_model, learn_gp_model, require_step_free
from gpfverify.rng import generator
from gpfverify.runtime import no_cycle_collection
from gpfverify.systems import load_filters, split_spec
from gpfverify.userfiles import read_npz
from gpfverify.validate import as_array, real_floats

NAME = "check"
DEFAULT_RUNS = 1
#: fields of results.json that are measurements of time, not results
TIMING_KEYS = ("time_per_step",)
#: two-sided level of the ANEES / ANIS bands
CONSISTENCY_LEVEL = 0.95


def params_for(system: str, filter: FilterName = "ukf", steps: int = 50, measurements: str | None = None,
               training: str | None = None, train: int = 200, fit_points: int | None = 200,
               restarts: int = 2, methods=("cmf", "dmf", "cc", "ci"), rank_rule: str = "canonical",
               ci_criterion: CiCriterion = "trace", sigma_alpha: float | None = None,
               sigma_beta: float | None = None, sigma_kappa: float | None = None,
               rcc_metric: RccMetric = "euclidean") -> Params:
    """The parameters of a check, validated, with the paths made absolute and the rank rule in its
    canonical spelling. ``rank_rule`` is a :func:`~gpfverify.fusion.exactness.parse_rank_rule`
    string: the unit-free canonical-correlation rule by default (``"canonical[:TAU]"``),
    ``"absolute:TOL"`` or ``"numpy"``; ``ci_criterion`` CI's weight criterion, ``"trace"`` or
    ``"det"``; ``rcc_metric`` RCC-CI's error norm, ``"euclidean"`` or ``"scaled"``; ``sigma_*``
    the sigma points of a gpfverify model's unscented filters. A ``training`` file with a filter
    that learns nothing is refused rather than ignored."""
    path, name = split_spec(system)
    if training is not None and filter not in GP_FAMILIES:
        raise InputError(f"--training is learned from by the GP filters ({', '.join(GP_FAMILIES)}) only; "
                         f"--filter {filter} uses the system's own functions and would ignore it")
    return Params(system=f"{path}:{name}", filter=filter, steps=steps,
                  measurements=None if measurements is None else str(Path(measurements).resolve()),
                  training=None if training is None else str(Path(training).resolve()),
                  train=train, fit_points=fit_points, restarts=restarts, methods=tuple(methods),
                  rank_rule=parse_rank_rule(rank_rule).spec, ci_criterion=ci_criterion,
                  sigma_alpha=sigma_alpha, sigma_beta=sigma_beta, sigma_kappa=sigma_kappa, rcc_metric=rcc_metric)


# -- the user's filters as written -------------------------------------------------------------------

def for_filters(params: Params, filters: LocalFilters, filter_given: bool) -> Params:
    """``params`` for the system's own filters: without ``--filter`` (``filter_given`` False) the
    family its library's filters are (a Stone Soup tracker's predictor and updater, filterpy's
    filter type), else ukf; ``--sigma-*`` refused for a system that brings its own sigma points
    (one line saying which), and for a family that draws none."""
    if not filter_given and filters.family is not None:
        params = params.replace(filter=filters.family)
    if params.sigma_given:
        if filters.params is not None:
            raise InputError(f"the system brings its own sigma points ({filters.origin.get('sigma_points', '')}): "
                             "--sigma-alpha, --sigma-beta and --sigma-kappa set them for a gpfverify model only")
        if params.filter not in SIGMA_POINT_FAMILIES:
            raise InputError(f"--sigma-alpha, --sigma-beta and --sigma-kappa set the sigma points of "
                             f"{' and '.join(SIGMA_POINT_FAMILIES)}; --filter {params.filter} draws none")
    if params.filter in SIGMA_POINT_FAMILIES:
        settings = sigma_settings(filters, params)
        for points in (settings.predict, settings.update):
            points.weights(filters.model.state_dim)  # InputError when D + λ ≤ 0: no sigma points
    return params


def sigma_settings(filters: LocalFilters, params: Params) -> SigmaSettings:
    """The sigma points the unscented families run: the library's own (prediction and update, with
    its angle mean), else the check's ``--sigma-*`` (gpfverify's defaults where not given)."""
    return filters.params if filters.params is not None else SigmaSettings.of(params.sigma_params())


def local_starts(filters: LocalFilters) -> list[Gaussian]:
    """Each sensor's filter's start: its own (a filterpy filter's x and P), else the model's prior."""
    model = filters.model
    if filters.local_priors is not None:
        return list(filters.local_priors)
    return [Gaussian(model.prior_mean, model.prior_cov)] * len(model.sensors)


def filters_record(filters: LocalFilters, params: Params) -> tuple[dict | None, dict]:
    """(``sigma_points``, ``tracker``) of results.json: the sigma points the check ran (None for a
    family that draws none) — α, β, κ and angle mean of the prediction and of the update, and where
    they came from — and the library, family and starts of the user's filters."""
    settings = sigma_settings(filters, params)
    native = filters.params is None
    source = ("--sigma-alpha, --sigma-beta, --sigma-kappa" + (" (gpfverify's defaults where not given)"
                                                               if not all((params.sigma_alpha, params.sigma_beta,
                                                                           params.sigma_kappa)) else "")
              if native and params.sigma_given else "gpfverify's defaults" if native
              else filters.origin.get("sigma_points", ""))
    sigma = ({**settings.to_json(), "source": source} if params.filter in SIGMA_POINT_FAMILIES else None)
    starts = filters.origin.get("starts", "every filter from the model's prior")
    tracker = {"library": filters.library or None, "family": filters.family,
               "family_source": filters.origin.get("family") if filters.library else None, "starts": starts}
    return sigma, tracker


def _load_npz(path: str, what: str, expects: str) -> dict[str, np.ndarray]:
    """The arrays of a user's npz file, read by :func:`gpfverify.userfiles.read_npz` (a regular
    file, every declared size checked before anything is decompressed); a file that is not an npz
    archive is refused naming the format ``expects`` describes (and, for a JSON file, what reads
    it)."""
    try:
        return read_npz(path)
    except OSError as exc:
        raise InputError(f"cannot read {what} {path}: {exc.strerror or exc}") from None
    except CaseFileError as exc:
        if Path(path).suffix.lower() in (".json", ".jsonl"):
            raise InputError(f"{path} is a {Path(path).suffix} file, not an npz archive (an audit run file or "
                             f"fusion case? 'gpfverify audit' reads those): {what} must be {expects}") from None
        raise InputError(f"{exc}; {what} must be {expects}") from None


#: what ``--training`` expects, for error messages
TRAINING_FORMAT = ("a training file (TRAIN.npz: x (n, D) consecutive states and y (n, L) their stacked "
                   "measurements)")


def measurements_format(model) -> str:
    """What ``--measurements`` expects, for error messages."""
    return (f"a measurements file (MEASUREMENTS.npz: y (T, {model.measurement_dim}) stacked in sensor order, "
            f"optional truth x (T, {model.state_dim}); docs/check-format.md)")


def logged_measurements(path: str, model) -> tuple[np.ndarray | None, np.ndarray]:
    """(truth x (T, D) or None, measurements y (T, L)) from a measurements file (``y`` required;
    docs/check-format.md): a NaN block of ``y`` is a sensor that did not report at that step, NaN
    anywhere else (part of a block, the truth) is refused naming the row, the sensor or component
    and the output. Not an audit run file: that one is refused saying which is which."""
    data = _load_npz(path, "--measurements", measurements_format(model))
    if "central_mu_p" in data:
        raise InputError(f"{path} is an audit run file of fusion cases ('gpfverify audit' reads it): "
                         f"--measurements expects {measurements_format(model)}")
    if "y" not in data:
        raise InputError(f"{path} has no array 'y': --measurements expects {measurements_format(model)}")
    name = Path(path).name
    try:
        ys = real_floats(data["y"], f"{name}: y")
        if ys.ndim != 2 or ys.shape[1] != model.measurement_dim or not ys.shape[0]:
            raise InputError(f"{name}: y must have shape (T, {model.measurement_dim}), got {ys.shape}")
        model.reported(ys, f"{name}: y")  # NaN only as whole sensor blocks, some sensor at every step
        truth = None
        if "x" in data:
            truth = real_floats(data["x"], f"{name}: x")
            if truth.shape != (ys.shape[0], model.state_dim):
                raise InputError(f"{name}: x must have shape ({ys.shape[0]}, {model.state_dim}), got {truth.shape}")
            if not np.isfinite(truth).all():
                row, component = (int(i) for i in np.argwhere(~np.isfinite(truth))[0])
                raise InputError(f"{name}: x row {row}, state component {component} is "
                                 f"{'NaN' if np.isnan(truth[row, component]) else 'inf'}: the truth must be known "
                                 "at every step (leave x out when it is not)")
    except InputError as exc:
        raise InputError(f"{exc}; --measurements expects {measurements_format(model)}") from None
    return truth, ys


def check_learnable(model, params: Params) -> None:
    """A GP family learns the system as GPs of the state alone: a model whose functions change with
    the step k over the steps the check learns from and filters is refused in one line
    (:func:`gpfverify.models.require_step_free`), before anything is written."""
    if params.filter in GP_FAMILIES:
        last = params.steps if params.training is not None else max(params.steps, params.train)
        require_step_free(model, range(1, last + 1), f"--filter {params.filter}")


def _gp_model(model, params: Params, rng: np.random.Generator):
    """The system learned as GPs from the user's training file or from samples of the system."""
    if params.training is None:
        return learn_gp_model(model, params.train, rng, restarts=params.restarts,
                              fit_points=params.fit_points)
    data = _load_npz(params.training, "--training", TRAINING_FORMAT)
    name = Path(params.training).name
    if "x" not in data or "y" not in data:
        raise InputError(f"{name} needs arrays 'x' (n, D) and 'y' (n, L): --training must be {TRAINING_FORMAT}")
    x = as_array(data["x"], f"{name}: x", shape=(None, model.state_dim))
    y = as_array(data["y"], f"{name}: y", shape=(x.shape[0], model.measurement_dim))
    return fit_gp_model(x[:-1], x[1:], x, [y[:, b] for b in model.blocks], rng, restarts=params.restarts,
                        fit_points=params.fit_points, sensor_circular=model.sensor_circular,
                        circular_state=model.circular_state)


def _run_inputs(params: Params, model, seed: np.random.SeedSequence):
    """(truth or None, measurements, the model the run's filters use) of one run: its measurements
    and training data from independent child streams of its seed."""
    # the first two children of the run's seed, built explicitly (the streams seed.spawn(2) gives a
    # fresh seed): spawn() would depend on the seed's earlier spawns
    data_rng, train_rng = (generator(np.random.SeedSequence(seed.entropy, spawn_key=(*seed.spawn_key, i)))
                           for i in range(2))
    truth: np.ndarray | None
    if params.measurements is None:
        truth, ys = model.simulate(params.steps, data_rng)
    else:
        truth, ys = logged_measurements(params.measurements, model)
    fusion_model = _gp_model(model, params, train_rng) if params.filter in GP_FAMILIES else model
    return truth, ys, fusion_model


def run_one(params: Params, seed: np.random.SeedSequence) -> RunRecord:
    """One run of the check (module docstring): every filter as the system's library runs it
    (:func:`sigma_settings`, :func:`local_starts`), the centre from the model's prior."""
    filters = load_filters(params.system)
    model = filters.model
    truth, ys, fusion_model = _run_inputs(params, model, seed)
    prior = Gaussian(model.prior_mean, model.prior_cov)
    fused = run_fusion(fusion_model, ys, family=params.filter, methods=params.methods,
                       params=sigma_settings(filters, params),
                       rank_rule=params.rank_rule, ci_criterion=params.ci_criterion, rcc_metric=params.rcc_metric,
                       local_priors=local_starts(filters), fused_prior=prior)
    return _one_record(model, fused, ys, truth)


def run_batch(params: Params, seeds: Sequence[np.random.SeedSequence]) -> list[RunRecord]:
    """:func:`run_one` of every seed, the runs' filters, fusion and audits advancing together
    (:func:`~gpfverify.model_fusion.run_fusion_batch`); each run draws its data from its own
    streams, and a GP family learns each run's GPs on their own (per-run L-BFGS), as in :func:`run_one`."""
    filters = load_filters(params.system)
    model = filters.model
    inputs = [_run_inputs(params, model, seed) for seed in seeds]
    ys = np.stack([i[1] for i in inputs])
    truths = None if inputs[0][0] is None else np.stack([i[0] for i in inputs])
    fusion_model = batch_gp_models([i[2] for i in inputs]) if params.filter in GP_FAMILIES else model
    prior = Gaussian(model.prior_mean, model.prior_cov)
    fused = run_fusion_batch(fusion_model, ys, family=params.filter, methods=params.methods,
                             params=sigma_settings(filters, params),
                             rank_rule=params.rank_rule, ci_criterion=params.ci_criterion,
                             rcc_metric=params.rcc_metric, local_priors=local_starts(filters), fused_prior=prior)
    return _records(model, fused, truths, _measures_batch(model, fused, ys, truths))


@dataclass(frozen=True)
class StepMeasures:
    """One run's normalised errors and gap sizes per step, which its record reports: the NIS of CMF
    and of each sensor's local filter, with the truth the NEES of every method (per step where it
    fused) and of each local filter, and the repaired and the recursive DMF − CMF gaps in prior
    standard deviations (:func:`~gpfverify.fusion.exactness.gap_size`)."""

    nis_cmf: list[float]
    nis_local: list[list[float]]
    nees: dict[str, dict[int, float]] | None
    local_nees: list[list[float]] | None
    repaired_gap_size: list[float]
    recursive_gap_size: list[float]


def _measures(model, fused, ys: np.ndarray, truth: np.ndarray | None) -> StepMeasures:
    """:class:`StepMeasures` of one run (module docstring: the per-step definitions)."""
    errors = _normalised_errors(model, fused, ys, truth)
    repaired, recursive = [], []
    for step in fused.steps:
        audit = step.audit
        repaired.append(gap_size(step.dmf.case, difference(audit.repaired_dmf_mean, audit.cmf_mean,
                                                           model.circular_state)))
        recursive.append(gap_size(step.dmf.case, difference(step.estimate("dmf").mean, step.estimate("cmf").mean,
                                                            model.circular_state)))
    return StepMeasures([float(v) for v in errors["nis"]["cmf"]],
                        [[float(x) for x in v] for v in errors["nis"]["local"]],
                        {m: {int(t): float(x) for t, x in v.items()} for m, v in errors["nees"].items()}
                        if truth is not None else None,
                        [[float(x) for x in v] for v in errors["local_nees"]] if truth is not None else None,
                        repaired, recursive)


def _measures_batch(model, runs: Sequence, ys: np.ndarray, truths: np.ndarray | None) -> list[StepMeasures]:
    """:class:`StepMeasures` of B runs, each measure computed over the runs and steps at once
    (the same formulas as :func:`_measures`, stacked: :class:`~gpfverify.consistency.Consistency`
    takes runs × steps, the gaps are whitened by every step's equilibrated factor of C_p)."""
    from gpfverify.audit.blockexactness import apply, equilibrated, solve_lower

    steps = [run.steps for run in runs]
    stacked = lambda get: np.array([[get(s) for s in run] for run in steps])  # noqa: E731
    nis_cmf = reported_nis(ys, stacked(lambda s: s.cmf.mu_y), stacked(lambda s: s.cmf.C_y), model.circular)
    nis_local = [reported_nis(ys[:, :, b], stacked(lambda s, m=m: s.local[m].mu_y),
                              stacked(lambda s, m=m: s.local[m].C_y), sensor.circular)
                 for m, (b, sensor) in enumerate(zip(model.blocks, model.sensors))]
    c_p = stacked(lambda s: s.dmf.case.central.C_p)
    count, length, dim = c_p.shape[:3]
    d, factor = equilibrated(c_p.reshape(-1, dim, dim))
    inverse = solve_lower(factor, np.broadcast_to(np.eye(dim), factor.shape) / d[:, :, None])  # L_p⁻¹

    def sizes(first, second) -> np.ndarray:
        diff = difference(stacked(first), stacked(second), model.circular_state).reshape(-1, dim)
        return np.linalg.norm(apply(inverse, diff), axis=1).reshape(count, length)

    repaired = sizes(lambda s: s.audit.repaired_dmf_mean, lambda s: s.audit.cmf_mean)
    recursive = sizes(lambda s: s.estimate("dmf").mean, lambda s: s.estimate("cmf").mean)
    nees: list[dict[str, dict[int, float]] | None] = [None] * count
    local_nees = None
    if truths is not None:
        methods = runs[0].methods
        fused_by = {m: stacked(lambda s, m=m: m not in s.failed) for m in methods}
        values = {}
        for m in methods:
            ok = fused_by[m]
            mean, cov = _stacked_estimates(steps, m, Gaussian(np.zeros(dim), np.eye(dim)))
            values[m] = np.where(ok, Consistency.from_estimates(truths, mean, cov,
                                                                circular_state=model.circular_state).values, np.nan)
        nees = [{m: {t: float(values[m][b, t]) for t in range(length) if fused_by[m][b, t]} for m in methods}
                for b in range(count)]
        local_nees = [Consistency.from_estimates(truths, stacked(lambda s, m=m: s.local[m].mu_e),
                                                 stacked(lambda s, m=m: s.local[m].C_e),
                                                 circular_state=model.circular_state).values
                      for m in range(len(model.sensors))]
    return [StepMeasures(nis_cmf[b].tolist(), [v[b].tolist() for v in nis_local], nees[b],
                         None if local_nees is None else [v[b].tolist() for v in local_nees],
                         repaired[b].tolist(), recursive[b].tolist()) for b in range(count)]


def _stacked_estimates(steps: Sequence[Sequence], method: str, missing: Gaussian) -> tuple[np.ndarray, np.ndarray]:
    """(B, T, D) means and (B, T, D, D) covariances of ``method`` in B runs' ``steps``, ``missing``'s
    at the steps where it did not fuse."""
    estimates = [[s.estimate(method) if method not in s.failed else missing for s in run] for run in steps]
    return (np.array([[e.mean for e in run] for run in estimates]),
            np.array([[e.cov for e in run] for run in estimates]))


def reported_nis(ys: np.ndarray, mu_y: np.ndarray, C_y: np.ndarray, circular) -> np.ndarray:
    """The NIS (:meth:`gpfverify.consistency.Consistency.nis`) of measurements ys (T, L) or (R, T, L)
    — (T,) or (R, T) — at the steps where every one of the L outputs reported, NaN where some did
    not (its χ² degrees of freedom would differ from L: such steps are left out of the ANIS)."""
    missing = np.isnan(ys).any(axis=-1)
    values = Consistency.nis(np.where(np.isnan(ys), mu_y, ys), mu_y, C_y, circular=circular).values
    return np.where(missing, np.nan, values.reshape(missing.shape))


def _normalised_errors(model, fused, ys: np.ndarray, truth: np.ndarray | None) -> dict:
    """NIS of CMF and of every local filter, and (with the truth) NEES of every estimate, per step
    (:class:`gpfverify.consistency.Consistency`; angle components wrapped)."""
    locals_ = [[s.local[m] for s in fused.steps] for m in range(len(model.sensors))]
    cmf_mu, cmf_cov = np.array([s.cmf.mu_y for s in fused.steps]), np.array([s.cmf.C_y for s in fused.steps])
    out: dict[str, Any] = {"nis": {"cmf": reported_nis(ys, cmf_mu, cmf_cov, model.circular),
                   "local": [reported_nis(ys[:, b], np.array([r.mu_y for r in records]),
                                          np.array([r.C_y for r in records]), sensor.circular)
                             for b, sensor, records in zip(model.blocks, model.sensors, locals_)]}}
    if truth is not None:
        nees = lambda estimates: Consistency.from_records(  # noqa: E731
            truth, estimates, circular_state=model.circular_state).values[0]
        out["nees"] = {}
        for m in fused.methods:  # per step, at the steps where the method fused
            at = [t for t, s in enumerate(fused.steps) if m not in s.failed]
            values = Consistency.from_records(truth[at], [fused.steps[t].estimate(m) for t in at],
                                              circular_state=model.circular_state).values[0] if at else []
            out["nees"][m] = dict(zip(at, values))
        out["local_nees"] = [nees([r.posterior for r in records]) for records in locals_]
    return out


def _with_missing(model, audit, entries: list[dict]) -> list[dict]:
    """A step's per-sensor entries, one for every sensor in sensor order: those the audit made, and
    for a sensor that did not report one saying so, its verdicts null (nothing was audited) and its
    share of the gap and repair size zero (it took no part in the step)."""
    if not audit.missing:
        return entries
    absent = [{"index": m, "reported": False, "rank": None, "cols": model.sizes[m], "full_column_rank": None,
               "exact": None, "repair_dim": 0, "singular_values": [], "tol": None, "gap_share": 0.0,
               "gap_share_size": 0.0, "min_canonical_correlation": None, "branch_offsets": [],
               "branch_offset_count": 0} for m in audit.missing]
    return sorted(entries + absent, key=lambda e: e["index"])


def _one_record(model, fused, ys: np.ndarray, truth: np.ndarray | None) -> RunRecord:
    """The :class:`RunRecord` of one run (its :class:`StepMeasures` by :func:`_measures`)."""
    return _records(model, [fused], None if truth is None else np.asarray(truth)[None],
                    [_measures(model, fused, ys, truth)])[0]


def _records(model, runs: Sequence, truths: np.ndarray | None, measures: Sequence[StepMeasures]) -> list[RunRecord]:
    """The :class:`RunRecord` of each of B runs (``truths`` (B, T, D) or None,
    ``measures`` one :class:`StepMeasures` per run): every per-step array of every run stacked once
    per field over runs and steps, its norms and squared errors computed on the stack, and each
    stack turned into lists once (a few numpy calls per field, not a few per step)."""
    with no_cycle_collection():
        return _built_records(model, runs, truths, measures)


def _built_records(model, runs: Sequence, truths: np.ndarray | None,
                   measures: Sequence[StepMeasures]) -> list[RunRecord]:
    methods = runs[0].methods
    steps = [run.steps for run in runs]
    circular = model.circular_state

    def stacked(get) -> np.ndarray:  # (B, T, ...)
        return np.array([[get(s) for s in run] for run in steps])

    audits = stacked(lambda s: (s.audit.cmf_mean, s.audit.dmf_mean, s.audit.gap, s.audit.predicted_gap,
                                s.audit.repaired_dmf_mean))
    cmf_mean, dmf_mean, gap, predicted_gap, repaired_mean = np.moveaxis(audits, 2, 0)
    missing = Gaussian(np.full(model.state_dim, np.nan), np.full((model.state_dim,) * 2, np.nan))
    estimates = {m: _stacked_estimates(steps, m, missing) for m in methods}
    means = {m: mean for m, (mean, _) in estimates.items()}
    covs = {m: cov.tolist() for m, (_, cov) in estimates.items()}
    local_means = stacked(lambda s: [r.mu_e for r in s.local])
    local_covs = stacked(lambda s: [r.C_e for r in s.local]).tolist()
    norm = lambda v: np.linalg.norm(v, axis=-1).tolist()  # noqa: E731
    gap_norm, predicted_gap_norm = norm(gap), norm(predicted_gap)
    repaired_gap_norm = norm(repaired_mean - cmf_mean)
    recursive_gap_norm = norm(means["dmf"] - means["cmf"])
    cases = cases_to_dicts([step.dmf.case for run in steps for step in run])
    if truths is not None:
        truth = np.asarray(truths)[:, :, None, :]
        sq_err = {m: np.sum(difference(truths, means[m], circular) ** 2, axis=-1).tolist() for m in methods}
        local_sq_err = np.sum(difference(truth, local_means, circular) ** 2, axis=-1).tolist()
        truths_listed = np.asarray(truths).tolist()
    listed = {m: means[m].tolist() for m in methods}
    columns = {"cmf_mean": cmf_mean.tolist(), "dmf_mean": dmf_mean.tolist(), "gap": gap.tolist(),
               "repaired_mean": repaired_mean.tolist(), "local_means": local_means.tolist()}
    records = []
    for b, run in enumerate(steps):
        measured = measures[b]
        entries = []
        for t, step in enumerate(run):
            audit = step.audit
            ok = [m for m in methods if m not in step.failed]
            entry = {
                "k": step.k, "cmf_mean": columns["cmf_mean"][b][t], "dmf_mean": columns["dmf_mean"][b][t],
                "gap": columns["gap"][b][t], "gap_norm": gap_norm[b][t],
                "predicted_gap_norm": predicted_gap_norm[b][t],
                "gap_size": float(audit.gap_size), "gap_bound": float(audit.gap_bound),
                "repaired_gap_norm": repaired_gap_norm[b][t],
                "repaired_gap_size": measured.repaired_gap_size[t],
                "recursive_gap_norm": recursive_gap_norm[b][t],
                "recursive_gap_size": measured.recursive_gap_size[t],
                "unit_dependence": audit.unit_dependence,
                "condition_holds": bool(audit.condition_holds), "exact": bool(audit.exact),
                "reported": [m not in audit.missing for m in range(audit.sensor_count)],
                "sensors": _with_missing(model, audit, [_sensor_entry(s) for s in audit.sensors]),
                "means": {m: listed[m][b][t] for m in ok},
                "covs": {m: covs[m][b][t] for m in ok},
                "repaired_mean": (columns["repaired_mean"][b][t] if any(s.repair_dim for s in audit.sensors)
                                  else None),
                "failed": dict(step.failed),
                "local_means": columns["local_means"][b][t],
                "local_covs": local_covs[b][t],
                "seconds": {**step.seconds, "local": list(step.local_seconds)},
                "nis": {"cmf": _number(measured.nis_cmf[t]), "local": [_number(v[t]) for v in measured.nis_local]},
                "case": cases[b * len(run) + t],
            }
            if truths is not None:
                assert measured.nees is not None and measured.local_nees is not None  # measured with the truth
                entry["truth"] = truths_listed[b][t]
                entry["sq_err"] = {m: sq_err[m][b][t] for m in ok}
                entry["nees"] = {m: v[t] for m, v in measured.nees.items() if t in v}
                entry["local_sq_err"] = local_sq_err[b][t]
                entry["local_nees"] = [v[t] for v in measured.local_nees]
            entries.append(entry)
        records.append(RunRecord(truths is not None, tuple(entries)))
    return records


def _sensor_entry(s) -> dict:
    """A step's entry for one reporting sensor (its :class:`~gpfverify.audit.case.SensorAudit`)."""
    return {"index": s.index, "reported": True, "rank": int(s.rank), "cols": s.cols,
            "full_column_rank": bool(s.full_column_rank), "exact": bool(s.exact),
            "repair_dim": int(s.repair_dim), "singular_values": s.singular_values.tolist(),
            "tol": float(s.tol),
            "gap_share": float(np.linalg.norm(s.gap_contribution)),
            "gap_share_size": float(s.gap_contribution_size),
            "min_canonical_correlation": (None if s.canonical_correlations is None
                                          or not s.canonical_correlations.size
                                          else float(s.canonical_correlations.min())),
            "branch_offsets": s.branch_offsets.tolist(),
            "branch_offset_count": int(np.count_nonzero(s.branch_offsets))}


def step_record_bytes(model, methods: Sequence[str]) -> int:
    """A lower estimate of the memory one step's record takes while the summary holds every run:
    the step's fusion case (the joint covariance of state and outputs, centre and each sensor) and
    the estimates, as Python floats in lists (32 bytes each), and 2 kB of fixed fields."""
    d, total = model.state_dim, model.measurement_dim
    floats = 3 * (d + total) ** 2 + (len(methods) + len(model.sensors) + 6) * d + len(methods) * d * d
    return 32 * floats + 2048


def check_size_fits(model, steps: int, runs: int, methods: Sequence[str]) -> None:
    """Refuse ``runs`` × ``steps`` when their records (:func:`step_record_bytes` each step) cannot
    be held in the memory available now (:func:`gpfverify.userfiles.memory_budget`), before
    anything is written."""
    from gpfverify.userfiles import human_bytes, memory_budget

    if not (isinstance(steps, int) and steps >= 1 and isinstance(runs, int) and runs >= 1):
        return  # refused where they are validated
    each, budget = step_record_bytes(model, methods), memory_budget()
    if runs * steps * each > budget:
        raise InputError(f"--runs {runs} × --steps {steps} is more than this machine can hold: the summary keeps "
                         f"every step's record in memory (at least {human_bytes(each)} each, "
                         f"{human_bytes(runs * steps * each)} in all; {human_bytes(budget)} may be used now)")


def run_file_name(index: int, runs: int) -> str:
    """The run file of run ``index`` in a check's output folder: ``run.jsonl`` when the check made
    one run, ``run-NNN.jsonl`` (the run's index, from 000) when it made several."""
    return "run.jsonl" if runs == 1 else f"run-{index:03d}.jsonl"


def write_run_files(out_dir: Path, runs: int) -> list[Path]:
    """Write the per-step fusion cases of every run saved in ``out_dir`` (the case each step's audit
    decided) as run files :command:`gpfverify audit` reads (docs/run-file-format.md), named by
    :func:`run_file_name`, each line's ``"k"`` the step's index; a failed run has none. Returns the
    paths written."""
    from gpfverify.experiments.runner import load_runs

    paths = []
    for record in load_runs(out_dir, runs):
        if record["status"] != "ok":
            continue
        steps = record["result"]["steps"]
        if any("case" not in step for step in steps):
            raise InputError(f"saved run {record['index']} in {out_dir} was made by an older gpfverify without "
                             "the per-step cases; choose a new --out")
        paths.append(write_run(out_dir / run_file_name(record["index"], runs),
                               [case_from_dict(step["case"]) for step in steps], ks=[step["k"] for step in steps]))
    return paths


# -- results.json ----------------------------------------------------------------------------------

def _sensor_table(model) -> list[dict]:
    return [{"index": m, "name": s.name or f"sensor {m}", "outputs": s.size, "circular": list(s.circular),
             "more_outputs_than_states": s.size > model.state_dim} for m, s in enumerate(model.sensors)]


def _per_sensor(steps_by_run: Sequence[Sequence[dict]], key: str) -> list:
    """(R, T, N) nested lists of a per-sensor field."""
    return [[[s[key] for s in e["sensors"]] for e in steps] for steps in steps_by_run]


def _number(value: float) -> float | None:
    """A measure as JSON: None where it is not defined (NaN: a NIS at a step where an output did
    not report)."""
    return None if np.isnan(value) else float(value)


def _average(kind: str, values: np.ndarray, dof: int) -> dict:
    """ANEES / ANIS at every step of (R, T) normalised errors with its two-sided χ² band
    (Bar-Shalom's test, :meth:`gpfverify.consistency.Consistency.average_over_runs`), over the
    steps where every run has the value (a NIS is not defined where an output did not report:
    ``average`` is None there and ``steps`` counts the steps tested)."""
    kept = ~np.isnan(values).any(axis=0)
    if not kept.any():
        return {"average": [None] * values.shape[1], "band": None, "dof": dof, "runs": values.shape[0],
                "level": CONSISTENCY_LEVEL, "fraction_inside": None, "verdict": "not tested", "steps": 0}
    test = Consistency(kind, values[:, kept], dof).average_over_runs(CONSISTENCY_LEVEL)
    average: list[float | None] = [None] * values.shape[1]
    for t, v in zip(np.flatnonzero(kept).tolist(), test.values.tolist()):
        average[t] = v
    return {"average": average, "band": [test.lower, test.upper], "dof": dof, "runs": test.samples,
            "level": test.level, "fraction_inside": test.fraction_inside, "verdict": test.verdict(),
            "steps": int(kept.sum())}


def _trajectory(steps: Sequence[dict], methods: Sequence[str]) -> dict:
    """The first run's trajectory: the truth (None when unknown), every method's mean and covariance
    per step (None at a step where it failed) and the repaired DMF mean at the steps whose audit
    proposes a repair (:attr:`gpfverify.audit.case.CaseAudit.repaired_dmf_mean`; CMF's mean to rounding)."""
    return {"k": [e["k"] for e in steps],
            "truth": [e["truth"] for e in steps] if all("truth" in e for e in steps) else None,
            "means": {m: [e["means"].get(m) for e in steps] for m in methods},
            "covs": {m: [e["covs"].get(m) for e in steps] for m in methods},
            "repaired": [{"k": e["k"], "mean": e["repaired_mean"]} for e in steps if e["repaired_mean"] is not None],
            "local": [{"means": [e["local_means"][m] for e in steps], "covs": [e["local_covs"][m] for e in steps]}
                      for m in range(len(steps[0]["local_means"]))]}


def summarize(params: Params, results: list[RunRecord], model=None, filters: LocalFilters | None = None) -> dict:
    """The results.json body (CONTRACT "Checking a user's own system" keys first); ``model`` the
    system, or ``filters`` the system with its filters (default: loaded from ``params.system``)."""
    if filters is None:
        filters = load_filters(params.system) if model is None else LocalFilters(model)
    model = filters.model
    sigma, tracker = filters_record(filters, params)
    rule = parse_rank_rule(params.rank_rule)
    steps_by_run = [r.steps for r in results]
    first = steps_by_run[0]
    every = [e for steps in steps_by_run for e in steps]
    methods = list(params.methods)
    failures = [{"run": i, "k": e["k"], "method": m, "reason": why}
                for i, steps in enumerate(steps_by_run) for e in steps for m, why in e.get("failed", {}).items()]
    failed_methods = [m for m in methods if any(f["method"] == m for f in failures)]
    out = {
        "steps": len(first), "filter": params.filter,
        "per_step": [{"k": e["k"], "cmf_mean": e["cmf_mean"], "dmf_mean": e["dmf_mean"], "gap": e["gap"],
                      "sensors": [{key: s.get(key, True) for key in ("index", "reported", "rank", "full_column_rank",
                                                                     "exact")}
                                  for s in e["sensors"]]} for e in first],
        "max_gap": max(e["gap_norm"] for e in every),
        "max_gap_size": max(e["gap_size"] for e in every),
        "condition_held_steps": sum(e["condition_holds"] for e in every),
        "exact_steps": sum(e["exact"] for e in every),
        "exact_steps_within_bound": sum(bool(e["exact"] and e["gap_size"] <= e["gap_bound"]) for e in every),
        "reproduced_steps": sum(bool(e["gap_size"] <= e["gap_bound"]) for e in every),
        "branch_offset_steps": sum(any(s["branch_offset_count"] for s in e["sensors"]) for e in every),
        "total_steps": len(every),
        "failed_methods": failed_methods, "method_failures": failures,
        "system": params.system, "state_dim": model.state_dim, "sensors": _sensor_table(model),
        "sigma_points": sigma, "tracker": tracker,
        "rank_rule": {**rank_rule_to_dict(rule), "description": rule.describe()},
        "k": [e["k"] for e in first],
        "gap_norm": [[e["gap_norm"] for e in steps] for steps in steps_by_run],
        "gap_size": [[e["gap_size"] for e in steps] for steps in steps_by_run],
        "gap_bound": [[e["gap_bound"] for e in steps] for steps in steps_by_run],
        "recursive_gap_norm": [[e["recursive_gap_norm"] for e in steps] for steps in steps_by_run],
        "recursive_gap_size": [[e["recursive_gap_size"] for e in steps] for steps in steps_by_run],
        "unit_dependence": [[e["unit_dependence"] for e in steps] for steps in steps_by_run],
        "max_unit_dependence": max((e["unit_dependence"] for e in every if e["unit_dependence"] is not None),
                                   default=None),
        **{key: _per_sensor(steps_by_run, key)
           for key in ("rank", "full_column_rank", "exact", "repair_dim", "gap_share", "gap_share_size", "tol",
                       "min_canonical_correlation", "branch_offset_count")},
        "reported": [[e.get("reported", [True] * len(model.sensors)) for e in steps] for steps in steps_by_run],
        "reported_steps": [sum(e.get("reported", [True] * len(model.sensors))[m] for e in every)
                           for m in range(len(model.sensors))],
        "time_per_step": {**{m: float(np.mean([e["seconds"][m] for e in every])) for m in methods},
                          "local": float(np.mean([sum(e["seconds"]["local"]) for e in every]))},
        "timing_keys": list(TIMING_KEYS),
        "truth_known": all(r.truth_known for r in results),
        "trajectory": _trajectory(first, methods),
    }
    nis = np.array([[e["nis"]["cmf"] for e in steps] for steps in steps_by_run], dtype=float)
    out["nis"] = {"cmf": _average("NIS", nis, model.measurement_dim),
                  "local": [_average("NIS", np.array([[e["nis"]["local"][m] for e in steps] for steps in steps_by_run],
                                                     dtype=float),
                                     s.size) for m, s in enumerate(model.sensors)]}
    if out["truth_known"]:
        d = model.state_dim
        scored = [m for m in methods if m not in failed_methods]  # averages need every step
        sq = {m: np.array([[e["sq_err"][m] for e in steps] for steps in steps_by_run]) for m in scored}
        nees = {m: np.array([[e["nees"][m] for e in steps] for steps in steps_by_run]) for m in scored}
        local_sq = np.array([[e["local_sq_err"] for e in steps] for steps in steps_by_run])   # (R, T, N)
        local_nees = np.array([[e["local_nees"] for e in steps] for steps in steps_by_run])
        out["rmse"] = {m: np.sqrt(v.mean(axis=0)).tolist() for m, v in sq.items()}
        out["local_rmse"] = [np.sqrt(local_sq[:, :, m].mean(axis=0)).tolist() for m in range(len(model.sensors))]
        out["nees"] = {m: _average("NEES", v, d) for m, v in nees.items()}
        out["local_nees"] = [_average("NEES", local_nees[:, :, m], d) for m in range(len(model.sensors))]
    return out



def results_of_run(fused, truth: np.ndarray | None = None, system: str = "") -> dict:
    """The results of a check made of one :func:`~gpfverify.model_fusion.run_fusion` result on a
    :class:`~gpfverify.models.StateSpaceModel` (it must have run CMF and DMF with the audit): what
    :func:`summarize` gives for one run, with the header fields of ``results.json`` (so that the
    equivalence page renders it, :func:`gpfverify.notebook.fusion_run_html`); ``truth`` (T, D)
    adds RMSE and NEES; ``system`` names it."""
    if fused.model is None or fused.ys is None or fused.steps[0].audit is None or "cmf" not in fused.methods:
        raise InputError("the check's results need a run_fusion result with its model and ys, CMF, DMF and the audit")
    rule = fused.steps[0].audit.rank_rule
    params = Params(system=system, filter=fused.family, steps=len(fused.steps), methods=fused.methods,
                    rank_rule=rule.spec, ci_criterion=fused.ci_criterion, rcc_metric=fused.rcc_metric)
    record = _one_record(fused.model, fused, fused.ys, truth)
    filters = LocalFilters(fused.model, params=fused.params, origin={"sigma_points": "the params run_fusion ran"})
    return {"experiment": NAME, "runs": 1, "seed": None, "runs_ok": 1, "failed_runs": [], "params": params.to_json(),
            **summarize(params, [record], filters=filters)}
