"""Executor-agnostic Monte Carlo runner.

* Run i is seeded by ``SeedSequence(seed).spawn(runs)[i]``, so results do not depend on how runs
  are spread over workers.
* Every finished run is written atomically to ``DIR/runs/run-NNNNNN.json`` (temporary file +
  ``os.replace``); a crash or Ctrl-C loses only the runs in flight, and ``resume=True`` continues.
* A run that raises is saved with its error and seed; the summary counts it and leaves it out. A
  run that runs out of memory (:func:`gpfverify.memory.out_of_memory`) is not a failed run: the
  command stops with :class:`~gpfverify.errors.OutOfMemory`, the runs saved so far kept for
  ``--resume``.
* ``results.json`` is always computed from the saved runs (JSON round-trips floats exactly), so an
  interrupted-and-resumed run ends with the same numbers as an uninterrupted one. Timing fields
  are measurements and naturally differ between executions: ``results.json`` lists their names
  in ``"timing_keys"`` (every key, at any depth, matching :data:`TIMING_KEY`, plus an experiment's
  own ``TIMING_KEYS``). Apart from those and ``"provenance"``, every field of ``results.json`` is
  byte-identical for any number of workers, with a dask scheduler, and after ``--resume``
  (CONTRACT.md, "Provenance"): each run is a function of its seed alone — which also requires the
  numerical code to be a function of its inputs alone (e.g. no solver warm-started from another
  run's problem; see :mod:`gpfverify.fusion.rcc_ci`).
* ``manifest.json`` and ``results.json`` carry the provenance record of
  :mod:`gpfverify.provenance`.
* Local worker processes exit when the main process dies, whatever the signal
  (:func:`gpfverify.supervise.exit_with_parent`), so a SIGKILL leaves no orphans behind.
"""

from __future__ import annotations

import contextlib
import functools
import importlib
import itertools
import json
import os
import re
import sys
import time
import traceback
import warnings
from concurrent.futures import FIRST_COMPLETED, BrokenExecutor, Executor, Future, ProcessPoolExecutor, wait
from collections.abc import Callable, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from gpfverify import provenance
from gpfverify.contract.params import Params
from gpfverify.contract.serial import from_json, to_json
from gpfverify.errors import InputError, OutOfMemory, WorkerLost
from gpfverify.experiments.batching import batching_caveat, with_batching_caveat
from gpfverify.memory import out_of_memory
from gpfverify.runtime import progress_shown
from gpfverify.runtime import BLAS_THREAD_VARS
from gpfverify.supervise import exit_with_parent
from gpfverify.usercode import (Interrupted, UserCodeError, guarded, interrupt_received, set_time_limit, system_file,
                                time_limit)

#: a key of ``results.json`` (at any depth) whose value is a measured time, not a result
TIMING_KEY = re.compile(r"time_per|seconds|machine_load|timing_claims")


class SerialExecutor(Executor):
    """Runs each task at submission, in this process (workers = 1)."""

    def submit(self, fn, /, *args, **kwargs) -> Future:
        future: Future = Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # noqa: BLE001 - handed to the caller through the future
            if isinstance(exc, KeyboardInterrupt):
                raise
            future.set_exception(exc)
        return future


def _check_address(address: str) -> None:
    """ValueError unless ``address`` is a scheduler address dask.distributed can parse
    (``[protocol://]host:port`` for TCP/TLS)."""
    from distributed.comm.addressing import parse_address, parse_host_port

    protocol, location = parse_address(address)
    if protocol in ("tcp", "tls"):
        parse_host_port(location)


