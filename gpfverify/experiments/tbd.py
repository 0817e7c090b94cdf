"""Seed 004: PF-TBD against the two-stage TPFTBD in Rutten's scenario — existence probability,
ROC, detection probability at a fixed false-alarm rate against SNR, position RMSE, the transfer
parameter ζ, and run time; the paper's claims as records.

One run = for every SNR in ``Params.snr``, one target-present and one target-absent image
sequence, each filtered by every method (methods with the same N share the PF random stream:
common random numbers); at the focus SNR also the ζ sweep. Detection: the filter declares a
target in a frame when its existence probability exceeds a threshold τ; the ROC sweeps τ, Pd is
the share of target-present frames (frames first … last of the target-present runs) above τ, Pfa
the share of all frames of the target-absent runs above τ.

Parameters, methods, the run record and the report profiles: :mod:`gpfverify.contract.tbd`.
"""

from __future__ import annotations

import math
import time

import numpy as np

from gpfverify.contract.claims import ClaimRecord, Verdict, combine, verdict_of
from gpfverify.contract.papers import PAPERS
from gpfverify.contract.tbd import (NAME, PAPER, PAPER_RUNS, PROFILES, MethodRun, Params, RunRecord, SnrRun,
                                   TbdMethod, main_methods, sweep_methods)
from gpfverify.filters.tbd import TbdConfig, TbdModel, filter_sequence
from gpfverify.scenarios.tbd import TbdScenario, scenario_model, simulate

__all__ = ["DEFAULT_RUNS", "NAME", "PAPER", "PROFILES", "Params", "RunRecord", "pd_at_pfa", "roc_curve",
           "run_one", "snr_gain", "summarize"]

DEFAULT_RUNS = PAPER_RUNS
ROC_POINTS = 201
GAIN_LEVELS = 21
#: a comparison "A at least as good as B" is NOT held when A falls short by more than this many
#: combined standard errors (over runs), undecided when it falls short by less
SIGNIFICANCE_SE = 2.0
#: the paper's thresholds: SNR gain at equal N (dB, §3.2), time ratios (Table 1)
GAIN_DB = 1.0
TIME_RATIO_EQUAL_N = 1.2
TIME_RATIO_HALF_N = 0.60
BEST_ZETA = 0.6
WORSE_ZETA = 0.4


# ---- methods ------------------------------------------------------------------------------------
def _config(params: Params, method: TbdMethod) -> TbdConfig:
    zeta = 1.0 if not method.two_stage else params.zeta if method.zeta is None else method.zeta
    return TbdConfig(method.particles, params.birth_threshold, params.birth_uniform_share, method.two_stage,
                     zeta, params.second_stage_radius)


def _stream(seed: np.random.SeedSequence, *key: int) -> np.random.Generator:
    """A generator for a fixed sub-key of this run's seed (independent of spawn order)."""
    return np.random.default_rng(np.random.SeedSequence(seed.entropy, spawn_key=(*seed.spawn_key, *key)))


def scenario_of(params: Params) -> TbdScenario:
    return TbdScenario(params.frames, params.first_frame, params.last_frame, params.initial_state)


def model_of(params: Params, snr_db: float) -> TbdModel:
    """The TBD model with σ set for ``snr_db`` (and the birth intensity range of the scenario)."""
    base = TbdModel(params.grid_size, params.cell_size, params.blur, 1.0, params.q1, params.q2, params.period,
                    params.p_birth, params.p_death, params.patch_radius, params.velocity_max)
    return scenario_model(snr_db, scenario_of(params), params.snr_convention, base)


def run_one(params: Params, seed: np.random.SeedSequence) -> RunRecord:
    main, sweep = main_methods(params), sweep_methods(params)
    scenario = scenario_of(params)
    cases: list[SnrRun] = []
    seconds: dict[TbdConfig, list[float]] = {}  # config -> seconds per sequence
    for s_index, snr in enumerate(params.snr):
        model = model_of(params, snr)
        scene_rng = _stream(seed, s_index, 0)
        sequences = {"present": simulate(model, scenario, scene_rng, True),
                     "absent": simulate(model, scenario, scene_rng, False)}
        methods = main + sweep if snr == params.focus_snr_db else main
        done: dict[TbdConfig, MethodRun] = {}
        out = {}
        for method in methods:
            config = _config(params, method)
            if config not in done:
                existence, sq_error = {}, ()
                for c_index, (case, seq) in enumerate(sequences.items()):
                    pf_rng = _stream(seed, s_index, 1, c_index, config.n_particles, 0)
                    second_rng = _stream(seed, s_index, 1, c_index, config.n_particles, 1)
                    start = time.process_time()
                    track = filter_sequence(seq.images, model, config, pf_rng, second_rng)
                    seconds.setdefault(config, []).append(time.process_time() - start)
                    existence[case] = tuple(track.existence.tolist())
                    if case == "present":
                        err = track.estimates[seq.present][:, [0, 2]] - seq.truth[seq.present][:, [0, 2]]
                        sq_error = tuple(np.sum(err**2, axis=1).tolist())
                done[config] = MethodRun(existence["present"], existence["absent"], sq_error)
            out[method.key] = done[config]
        cases.append(SnrRun(snr, out))
    return RunRecord(tuple(cases), {m.key: float(np.mean(seconds[_config(params, m)])) for m in main + sweep})


