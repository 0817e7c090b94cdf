"""Seed 001 §3 (Fig. 1–6, Table 1): SINS/GPS integrated navigation with a basic UPF on the
inaccurate model against GPSR-UPF (SR-UKF proposal on the inaccurate model + GP-learned residual);
the paper's claims as records.

Scenario, model mismatch and noise: :mod:`gpfverify.papers.gpsr_upf.scenario` (the filters' model
evaluates fⁿ × φ with the level-flight specific force; the GP learns the residual from training
flights flown from other headings). Both filters use the same particle count, resampling rule
(systematic, N_eff < N_T = threshold · N), prior N(0, P₀) and measurements; the truth starts from
a draw of N(0, P₀).

Process noise: by default the filters use the model's Q, the true one unless ``accel_noise_scale``
mis-specifies it (GPSR-UPF takes the velocity rows of its Q from the GP predictive variance, which
learns the true noise of the training flights). ``noise_floor`` (standard deviations per step of φ, δv, δp,
ε, ∇, default 0) adds the same diagonal floor to both filters' Q, and ``q_inflation`` multiplies
the filter-design Q (GPSR-UPF: outside the learned block, and (c − 1) Q_vv added to the GP
variance), tunings the paper does not report. With navigation-grade Q the transition density
p(xₖ | xⁱₖ₋₁) is far narrower than each particle's UKF proposal, so the importance weights
degenerate (N_eff ≈ 1 at every step). Inflating Q does not cure it: each particle's own covariance
grows with Q as well, and in the weakly observable bias states its stationary value is about T/2
steps of Q (T the Markov correlation time), whatever the factor. The remedies tried
(``INTERPRETATIONS`` of the contract): Q inflation, roughening or a regularisation kernel after
resampling (``jitter``), more particles, and ``particle_covariance = "reset"``: each particle's
(SR-)UKF proposal taken from the particle itself (a point mass), which for this linear-Gaussian
error model is the optimal importance density p(xₖ | xⁱₖ₋₁, yₖ) (Doucet, Godsill & Andrieu 2000),
with weights p(yₖ | xⁱₖ₋₁). The moves and the reset act on the filters' :class:`Particles`
between steps; the filter steps are unchanged.

Health (:mod:`gpfverify.health`): per particle filter, N_eff/N per step (``ess_check``) and
divergence (position error norm above ``DIVERGENCE_GPS_SDS`` GPS standard deviations at any step);
``results.json`` lists them under ``"health"``, and a claim comparing the particle filters is
"not decidable" (:func:`~gpfverify.health.decide`) when either fails. For reference, the proposal
filters are also run alone as single Gaussian filters: ``SR-UKF`` (inaccurate model) and
``GP-SR-UKF`` (model + GP residual), and ``TRUE-SR-UKF``, the SR-UKF on the model that generated the
flight with the SR-UKF's design noise. Its reduction 1 − RMS(TRUE-SR-UKF)/RMS(SR-UKF) is the
true-model ceiling: what a perfect correction of the model error could reach. A claimed reduction
above the ceiling cannot be confirmed by this scenario whatever the filters do, so its "NOT held" is
withheld as "not decidable" with the ceiling as the reason.

Errors are estimate − truth of the error state, per axis: attitude (arcmin), velocity (m/s),
position (m). ``position_error`` etc. are per-step RMS over runs of the 3-axis error norm;
``reduction`` is 1 − RMS(GPSR-UPF)/RMS(UPF) with the RMS over runs and steps.

Parameters, method names, the run record and the report profiles: :mod:`gpfverify.papers.gpsr_upf.contract`.
"""

from __future__ import annotations

import dataclasses
import functools
import time

import numpy as np

from gpfverify.contract.claims import Band, ClaimRecord, PairedDifference, Verdict, verdict_of
from gpfverify.contract.health_records import HealthCheck, stored_checks
from gpfverify.papers.gpsr_upf.claims import statement_of
from gpfverify.papers.gpsr_upf.contract import (CLAIMED_REDUCTION, CRUISE_RANGE_SDS, DEFAULT_RUNS, DIVERGENCE_GPS_SDS,
                                                PAPER_CRUISE_RANGE,
                                                GP_SR_UKF, GPSR_UPF, INTERPRETATIONS, NAME, PAPER, PARTICLE_FILTERS,
                                                PROFILES, QUANTITIES, REFERENCES, RESET_FACTOR_SCALE,
                                                ROUGHENING_CONSTANT, SR_UKF, TRUE_SR_UKF, UNITS, UPF, FilterRun, Params,
                                                ParticleFilterRun, RunRecord)
