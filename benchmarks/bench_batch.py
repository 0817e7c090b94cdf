"""Monte Carlo runs advanced together as arrays, against the same runs one at a time, and the cost of
every fusion rule and the audit along the state dimension.

Runs axis. For ct2d (κ = 300 and κ = 30), ungm1d and ``check`` on examples/three_sensor_system.py
(UKF, 40 steps; ``--experiments`` names some of them), the experiment's ``run_one`` over R runs
and its ``run_batch`` of the same R runs in one call, in one process, alternated over ``--rounds``
rounds; each side timed by process CPU time with BLAS on one thread, and its runs per CPU-second
reported (the median over rounds). Before
timing, the batch's records are checked to be those of the runs batched one by one (run_batch of
one, bit for bit outside the timing fields). Each side also reports the part of its time spent in
GP learning (per run in both: each run's L-BFGS keeps its own path) and the floor: the CPU time
inside the calls that do the arithmetic — LAPACK and BLAS through numpy and scipy, the compiled
moment kernels (the n² expm1 sums), numpy's exp and expm1, Clarabel's solves and the evidence's
factorisations — counted by wrapping those functions (outermost calls only) in a batched pass of
its own: how far the batched path is from the arithmetic's own cost. Matrix products written with
``@`` and einsum cannot be wrapped and are not in the floor (so the floor is low, and the distance
from it an upper bound); each wrapped call's own timer reads are in it.

State dimension. A linear system with D states and three sensors of D/2 outputs each (random
orthogonal-times-0.95 transition, random H), :func:`~gpfverify.model_fusion.run_fusion`
with the Kalman family and every rule, a few steps: the median CPU time per step of each rule and of
the per-step audit (:func:`~gpfverify.audit.audit_case`), D = 8 … 512 (RCC-CI by its Newton route
over the weights up to ``--rcc-max``, and by its conic route — a semidefinite program whose
interior-point cost grows like D⁶ — up to ``--rcc-conic-max``). Goals: no rule above
twice CMF + DMF at any D, and the cost growing no faster than D³ from D = 64 (the exponent per
doubling, log₂ of the ratio).

    .venv/bin/python benchmarks/bench_batch.py --out benchmarks/results/batch.md
"""

from __future__ import annotations

import os

# one BLAS thread in every BLAS library, numpy's and scipy's (scipy's OpenBLAS is loaded only when
# gpfverify first imports scipy.linalg, after any threadpoolctl limit set here: a limit alone left it
# at its default thread count, and the rules timed outside gpfverify's one-thread entry points ran
# their LAPACK calls on two threads, the second spinning — milliseconds of CPU at D = 64); as the
# command line sets them (gpfverify.runtime.default_single_blas_thread)
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "VECLIB_MAXIMUM_THREADS",
             "NUMEXPR_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import contextlib  # noqa: E402
import functools  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy.linalg  # noqa: E402,F401  (its BLAS loaded before the limit below)
from threadpoolctl import threadpool_info, threadpool_limits  # noqa: E402

from _timing import markdown_table  # noqa: E402


def blas_threads() -> str:
    """Every loaded BLAS library and its thread count (threadpoolctl)."""
    return ", ".join(f"{os.path.basename(i['filepath'])} {i['num_threads']}" for i in threadpool_info()
                     if i.get("user_api") == "blas")



def load() -> str:
    try:
        return ", ".join(f"{v:.2f}" for v in os.getloadavg())
    except OSError:
        return "unknown"


# -- the floor: time inside the arithmetic's own calls ---------------------------------------------

def _arithmetic_calls():
    """(owner, attribute) of the functions whose time is the floor."""
    import clarabel
    import scipy.linalg as sla

    from gpfverify import linalg
    from gpfverify.gp import fused_kernels

    calls = [(np.linalg, name) for name in ("cholesky", "solve", "svd", "eigh", "eigvalsh", "pinv", "inv", "cond",
                                            "lstsq", "det", "slogdet", "qr")]
    calls += [(sla.lapack, name) for name in ("dpotrf", "dpotrs", "dpotri", "dgesv", "dgejsv")]
    calls += [(sla.blas, name) for name in ("dtrsv", "dtrsm", "ddot")]
    calls += [(linalg, name) for name in ("_ddot", "_dgejsv")]  # bound when gpfverify.linalg is imported
    calls += [(np, name) for name in ("exp", "expm1")]
    calls += [(fused_kernels, name) for name in ("first_moments", "prepare", "centred_sums")]
    calls += [(clarabel, "DefaultSolver")]  # a Rust class: its construction and its solve, through a wrapper
    return calls


