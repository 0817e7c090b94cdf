"""gpfverify at scale: long run files, model learning and filter steps through the Python API with
the machine idle and with a competing busy process, start-up, and the moment kernel against
numpy's exp. Every row is a ratio against a reference measured side by side, interleaved
(ours, reference, reference, ours, …), median over rounds.

    .venv/bin/python benchmarks/bench_scale.py [--quick] [--million] [--out benchmarks/results/scale.md]

Rows (each with its goal):

* ``audit RUN.jsonl``, 20 000 steps (D = 4, three 2-output sensors, ~91 MB): wall time of the
  command against Python's ``json`` parsing the same file line by line (goal ≤ 10 ×), and its
  peak resident memory at two run lengths (flat in the run length; ≤ 400 MB at 10⁶ steps, run
  with ``--million``, which writes a 10⁶-step file of about 4.6 GB to a temporary folder);
* ``audit RUN.npz``, same steps: steps per CPU-second (goal ≥ 5 000); and a run of the same
  layout where every second step has a sensor that lost rank (sensor 1's C_xy of rank 1): its
  rate against the full-rank run's, interleaved (goal ≥ 0.5), and its peak resident memory at two
  run lengths (flat); with ``--million`` that run audited at 10⁵ and 10⁶ steps (about 1.6 GB of
  npz, and the output, about 3 GB, spooled to a temporary file and discarded): peak memory at
  both lengths (independent of the length);
* ``learn_gp_model(model, 300, rng)`` (the README's tracker) against scikit-learn fitting the same
  GPs (same data, ARD squared-exponential plus noise, as many restarts), both with the default
  BLAS threads, idle and busy (goal ≤ 2 ×);
* UKF steps through the Python API with the default BLAS threads against a process pinned to one
  thread, idle and busy (goal ≤ 1.3 ×);
* ``check --json`` of a 2-step run against ``import numpy, scipy.linalg`` (goal ≤ 2 ×);
* ``predict_uncertain`` (n = 300, E = 4) against numpy's exp over E(E+1)/2·n² numbers (goal ≤ 1.5 ×).

Every measurement that depends on BLAS threads or start-up runs in a fresh process, so that the
thread variables of the process under test are exactly the ones named. "Busy" means one other
process spinning on a core for the whole measurement (the machine has two). Times are never
asserted anywhere.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
import zipfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
BLAS_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "VECLIB_MAXIMUM_THREADS",
             "NUMEXPR_NUM_THREADS")
GPFVERIFY = [sys.executable, "-m", "gpfverify"]


# -- processes ----------------------------------------------------------------------------------
def _env(pinned: bool) -> dict:
    """This process's environment with the BLAS thread variables removed (or set to 1: pinned) and
    bytecode caching on: an installed package has its .pyc files, as numpy and scipy on the other
    side of each ratio do (PYTHONDONTWRITEBYTECODE would make every gpfverify start-up compile its
    modules again, about 0.15 s)."""
    env = {k: v for k, v in os.environ.items() if k not in BLAS_VARS and k != "PYTHONDONTWRITEBYTECODE"}
    if pinned:
        env.update({k: "1" for k in BLAS_VARS})
    return env


def timed_process(argv, pinned: bool = True, stdout=subprocess.DEVNULL) -> dict:
    """Run ``argv`` to completion: wall seconds, CPU seconds and peak resident MB of that child
    (its own resource usage, from wait4: RUSAGE_CHILDREN's peak is the largest of every child so far)."""
    start = time.perf_counter()
    proc = subprocess.Popen(argv, env=_env(pinned), stdout=stdout, stderr=subprocess.DEVNULL, cwd=ROOT)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode:
        raise subprocess.CalledProcessError(proc.returncode, argv)
    return {"wall": wall, "cpu": usage.ru_utime + usage.ru_stime, "rss_mb": usage.ru_maxrss / 1024}


def child_numbers(what: str, *args: str, pinned: bool) -> list[float]:
    """The numbers printed by this script run as ``--child WHAT ARGS`` in a fresh process."""
    out = subprocess.run([sys.executable, __file__, "--child", what, *args], env=_env(pinned), check=True,
                         capture_output=True, text=True, cwd=ROOT).stdout
    return [float(word) for word in out.split()]


def child(what: str, *args: str, pinned: bool) -> float:
    """Seconds printed (last) by this script run as ``--child WHAT ARGS`` in a fresh process."""
    return child_numbers(what, *args, pinned=pinned)[-1]


@contextmanager
def busy(active: bool):
    """One other process spinning on a core while the block runs."""
    if not active:
        yield
        return
    spinner = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(0.5)
        yield
    finally:
        spinner.kill()
        spinner.wait()


def interleaved(ours, reference, rounds: int) -> tuple[float, float]:
    """Medians of ``ours()`` and ``reference()`` measured ours, reference, reference, ours, …"""
    a, b = [], []
    for r in range(rounds):
        if r % 2 == 0:
            a.append(ours())
            b.append(reference())
        else:
            b.append(reference())
            a.append(ours())
    return float(np.median(a)), float(np.median(b))


# -- run files ----------------------------------------------------------------------------------
def case_pool(count: int = 64):
    from gpfverify.fusion.synthetic import random_case

    rng = np.random.default_rng(0)
    return [random_case(rng, 4, (2, 2, 2)) for _ in range(count)]


def half_lost_pool(count: int = 64):
    """Steps of the same layout, every second one with sensor 1's C_xy of rank 1 (rank lost, DMF not
    exact there)."""
    from gpfverify.fusion.synthetic import random_case

    rng = np.random.default_rng(1)
    return [random_case(rng, 4, (2, 2, 2), ranks=(2, 1, 2) if k % 2 else None) for k in range(count)]


def write_jsonl(path: Path, steps: int, pool) -> Path:
    """``steps`` lines cycling through ``pool`` with k = 0, 1, …, written as a stream."""
    from gpfverify.fusion.case import case_to_dict

    lines = [json.dumps(case_to_dict(c))[1:] for c in pool]
    with open(path, "w") as fh:
        for k in range(steps):
            fh.write(f'{{"k": {k}, ' + lines[k % len(lines)] + "\n")
    return path


def write_npz(path: Path, steps: int, pool) -> Path:
    """The npz layout of ``steps`` steps cycling through ``pool``, each array written as a stream
    (never the whole run in memory)."""
    from gpfverify.audit.runfile import _npz_arrays

    arrays = _npz_arrays(list(pool), None)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED, allowZip64=True) as archive:
        for name, arr in arrays.items():
            stacked = name not in ("sizes",) and not name.startswith("circular") and arr.ndim >= 1 \
                and arr.shape[0] == len(pool)
            with archive.open(name + ".npy", "w", force_zip64=True) as member:
                if not stacked:
                    np.lib.format.write_array(member, arr)
                    continue
                shape = (steps,) + arr.shape[1:]
                np.lib.format.write_array_header_1_0(member, {"descr": np.lib.format.dtype_to_descr(arr.dtype),
                                                              "fortran_order": False, "shape": shape})
                done = 0
                while done < steps:
                    take = min(len(pool), steps - done)
                    member.write(np.ascontiguousarray(arr[:take]).tobytes())
                    done += take
    return path