from gpfverify.filters.gpsr_upf import GPResidualModel, gpsr_upf_step, sr_ukf_proposal
from gpfverify.filters.resampling import Particles, ParticleStep
from gpfverify.filters.upf import upf_step
from gpfverify.gp.residual import fit_residual
from gpfverify.health import divergence_check, ess_check
from gpfverify.rng import child_rng, generator
from gpfverify.papers.gpsr_upf.scenario import (ATTITUDE, POSITION, STATE_DIM, VELOCITY, SinsGpsConfig, build_models,
                                                generate_flight, training_set)

__all__ = ["DEFAULT_RUNS", "INTERPRETATIONS", "METHODS", "NAME", "PAPER", "PROFILES", "Params", "REFERENCE_NAMES",
           "RunRecord", "ceiling_model", "cruise_range", "health_checks", "jitter_particles", "run_one", "run_sr_ukf",
           "setup", "summarize"]

#: the particle filters and the reference filters by name (results.json keys)
METHODS: tuple[str, ...] = tuple(m.key for m in PARTICLE_FILTERS)
REFERENCE_NAMES: tuple[str, ...] = tuple(m.key for m in REFERENCES)
AXES = {"attitude": ATTITUDE, "velocity": VELOCITY, "position": POSITION}
#: a reduction "≈ claimed" holds when it is at most this far below the claim
CLAIM_MARGIN = 0.10


def config_of(params: Params) -> SinsGpsConfig:
    return SinsGpsConfig(duration=params.duration, dt=params.dt, gps_position_sd=params.gps_position_sd,
                         gps_velocity_sd=params.gps_velocity_sd, initial_velocity_sd=params.initial_velocity_sd,
                         initial_position_sd=params.initial_position_sd, accel_scale_ppm=params.accel_scale_ppm,
                         accel_noise_scale=params.accel_noise_scale)


def _floor_cov(floor) -> np.ndarray:
    return np.diag(np.repeat(np.asarray(floor, dtype=float), 3) ** 2)


@functools.lru_cache(maxsize=2)
def setup(params: Params):
    """Flight, models and the fitted residual GP for one parameter set (cached per process: every
    run of an experiment shares the training flights and the GP)."""
    config = config_of(params)
    models = build_models(generate_flight(config), config)
    rng = generator(params.train_seed)
    data = training_set(config, list(params.train_headings), params.train_points, rng)
    started = time.process_time()
    residual = fit_residual(data.states, data.next_true, data.next_approx, outputs=range(3, 6),
                            state_inputs=range(3), inputs=data.inputs, restarts=params.restarts, seed=rng)
    fit_seconds = time.process_time() - started
    floor = _floor_cov(params.noise_floor)
    design_q = params.q_inflation * models.approx.Q
    upf_model = models.approx.with_noise(process_cov=design_q + floor)
    # GPSR-UPF: the GP variance replaces the velocity block of the design Q; the inflation beyond the
    # true Q, (c − 1) Q_vv, is added to it so that both filters carry the same extra noise
    extra = floor.copy()
    extra[VELOCITY, VELOCITY] += (params.q_inflation - 1.0) * models.approx.Q[VELOCITY, VELOCITY]
    gpsr_model = GPResidualModel(models.approx.with_noise(process_cov=design_q), residual,
                                 transition_inputs=models.transition_inputs,
                                 extra_noise=extra if np.any(extra) else None)
    return config, models, upf_model, gpsr_model, fit_seconds