class Floor:
    """Accumulates the process CPU time spent inside :func:`_arithmetic_calls` (outermost only)."""

    def __init__(self):
        self.seconds = 0.0
        self.depth = 0

    @contextlib.contextmanager
    def counting(self):
        saved = []
        for owner, name in _arithmetic_calls():
            original = getattr(owner, name)
            saved.append((owner, name, original))
            setattr(owner, name, self._wrapped(original))
        try:
            yield self
        finally:
            for owner, name, original in saved:
                setattr(owner, name, original)

    def _wrapped(self, fn):
        if isinstance(fn, type):  # Clarabel's solver: time its construction and its solve
            floor, make = self, self._timed(fn)

            class Timed:
                def __init__(self, *args, **kwargs):
                    self.solver = make(*args, **kwargs)

                def solve(self):
                    return floor._timed(self.solver.solve)()
            return Timed
        return self._timed(fn)

    def _timed(self, fn):
        @functools.wraps(fn)
        def timed(*args, **kwargs):
            if self.depth:
                return fn(*args, **kwargs)
            self.depth += 1
            start = time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                self.seconds += time.process_time() - start
                self.depth -= 1
        return timed


# -- the runs axis ----------------------------------------------------------------------------------

def _training(records) -> float:
    """CPU seconds of GP learning the records report (ct2d, ungm1d), summed."""
    from gpfverify.contract.serial import to_json

    total = 0.0
    for r in records:
        body = to_json(r)
        settings = body.get("settings", {"": body}).values()
        total += sum(s.get("training_seconds", 0.0) for s in settings)
    return total


def experiments(runs: int):
    from gpfverify.experiments import check
    from gpfverify.papers.fusion import ct2d_experiment as ct2d
    from gpfverify.papers.fusion import ungm1d_experiment as ungm1d

    tracker = check.params_for("examples/three_sensor_system.py:tracker", filter="ukf", steps=40)
    return {"ct2d300": ("ct2d, κ = 300, Ω = 2π/90 (50 steps, 12 methods)", ct2d, ct2d.Params(), runs, 10),
            "ct2d30": ("ct2d, κ = 30, Ω = 2π/90", ct2d, ct2d.Params(kappa=30), runs, 10),
            "ungm1d": ("ungm1d (4 σ², 50 steps, 12 methods each)", ungm1d, ungm1d.Params(), runs, 3),
            "check": ("check three_sensor_system.py, UKF, 40 steps", check, tracker, 4 * runs, 10)}


#: the keys of :func:`experiments`, in the order the runs axis times them (``--experiments``)
EXPERIMENTS = ("ct2d300", "ct2d30", "ungm1d", "check")