@contextlib.contextmanager
def make_executor(workers: int = 1, scheduler: str | None = None):
    """Serial for one worker; a local process pool with BLAS pinned to one thread per worker;
    or, with ``scheduler``, the executor of a ``dask.distributed`` client at that address."""
    if scheduler:
        try:
            from distributed import Client
        except ImportError:
            raise InputError("--scheduler needs dask.distributed: pip install 'gpfverify[cluster]'") from None
        try:
            _check_address(scheduler)  # the syntax first: Client's own checks can race with its timeouts
            client = Client(scheduler)
        except (ValueError, TypeError, OSError, TimeoutError) as exc:  # a malformed or unreachable address
            raise InputError(f"--scheduler {scheduler}: cannot connect ({exc})") from None
        try:
            yield client.get_executor()
        finally:
            client.close()
        return
    check_workers(workers)
    if workers == 1:
        yield SerialExecutor()
        return
    saved = {k: os.environ.get(k) for k in BLAS_THREAD_VARS}
    os.environ.update({k: "1" for k in BLAS_THREAD_VARS})  # inherited by the spawned workers
    import multiprocessing as mp

    _quiet_manager_thread_on_interrupt()
    pool = _WorkerPool(max_workers=workers, mp_context=mp.get_context("spawn"),
                       initializer=_start_worker, initargs=(os.getpid(), time_limit()))
    try:
        yield pool
    except BaseException:
        # interrupted or failed: stop the workers now rather than let them finish (or outlive us);
        # runs already saved stay saved. (ProcessPoolExecutor has no public terminate before 3.14.)
        _quiet_resource_tracker()
        _stop(pool)
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    else:
        # every result is in: a worker that a thread of the user's code keeps alive is not waited for
        _quiet_resource_tracker()
        processes = list((getattr(pool, "_processes", None) or {}).values())
        manager = getattr(pool, "_executor_manager_thread", None)
        pool.shutdown(wait=False)
        deadline = time.monotonic() + WORKER_EXIT_SECONDS
        for process in processes:
            process.join(max(0.0, deadline - time.monotonic()))
            if process.is_alive():
                process.terminate()
        if manager is not None:
            manager.join()
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


class _WorkerPool(ProcessPoolExecutor):
    """A local process pool whose worker processes start with SIGINT blocked, as multiprocessing
    starts its resource tracker: a Ctrl-C from the terminal reaches every process, and one reaching
    a worker while Python starts it (before :func:`_start_worker` runs) would print a traceback
    (ProcessPoolExecutor starts its workers as tasks are submitted). A Ctrl-C reaching this process
    meanwhile waits until the worker is started, then stops the command as usual."""

    def submit(self, fn, /, *args, **kwargs):
        import signal

        blocked = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            return super().submit(fn, *args, **kwargs)
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, blocked)


#: how long a worker may take to end once the pool is shut down before it is stopped
WORKER_EXIT_SECONDS = 2.0


def _stop(pool: ProcessPoolExecutor) -> None:
    """Terminate the pool's worker processes that are still running."""
    for process in list((getattr(pool, "_processes", None) or {}).values()):
        if process.is_alive():
            process.terminate()


def _quiet_resource_tracker() -> None:
    """Start multiprocessing's resource tracker again, with its stderr on /dev/null, if it died
    (someone killed it): started by multiprocessing itself at the next semaphore it releases, it
    would print a traceback for every semaphore it never saw registered. The warning that it
    died is raised here, and collected like any other (one note line)."""
    from multiprocessing import resource_tracker

    try:
        saved = os.dup(2)
        null = os.open(os.devnull, os.O_WRONLY)
    except OSError:
        return
    try:
        sys.stderr.flush()
        os.dup2(null, 2)
        resource_tracker.ensure_running()
    except Exception:  # noqa: BLE001 - the tracker is multiprocessing's affair; the runs are saved
        pass
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(null)


_QUIET_MANAGER_INSTALLED = False