def json_parse_seconds(path: Path) -> float:
    start = time.perf_counter()
    with open(path, "rb") as fh:
        for line in fh:
            json.loads(line)
    return time.perf_counter() - start


# -- children -----------------------------------------------------------------------------------
def run_child(what: str, args: list[str]) -> None:
    sys.path.insert(0, str(ROOT / "examples"))
    if what == "json":
        print(json_parse_seconds(Path(args[0])))
    elif what == "import":
        start = time.perf_counter()
        import scipy.linalg  # noqa: F401

        print(time.perf_counter() - start)
    elif what == "ukf":
        from three_sensor_system import tracker

        from gpfverify.filters import Gaussian, run_filter, ukf_step

        _, ys = tracker.simulate(300, np.random.default_rng(1))
        belief = Gaussian(tracker.prior_mean, tracker.prior_cov)
        run_filter(ukf_step, tracker, belief, ys[:20])
        start = time.perf_counter()
        run_filter(ukf_step, tracker, belief, ys)
        print((time.perf_counter() - start) / len(ys))
    elif what == "learn":
        from three_sensor_system import tracker

        from gpfverify.models import learn_gp_model

        start = time.perf_counter()
        learn_gp_model(tracker, 300, np.random.default_rng(0))
        print(time.perf_counter() - start)
    elif what == "moments":
        print(*moment_pair(int(args[0])))
    elif what == "sklearn":
        from three_sensor_system import tracker

        print(sklearn_same_gps(tracker))
    elif what == "read":
        from gpfverify.audit.runfile import open_run

        start = time.process_time()
        with open_run(args[0]) as reader:
            steps = sum(len(block) for block in reader.blocks())
        print(steps, (time.process_time() - start))
    else:
        raise SystemExit(f"unknown child {what}")