def jitter_particles(step: ParticleStep, kind: str, rng: np.random.Generator) -> Particles:
    """The posterior of a step that resampled, moved by ``kind``: "roughening" adds
    N(0, (K E_j N^(−1/D))²) to component j, E_j = max − min of the resampled particles, K =
    ROUGHENING_CONSTANT (Gordon, Salmond & Smith 1993, §4); "regularised" adds h L ε with L the
    symmetric square root of the weighted covariance before resampling and h = (4 / (N (D + 2)))^(1/(D+4))
    the optimal bandwidth of the Gaussian kernel (Musso, Oudjane & Le Gland 2001, post-RPF); "none"
    or a step that did not resample: the posterior unchanged."""
    posterior = step.posterior
    if kind == "none" or not step.resampled:
        return posterior
    x = posterior.particles
    n, d = x.shape
    if kind == "roughening":
        sd = ROUGHENING_CONSTANT * np.ptp(x, axis=0) * n ** (-1.0 / d)
        moved = x + rng.standard_normal(x.shape) * sd
    elif kind == "regularised":
        bandwidth = (4.0 / (n * (d + 2))) ** (1.0 / (d + 4))
        # a square root of the (possibly rank-deficient) weighted covariance
        values, vectors = np.linalg.eigh(step.cov)
        root = vectors * np.sqrt(np.clip(values, 0.0, None))
        moved = x + bandwidth * rng.standard_normal(x.shape) @ root.T
    else:
        raise ValueError(f"unknown jitter {kind!r}")
    return dataclasses.replace(posterior, particles=moved)


def _errors(estimates: np.ndarray, truth: np.ndarray) -> dict[str, tuple[tuple[float, float, float], ...]]:
    errors = estimates - truth
    return {q: tuple((float(a), float(b), float(c)) for a, b, c in errors[:, sl]) for q, sl in AXES.items()}


def _run_filter(method: str, params: Params, upf_model, gpsr_model, prior_cov, ys, truth, rng) -> ParticleFilterRun:
    belief = Particles.from_gaussian(np.zeros(STATE_DIM), prior_cov, params.particles, rng)
    step, model = (upf_step, upf_model) if method == UPF.key else (gpsr_upf_step, gpsr_model)
    point = None
    if params.particle_covariance == "reset":  # the proposal from each particle itself (a point mass)
        point = np.broadcast_to(RESET_FACTOR_SCALE * np.linalg.cholesky(upf_model.Q),
                                (params.particles, STATE_DIM, STATE_DIM))
    estimates, ess, resampled = [], [], 0
    min_diag = np.inf
    started = time.process_time()
    for k, y in enumerate(ys, 1):
        if point is not None:
            belief = dataclasses.replace(belief, sqrt_covs=point.copy())
        record = step(belief, model, y, k=k, rng=rng, resample_threshold=params.resample_threshold)
        belief = jitter_particles(record, params.jitter, rng)
        estimates.append(record.mean)
        ess.append(float(record.ess))
        resampled += bool(record.resampled)
        factors = belief.sqrt_covs
        if factors is None:  # the UPF and GPSR-UPF carry one covariance factor per particle
            raise RuntimeError(f"{method} returned particles without covariance factors")
        min_diag = min(min_diag, float(np.diagonal(factors, axis1=1, axis2=2).min()))
    seconds = time.process_time() - started
    fractions = np.asarray(ess) / params.particles
    return ParticleFilterRun(seconds=seconds, **_errors(np.array(estimates), truth),
                             ess_mean=float(np.mean(ess)) / params.particles, resample_rate=resampled / len(ys),
                             min_factor_diagonal=min_diag, ess_fraction=tuple(float(f) for f in fractions))


def ceiling_model(models, design_model):
    """The true-model ceiling's model: the transition that generated the flight with the filter-design
    noise of ``design_model`` (the SR-UKF's) plus the process noise the inaccurate model leaves out
    (true Q − model Q, zero unless Q is mis-specified), so that it differs from the SR-UKF by the model
    error alone."""
    return models.true.with_noise(process_cov=design_model.Q + (models.true.Q - models.approx.Q))


def run_sr_ukf(model_at, prior_cov, ys, truth, process_sqrt=None) -> FilterRun:
    """One SR-UKF (a batch of one) from N(0, P₀) on the model ``model_at(k)`` of step k; its errors
    against ``truth`` and its CPU seconds."""
    mean, factor = np.zeros((1, STATE_DIM)), np.linalg.cholesky(prior_cov)[None]
    estimates = []
    started = time.process_time()
    for k, y in enumerate(ys, 1):
        mean, factor = sr_ukf_proposal(Particles(mean, np.zeros(1), factor), model_at(k), y, k=k,
                                       process_sqrt=process_sqrt)
        estimates.append(mean[0])
    seconds = time.process_time() - started
    return FilterRun(seconds=seconds, **_errors(np.array(estimates), truth))