def _quiet_manager_thread_on_interrupt() -> None:
    """Keep CPython 3.11's process-pool race off the terminal: when the workers are stopped on an
    interruption, the pool's manager thread marks every pending future broken, including those
    already cancelled, and its ``InvalidStateError`` would be printed as a traceback after the one
    "interrupted" line. Only that exception of that thread is dropped (the hook, installed once per
    process when a local pool is first made, passes everything else to the hook it wraps)."""
    global _QUIET_MANAGER_INSTALLED
    if _QUIET_MANAGER_INSTALLED:
        return
    import threading
    from concurrent.futures import InvalidStateError
    from concurrent.futures.process import _ExecutorManagerThread

    previous = threading.excepthook

    def hook(args) -> None:
        if isinstance(args.thread, _ExecutorManagerThread) and isinstance(args.exc_value, InvalidStateError):
            return
        previous(args)

    threading.excepthook = hook
    _QUIET_MANAGER_INSTALLED = True


def check_workers(workers) -> int:
    """``workers`` as a count of at least 1 (InputError otherwise: 0 used to mean serial silently)."""
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise InputError(f"--workers must be an integer >= 1, got {workers!r}")
    return workers


def run_seed(seed: int, index: int) -> np.random.SeedSequence:
    """The seed of run ``index``: ``SeedSequence(seed).spawn(runs)[index]``, made without the
    other runs' seeds."""
    return np.random.SeedSequence(seed, spawn_key=(index,))


#: the least memory one run's record takes while the summary holds them all
RUN_RECORD_BYTES = 2048


def check_runs_fit(runs: int, bytes_each: int = RUN_RECORD_BYTES) -> None:
    """Refuse a run count whose records (``bytes_each`` at least, each) cannot all be held in the
    memory this machine has available (:func:`gpfverify.userfiles.memory_budget`), before anything
    is written."""
    from gpfverify.userfiles import human_bytes, memory_budget

    fits = memory_budget() // max(1, bytes_each)
    if runs > fits:
        raise InputError(f"--runs {runs} is more than this machine can hold: the summary keeps every run's record "
                         f"in memory (at least {human_bytes(bytes_each)} each), so at most {fits} runs fit in the "
                         "memory available now")


def check_run_count(runs) -> int:
    """``runs`` as a run count: an integer >= 1."""
    if isinstance(runs, bool) or not isinstance(runs, int) or runs < 1:
        raise InputError(f"--runs must be an integer >= 1, got {runs!r}")
    return runs


def check_seed(seed) -> int:
    """``seed`` as a root seed for ``SeedSequence``: an integer >= 0."""
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise InputError(f"--seed must be an integer >= 0, got {seed!r}")
    return seed


def _start_worker(parent_pid: int, seconds: float | None = None) -> None:
    """Worker initializer: the worker ends as soon as its parent (the main process, which started
    it) is gone, killed by any signal (:func:`gpfverify.supervise.exit_with_parent`; the
    multiprocessing resource tracker exits by itself once every process holding its pipe is
    gone), and ignores Ctrl-C (SIGINT, blocked until now: :class:`_WorkerPool`): the main process
    stops the command and its workers, and a KeyboardInterrupt in a worker is then always one the
    user's code raised itself (:func:`gpfverify.usercode.guarded`). ``seconds``: the time limit of
    each call of the user's code (``--timeout``, :func:`gpfverify.usercode.set_time_limit`); the
    worker's BLAS buffers are taken now, while its memory is known to be there
    (:func:`gpfverify.memory.reserve_blas_buffers`)."""
    import signal

    from gpfverify.memory import reserve_blas_buffers

    exit_with_parent(parent_pid)
    set_time_limit(seconds)
    reserve_blas_buffers()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # a Ctrl-C pending since the worker started is dropped
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def _local_workers(executor: Executor) -> int | None:
    """The executor's worker processes: 1 for the serial executor, the pool's size for a local
    pool, None for a cluster executor whose size is not known here."""
    if isinstance(executor, SerialExecutor):
        return 1
    return getattr(executor, "_max_workers", None)


def _in_flight_limit(executor: Executor) -> int:
    """How many batches to keep submitted at once: two per local worker process (so none idles),
    one for the serial executor, and many for a cluster executor whose size is not known here."""
    workers = _local_workers(executor)
    return 1 if workers == 1 else 2 * workers if workers else 1024