# ---- metrics ------------------------------------------------------------------------------------
def roc_curve(present: np.ndarray, absent: np.ndarray) -> dict:
    """P_d and P_fa at thresholds τ on the existence probability: τ = 0, the pooled quantiles, 1."""
    pooled = np.concatenate([present.ravel(), absent.ravel()])
    taus = np.unique(np.concatenate([[0.0], np.quantile(pooled, np.linspace(0, 1, ROC_POINTS)), [1.0]]))
    pd = (present.ravel()[None, :] > taus[:, None]).mean(axis=1)
    pfa = (absent.ravel()[None, :] > taus[:, None]).mean(axis=1)
    return {"threshold": taus.tolist(), "pfa": pfa.tolist(), "pd": pd.tolist()}


def pd_at_pfa(present: np.ndarray, absent: np.ndarray, pfa: float) -> tuple[float, float, float]:
    """(P_d, its standard error over runs, τ) at the smallest τ whose false-alarm rate is ≤ pfa.

    present (runs, present frames), absent (runs, frames). The standard error treats the runs as
    independent (frames within a run are not) and ignores the sampling error of τ.
    """
    values = np.sort(absent.ravel())
    tau = float(values[max(math.ceil((1.0 - pfa) * values.size) - 1, 0)])
    per_run = (present > tau).mean(axis=1)
    se = float(per_run.std(ddof=1) / math.sqrt(per_run.size)) if per_run.size > 1 else float("nan")
    return float(per_run.mean()), se, tau


def snr_gain(snrs, pd_better, pd_worse, levels: int = GAIN_LEVELS) -> dict | None:
    """Horizontal distance (dB) between two P_d-vs-SNR curves: SNR_worse(P) − SNR_better(P) at
    P_d levels inside both curves' ranges (curves made monotone by a running maximum)."""
    snrs = np.asarray(snrs, dtype=float)
    order = np.argsort(snrs)
    snrs = snrs[order]
    better = np.maximum.accumulate(np.asarray(pd_better, dtype=float)[order])
    worse = np.maximum.accumulate(np.asarray(pd_worse, dtype=float)[order])
    lo, hi = max(better[0], worse[0]), min(better[-1], worse[-1])
    if not hi > lo:
        return None
    grid = np.linspace(lo, hi, levels)
    gain = np.interp(grid, worse, snrs) - np.interp(grid, better, snrs)
    return {"pd_levels": grid.tolist(), "gain_db": gain.tolist(), "mean_gain_db": float(gain.mean())}


def _stack(records: list[RunRecord], s_index: int, key: str, field: str) -> np.ndarray:
    return np.array([getattr(r.cases[s_index].methods[key], field) for r in records], dtype=float)


def _curves(params: Params, records: list[RunRecord], s_index: int, methods: tuple[TbdMethod, ...]) -> dict:
    present_mask = scenario_of(params).present
    out: dict[str, dict] = {"existence_prob": {}, "existence_prob_absent": {}, "rmse": {}, "roc": {},
                            "pd_at_pfa": {}, "pd_at_pfa_se": {}, "rmse_mean": {}}
    for key in (m.key for m in methods):
        present = _stack(records, s_index, key, "present")
        absent = _stack(records, s_index, key, "absent")
        sq = _stack(records, s_index, key, "sq_error")
        rmse: list[float | None] = [None] * present_mask.size
        for frame, value in zip(np.flatnonzero(present_mask), np.sqrt(sq.mean(axis=0))):
            rmse[frame] = float(value)
        pd, se, _ = pd_at_pfa(present[:, present_mask], absent, params.pfa)
        out["existence_prob"][key] = present.mean(axis=0).tolist()
        out["existence_prob_absent"][key] = absent.mean(axis=0).tolist()
        out["rmse"][key] = rmse
        out["roc"][key] = roc_curve(present[:, present_mask], absent)
        out["pd_at_pfa"][key] = pd
        out["pd_at_pfa_se"][key] = se
        out["rmse_mean"][key] = float(np.sqrt(sq.mean()))
    return out