def run_one(params: Params, seed_seq: np.random.SeedSequence) -> RunRecord:
    config, models, upf_model, gpsr_model, fit_seconds = setup(params)
    prior_cov = config.initial_cov()
    truth_rng = child_rng(seed_seq, 0)
    x0 = truth_rng.multivariate_normal(np.zeros(STATE_DIM), prior_cov)
    xs, ys = models.true.simulate(config.steps, truth_rng, x0=x0)
    # how well the GP knows this run's residual (Δt (fⁿ − f̂ⁿ) × φ and the scale-factor forcing) along
    # the true trajectory
    previous = np.vstack([x0, xs[:-1]])
    true_residual = models.residual(previous)[:, VELOCITY]
    gp_residual = gpsr_model.transition.mean(previous, models.transition_inputs[:-1])
    particle_filters = {m: _run_filter(m, params, upf_model, gpsr_model, prior_cov, ys, xs, child_rng(seed_seq, i))
                        for i, m in enumerate(METHODS, 1)}
    true_model = ceiling_model(models, upf_model)
    references = {SR_UKF.key: run_sr_ukf(lambda k: upf_model, prior_cov, ys, xs),
                  GP_SR_UKF.key: run_sr_ukf(gpsr_model.at_step, prior_cov, ys, xs, gpsr_model.process_sqrt),
                  TRUE_SR_UKF.key: run_sr_ukf(lambda k: true_model, prior_cov, ys, xs)}
    return RunRecord(residual_rms=float(np.sqrt(np.mean(true_residual**2))),
                     gp_residual_error_rms=float(np.sqrt(np.mean((gp_residual - true_residual) ** 2))),
                     gp_fit_seconds=fit_seconds, particle_filters=particle_filters, references=references)


def _rms(values) -> float | None:
    """√mean, or None for an empty selection (a flight too short to have that segment)."""
    values = np.asarray(values, dtype=float)
    return float(np.sqrt(np.mean(values))) if values.size else None


def _reduction(new, old) -> float | None:
    return None if new is None or old is None else 1.0 - new / old


def _filter(record: RunRecord, method: str) -> FilterRun:
    return record.particle_filters[method] if method in record.particle_filters else record.references[method]


def _squared_norms(records: list[RunRecord], method: str, quantity: str) -> tuple[np.ndarray, np.ndarray]:
    """(errors (runs, K, 3), squared error norms (runs, K))."""
    err = np.array([getattr(_filter(r, method), quantity) for r in records], dtype=float)
    return err, np.sum(err**2, axis=2)


def cruise_range(band: dict, manoeuvre: np.ndarray) -> list[float] | None:
    """The range of a filter's per-axis error in cruise, comparable to the paper's ranges read off its
    figures: the smallest and largest of mean ± CRUISE_RANGE_SDS s.d. over runs, over the axes and the
    cruise steps (``band``: per-step per-axis mean and s.d.); None for a flight without cruise."""
    mean, sd = np.asarray(band["mean"]), np.asarray(band["sd"])
    cruise = ~np.asarray(manoeuvre, dtype=bool)
    if not cruise.any():
        return None
    return [float((mean - CRUISE_RANGE_SDS * sd)[cruise].min()), float((mean + CRUISE_RANGE_SDS * sd)[cruise].max())]


