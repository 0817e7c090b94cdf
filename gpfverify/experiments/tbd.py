"""Seed 004: PF-TBD against the two-stage TPFTBD in Rutten's scenario — existence probability,
ROC, detection probability at a fixed false-alarm rate against SNR, position RMSE, the transfer
parameter ζ, and run time.

One run = for every SNR in --snr, one target-present and one target-absent image sequence, each
filtered by every method (methods with the same N share the PF random stream: common random
numbers); at --focus-snr also the ζ sweep. Detection: the filter declares a target in a frame when
its existence probability exceeds a threshold τ; the ROC sweeps τ, P_d is the share of
target-present frames (frames first … last of the target-present runs) above τ, P_fa the share of
all frames of the target-absent runs above τ.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from gpfverify.errors import InputError
from gpfverify.filters.tbd import TbdConfig, TbdModel, filter_sequence
from gpfverify.scenarios.tbd import SNR_CONVENTIONS, TbdScenario, scenario_model, simulate

NAME = "tbd"
DEFAULT_RUNS = 3000  # seed 004 §3: 3000 runs at each SNR
PAPER_SNRS = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]
ROC_POINTS = 201
GAIN_LEVELS = 21

INTERPRETATIONS = {
    "snr": "SNR = 10 log10(a^2 / sigma^2), a = I0 / (2 pi Sigma^2) the peak pixel of the blurred target "
           "('peak'); 'intensity' uses I0 in place of a. SNR is set through sigma (seed 004 §3).",
    "scenario": "target appears at [4.2, 0.45, 7.2, 0.25, 20] in frame 7 and follows the model's "
                "near-constant-velocity dynamics with process noise Q (Ristic et al. 2004, ch. 11)",
    "birth": "N_b = N_c = N/2; birth cells drawn with probability (1-eps)/n_bright on cells with "
             "z > birth_threshold*sigma plus eps/n^2 everywhere, position uniform in the cell, velocity "
             "uniform on +-velocity_max, intensity uniform on [I0/2, 3I0/2]; weights carry p_b/q_b",
    "likelihood": "point spread truncated to the (2p+1)^2 patch around the particle's nearest cell "
                  "(patch_radius p), so the patch likelihood ratio is the full-image one",
    "second_stage": "moments of the merged weighted set of step 4 (posterior weights) for s and for the "
                    "point-spread measurement of the (2r+1)^2 image patch around the PF estimate "
                    "(second_stage_radius r), noise sigma^2 I; applied in every frame",
    "estimate": "PF: weighted mean of the merged set; TPFTBD: zeta * PF estimate + (1-zeta) * "
                "second-stage mean (the expected mean of the transferred particles)",
    "detection": "a frame counts as a detection when P_k > tau (no position gate)",
    "rmse": "position RMSE over the target-present runs, frames where the target exists, whatever P_k",
    "time": "CPU seconds of the process (time.process_time) per 30-frame sequence, mean over the "
            "sequences of every SNR and case; robust to other load on the machine",
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--snr", type=float, nargs="+", default=PAPER_SNRS, metavar="DB",
                        help="SNR values in dB (default 1 … 9)")
    parser.add_argument("--focus-snr", type=float, default=None, metavar="DB",
                        help="SNR of the existence/RMSE/ROC curves and the ζ sweep "
                             "(default 6 if in --snr, else the median of --snr)")
    parser.add_argument("--snr-convention", choices=SNR_CONVENTIONS, default="peak")
    parser.add_argument("--particles", type=int, default=2000, help="PF-TBD particles N (default 2000)")
    parser.add_argument("--tpf-particles", type=int, nargs="+", default=[2000, 1000],
                        help="TPFTBD particle counts (default 2000 1000)")
    parser.add_argument("--zeta", type=float, default=0.6, help="ζ of the TPFTBD methods (default 0.6)")
    parser.add_argument("--zeta-sweep", type=float, nargs="*", default=[1.0, 0.9, 0.6, 0.4],
                        help="ζ values of the sweep at --focus-snr (default 1 0.9 0.6 0.4; none: no sweep)")
    parser.add_argument("--zeta-sweep-particles", type=int, default=1000)
    parser.add_argument("--pfa", type=float, default=0.05, help="false-alarm rate of the P_d-vs-SNR curve")
    parser.add_argument("--birth-threshold", type=float, default=1.0, help="bright cell: z > this · σ")
    parser.add_argument("--birth-uniform-share", type=float, default=0.1)
    parser.add_argument("--patch-radius", type=int, default=2, help="likelihood patch (2p+1)²")
    parser.add_argument("--second-stage-radius", type=int, default=2, help="second-stage patch (2r+1)²")


def params_from_args(args: argparse.Namespace) -> dict:
    snrs = [float(s) for s in args.snr]
    if len(set(snrs)) != len(snrs):
        raise InputError(f"--snr has repeated values: {snrs}")
    focus = args.focus_snr
    if focus is None:
        focus = 6.0 if 6.0 in snrs else float(np.median(snrs))
    if float(focus) not in snrs:
        raise InputError(f"--focus-snr {focus} must be one of --snr {snrs}")
    if not 0.0 < args.pfa < 1.0:
        raise InputError(f"--pfa must lie in (0, 1), got {args.pfa}")
    model, scenario = TbdModel(patch_radius=args.patch_radius), TbdScenario()
    params = {
        "snr_db": snrs, "focus_snr_db": float(focus), "snr_convention": args.snr_convention,
        "pf_particles": args.particles, "tpf_particles": list(args.tpf_particles), "zeta": args.zeta,
        "zeta_sweep": list(args.zeta_sweep), "zeta_sweep_particles": args.zeta_sweep_particles,
        "pfa": args.pfa, "birth_threshold": args.birth_threshold,
        "birth_uniform_share": args.birth_uniform_share, "second_stage_radius": args.second_stage_radius,
        "model": {"grid_size": model.grid_size, "cell_size": model.cell_size, "blur": model.blur,
                  "q1": model.q1, "q2": model.q2, "period": model.period, "p_birth": model.p_birth,
                  "p_death": model.p_death, "patch_radius": model.patch_radius,
                  "velocity_max": model.velocity_max},
        "scenario": {"frames": scenario.frames, "first_frame": scenario.first_frame,
                     "last_frame": scenario.last_frame, "initial_state": list(scenario.initial_state)},
        "interpretations": INTERPRETATIONS,
    }
    _methods(params)  # validates particle counts and ζ
    return params


def default_params(argv=()) -> dict:
    """The parameters of ``gpfverify reproduce tbd`` with these extra command-line options."""
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    return params_from_args(parser.parse_args(list(argv)))


# ---- methods ------------------------------------------------------------------------------------
def _config(params: dict, n: int, two_stage: bool, zeta: float) -> TbdConfig:
    return TbdConfig(n, params["birth_threshold"], params["birth_uniform_share"], two_stage, zeta,
                     params["second_stage_radius"])


def _methods(params: dict) -> tuple[dict, dict]:
    """(main, sweep): label -> TbdConfig. Main methods run at every SNR, the sweep at the focus SNR."""
    main = {f"PFTBD-N{params['pf_particles']}": _config(params, params["pf_particles"], False, 1.0)}
    for n in params["tpf_particles"]:
        main[f"TPFTBD-N{n}"] = _config(params, n, True, params["zeta"])
    sweep = {}
    if params["zeta_sweep"]:
        sweep[f"PFTBD-N{params['pf_particles']}"] = main[f"PFTBD-N{params['pf_particles']}"]
        n = params["zeta_sweep_particles"]
        for zeta in params["zeta_sweep"]:
            sweep[f"TPFTBD-N{n}-{zeta:g}"] = _config(params, n, True, zeta)
    return main, sweep


def _stream(seed: np.random.SeedSequence, *key: int) -> np.random.Generator:
    """A generator for a fixed sub-key of this run's seed (independent of spawn order)."""
    return np.random.default_rng(np.random.SeedSequence(seed.entropy, spawn_key=(*seed.spawn_key, *key)))


