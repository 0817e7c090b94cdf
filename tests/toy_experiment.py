"""A tiny experiment for runner tests: each run draws numbers from its own stream."""

import numpy as np

NAME = "toy"
DEFAULT_RUNS = 4


def add_arguments(parser):
    parser.add_argument("--scale", type=float, default=1.0)
    parser.add_argument("--fail-run", type=int, default=-1)
    parser.add_argument("--interrupt-run", type=int, default=-1)


def params_from_args(args):
    return {"scale": args.scale, "fail_run": args.fail_run, "interrupt_run": args.interrupt_run}


def run_one(params, seed):
    if seed.spawn_key[-1] == params["fail_run"]:
        raise RuntimeError("planned failure")
    if seed.spawn_key[-1] == params.get("interrupt_run", -1):
        raise KeyboardInterrupt  # as if the user pressed Ctrl-C during this run
    rng = np.random.default_rng(seed)
    return {"x": (params["scale"] * rng.standard_normal(3)).tolist()}


def summarize(params, results):
    x = np.array([r["x"] for r in results])
    return {"mean": x.mean(axis=0).tolist(), "time_per_run": {"toy": 0.0}}