def summarize(params: Params, records: list[RunRecord]) -> dict:
    """Per-step RMS error norms, per-axis bands (mean ± s.d. over runs) and their range in cruise, RMS
    reductions overall and by flight segment, filter time per run, importance-weight health, GP
    residual accuracy and the paper's claims."""
    config = config_of(params)
    manoeuvre = generate_flight(config).manoeuvring()[1:]
    body: dict = {f"{q}_error": {} for q in AXES}
    bands: dict = {m: {} for m in METHODS}
    overall: dict = {m: {} for m in METHODS}
    per_run: dict = {m: {} for m in METHODS}
    segments: dict = {m: {} for m in METHODS}
    for method in METHODS:
        for q in AXES:
            err, sq = _squared_norms(records, method, q)
            body[f"{q}_error"][method] = np.sqrt(sq.mean(axis=0)).tolist()
            bands[method][q] = {"mean": err.mean(axis=0).tolist(), "sd": err.std(axis=0).tolist()}
            overall[method][q] = _rms(sq)
            per_run[method][q] = np.sqrt(sq.mean(axis=1)).tolist()
            segments[method][q] = {"manoeuvre": _rms(sq[:, manoeuvre]), "cruise": _rms(sq[:, ~manoeuvre])}
    reduction = {q: 1.0 - overall[GPSR_UPF.key][q] / overall[UPF.key][q] for q in AXES}
    cruise = {m: {q: cruise_range(bands[m][q], manoeuvre) for q in AXES} for m in METHODS}
    # records saved before the true-model ceiling was run lack TRUE-SR-UKF
    present = tuple(m for m in REFERENCE_NAMES if all(m in r.references for r in records))
    reference: dict = {"error": {q: {} for q in AXES}, "rms": {m: {} for m in present}}
    for method in present:
        for q in AXES:
            _, sq = _squared_norms(records, method, q)
            reference["error"][q][method] = np.sqrt(sq.mean(axis=0)).tolist()
            reference["rms"][method][q] = _rms(sq)
    reference["reduction"] = {q: 1.0 - reference["rms"][GP_SR_UKF.key][q] / reference["rms"][SR_UKF.key][q]
                              for q in AXES}
    # the true-model ceiling: the reduction an SR-UKF reaches by knowing the true model
    reference["ceiling"] = ({q: 1.0 - reference["rms"][TRUE_SR_UKF.key][q] / reference["rms"][SR_UKF.key][q]
                             for q in AXES} if TRUE_SR_UKF.key in present else None)
    segment_reduction = {seg: {q: _reduction(segments[GPSR_UPF.key][q][seg], segments[UPF.key][q][seg])
                               for q in AXES} for seg in ("manoeuvre", "cruise")}
    ess = {m: float(np.mean([r.particle_filters[m].ess_mean for r in records])) for m in METHODS}
    seconds = {m: float(np.mean([_filter(r, m).seconds for r in records])) for m in METHODS + present}
    body.update({
        "reduction": reduction, "rms": overall, "per_run_rms": per_run, "segment_rms": segments,
        "segment_reduction": segment_reduction, "error_bands": bands, "cruise_range": cruise,
        "reference": reference,
        "time_per_run": seconds, "time_per_step": {m: s / config.steps for m, s in seconds.items()},
        "ess_fraction": ess,
        # CONTRACT.md "Claims as records": mean N_eff / N of every particle-filter configuration run
        "mean_ess_fraction": dict(ess),
        "resample_rate": {m: float(np.mean([r.particle_filters[m].resample_rate for r in records])) for m in METHODS},
        "min_factor_diagonal": {m: float(np.min([r.particle_filters[m].min_factor_diagonal for r in records]))
                                for m in METHODS},
        "gp_residual": {"residual_rms": _rms([r.residual_rms ** 2 for r in records]),
                        "error_rms": _rms([r.gp_residual_error_rms ** 2 for r in records]),
                        "fit_seconds": records[0].gp_fit_seconds},
        "time": (np.arange(1, config.steps + 1) * config.dt).tolist(),
        "manoeuvre": manoeuvre.tolist()})
    masks = window_masks(body)
    # each run's RMS error in each flight window (none for a window the flight is too short to have)
    body["per_run_window_rms"] = {
        m: {window: {q: np.sqrt(_squared_norms(records, m, q)[1][:, mask].mean(axis=1)).tolist() if mask.any()
                     else None for q in AXES}
            for window, mask in masks.items()} for m in METHODS}
    body["health"] = [dataclasses.asdict(c) for c in health_checks(params, records)]
    body["claims"] = claims(params, body, len(records))
    return body


def judge(params: Params, body: dict, runs: int) -> tuple[list[ClaimRecord], list[ClaimRecord]]:
    """The claims judged on a summary ``body`` of ``runs`` runs (what :func:`summarize` writes, and
    what a reference page re-judges from a stored ``results.json``); none on computation time."""
    return claims(params, body, runs), []


def divergence_bounds(params: Params) -> dict[str, float]:
    """Error-norm bounds of the divergence check per quantity: DIVERGENCE_GPS_SDS times the GPS
    position noise (m), the initial velocity error (m/s) and the largest initial attitude error
    (arcmin) standard deviations."""
    attitude = max(SinsGpsConfig().initial_attitude_arcmin)
    return {"position": DIVERGENCE_GPS_SDS * params.gps_position_sd,
            "velocity": DIVERGENCE_GPS_SDS * params.initial_velocity_sd,
            "attitude": DIVERGENCE_GPS_SDS * attitude}