def sklearn_same_gps(model) -> float:
    """Seconds for scikit-learn to fit the GPs ``learn_gp_model(model, 300, rng)`` fits: the same
    trajectory, one GP per output (ARD squared exponential × constant + white noise), three starts
    (its first from the initial values, two restarts)."""
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

    rng = np.random.default_rng(0)
    states, ys = model.simulate(300, rng)
    problems = [(states[:-1], states[1:])] + [(states, ys[:, b]) for b in model.blocks]
    d = states.shape[1]
    start = time.perf_counter()
    for x, y in problems:
        for column in np.asarray(y).reshape(len(x), -1).T:
            kernel = ConstantKernel() * RBF(np.ones(d)) + WhiteKernel()
            GaussianProcessRegressor(kernel, n_restarts_optimizer=2, normalize_y=True, random_state=0).fit(x, column)
    return time.perf_counter() - start


# -- rows ---------------------------------------------------------------------------------------
def fmt(seconds: float) -> str:
    if seconds >= 1:
        return f"{seconds:.2f} s"
    if seconds >= 1e-3:
        return f"{seconds * 1e3:.2f} ms"
    return f"{seconds * 1e6:.1f} µs"


def audit_rows(rounds: int, steps: int, small: int, million: bool) -> list[list[str]]:
    rows = []
    pool, half = case_pool(), half_lost_pool()

    def audit(path: Path) -> dict:
        return timed_process(GPFVERIFY + ["audit", str(path), "--json"])

    with tempfile.TemporaryDirectory(prefix="gpfverify-bench-") as tmp:
        tmp = Path(tmp)
        jsonl = write_jsonl(tmp / "run.jsonl", steps, pool)
        size_mb = jsonl.stat().st_size / 1e6
        ours, ref = interleaved(lambda: audit(jsonl)["wall"], lambda: child("json", str(jsonl), pinned=True), rounds)
        rows.append([f"`audit RUN.jsonl --json`, {steps} steps ({size_mb:.0f} MB)",
                     "Python's json parsing the file, line by line", fmt(ours), fmt(ref), f"{ours / ref:.2f}",
                     "≤ 10"])
        memory = {t: audit(jsonl if t == steps else write_jsonl(tmp / f"run{t}.jsonl", t, pool))["rss_mb"]
                  for t in (small, steps)}
        rows.append([f"`audit RUN.jsonl --json`, peak resident memory at {small} and {steps} steps", "",
                     f"{memory[small]:.0f} MB, {memory[steps]:.0f} MB", "", "", "flat; ≤ 400 MB at 10⁶"])
        npz, lost = write_npz(tmp / "run.npz", steps, pool), write_npz(tmp / "lost.npz", steps, half)
        full_cpu, lost_cpu = interleaved(lambda: audit(npz)["cpu"], lambda: audit(lost)["cpu"], rounds)
        rows.append([f"`audit RUN.npz --json`, {steps} steps", "", f"{steps / full_cpu:.0f} steps per CPU-second",
                     "", "", "≥ 5000"])
        rows.append([f"`audit RUN.npz --json`, {steps} steps, every second one with a sensor that lost rank",
                     "the full-rank run's rate (above), interleaved", f"{steps / lost_cpu:.0f} steps per CPU-second",
                     f"{steps / full_cpu:.0f}", f"{full_cpu / lost_cpu:.2f}", "≥ 0.5"])
        memory = {t: audit(lost if t == steps else write_npz(tmp / f"lost{t}.npz", t, half))["rss_mb"]
                  for t in (small, steps)}
        rows.append([f"`audit RUN.npz --json` with rank lost, peak resident memory at {small} and {steps} steps",
                     "", f"{memory[small]:.0f} MB, {memory[steps]:.0f} MB", "", "", "flat"])
        if million:
            measured = {}
            for t in (100_000, 1_000_000):
                path = write_npz(tmp / f"lost{t}.npz", t, half)
                measured[t] = audit(path)
                path.unlink()
            rates = ", ".join(f"{t / m['cpu']:.0f}" for t, m in measured.items())
            rows.append(["`audit RUN.npz --json` with rank lost on every second step, peak resident memory at "
                         "10⁵ and 10⁶ steps", "", ", ".join(f"{m['rss_mb']:.0f} MB" for m in measured.values())
                         + f" ({rates} steps per CPU-second)", "", "", "independent of the length"])
            big_jsonl = write_jsonl(tmp / "million.jsonl", 1_000_000, pool)
            read = timed_process([sys.executable, __file__, "--child", "read", str(big_jsonl)])
            rows.append([f"read and check a 10⁶-step RUN.jsonl ({big_jsonl.stat().st_size / 1e9:.1f} GB), block by "
                         "block (no audit)", "", f"{read['rss_mb']:.0f} MB peak, {1e6 / read['cpu']:.0f} steps per "
                         "CPU-second", "", "", "≤ 400 MB"])
    return rows