def _execute(module_name: str, params: Params, seed_entropy: int, indices: Sequence[int]) -> list[dict]:
    """The runs ``indices`` of one batch, never raising: one record per run, as saved under ``runs/``.

    With the experiment's ``run_batch`` the runs advance together (each on its own seed stream,
    :func:`run_seed`); should the batch raise, each of its runs is run again alone (``run_batch`` of
    one, the same bits as in any batch), so that a failing run is recorded with its own error and
    the others are kept. Without ``run_batch``, ``run_one`` runs each in turn. A run's ``seconds`` is
    the batch's wall time divided by its size; its warnings (numpy's floating-point ones, kept with
    the runs instead of printed by whichever process ran them) are those of its batch."""
    module = importlib.import_module(module_name)
    seeds = [run_seed(seed_entropy, i) for i in indices]
    batched = getattr(module, "run_batch", None)
    spec = getattr(params, "system", None)  # check: the user's system file; print() to stderr, exits reported
    label = system_file(spec) if spec else f"the code run by {module.NAME}"
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        outcomes: list[tuple[str, Any]] = []
        if batched is not None and len(seeds) > 1:
            outcomes = _attempt(label, lambda: batched(params, seeds))
        if not outcomes or outcomes[0][0] == "error":  # one by one: each run's own error
            outcomes = [_attempt(label, functools.partial(_one_run, module, params, seed))[0] for seed in seeds]
    seconds = (time.perf_counter() - start) / len(seeds)
    load = machine_load()
    records = []
    for index, seed, (status, value) in zip(indices, seeds, outcomes):
        record: dict[str, Any] = {"index": index, "seed_entropy": str(seed.entropy), "spawn_key": list(seed.spawn_key)}
        if status == "ok":
            record["result"], record["status"] = value, "ok"
        else:
            record["status"], (record["error"], record["traceback"]) = "error", value
        if caught:
            record["warnings"] = sorted({f"{w.category.__name__}: {w.message}" for w in caught})
        record["seconds"] = seconds
        record["batch_size"] = len(seeds)
        record["machine_load"] = load
        records.append(record)
    return records


def _one_run(module: ModuleType, params: Params, seed: np.random.SeedSequence) -> list:
    """Run ``seed`` alone: the experiment's ``run_batch`` of one when it has one (the same bits as in
    any batch), else its ``run_one``."""
    batched = getattr(module, "run_batch", None)
    return batched(params, [seed]) if batched is not None else [module.run_one(params, seed)]


def _attempt(label: str, fn: Callable[[], list]) -> list[tuple[str, Any]]:
    """``[("ok", run record as JSON), …]`` for the runs ``fn`` returns, or ``[("error", (message,
    traceback))]`` when it raises; the user's code trying to end the process stops the command."""
    try:
        with guarded(label):
            return [("ok", to_json(record)) for record in fn()]
    except UserCodeError:  # the user's code tried to end the process (or to stop it): the command stops
        raise
    except Exception as exc:  # noqa: BLE001 - recorded, counted, reported
        if interrupt_received():  # a Ctrl-C that compiled code turned into another error: not the run's
            raise Interrupted from None
        memory = out_of_memory(exc)
        if memory is not None:  # the machine's fault, not the run's: the command stops, --resume continues
            raise OutOfMemory(memory) from None
        return [("error", (f"{type(exc).__name__}: {exc}", traceback.format_exc(limit=8)))]


#: the largest batch the runner chooses by itself: beyond it a batch's arrays outgrow the caches and
#: the time per run stops falling (benchmarks/results/batch.md), while a crash loses more runs
MAX_DEFAULT_BATCH = 64
#: the working memory of one run in a batch when the experiment does not state its own
#: (``batch_run_bytes``)
DEFAULT_RUN_BYTES = 32 << 20


def check_batch(batch) -> int:
    """``batch`` as a batch size: an integer >= 1 (InputError otherwise)."""
    if isinstance(batch, bool) or not isinstance(batch, int) or batch < 1:
        raise InputError(f"--batch must be an integer >= 1, got {batch!r}")
    return batch