def health_checks(params: Params, records: list[RunRecord]) -> list[HealthCheck]:
    """Weight collapse (N_eff/N per step over all runs; the per-run means for records that lack the
    per-step values) and divergence (an error norm above :func:`divergence_bounds` at some step, per
    quantity) of each particle filter."""
    out = []
    bounds = divergence_bounds(params)
    for method in METHODS:
        runs = [r.particle_filters[method] for r in records]
        fractions = [f for run in runs for f in (run.ess_fraction or (run.ess_mean,))]
        # N_eff ≥ 1 exactly; the clip keeps a rounding of 1/N − ε inside ess_check's (0, 1]
        out.append(ess_check(method, np.clip(fractions, 1e-12, 1.0), params.particles))
        for q in QUANTITIES:
            errors = np.array([getattr(run, q) for run in runs], dtype=float)
            out.append(divergence_check(f"{method} {q}", errors, bound=bounds[q]))
    return out


# ---- claims -------------------------------------------------------------------------------------
def reduction_with_error(per_run_rms: dict, quantity: str) -> tuple[float, float | None]:
    """Mean over runs of the per-run reduction 1 − RMS_GPSR/RMS_UPF and its standard error (None
    with a single run)."""
    upf = np.asarray(per_run_rms[UPF.key][quantity])
    gpsr = np.asarray(per_run_rms[GPSR_UPF.key][quantity])
    per_run = 1.0 - gpsr / upf
    se = float(per_run.std(ddof=1) / np.sqrt(per_run.size)) if per_run.size > 1 else None
    return float(per_run.mean()), se


def _ceiling_text(ceiling: dict | None, quantity: str) -> str:
    if ceiling is None:
        return ""
    return (f"true-model ceiling (TRUE-SR-UKF against SR-UKF) {100 * ceiling[quantity]:.1f} %; ")


#: the flight windows the paper's text compares the filters in (§3): 0–200 s take-off, roll and climb;
#: 500–600 s acceleration and turn; cruise the steps outside the manoeuvres
WINDOWS = {"0-200": (0.0, 200.0), "500-600": (500.0, 600.0)}
#: "no big difference" (差別不大, the velocity error in 0–200 s), read as per-run RMS within this factor
NO_BIG_DIFFERENCE = 1.25


def window_masks(body: dict) -> dict[str, np.ndarray]:
    """Each window of :data:`WINDOWS` and "cruise" as a mask over the steps of a summary."""
    t = np.asarray(body["time"])
    masks = {name: (t > lo) & (t <= hi) for name, (lo, hi) in WINDOWS.items()}
    masks["cruise"] = ~np.asarray(body["manoeuvre"], dtype=bool)
    return masks


