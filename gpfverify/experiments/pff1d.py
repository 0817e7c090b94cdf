"""Seed 003 §3.1: bootstrap PF, UPF, Daum–Huang EDH flow and the innovation-error flow (IE-PFF) on
1-D nonlinear models — the (Q, R, Δλ) grid of Table 1 on the UNGM and the Γ(3, 2) process-noise
case of Fig. 2 on the van der Merwe et al. (2000) benchmark (models in
:mod:`gpfverify.scenarios.growth`). N = 50 particles, T = 50 steps, 30 runs.

Each run draws one trajectory per (model, Q, R) and filters it with every method; the flows run
once per (Δλ, spacing): ``uniform`` is the seed's Euler scheme, ``exponential`` the same number of
geometrically growing steps (ratio 1.2). The truth and every filter start from the same prior.
A filter that breaks down is counted as diverged and left out of its RMSE (the count is reported).
"""

from __future__ import annotations

import argparse

import numpy as np

from gpfverify.experiments.particle_methods import child_rng, flow_steps, run_method
from gpfverify.scenarios.growth import GAMMA_PRIOR, UNGM_PRIOR, gamma_benchmark_model, ungm_model

NAME = "pff1d"
DEFAULT_RUNS = 30
#: methods of Table 1 (Gaussian UNGM) and of Fig. 2 (gamma noise)
TABLE_METHODS = ("PF", "EDH", "IE-PFF")
GAMMA_METHODS = ("PF", "UPF", "EDH", "IE-PFF")
FLOWS = ("EDH", "IE-PFF")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--particles", type=int, default=50, help="particles per filter (default 50)")
    parser.add_argument("--steps", type=int, default=50, help="time steps T (default 50)")
    parser.add_argument("--table-q", type=float, nargs="+", default=[0.1, 1.0, 10.0],
                        help="UNGM process-noise variances Q of the Table-1 grid")
    parser.add_argument("--table-r", type=float, nargs="+", default=[0.1, 1.0],
                        help="UNGM measurement-noise variances R of the Table-1 grid")
    parser.add_argument("--dlambda", type=float, nargs="+", default=[0.1, 0.01, 0.001],
                        help="pseudo-time steps Δλ of the flows (Table-1 grid)")
    parser.add_argument("--spacings", nargs="+", choices=["uniform", "exponential"],
                        default=["uniform", "exponential"], help="λ-step schedules of the flows")
    parser.add_argument("--gamma-r", type=float, nargs="+", default=[0.01, 0.1, 1.0],
                        help="measurement-noise variances R of the gamma case (Fig. 2)")
    parser.add_argument("--gamma-main-r", type=float, default=0.1,
                        help="R of the gamma case reported under the 'rmse' key")
    parser.add_argument("--gamma-dlambda", type=float, default=0.01, help="Δλ of the gamma case")


def params_from_args(args: argparse.Namespace) -> dict:
    from gpfverify.errors import InputError

    if args.gamma_main_r not in args.gamma_r:
        raise InputError(f"--gamma-main-r {args.gamma_main_r} must be one of --gamma-r {args.gamma_r}")
    if args.particles < 2 or args.steps < 1:
        raise InputError("--particles must be at least 2 and --steps at least 1")
    return {"particles": args.particles, "steps": args.steps, "table_q": args.table_q,
            "table_r": args.table_r, "dlambda": args.dlambda, "spacings": args.spacings,
            "gamma_r": args.gamma_r, "gamma_main_r": args.gamma_main_r,
            "gamma_dlambda": args.gamma_dlambda, "gamma_shape": 3.0, "gamma_rate": 2.0,
            "ungm_prior": dict(zip(("mean", "var"), UNGM_PRIOR)),
            "gamma_prior": dict(zip(("mean", "var"), GAMMA_PRIOR))}


def _cases(params: dict):
    """(case, Q, R, model, methods, Δλ list) in a fixed order; the truth's x_0 and every filter's
    initial particles come from the model's prior (interpretation, see report)."""
    for q in params["table_q"]:
        for r in params["table_r"]:
            yield "ungm", q, r, ungm_model(q, r), TABLE_METHODS, params["dlambda"]
    for r in params["gamma_r"]:
        model = gamma_benchmark_model(r, params["gamma_shape"], params["gamma_rate"])
        yield "gamma", float(model.Q[0, 0]), r, model, GAMMA_METHODS, [params["gamma_dlambda"]]