def summarize(params: Params, records: list[RunRecord]) -> dict:
    main, sweep = main_methods(params), sweep_methods(params)
    focus = params.focus_index
    body = _curves(params, records, focus, main)
    by_snr: dict[str, list[float]] = {m.key: [] for m in main}
    by_snr_se: dict[str, list[float]] = {m.key: [] for m in main}
    for s_index in range(len(params.snr)):
        curves = _curves(params, records, s_index, main)
        for m in main:
            by_snr[m.key].append(curves["pd_at_pfa"][m.key])
            by_snr_se[m.key].append(curves["pd_at_pfa_se"][m.key])
    pf = main[0]
    body.update({"snr_db": list(params.snr), "focus_snr_db": params.focus_snr_db,
                 "target_frames": int(scenario_of(params).present.sum()),
                 "pd_vs_snr": by_snr, "pd_vs_snr_se": by_snr_se,
                 # horizontal gap (dB) of each TPFTBD method's Pd-vs-SNR curve to PF-TBD's
                 "snr_gain": {m.key: snr_gain(params.snr, by_snr[m.key], by_snr[pf.key]) for m in main[1:]}})
    if sweep:
        body["zeta_sweep"] = {"zeta": list(params.zeta_sweep), "n_particles": params.zeta_sweep_particles,
                              "snr_db": params.focus_snr_db, "methods": [m.key for m in sweep],
                              **_curves(params, records, focus, sweep)}
    body["time_per_run"] = {m.key: float(np.mean([r.seconds[m.key] for r in records])) for m in main + sweep}
    body["claims"] = claims(params, body, len(records))
    return body


# ---- claims -------------------------------------------------------------------------------------
def _at_least(better: float, worse: float, se: float) -> bool | None:
    """Held when better ≥ worse, NOT held when it falls short by more than SIGNIFICANCE_SE s.e.,
    undecided in between (and with a single run, whose s.e. is not a number)."""
    if better >= worse:
        return True
    return False if worse - better > SIGNIFICANCE_SE * se else None


def _fmt_pd(pd: dict, se: dict, key: str) -> str:
    return f"{key} {pd[key]:.3f} ± {se[key]:.3f}"