def thread_rows(rounds: int, learn_rounds: int) -> list[list[str]]:
    rows = []
    for load in (False, True):
        state = "busy" if load else "idle"
        with busy(load):
            ours, ref = interleaved(lambda: child("learn", pinned=False), lambda: child("sklearn", pinned=False),
                                    learn_rounds)
            rows.append([f"`learn_gp_model(tracker, 300, rng)`, default BLAS threads, {state}",
                         "scikit-learn fitting the same 9 GPs, default BLAS threads", fmt(ours), fmt(ref),
                         f"{ours / ref:.2f}", "≤ 2"])
            ours, ref = interleaved(lambda: child("ukf", pinned=False), lambda: child("ukf", pinned=True), rounds)
            rows.append([f"UKF step through the Python API (three-sensor tracker), default BLAS threads, {state}",
                         "the same in a process pinned to one BLAS thread", fmt(ours), fmt(ref), f"{ours / ref:.2f}",
                         "≤ 1.3"])
    return rows


def startup_rows(rounds: int) -> list[list[str]]:
    check = GPFVERIFY + ["check", "examples/three_sensor_system.py:tracker", "--steps", "2", "--json"]

    def imports() -> float:
        return timed_process([sys.executable, "-c", "import numpy, scipy.linalg"])["wall"]

    rows = []
    for extra, label in ((["--methods", "cmf,dmf"], "CMF and DMF"),
                         ([], "default methods (CMF, DMF, CC, CI over 3 sensors)")):
        timed_process(check + extra)  # writes gpfverify's .pyc files where none are yet (untimed)
        ours, ref = interleaved(lambda extra=extra: timed_process(check + extra)["wall"], imports, rounds)
        rows.append([f"`check --json`, 2 steps, {label}", "`python -c 'import numpy, scipy.linalg'`", fmt(ours),
                     fmt(ref), f"{ours / ref:.2f}", "≤ 2"])
    return rows


#: fresh processes the moment kernel's row is measured in: on a virtual machine the speed of both
#: sides moves between processes (numpy's exp over cache-resident blocks took 0.77 ms in one
#: process and 2.0 ms in the next on the same idle AMD EPYC), so one process's ratio says little
MOMENT_PROCESSES = 5