def runs_axis(rounds: int, runs: int, chosen: tuple[str, ...] = EXPERIMENTS) -> list[list]:
    from gpfverify.contract.serial import to_json
    from gpfverify.experiments.runner import untimed

    rows = []
    table = experiments(runs)
    for label, module, params, count, goal in (table[key] for key in chosen):
        seeds = [np.random.SeedSequence(2024, spawn_key=(i,)) for i in range(count)]
        module.run_batch(params, seeds[:2])  # compile and import outside the timing
        batched = [untimed(to_json(r)) for r in module.run_batch(params, seeds[:3])]
        assert batched == [untimed(to_json(module.run_batch(params, [s])[0])) for s in seeds[:3]], label
        per_run, per_batch, floors, train_one, train_batch = [], [], [], [], []
        for _ in range(rounds):
            start = time.process_time()
            records = [module.run_one(params, s) for s in seeds]
            per_run.append(time.process_time() - start)
            train_one.append(_training(records))
            start = time.process_time()
            records = module.run_batch(params, seeds)
            per_batch.append(time.process_time() - start)
            train_batch.append(_training(records))
            floor = Floor()  # a pass of its own: the wrappers' overhead stays out of the batched time
            with floor.counting():
                module.run_batch(params, seeds)
            floors.append(floor.seconds)
        one, batch, floor_s = np.median(per_run), np.median(per_batch), np.median(floors)
        ratio = one / batch
        rows.append([label, count, f"{count / one:.2f}", f"{count / batch:.2f}", f"{ratio:.1f}×", f"≥ {goal}×",
                     f"{np.median(train_one) / one:.0%} / {np.median(train_batch) / batch:.0%}",
                     f"{count / floor_s:.1f}", f"{batch / floor_s:.1f}×"])
        print(" | ".join(str(c) for c in rows[-1]), flush=True)
    return rows


# -- the state dimension ----------------------------------------------------------------------------