def claims(params: Params, body: dict, n: int) -> list[ClaimRecord]:
    """The paper's claims checked on a summary body (``n`` runs)."""
    short = PAPERS[PAPER].short
    pf = TbdMethod("PFTBD", params.particles)
    same = TbdMethod("TPFTBD", params.particles) if params.particles in params.tpf_particles else None
    half_n = params.particles // 2
    half = TbdMethod("TPFTBD", half_n) if half_n in params.tpf_particles else None
    pd, se, times = body["pd_at_pfa"], body["pd_at_pfa_se"], body["time_per_run"]
    focus = params.focus_snr_db
    rule = (f"held when A ≥ B, NOT held when A falls short by more than {SIGNIFICANCE_SE:g} combined standard "
            "errors over runs, undecided in between")
    out = []

    def record(claim: str, source: str, verdict: Verdict, statistic: float | None, threshold: float,
               evidence: str, slug: str, caveats: tuple[str, ...] = (), timing: bool = False) -> ClaimRecord:
        return ClaimRecord(claim, f"{short}, {source}", verdict, statistic, threshold, n, evidence, caveats,
                           id=f"{NAME}/{slug}", paper=PAPER, paper_n=PAPER_RUNS, timing=timing)

    if same:
        gain = body["snr_gain"][same.key]
        evidence = ("the Pd-against-SNR curves share no Pd level, so no horizontal gap can be read"
                    if gain is None else
                    f"mean horizontal gap {gain['mean_gain_db']:.2f} dB over Pd ∈ [{gain['pd_levels'][0]:.2f}, "
                    f"{gain['pd_levels'][-1]:.2f}] (min {min(gain['gain_db']):.2f}, max {max(gain['gain_db']):.2f} dB; "
                    f"linear interpolation between the SNRs {', '.join(f'{s:g}' for s in params.snr)} dB)")
        out.append(record(
            f"At equal N = {params.particles}, TPFTBD gains at least {GAIN_DB:g} dB of SNR over PF-TBD "
            f"(Pd at Pfa = {params.pfa:g})", "§3.2, Fig. 4",
            verdict_of(None if gain is None else gain["mean_gain_db"] >= GAIN_DB),
            None if gain is None else gain["mean_gain_db"], GAIN_DB, evidence=evidence,
            caveats=("the gain is read off Monte Carlo Pd curves; no interval is attached to it",),
            slug="snr-gain-equal-n"))
        ratio = times[same.key] / times[pf.key]
        out.append(record(
            "At equal N, TPFTBD costs about 10–20 % more time than PF-TBD (at most 20 %)", "§3.2, Table 1",
            verdict_of(ratio <= TIME_RATIO_EQUAL_N), ratio, TIME_RATIO_EQUAL_N,
            evidence=f"time ratio {ratio:.2f} ({times[same.key]:.3f} s against {times[pf.key]:.3f} s CPU per sequence)",
            slug="time-equal-n", timing=True))
    if half:
        comb = float(np.hypot(se[half.key], se[pf.key]))
        out.append(record(
            f"TPFTBD with N = {half_n} detects at least as well as PF-TBD with N = {params.particles} "
            f"({focus:g} dB, Pfa = {params.pfa:g})", "§3.1, Fig. 1–3",
            verdict_of(_at_least(pd[half.key], pd[pf.key], comb)), pd[half.key] - pd[pf.key], 0.0,
            evidence=f"Pd {_fmt_pd(pd, se, half.key)} against {_fmt_pd(pd, se, pf.key)} ({rule}); position RMSE "
                     f"{body['rmse_mean'][half.key]:.3f} against {body['rmse_mean'][pf.key]:.3f} cells",
            slug="half-n-detects-as-well"))
        ratio = times[half.key] / times[pf.key]
        out.append(record(
            f"TPFTBD with N = {half_n} needs only 55–60 % of the time of PF-TBD with N = {params.particles} "
            f"(at most {100 * TIME_RATIO_HALF_N:.0f} %)", "§3.2, Table 1",
            verdict_of(ratio <= TIME_RATIO_HALF_N), ratio, TIME_RATIO_HALF_N,
            evidence=f"time ratio {ratio:.2f} ({times[half.key]:.3f} s against {times[pf.key]:.3f} s CPU per sequence)",
            slug="time-half-n", timing=True))
    sweep = body.get("zeta_sweep")
    if sweep:
        by_zeta = {z: TbdMethod("TPFTBD", params.zeta_sweep_particles, z).key for z in params.zeta_sweep}
        spd, sse, rmse = sweep["pd_at_pfa"], sweep["pd_at_pfa_se"], sweep["rmse_mean"]
        listing = "; ".join(f"ζ = {z:g}: Pd {spd[k]:.3f} ± {sse[k]:.3f}, RMSE {rmse[k]:.3f}"
                            for z, k in by_zeta.items())
        setting = f"N = {params.zeta_sweep_particles}, {params.focus_snr_db:g} dB"
        if BEST_ZETA in by_zeta:
            best = max(by_zeta.values(), key=lambda k: spd[k])
            six = by_zeta[BEST_ZETA]
            out.append(record(
                f"ζ ≈ {BEST_ZETA:g} is the best transfer parameter ({setting})", "§3.3, Fig. 5–6",
                verdict_of(_at_least(spd[six], spd[best], float(np.hypot(sse[six], sse[best])))),
                spd[six] - spd[best], 0.0, evidence=f"best Pd: {best}; {listing} ({rule})",
                slug="zeta-best"))
        if WORSE_ZETA in by_zeta and pf.key in spd:
            verdicts: list[Verdict] = []
            margins = []
            for z, key in by_zeta.items():
                comb = float(np.hypot(sse[key], sse[pf.key]))
                better, worse = (spd[key], spd[pf.key]) if z != WORSE_ZETA else (spd[pf.key], spd[key])
                verdicts.append(verdict_of(_at_least(better, worse, comb)))
                margins.append(better - worse)
            out.append(record(
                f"Only ζ = {WORSE_ZETA:g} is worse than PF-TBD with N = {params.particles}; the other ζ "
                f"(including ζ = 1) beat it ({setting})", "§3.3, Fig. 5–6",
                combine(verdicts), float(min(margins)), 0.0,
                evidence=f"PF-TBD: Pd {spd[pf.key]:.3f} ± {sse[pf.key]:.3f}; {listing}; statistic: the smallest "
                         f"margin in the claimed direction ({rule})",
                slug="only-zeta-0.4-worse"))
    return out