def default_batch(module: ModuleType, params: Params, pending: int, workers: int | None) -> int:
    """Runs per batch when ``--batch`` is not given: 1 for an experiment without ``run_batch``;
    else as many as the memory available holds for every worker at once (the experiment's
    ``batch_run_bytes(params)`` per run, :func:`gpfverify.userfiles.memory_budget`), at most
    :data:`MAX_DEFAULT_BATCH`, and no more than gives every local worker a batch of the ``pending``
    runs. Results do not depend on it."""
    from gpfverify.userfiles import memory_budget

    if not hasattr(module, "run_batch"):
        return 1
    sizer = getattr(module, "batch_run_bytes", None)
    per_run = max(1, int(sizer(params)) if sizer is not None else DEFAULT_RUN_BYTES)
    fits = memory_budget() // (per_run * (workers or 1))
    spread = -(-pending // workers) if workers else pending
    return max(1, min(MAX_DEFAULT_BATCH, fits, spread))


def _atomic_write_json(path: Path, obj) -> None:
    tmp = path.with_name(path.name + f".tmp{os.getpid()}")
    tmp.write_text(json.dumps(obj, allow_nan=True), encoding="utf-8")
    os.replace(tmp, path)


def _run_path(out_dir: Path, index: int) -> Path:
    return out_dir / "runs" / f"run-{index:06d}.json"


def _read_json(path: Path, what: str):
    """A JSON file this runner wrote, or InputError saying it is damaged (never a traceback)."""
    try:
        return json.loads(path.read_bytes().decode("utf-8"))
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from None
    except (ValueError, RecursionError) as exc:  # JSONDecodeError, UnicodeDecodeError, huge ints
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"{path} is not a valid {what} ({reason}); remove it or choose a new "
                         "--out") from None


SETTINGS_KEYS = ("experiment", "seed", "params")


def read_manifest(out_dir: Path) -> dict:
    """``DIR/manifest.json`` as a dict; InputError when it is missing, corrupted or not a manifest."""
    manifest = _read_json(Path(out_dir) / "manifest.json", "manifest")
    if not isinstance(manifest, dict) or not all(k in manifest for k in (*SETTINGS_KEYS, "runs")):
        raise InputError(f"{Path(out_dir) / 'manifest.json'} is not a gpfverify run manifest; "
                         "remove it or choose a new --out")
    return manifest


def _check_manifest(out_dir: Path, manifest: dict, resume: bool, write: bool = True) -> None:
    """Refuse to mix settings or to overwrite saved runs without ``resume``; then (``write``)
    write the manifest with this command's provenance."""
    path = out_dir / "manifest.json"
    existing_runs = list((out_dir / "runs").glob("run-*.json")) if (out_dir / "runs").exists() else []
    if path.exists() and (resume or not existing_runs):
        old = read_manifest(out_dir)
        if resume and {k: old.get(k) for k in (*SETTINGS_KEYS, "interpretation")} != \
                {k: manifest.get(k) for k in (*SETTINGS_KEYS, "interpretation")}:
            raise InputError("--out holds runs of different settings; use a new --out")
    elif existing_runs and not resume:
        raise InputError(f"--out already holds {len(existing_runs)} saved runs; "
                         "pass --resume to continue them or choose a new --out")
    if write:
        _atomic_write_json(path, {**manifest, "provenance": provenance.current()})


def _progress(enabled: bool):
    if not enabled:
        return contextlib.nullcontext(None)
    from rich.console import Console
    from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TextColumn,
                               TimeElapsedColumn, TimeRemainingColumn)

    from gpfverify.streams import diagnostics

    return Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                    TextColumn("{task.fields[rate]}"), TimeElapsedColumn(), TimeRemainingColumn(),
                    transient=False, console=Console(file=diagnostics()))  # progress is a diagnostic: stderr