def claims(params: Params, body: dict, n: int) -> list[ClaimRecord]:
    """The paper's claims (and the toolkit's supplementary checks) decided on a summary body of
    ``n`` runs, each with the health of the particle filters it compares (the weight-collapse and
    divergence gates; :meth:`~gpfverify.contract.claims.ClaimRecord.checked`). A claim comparing
    the two particle filters in a flight window needs each run's RMS there (``"per_run_window_rms"``,
    not in a summary made before it was kept)."""
    checks = stored_checks(body.get("health", []))
    ess = body["mean_ess_fraction"]
    ess_text = (f"mean N_eff/N {', '.join(f'{m} {ess[m]:.4f}' for m in METHODS)} with N = {params.particles} "
                f"(1/N = {1 / params.particles:.4f})")
    few = (f"rests on {n} run{'s' if n != 1 else ''}; the full profile runs {DEFAULT_RUNS} (the paper states no "
           "run count)",) if n < DEFAULT_RUNS else ()

    def record(claim: str, verdict: Verdict, statistic: float | None, threshold: float | None, evidence: str,
               slug: str, caveats: tuple[str, ...], compared: tuple[str, ...], runs_to_decide: int | None = None,
               would_be: Verdict | None = None, needs: str = "") -> ClaimRecord:
        statement = statement_of(slug)
        made = ClaimRecord(claim, statement.source, verdict, statistic, threshold, n, evidence, caveats,
                           id=f"{NAME}/{slug}", paper=PAPER,
                           runs_to_decide=runs_to_decide if verdict == "undecided" else None, would_be=would_be,
                           needs=needs)
        return statement.applied(made).checked(compared, checks)

    def filters(q: str) -> tuple[str, ...]:
        return (UPF.key, f"{UPF.key} {q}", GPSR_UPF.key, f"{GPSR_UPF.key} {q}")

    ceiling = body["reference"].get("ceiling")
    out = []
    for q in QUANTITIES:
        claimed = CLAIMED_REDUCTION[q]
        threshold = claimed - CLAIM_MARGIN
        value = body["reduction"][q]
        per_run = 1.0 - (np.asarray(body["per_run_rms"][GPSR_UPF.key][q])
                         / np.asarray(body["per_run_rms"][UPF.key][q]))
        # held when the per-run reduction is above the threshold beyond the Monte Carlo tolerance
        test = PairedDifference.of(np.full(per_run.size, threshold), per_run)
        mean, se = reduction_with_error(body["per_run_rms"], q)
        spread = "" if se is None else f" ± {100 * se:.1f}"
        verdict, would_be, reach = _within_reach(test.verdict, ceiling, q, threshold)
        out.append(record(
            f"GPSR-UPF lowers the {q} error by about {100 * claimed:.0f} % against the UPF "
            f"(held if the reduction is at least {100 * threshold:.0f} %)", verdict, mean, threshold,
            f"per-run reduction 1 − RMS(GPSR-UPF)/RMS(UPF) {100 * mean:.1f}{spread} % (mean ± s.e. over {n} "
            f"runs); over all runs RMS {body['rms'][UPF.key][q]:.4g} → {body['rms'][GPSR_UPF.key][q]:.4g} "
            f"{UNITS[q]}, reduction {100 * value:.1f} %; {_ceiling_text(ceiling, q)}{ess_text}", f"reduction-{q}",
            reach + few, filters(q), test.runs_to_decide, would_be))
    out += _window_claims(body, n, record, filters)
    reference = body["reference"]
    for q in QUANTITIES:
        claimed = CLAIMED_REDUCTION[q]
        threshold = claimed - CLAIM_MARGIN
        value = reference["reduction"][q]
        out.append(record(
            f"the GP residual lowers the {q} error by about {100 * claimed:.0f} % when the proposal filters run "
            f"alone (SR-UKF → GP-SR-UKF; held if the reduction is at least {100 * threshold:.0f} %)",
            verdict_of(value >= threshold), value, threshold,
            f"RMS {reference['rms'][SR_UKF.key][q]:.4g} → {reference['rms'][GP_SR_UKF.key][q]:.4g} {UNITS[q]}: "
            f"reduction {100 * value:.1f} %", f"single-filter-reduction-{q}", few, (SR_UKF.key, GP_SR_UKF.key)))
    if ceiling is not None:
        for q in QUANTITIES:
            threshold = CLAIMED_REDUCTION[q] - CLAIM_MARGIN
            out.append(record(
                f"the scenario's model error leaves room for the claimed {q} reduction — the SR-UKF that knows the "
                f"true model lowers the {q} error by at least {100 * threshold:.0f} % against the SR-UKF on the "
                "inaccurate model", verdict_of(ceiling[q] >= threshold), ceiling[q], threshold,
                f"RMS {reference['rms'][SR_UKF.key][q]:.4g} (inaccurate model) → "
                f"{reference['rms'][TRUE_SR_UKF.key][q]:.4g} {UNITS[q]} (true model): ceiling "
                f"{100 * ceiling[q]:.1f} %", f"true-model-ceiling-{q}",
                ("checked on the SR-UKF, the particle filters' proposal; a point estimate over runs and steps",)
                + few, (SR_UKF.key, TRUE_SR_UKF.key)))
    diag = body["min_factor_diagonal"]
    smallest = min(diag.values())
    out.append(record(
        "The square-root form keeps every covariance factor valid over the flight",
        verdict_of(all(np.isfinite(v) and v > 0 for v in diag.values())), smallest, 0.0,
        f"{n} runs finished; smallest diagonal entry of any particle's covariance factor: "
        + ", ".join(f"{m} {v:.3g}" for m, v in diag.items()), "factors-valid",
        ("counts the runs that finished; a run stopped by an error is listed with its error among the failed "
         "runs of results.json; a property of the arithmetic, which compares no filter's estimates",) + few, ()))
    return out