def run_one(params: dict, seed_seq: np.random.SeedSequence) -> dict:
    records = []
    for c, (case, q, r, model, methods, dlambdas) in enumerate(_cases(params)):
        data_rng = child_rng(seed_seq, c, 0)
        x0 = data_rng.multivariate_normal(model.prior_mean, model.prior_cov)
        xs, ys = model.simulate(params["steps"], data_rng, x0=x0)
        variants = [(m, None, None) for m in methods if m not in FLOWS]
        variants += [(m, d, s) for m in methods if m in FLOWS for d in dlambdas for s in params["spacings"]]
        for v, (method, dlam, spacing) in enumerate(variants):
            steps = flow_steps(dlam, spacing) if dlam is not None else None
            out = run_method(method, model, ys, params["particles"], child_rng(seed_seq, c, 1 + v), steps)
            sq = None if out.estimates is None else ((out.estimates - xs)[:, 0] ** 2).tolist()
            records.append({"case": case, "Q": q, "R": r, "method": method, "dlambda": dlam,
                            "spacing": spacing, "sq_err": sq, "seconds": out.seconds})
    return {"records": records}


def _key(rec: dict) -> tuple:
    return rec["case"], rec["Q"], rec["R"], rec["method"], rec["dlambda"], rec["spacing"]


def _aggregate(results: list[dict], steps: int) -> dict:
    """key -> {"rmse": [T] over the runs that did not diverge, "diverged": int, "seconds": mean,
    "run_rmse": per run √(mean_t err²), None where the filter diverged}."""
    groups: dict[tuple, dict] = {}
    for res in results:
        for rec in res["records"]:
            g = groups.setdefault(_key(rec), {"sq": [], "seconds": [], "run_rmse": []})
            g["seconds"].append(rec["seconds"])
            if rec["sq_err"] is None:
                g["run_rmse"].append(None)
            else:
                g["sq"].append(rec["sq_err"])
                g["run_rmse"].append(float(np.sqrt(np.mean(rec["sq_err"]))))
    out = {}
    for key, g in groups.items():
        rmse = np.sqrt(np.mean(g["sq"], axis=0)) if g["sq"] else np.full(steps, np.nan)
        out[key] = {"rmse": rmse.tolist(), "diverged": g["run_rmse"].count(None),
                    "seconds": float(np.mean(g["seconds"])), "run_rmse": g["run_rmse"]}
    return out


def variant_label(method: str, dlam, spacing) -> str:
    """"PF", or "IE-PFF Δλ=0.01 uniform" for a flow."""
    return method if dlam is None else f"{method} Δλ={dlam:g} {spacing}"


def summarize(params: dict, results: list[dict]) -> dict:
    agg = _aggregate(results, params["steps"])
    runs = len(results)
    table = []
    for (case, q, r, method, dlam, spacing), g in agg.items():
        if case != "ungm":
            continue
        rm = np.asarray(g["rmse"])
        table.append({"Q": q, "R": r, "method": method, "dlambda": dlam, "spacing": spacing,
                      "mean_rmse": float(np.mean(rm)), "diverged": g["diverged"], "runs": runs,
                      "time_per_run": g["seconds"], "rmse": g["rmse"], "run_rmse": g["run_rmse"]})
    gamma = {}
    for (case, q, r, method, dlam, spacing), g in agg.items():
        if case == "gamma":
            gamma.setdefault(f"{r:g}", {})[variant_label(method, dlam, spacing)] = {
                "method": method, "dlambda": dlam, "spacing": spacing, "rmse": g["rmse"],
                "mean_rmse": float(np.mean(g["rmse"])), "diverged": g["diverged"],
                "time_per_run": g["seconds"], "run_rmse": g["run_rmse"]}
    main_r, main_spacing = params["gamma_main_r"], params["spacings"][0]
    main = {}
    for (case, q, r, method, dlam, spacing), g in agg.items():
        if case == "gamma" and r == main_r and spacing in (None, main_spacing):
            main[method] = g
    return {
        "rmse": {m: main[m]["rmse"] for m in GAMMA_METHODS},
        "time_per_run": {m: main[m]["seconds"] for m in GAMMA_METHODS},
        "diverged": {m: main[m]["diverged"] for m in GAMMA_METHODS},
        "main_case": {"model": "gamma", "R": main_r, "dlambda": params["gamma_dlambda"],
                      "spacing": main_spacing},
        "table1": table,
        "gamma": gamma,
    }