def system(d: int, rng: np.random.Generator):
    from gpfverify.models import linear_model

    F = 0.95 * np.linalg.qr(rng.normal(size=(d, d)))[0]
    H = rng.normal(size=(3 * d // 2, d)) / np.sqrt(d)
    return linear_model(F, H, 0.1 * np.eye(d), 0.5 * np.eye(3 * d // 2), sizes=(d // 2,) * 3)


RULES = ("cmf", "dmf", "cc", "ci", "ei", "ici", "rcc-ci", "rcc-conic", "audit")


def _steal() -> int:
    """The machine's stolen CPU ticks so far (/proc/stat), -1 where unknown."""
    try:
        with open("/proc/stat", encoding="ascii") as f:
            return int(f.readline().split()[8])
    except (OSError, IndexError, ValueError):
        return -1


def state_axis(dims: list[int], steps: int, rcc_max: int, rounds: int, cap: float, conic_max: int = 32
               ) -> tuple[list[list], dict, dict, list[str]]:
    """Per D: every rule's one step, timed by process CPU time in interleaved rounds (each round calls
    every rule once, so a burst of load on the machine falls on all of them alike); the best of the
    rounds (the least disturbed call) and their median. A rule whose first call at some D takes more
    than ``cap`` seconds is not timed at larger D (said in the notes). RCC-CI is timed by its Newton
    route (``rcc-ci``, up to ``rcc_max``) and by its conic route (``rcc-conic``, Clarabel on the
    semidefinite program, up to ``conic_max``), as run_fusion calls it (c = χ²_D(0.99), enlarged
    when the ellipsoids miss)."""
    from gpfverify.audit.case import audit_case
    from gpfverify.fusion.rcc_ci import rcc_ci
    from gpfverify.model_fusion import _baselines, cmf_step, dmf_step, run_fusion

    rows, best, median, notes, capped = [], {}, {}, [], set()
    for d in dims:
        load_before, steal_before = load(), _steal()
        rng = np.random.default_rng(d)
        model = system(d, rng)
        _, ys = model.simulate(steps + 1, rng)
        methods = ("cmf", "dmf", "cc", "ci", "ei", "ici")
        fused = run_fusion(model, ys, family="kf", methods=methods, audit=False)
        before, step, y = fused.steps[-2], fused.steps[-1], ys[-1]  # the last step, from the one before
        beliefs = [r.posterior for r in step.local]
        timers = {"cmf": functools.partial(cmf_step, before.estimate("cmf"), model, y, k=step.k, family="kf"),
                  "dmf": functools.partial(dmf_step, before.estimate("dmf"), model, y, local_records=step.local,
                                           k=step.k, family="kf"),
                  # the audit as run_fusion(..., audit=True) runs it: reusing the step's eq. 35
                  "audit": functools.partial(audit_case, step.dmf.case, rank_rule=step.dmf.result.rank_rule,
                                             dmf=step.dmf.result)}
        for name, rule in _baselines(methods + ("rcc-ci",), None, (), "trace").items():
            if name == "rcc-ci":  # the conic route, the default of the rule run_fusion calls
                if d <= conic_max:
                    timers["rcc-conic"] = functools.partial(rule, beliefs)
                continue
            timers[name] = functools.partial(rule, beliefs)
        if d <= rcc_max:
            timers["rcc-ci"] = functools.partial(rcc_ci, beliefs, on_empty="enlarge", route="newton")
        times: dict[str, list[float]] = {}
        for name in list(timers):  # warm-up, and the cap
            if name in capped:
                del timers[name]
                continue
            start = time.process_time()
            timers[name]()
            first = time.process_time() - start
            if first > cap:
                capped.add(name)
                notes.append(f"{name} took {first:.1f} CPU-s at D = {d} (one call): not timed at larger D")
        repeats = 4 * rounds if d <= 32 else rounds if d <= 128 else max(3, rounds // 3)
        for _ in range(repeats):
            for name, fn in timers.items():
                if name in ("rcc-ci", "rcc-conic") and len(times.get(name, ())) >= 3:
                    continue
                start = time.process_time()
                fn()
                times.setdefault(name, []).append(time.process_time() - start)
        best[d] = {name: min(t) for name, t in times.items()}
        median[d] = {name: float(np.median(t)) for name, t in times.items()}
        base = best[d]["cmf"] + best[d]["dmf"]
        worst = max((m for m in best[d] if m not in ("cmf", "dmf", "rcc-conic")), key=lambda m: best[d][m])
        steal = _steal()
        rows.append([d, *(f"{best[d][m] * 1e3:.2f}" if m in best[d] else "–" for m in RULES),
                     f"{worst} {best[d][worst] / base:.2f}", repeats,
                     f"{load_before} / {load()}"
                     + (f"; stolen {(steal - steal_before) / os.sysconf('SC_CLK_TCK'):.1f} s" if steal >= 0 else "")])
        print(" | ".join(str(c) for c in rows[-1]), flush=True)
    return rows, best, median, notes


#: a measured doubling ratio up to this much above 8 (the arithmetic's D³) is counted as timing noise
GROWTH_TOLERANCE = 1.25


def growth(per_method: dict, start: int = 64) -> list[list]:
    """The ratio t(2D)/t(D) per doubling of D of each rule from D = ``start`` on, and its exponent."""
    dims = [d for d in sorted(per_method) if d >= start]
    rows = []
    for m in RULES:
        steps = [per_method[b][m] / per_method[a][m] for a, b in zip(dims, dims[1:])
                 if m in per_method[a] and m in per_method[b]]
        if steps:
            rows.append([m, *(f"{s:.1f} ({np.log2(s):.2f})" for s in steps),
                         f"{max(steps):.1f}", "met" if max(steps) <= 8.0 * GROWTH_TOLERANCE else "missed"])
    return [["rule", *(f"{a}→{b}" for a, b in zip(dims, dims[1:])), "largest", "goal"]] + rows


def verdicts(best: dict) -> list[str]:
    """The goals, rule by rule, from the best-of times."""
    lines = []
    for m in RULES:
        if m in ("cmf", "dmf"):
            continue
        over = [(d, best[d][m] / (best[d]["cmf"] + best[d]["dmf"])) for d in sorted(best) if m in best[d]]
        if not over:
            continue
        missed = [f"D = {d} ({r:.2f})" for d, r in over if r > 2.0]
        worst = max(over, key=lambda x: x[1])
        met = f"met at every D measured (largest {worst[1]:.2f} at D = {worst[0]})"
        lines.append(f"- {m}: ≤ 2 × (CMF + DMF) " + (f"missed at {', '.join(missed)}" if missed else met))
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--runs", type=int, default=16, help="runs per experiment (check: four times as many)")
    parser.add_argument("--dims", default="8,16,32,64,128,256,512")
    parser.add_argument("--steps", type=int, default=3, help="steps run before the one timed")
    parser.add_argument("--rcc-max", type=int, default=512, help="largest D at which RCC-CI's Newton route is timed")
    parser.add_argument("--rcc-conic-max", type=int, default=32,
                        help="largest D at which RCC-CI's conic route (Clarabel) is timed")
    parser.add_argument("--dim-rounds", type=int, default=15,
                        help="interleaved rounds per D (four times as many up to D = 32, a third from D = 256)")
    parser.add_argument("--cap", type=float, default=20.0, help="CPU-s of one call above which a rule stops")
    parser.add_argument("--only", choices=("runs", "dims"), default=None)
    parser.add_argument("--experiments", default=",".join(EXPERIMENTS),
                        help=f"the runs axis's experiments, comma-separated, of {', '.join(EXPERIMENTS)}")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    started = load()
    text = [f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python "
            f"{platform.python_version()}, numpy {np.__version__}; BLAS threads 1 (the thread variables "
            f"and threadpoolctl: {blas_threads()}); load average (1, 5, 15 min) at the start {started}"]
    if args.only != "dims":
        chosen = tuple(args.experiments.split(","))
        unknown = sorted(set(chosen) - set(EXPERIMENTS))
        if unknown:
            parser.error(f"--experiments: unknown {', '.join(unknown)} (known: {', '.join(EXPERIMENTS)})")
        rows = runs_axis(args.rounds, args.runs, chosen)
        text += ["", "Runs per CPU-second, one process, per-run (run_one in a loop) and batched (run_batch of all "
                 "the runs), median of the rounds; GP learning's share of each side's time; the floor: runs per "
                 "CPU-second if only the arithmetic's own calls (LAPACK/BLAS, the compiled moment kernels, "
                 "Clarabel) took time, and the batched path's time over it.", "",
                 markdown_table(["experiment", "runs", "per-run", "batched", "ratio", "goal",
                                 "GP learning (per-run / batched)", "floor", "batched / floor"], rows)]
    if args.only != "runs":
        dims = [int(d) for d in args.dims.split(",")]
        rows, best, median, notes = state_axis(dims, args.steps, args.rcc_max, args.dim_rounds, args.cap,
                                               args.rcc_conic_max)
        text += ["", f"CPU milliseconds of one step of each rule (Kalman family: CMF and DMF from the previous "
                 f"fused posterior, the baselines on the sensors' posteriors) and of the step's audit, on the last "
                 f"step of a short run: the best of the rounds (every rule called once per round, interleaved); "
                 f"RCC-CI by its Newton route up to D = {args.rcc_max} and by its conic route (Clarabel, the "
                 f"reference) up to D = {args.rcc_conic_max}. The column 'max / (CMF + DMF)': the costliest rule "
                 f"other than the conic RCC-CI against CMF + DMF (goal ≤ 2).", "",
                 markdown_table(["D", "CMF", "DMF", "CC", "CI", "EI", "ICI", "RCC-CI (Newton)", "RCC-CI (conic)",
                                 "audit", "max / (CMF + DMF)", "rounds", "load before / after"], rows),
                 "", "The median of the same rounds:", "",
                 markdown_table(["D", "CMF", "DMF", "CC", "CI", "EI", "ICI", "RCC-CI (Newton)", "RCC-CI (conic)",
                                 "audit"],
                                [[d, *(f"{median[d][m] * 1e3:.2f}" if m in median[d] else "–" for m in RULES)]
                                 for d in sorted(median)]),
                 "", f"Growth per doubling of D from the best-of times: t(2D)/t(D) (log₂ in brackets); goal ≤ 8, "
                 f"the arithmetic's D³, counted as met up to {8 * GROWTH_TOLERANCE:g} (timing noise):", "",
                 markdown_table(*(lambda t: (t[0], t[1:]))(growth(best))),
                 "", "Goal ≤ 2 × (CMF + DMF), from the best-of times:", "", *verdicts(best)]
        text += ["", *notes] if notes else []
    text += ["", f"load average at the end {load()}; BLAS threads at the end: {blas_threads()}"]
    out = "\n".join(text)
    print(out)
    if args.out:
        args.out.write_text(out + "\n", encoding="utf-8")


if __name__ == "__main__":
    with threadpool_limits(1):  # and the environment variables above, for any BLAS loaded later
        main()