def _window_claims(body: dict, n: int, record, filters) -> list[ClaimRecord]:
    """§3's remarks on each flight window (Figs. 1–6): in cruise, and in 500–600 s, GPSR-UPF's error
    is smaller than UPF's for every quantity; in 0–200 s its position and attitude error are smaller
    and its velocity error differs little (within :data:`NO_BIG_DIFFERENCE` ×) — each a paired
    comparison of the per-run RMS in the window (5 standard errors of the difference; the velocity
    within a band of the per-run log ratio)."""
    stored = body.get("per_run_window_rms")
    out = []
    for q in QUANTITIES:
        paper = PAPER_CRUISE_RANGE
        for window, slug, what in (("cruise", f"cruise-band-{q}", "in cruise"),
                                   ("0-200", f"manoeuvre-0-200-{q}", "in 0–200 s (take-off, roll, climb)"),
                                   ("500-600", f"manoeuvre-500-600-{q}", "in 500–600 s (acceleration, turn)")):
            similar = window == "0-200" and q == "velocity"
            claim = (f"GPSR-UPF's {q} error differs little from UPF's {what} (per-run RMS within "
                     f"{NO_BIG_DIFFERENCE:g} × either way)" if similar else
                     f"GPSR-UPF's {q} error is smaller than UPF's {what}")
            said = (f"; the paper's cruise ranges: UPF {paper[UPF.key][q]}, GPSR-UPF {paper[GPSR_UPF.key][q]} "
                    f"{UNITS[q]}" if window == "cruise" else "")
            if stored is None:
                out.append(record(claim, "not decidable", None, None, "not judged" + said, slug, (), filters(q),
                                  needs="each run's RMS error in the flight windows (results.json "
                                        "'per_run_window_rms'), which a summary made before it was kept does not "
                                        "have"))
                continue
            if stored[UPF.key][window][q] is None:
                out.append(record(claim, "not decidable", None, None, "not judged" + said, slug, (), filters(q),
                                  needs=f"a flight long enough to have the window {what}"))
                continue
            upf = np.asarray(stored[UPF.key][window][q])
            gpsr = np.asarray(stored[GPSR_UPF.key][window][q])
            if similar:
                band = Band.of(float(np.mean(np.log(gpsr / upf))),
                               PairedDifference.of(np.log(gpsr / upf), np.zeros(n)).atol,
                               -np.log(NO_BIG_DIFFERENCE), np.log(NO_BIG_DIFFERENCE), n)
                out.append(record(claim, band.verdict, float(np.exp(band.value)), NO_BIG_DIFFERENCE,
                                  f"per-run RMS ratio GPSR-UPF / UPF {float(np.exp(band.value)):.3g} (geometric mean "
                                  f"over {n} runs; held when within {1 / NO_BIG_DIFFERENCE:.3g}–{NO_BIG_DIFFERENCE:g} "
                                  "beyond 5 standard errors of the log ratio)", slug, (), filters(q),
                                  band.runs_to_decide))
                continue
            d = PairedDifference.of(gpsr, upf)
            out.append(record(claim, d.verdict, d.mean, 0.0,
                              f"per-run RMS GPSR-UPF − UPF {d.mean:+.4g} ± {d.atol if d.atol is not None else 0:.2g} "
                              f"{UNITS[q]} (mean over {n} runs ± 5 standard errors; RMS {upf.mean():.4g} → "
                              f"{gpsr.mean():.4g})" + said, slug, (), filters(q), d.runs_to_decide))
    return out


def _within_reach(verdict: Verdict, ceiling: dict | None, quantity: str,
                  threshold: float) -> tuple[Verdict, Verdict | None, tuple[str, ...]]:
    """A "NOT held" becomes "not decidable" (the verdict the runs gave kept) when the scenario cannot
    reach the threshold at all: the true-model ceiling (the reduction of an SR-UKF that knows the true
    model) is below it, so no correction of the model, however good, could confirm the claim here."""
    if ceiling is None or ceiling[quantity] >= threshold:
        return verdict, None, ()
    reason = (f"the claim is out of reach in this scenario: an SR-UKF that knows the true model lowers the "
              f"{quantity} error by only {100 * ceiling[quantity]:.1f} % (true-model ceiling), below the "
              f"{100 * threshold:.0f} % threshold")
    if verdict == "NOT held":
        return "not decidable", verdict, (reason,)
    return verdict, None, (reason,)