def moment_pair(rounds: int) -> tuple[float, float]:
    """Median seconds per call of the moment kernel and of its exp floor, paired, in this process."""
    sys.path.insert(0, str(HERE))
    import bench_peers as bp

    from gpfverify.gp import GaussianProcess
    from gpfverify.gp.moments import moment_match

    rng = np.random.default_rng(0)
    n, d, e = 300, 2, 4
    X = rng.uniform(-3, 3, (n, d))
    Y = np.sin(X @ rng.normal(size=(d, e)))
    gp = GaussianProcess(X, Y, rng.uniform(0.5, 2, (e, d)), rng.uniform(0.5, 2, e), np.full(e, 0.01))
    mu, sigma = np.array([0.2, -0.1]), np.array([[0.3, 0.1], [0.1, 0.2]])
    # the floor: E(E+1)/2·n² exponentials in cache-resident blocks, as the kernel computes them (one
    # 7 MB array would time the memory and whether its pages happened to be huge ones)
    block = n * n // 10
    uniform = rng.uniform(-2.0, 0.0, block)
    out = np.empty_like(uniform)
    blocks = e * (e + 1) // 2 * n * n // block

    def exp_floor() -> None:
        for _ in range(blocks):
            np.exp(uniform, out=out)

    return bp.paired(lambda: moment_match(gp, mu, sigma), exp_floor, rounds)


def moment_rows(rounds: int) -> list[list[str]]:
    from gpfverify.gp import fused

    pairs = [child_numbers("moments", str(rounds), pinned=True)[-2:] for _ in range(MOMENT_PROCESSES)]
    ours, floor = (float(np.median(side)) for side in zip(*pairs))
    ratios = sorted(a / b for a, b in pairs)
    label = "fused kernel" if fused.enabled else "numpy path (numba not installed)"
    return [[f"`predict_uncertain`, n = 300, D = 2, E = 4 ({label}); {MOMENT_PROCESSES} processes",
             "numpy exp over E(E+1)/2·n² = 900,000 numbers (blocks of 9,000)", fmt(ours), fmt(floor),
             f"{float(np.median(ratios)):.2f} (processes {ratios[0]:.2f}–{ratios[-1]:.2f})", "≤ 1.5"]]


def machine_line() -> str:
    sys.path.insert(0, str(HERE))
    import bench_peers as bp

    load = os.getloadavg()
    return (f"{platform.machine()}, {bp.cpu()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
            f"numpy {np.__version__}; load average (1, 5, 15 min) at the start {load[0]:.2f}, {load[1]:.2f}, "
            f"{load[2]:.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--steps", type=int, default=20_000)
    parser.add_argument("--quick", action="store_true", help="fewer rounds and steps")
    parser.add_argument("--million", action="store_true", help="also read 10⁶-step run files (minutes, ~6 GB disk)")
    parser.add_argument("--only", nargs="*", default=None, help="audit, threads, startup, moments")
    parser.add_argument("--out", type=Path)
    parser.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        run_child(args.child[0], args.child[1:])
        return
    rounds, steps = (3, 2_000) if args.quick else (args.rounds, args.steps)
    header = machine_line()
    rows = []
    wanted = set(args.only or ("audit", "threads", "startup", "moments"))
    if "audit" in wanted:
        rows += audit_rows(rounds, steps, max(1, steps // 10), args.million)
    if "threads" in wanted:
        rows += thread_rows(rounds, max(1, rounds // 2))
    if "startup" in wanted:
        rows += startup_rows(rounds)
    if "moments" in wanted:
        rows += moment_rows(max(rounds, 11))
    table = ["| operation | reference | gpfverify | reference time | ratio | goal |", "|---|---|---|---|---|---|"]
    table += ["| " + " | ".join(r) + " |" for r in rows]
    text = f"Machine: {header}\n\n" + "\n".join(table) + "\n"
    print(text)
    if args.out:
        args.out.write_text(text, encoding="utf-8")


if __name__ == "__main__":
    main()
