"""CONTRACT.md, "Provenance": apart from ``provenance`` and the fields named in ``timing_keys``,
``results.json`` is byte-identical for any ``--workers``, with ``--scheduler`` (a dask cluster
whose workers are separate processes: a ``LocalCluster``, and a ``dask scheduler`` with a ``dask
worker`` started as docs/cluster.md starts them, each compared with ``--workers 2``) and after a
SIGKILL and ``--resume`` — checked end to end
through the command line on a small ct2d (RCC-CI included, whose solver once depended on the
process's earlier solves) and a small ungm1d. The SIGKILL also checks that neither the command's
process, nor a worker process, nor the resource tracker outlives the killed main process; a worker
killed alone ends the command with exit status 2 and one line, its saved runs kept in --out for
``--resume``."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from gpfverify.experiments.runner import without_timing

sys.path.insert(0, str(Path(__file__).parent))  # the suite imports in importlib mode: the helper beside it
from processes import alive, descendants, pool_workers  # noqa: E402

pytestmark = pytest.mark.slow

EXPERIMENTS = {
    "ct2d": ["ct2d", "--kappa", "12", "--omega", "0.0698", "--test-steps", "3", "--fit-points", "12"],
    "ungm1d": ["ungm1d", "--train-points", "15", "--test-steps", "3", "--sweep", "2"],
}
RUNS, SEED = "3", "11"


def _cli(*args, **kwargs):
    return [sys.executable, "-m", "gpfverify", *args]


def _reproduce(name, out, *extra, check=True):
    proc = subprocess.run(_cli("reproduce", *EXPERIMENTS[name], "--runs", RUNS, "--seed", SEED,
                               "--out", str(out), *extra), capture_output=True, text=True, timeout=300)
    if check:
        assert proc.returncode == 0, proc.stderr
    return proc


def _canonical(out: Path) -> str:
    """The part of results.json the contract makes byte-identical, as bytes-comparable text."""
    results = json.loads((out / "results.json").read_text(encoding="utf-8"))
    assert results["timing_keys"] and "provenance" in results
    return json.dumps(without_timing(results))


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    """The reference: one process, uninterrupted."""
    base = tmp_path_factory.mktemp("serial")
    return {name: _canonical(_reproduce(name, base / name, "--workers", "1") and base / name)
            for name in EXPERIMENTS}


@pytest.fixture(scope="module")
def two_workers(tmp_path_factory):
    """The same runs in two local worker processes."""
    base = tmp_path_factory.mktemp("workers-2")
    return {name: _canonical(_reproduce(name, base / name, "--workers", "2") and base / name) for name in EXPERIMENTS}


@pytest.mark.parametrize("name", sorted(EXPERIMENTS))
def test_two_workers_give_the_same_bytes(serial, two_workers, name):
    assert two_workers[name] == serial[name]


@pytest.mark.parametrize("name", sorted(EXPERIMENTS))
def test_a_dask_cluster_of_worker_processes_gives_the_same_bytes(two_workers, tmp_path, name):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        _reproduce(name, tmp_path / "dask", "--scheduler", cluster.scheduler_address)
    assert _canonical(tmp_path / "dask") == two_workers[name]


def test_a_dask_scheduler_and_workers_started_from_the_shell_give_the_same_bytes(two_workers, tmp_path):
    """``dask scheduler`` and ``dask worker ADDRESS --nworkers 2 --nthreads 1`` as separate commands
    (docs/cluster.md), then ``reproduce --scheduler ADDRESS``: the bytes of ``--workers 2``."""
    distributed = pytest.importorskip("distributed")
    dask = Path(sys.executable).with_name("dask")
    if not dask.exists():
        pytest.skip("no dask command beside this Python (pip install 'gpfverify[cluster]')")
    log = tmp_path / "scheduler.log"
    with open(log, "w") as sink:
        scheduler = subprocess.Popen([str(dask), "scheduler", "--host", "127.0.0.1", "--port", "0",
                                      "--no-dashboard"], stdout=sink, stderr=subprocess.STDOUT)
    worker = None
    try:
        address = None
        deadline = time.monotonic() + 60
        while address is None and time.monotonic() < deadline and scheduler.poll() is None:
            found = [line.split("Scheduler at:", 1)[1].strip() for line in log.read_text().splitlines()
                     if "Scheduler at:" in line]
            address = found[0] if found else None
            time.sleep(0.2)
        assert address, log.read_text()
        worker = subprocess.Popen([str(dask), "worker", address, "--nworkers", "2", "--nthreads", "1",
                                   "--no-dashboard"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                  env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
        with distributed.Client(address, timeout=60) as client:
            client.wait_for_workers(2, timeout=120)
        _reproduce("ungm1d", tmp_path / "shell-cluster", "--scheduler", address)
    finally:
        for proc in (worker, scheduler):
            if proc is not None and proc.poll() is None:
                proc.terminate()
                try:
                    proc.wait(timeout=30)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()
    assert _canonical(tmp_path / "shell-cluster") == two_workers["ungm1d"]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("name", sorted(EXPERIMENTS))
def test_sigkill_leaves_no_orphans_and_resume_gives_the_same_bytes(serial, tmp_path, name):
    out = tmp_path / "killed"
    # one run per batch: a run is saved as soon as it ends, and the kill lands with runs still to do
    proc = subprocess.Popen(_cli("reproduce", *EXPERIMENTS[name], "--runs", RUNS, "--seed", SEED,
                                 "--out", str(out), "--workers", "2", "--batch", "1"),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    children: set[int] = set()
    deadline = time.monotonic() + 120
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            children |= descendants(proc.pid)  # the command's process, two workers and the resource tracker
            if list(tmp_path.glob(".gpfverify-partial-killed-*/runs/run-*.json")):  # docs/output-and-errors.md
                break
            time.sleep(0.02)
        children |= descendants(proc.pid)
        assert proc.poll() is None, "the run finished before it could be killed"
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert len(children) >= 3  # the command's process and two workers at least
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline and any(alive(pid) for pid in children):
        time.sleep(0.05)
    orphans = [pid for pid in children if alive(pid)]
    for pid in orphans:  # do not leave them to the rest of the suite
        os.kill(pid, signal.SIGKILL)
    assert not orphans, f"processes outlived the killed main process: {orphans}"
    saved = sorted(p.name for p in tmp_path.glob(".gpfverify-partial-killed-*/runs/run-*.json"))
    assert 1 <= len(saved) < int(RUNS), saved
    assert not out.exists()  # the killed command's runs wait in its staging folder for the next command
    refused = _reproduce(name, out, check=False)  # without --resume: refused, one line
    assert refused.returncode == 2 and len(refused.stderr.strip().splitlines()) == 1
    # ... which has kept them in --out, as an interruption would have, and removed the staging folder
    assert sorted(p.name for p in (out / "runs").glob("run-*.json")) == saved
    assert not list(tmp_path.glob(".gpfverify-*"))
    _reproduce(name, out, "--resume", "--workers", "1")
    assert _canonical(out) == serial[name]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_killed_worker_keeps_the_saved_runs_and_resume_gives_the_same_bytes(serial, tmp_path):
    name, out = "ungm1d", tmp_path / "out"
    # one run per batch: a run is saved as soon as it ends, and the kill lands with runs still to do
    proc = subprocess.Popen(_cli("reproduce", *EXPERIMENTS[name], "--runs", RUNS, "--seed", SEED,
                                 "--out", str(out), "--workers", "2", "--batch", "1"),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            if list(tmp_path.glob(".gpfverify-partial-out-*/runs/run-*.json")) and pool_workers(proc.pid):
                break
            time.sleep(0.02)
        assert proc.poll() is None, "the run finished before a worker could be killed"
        os.kill(pool_workers(proc.pid)[0], signal.SIGKILL)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 2 and stdout == "", stderr
    lines = stderr.strip().splitlines()
    assert lines[-1].startswith("gpfverify reproduce: error: a worker process ended abruptly") \
        and "--resume" in lines[-1] and "Traceback" not in stderr, stderr
    kept = sorted(p.name for p in (out / "runs").glob("run-*.json"))
    assert 1 <= len(kept) < int(RUNS) and (out / "manifest.json").is_file(), kept
    assert not list(tmp_path.glob(".gpfverify-partial-*"))  # the staging folder is gone
    _reproduce(name, out, "--resume", "--workers", "1")
    assert _canonical(out) == serial[name]