def run_experiment(module: ModuleType | str, params: Params, runs: int, seed: int, out_dir: Path,
                   resume: bool = False, executor: Executor | None = None,
                   show_progress: bool | None = None,
                   on_run: Callable[[int, int], None] | None = None, batch: int | None = None,
                   interpretation: str | None = None) -> dict:
    """Run (or finish) ``runs`` Monte Carlo runs of an experiment and write ``results.json``.

    ``params`` is the experiment's ``Params`` (see :mod:`gpfverify.contract.experiment`);
    ``on_run(saved, runs)`` is called after every saved run (progress off a terminal);
    ``show_progress`` draws rich's progress bar (default: on a terminal and in a Jupyter notebook);
    ``batch`` the runs each task advances together (default :func:`default_batch`): the runs still to
    do, in order, are cut into batches, each batch is one task for the executor (a worker process or
    a dask cluster receives batches, not runs), and each of its runs is saved as it comes back;
    ``interpretation``: the name of the interpretation whose changes ``params`` carries (``gpfverify
    reproduce NAME --interpretation``), recorded in ``manifest.json`` and ``results.json``."""
    module = importlib.import_module(module) if isinstance(module, str) else module
    name = module.NAME
    check_run_count(runs)
    check_seed(seed)
    if batch is not None:
        check_batch(batch)
    check_runs_fit(runs)
    out_dir = Path(out_dir)
    for folder in (out_dir, out_dir / "runs"):
        if folder.exists() and not folder.is_dir():
            raise InputError(f"--out {folder} exists and is not a folder")
    if not isinstance(params, module.Params):
        raise InputError(f"{name} takes its own Params, got {type(params).__name__}")
    manifest = {"experiment": name, "seed": seed, "runs": runs, "params": params.to_json()}
    if interpretation is not None:
        manifest["interpretation"] = interpretation
    manifest = json.loads(json.dumps(manifest))  # exactly what a resumed run reads back
    run_params = _typed_params(module, manifest["params"])
    if out_dir.exists():  # check before writing anything: a refused run leaves no trace
        _check_manifest(out_dir, manifest, resume, write=False)
    (out_dir / "runs").mkdir(parents=True, exist_ok=True)
    _check_manifest(out_dir, manifest, resume)
    pending = [i for i in range(runs) if not _is_ok(_run_path(out_dir, i))]
    show = progress_shown() if show_progress is None else show_progress
    with contextlib.ExitStack() as stack:
        if executor is None:
            executor = stack.enter_context(make_executor(1))
        progress = stack.enter_context(_progress(show))
        task = progress.add_task(name, total=runs, completed=runs - len(pending), rate="") if progress else None
        started = time.perf_counter()
        size = batch or default_batch(module, run_params, len(pending), _local_workers(executor))
        queue = iter([pending[i:i + size] for i in range(0, len(pending), size)])
        in_flight: set[Future] = set()
        limit = _in_flight_limit(executor)
        n_done = 0
        try:
            while True:
                # submit lazily so each batch's runs are saved as soon as it finishes, whatever the executor
                for indices in itertools.islice(queue, max(0, limit - len(in_flight))):
                    in_flight.add(executor.submit(_execute, module.__name__, run_params, seed, indices))
                if not in_flight:
                    break
                done, in_flight = wait(in_flight, return_when=FIRST_COMPLETED)
                for future in done:
                    try:
                        records = future.result()
                    except BrokenExecutor:
                        lost = WorkerLost("a worker process ended abruptly (killed by a signal or out of memory)")
                        lost.add_note(_finished_note(out_dir, runs))
                        raise lost from None
                    for record in records:
                        _atomic_write_json(_run_path(out_dir, record["index"]), record)
                        n_done += 1
                        if on_run is not None:
                            on_run(runs - len(pending) + n_done, runs)
                    if progress:
                        rate = n_done / max(time.perf_counter() - started, 1e-9)
                        progress.update(task, advance=len(records), rate=f"{rate:.2f} runs/s")
        except BaseException as exc:
            if isinstance(exc, KeyboardInterrupt) or interrupt_received():  # the Ctrl-C may arrive as another error
                for f in in_flight:
                    f.cancel()
                exc.add_note(_finished_note(out_dir, runs))  # what is kept of them: gpfverify.outputs says
            raise
    return write_results(module, out_dir, manifest)