def _scenario(params: dict) -> TbdScenario:
    s = params["scenario"]
    return TbdScenario(s["frames"], s["first_frame"], s["last_frame"], tuple(s["initial_state"]))


def _model(params: dict, snr_db: float) -> tuple[TbdModel, TbdScenario]:
    m, scenario = params["model"], _scenario(params)
    base = TbdModel(m["grid_size"], m["cell_size"], m["blur"], 1.0, m["q1"], m["q2"], m["period"],
                    m["p_birth"], m["p_death"], m["patch_radius"], m["velocity_max"])
    return scenario_model(snr_db, scenario, params["snr_convention"], base), scenario


def run_one(params: dict, seed: np.random.SeedSequence) -> dict:
    main, sweep = _methods(params)
    cases, seconds = [], {}  # seconds: config -> seconds per sequence
    for s_index, snr in enumerate(params["snr_db"]):
        model, scenario = _model(params, snr)
        scene_rng = _stream(seed, s_index, 0)
        sequences = {"present": simulate(model, scenario, scene_rng, True),
                     "absent": simulate(model, scenario, scene_rng, False)}
        labels = dict(main)
        if snr == params["focus_snr_db"]:
            labels.update(sweep)
        done: dict[TbdConfig, dict] = {}
        out = {}
        for label, config in labels.items():
            if config not in done:
                record = {}
                for c_index, (case, seq) in enumerate(sequences.items()):
                    pf_rng = _stream(seed, s_index, 1, c_index, config.n_particles, 0)
                    second_rng = _stream(seed, s_index, 1, c_index, config.n_particles, 1)
                    start = time.process_time()
                    track = filter_sequence(seq.images, model, config, pf_rng, second_rng)
                    seconds.setdefault(config, []).append(time.process_time() - start)
                    record[case] = track.existence.tolist()
                    if case == "present":
                        err = track.estimates[seq.present][:, [0, 2]] - seq.truth[seq.present][:, [0, 2]]
                        record["sq_error"] = np.sum(err**2, axis=1).tolist()
                done[config] = record
            out[label] = done[config]
        cases.append({"snr_db": snr, "methods": out})
    return {"cases": cases,
            "seconds": {label: float(np.mean(seconds[config])) for label, config in {**main, **sweep}.items()}}


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


def _stack(results: list[dict], s_index: int, label: str, key: str) -> np.ndarray:
    return np.array([r["cases"][s_index]["methods"][label][key] for r in results], dtype=float)


def _curves(params: dict, results: list[dict], s_index: int, labels) -> dict:
    present_mask = _scenario(params).present
    out = {"existence_prob": {}, "existence_prob_absent": {}, "rmse": {}, "roc": {},
           "pd_at_pfa": {}, "pd_at_pfa_se": {}, "rmse_mean": {}}
    for label in labels:
        present = _stack(results, s_index, label, "present")
        absent = _stack(results, s_index, label, "absent")
        sq = _stack(results, s_index, label, "sq_error")
        rmse = np.full(present_mask.size, None, dtype=object)
        rmse[present_mask] = np.sqrt(sq.mean(axis=0))
        pd, se, _ = pd_at_pfa(present[:, present_mask], absent, params["pfa"])
        out["existence_prob"][label] = present.mean(axis=0).tolist()
        out["existence_prob_absent"][label] = absent.mean(axis=0).tolist()
        out["rmse"][label] = [None if v is None else float(v) for v in rmse]
        out["roc"][label] = roc_curve(present[:, present_mask], absent)
        out["pd_at_pfa"][label] = pd
        out["pd_at_pfa_se"][label] = se
        out["rmse_mean"][label] = float(np.sqrt(sq.mean()))
    return out


def summarize(params: dict, results: list[dict]) -> dict:
    main, sweep = _methods(params)
    focus = params["snr_db"].index(params["focus_snr_db"])
    body = _curves(params, results, focus, main)
    by_snr = {label: [] for label in main}
    by_snr_se = {label: [] for label in main}
    for s_index in range(len(params["snr_db"])):
        curves = _curves(params, results, s_index, main)
        for label in main:
            by_snr[label].append(curves["pd_at_pfa"][label])
            by_snr_se[label].append(curves["pd_at_pfa_se"][label])
    body.update({"snr_db": params["snr_db"], "focus_snr_db": params["focus_snr_db"],
                 "target_frames": int(_scenario(params).present.sum()),
                 "pd_vs_snr": by_snr, "pd_vs_snr_se": by_snr_se})
    if sweep:
        body["zeta_sweep"] = {"zeta": params["zeta_sweep"], "n_particles": params["zeta_sweep_particles"],
                              "snr_db": params["focus_snr_db"], "methods": list(sweep),
                              **_curves(params, results, focus, sweep)}
    body["time_per_run"] = {label: float(np.mean([r["seconds"][label] for r in results]))
                            for label in {**main, **sweep}}
    return body