def _finished_note(out_dir: Path, runs: int) -> str:
    """How many runs had finished when the command was stopped (a note on the exception that
    stopped it)."""
    saved = sum(_is_ok(_run_path(out_dir, i)) for i in range(runs))
    return f"{saved} of {runs} runs had finished" if saved else "no run had finished"


def _typed_params(module: ModuleType, params: dict) -> Params:
    """The recorded parameters read back through the experiment's ``Params`` type (so a resumed
    run uses exactly what was recorded)."""
    return module.Params.from_json(params)


def _typed_record(module: ModuleType, result):
    return from_json(module.RunRecord, result, "run record")


def machine_load() -> dict:
    """The 1-, 5- and 15-minute load averages and the core count now (each run records them when
    it ends): timings depend on them (a timing field, see :data:`TIMING_KEY`)."""
    try:
        load = [round(v, 2) for v in os.getloadavg()]
    except OSError:  # not available on this platform
        load = []
    return {"load_average": load, "cpus": os.cpu_count()}


def runs_machine_load(records: list[dict]) -> dict:
    """The load the runs met: the median of each load average over the runs that recorded one
    (at their end), the largest core count among them and how many runs recorded a load; and how the
    runs were batched (the largest batch, and how many runs shared a batch with others: their
    methods' times per step are the batch's divided by its size). Runs
    saved before runs recorded their load give an empty ``load_average`` (unknown), never the load
    at the time ``results.json`` is recomputed."""
    loads = [r["machine_load"] for r in records if len((r.get("machine_load") or {}).get("load_average") or []) == 3]
    average = [round(float(v), 2) for v in np.median([m["load_average"] for m in loads], axis=0)] if loads else []
    cpus = max((m["cpus"] for m in loads if isinstance(m.get("cpus"), int)), default=None)
    sizes = [r["batch_size"] for r in records if isinstance(r.get("batch_size"), int)]
    return {"load_average": average, "cpus": cpus, "runs_measured": len(loads),
            "largest_batch": max(sizes, default=1), "runs_batched": sum(size > 1 for size in sizes)}


def _well_formed(record, index: int) -> bool:
    """Whether ``record`` is what :func:`_execute` saves for run ``index``: a finished run with its
    result, or a failed one with its error and seed."""
    if not isinstance(record, dict) or record.get("index") != index:
        return False
    if record.get("status") == "ok":
        return "result" in record
    return record.get("status") == "error" and isinstance(record.get("error"), str) and "spawn_key" in record


def _is_ok(path: Path) -> bool:
    """Whether run ``path`` is saved and finished; anything else (absent, damaged, failed) runs again."""
    if not path.exists():
        return False
    try:
        record = json.loads(path.read_bytes().decode("utf-8"))
    except (ValueError, RecursionError, OSError):
        return False
    index = int(path.stem.removeprefix("run-"))
    return _well_formed(record, index) and record["status"] == "ok"


def load_runs(out_dir: Path, runs: int) -> list[dict]:
    """The saved runs of ``out_dir`` in order; InputError for one that is not a saved run."""
    records = []
    for i in range(runs):
        path = _run_path(out_dir, i)
        if path.exists():
            record = _read_json(path, "saved run")
            if not _well_formed(record, i):
                raise InputError(f"{path} is not a saved run of run {i} (damaged or edited); remove it or "
                                 "choose a new --out")
            records.append(record)
    return records


def timing_keys(module: ModuleType, body) -> list[str]:
    """Names of the timing fields in a ``results.json`` body: every key, at any depth, matching
    :data:`TIMING_KEY`, and the experiment's own ``TIMING_KEYS`` when it declares any."""
    found = set(getattr(module, "TIMING_KEYS", ()))

    def walk(value):
        if isinstance(value, dict):
            for key, item in value.items():
                if TIMING_KEY.search(str(key)):
                    found.add(str(key))
                else:
                    walk(item)
        elif isinstance(value, list):
            for item in value:
                walk(item)

    walk(body)
    return sorted(found)


def untimed(value):
    """``value`` (a run record as JSON, or any part of one) without the keys, at any depth, that
    :data:`TIMING_KEY` matches: what must be the same bits for every batch, worker and scheduler."""
    if isinstance(value, dict):
        return {k: untimed(v) for k, v in value.items() if not TIMING_KEY.search(str(k))}
    if isinstance(value, (list, tuple)):
        return [untimed(v) for v in value]
    return value


def without_timing(results: dict) -> dict:
    """``results`` without ``provenance`` and the fields named in its ``timing_keys`` (at any
    depth): the part that the contract requires to be byte-identical across executions."""
    keys = set(results.get("timing_keys", ())) | {"provenance"}

    def strip(value):
        if isinstance(value, dict):
            return {k: strip(v) for k, v in value.items() if k not in keys}
        if isinstance(value, list):
            return [strip(v) for v in value]
        return value

    return strip(results)


def _separate_timing_claims(body: dict) -> None:
    """Claims that compare measured times (``"timing": true``) differ between executions like the
    times they rest on: they go to ``"timing_claims"``, a timing field, and ``"claims"`` keeps the
    rest (:func:`gpfverify.contract.claims.read_claims` reads both)."""
    claims = body.get("claims")
    if not claims:
        return
    body["claims"] = [c for c in claims if not c.get("timing")]
    timed = [c for c in claims if c.get("timing")]
    if timed:
        body["timing_claims"] = [*body.get("timing_claims", []), *timed]


def write_results(module: ModuleType, out_dir: Path, manifest: dict) -> dict:
    """``results.json`` from the saved runs, in run order."""
    results = results_of(module, out_dir, manifest)
    _atomic_write_json(out_dir / "results.json", results)
    return results


def results_of(module: ModuleType, out_dir: Path, manifest: dict, runs: int | None = None) -> dict:
    """The ``results.json`` body of the first ``runs`` runs saved in ``out_dir`` (default: all
    that the manifest counts), without writing it."""
    records = load_runs(out_dir, manifest["runs"] if runs is None else min(runs, manifest["runs"]))
    ok = [r for r in records if r["status"] == "ok"]
    failed = [{"index": r["index"], "error": r["error"], "spawn_key": r["spawn_key"]}
              for r in records if r["status"] != "ok"]
    if not ok:
        first = failed[0]["error"] if failed else "no run finished"
        raise InputError(f"every run of {manifest['experiment']} failed; first error: {first}")
    body = to_json(module.summarize(_typed_params(module, manifest["params"]),
                                    [_typed_record(module, r["result"]) for r in ok]))
    body["machine_load"] = runs_machine_load(records)
    _separate_timing_claims(body)
    body = with_batching_caveat(body, batching_caveat(module))
    results = {"experiment": manifest["experiment"], "runs": manifest["runs"], "seed": manifest["seed"],
               "params": manifest["params"],
               **({"interpretation": manifest["interpretation"]} if manifest.get("interpretation") else {}),
               "runs_ok": len(ok), "failed_runs": failed, **body,
               "timing_keys": timing_keys(module, body), "provenance": provenance.current()}
    if runs is not None:
        results["runs"] = len(records)
    return results


def rewrite_results(out_dir: Path, module: ModuleType | str) -> dict:
    """``results.json`` recomputed from the runs saved in ``out_dir`` with its manifest (e.g. after
    an experiment's summary gained fields); returns it."""
    module = importlib.import_module(module) if isinstance(module, str) else module
    manifest = read_manifest(Path(out_dir))
    return write_results(module, Path(out_dir), manifest)
