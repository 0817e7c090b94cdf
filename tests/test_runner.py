"""Monte Carlo runner: worker-count independence, resume, recorded failures, dask executor."""

import json
import sys
from pathlib import Path

import pytest

from gpfverify.errors import InputError
from gpfverify.experiments.runner import make_executor, run_experiment, without_timing

HERE = Path(__file__).parent


@pytest.fixture()
def toy(monkeypatch):
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setenv("PYTHONPATH", str(HERE))  # for spawned workers
    sys.modules.pop("toy_experiment", None)
    import toy_experiment

    return toy_experiment


def _numbers(results):
    return without_timing(results)


def test_same_results_for_any_worker_count(toy, tmp_path):
    serial = run_experiment(toy, toy.Params(scale=2.0), 6, 11, tmp_path / "a")
    with make_executor(workers=2) as pool:
        parallel = run_experiment(toy, toy.Params(scale=2.0), 6, 11, tmp_path / "b", executor=pool)
    assert _numbers(serial) == _numbers(parallel)
    assert serial["runs_ok"] == 6 and serial["failed_runs"] == []
    other_seed = run_experiment(toy, toy.Params(scale=2.0), 6, 12, tmp_path / "c")
    assert other_seed["mean"] != serial["mean"]


def test_resume_after_lost_runs_ends_with_the_same_results(toy, tmp_path):
    full = run_experiment(toy, toy.Params(scale=2.0), 5, 3, tmp_path / "full")
    out = tmp_path / "partial"
    run_experiment(toy, toy.Params(scale=2.0), 5, 3, out)
    for i in (1, 4):  # as if the process died before these runs were saved
        (out / "runs" / f"run-{i:06d}.json").unlink()
    (out / "results.json").unlink()
    resumed = run_experiment(toy, toy.Params(scale=2.0), 5, 3, out, resume=True)
    assert _numbers(resumed) == _numbers(full)
    assert json.loads((out / "results.json").read_text()) == resumed


def test_existing_runs_need_resume_and_matching_settings(toy, tmp_path):
    run_experiment(toy, toy.Params(scale=2.0), 2, 1, tmp_path)
    with pytest.raises(InputError, match="--resume"):
        run_experiment(toy, toy.Params(scale=2.0), 2, 1, tmp_path)
    with pytest.raises(InputError, match="different settings"):
        run_experiment(toy, toy.Params(scale=2.0).replace(scale=3.0), 2, 1, tmp_path, resume=True)


def test_a_failing_run_is_recorded_with_its_seed_and_counted(toy, tmp_path):
    results = run_experiment(toy, toy.Params(scale=2.0).replace(fail_run=2), 4, 5, tmp_path)
    assert results["runs_ok"] == 3
    assert results["failed_runs"] == [{"index": 2, "error": "RuntimeError: planned failure", "spawn_key": [2]}]
    record = json.loads((tmp_path / "runs" / "run-000002.json").read_text())
    assert record["status"] == "error" and "planned failure" in record["traceback"]


def test_dask_executor_gives_the_same_results(toy, tmp_path):
    distributed = pytest.importorskip("distributed")
    serial = run_experiment(toy, toy.Params(scale=2.0), 4, 9, tmp_path / "serial")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster:
        with make_executor(scheduler=cluster.scheduler_address) as executor:
            remote = run_experiment(toy, toy.Params(scale=2.0), 4, 9, tmp_path / "dask", executor=executor)
    assert _numbers(remote) == _numbers(serial)


def test_serial_run_saves_each_run_as_it_finishes_and_ctrl_c_loses_only_the_current_one(toy, tmp_path, capsys):
    full = run_experiment(toy, toy.Params(scale=2.0), 6, 8, tmp_path / "full")
    out = tmp_path / "interrupted"
    with pytest.raises(KeyboardInterrupt) as interrupted:
        run_experiment(toy, toy.Params(scale=2.0).replace(interrupt_run=3), 6, 8, out)
    saved = sorted(p.name for p in (out / "runs").glob("run-*.json"))
    assert saved == [f"run-{i:06d}.json" for i in range(3)]
    assert interrupted.value.__notes__ == ["3 of 6 runs had finished"]  # the command line's one line ends with it
    assert capsys.readouterr().err == ""
    # the manifest's params differ only by the interruption switch: resume with the plain settings
    manifest = json.loads((out / "manifest.json").read_text())
    manifest["params"] = toy.Params(scale=2.0).to_json()
    (out / "manifest.json").write_text(json.dumps(manifest))
    resumed = run_experiment(toy, toy.Params(scale=2.0), 6, 8, out, resume=True)
    assert _numbers(resumed) == _numbers(full)


def test_interrupting_a_pool_terminates_its_workers():
    import time
    from multiprocessing.connection import wait

    with pytest.raises(KeyboardInterrupt):
        with make_executor(workers=2) as pool:
            pool.submit(time.sleep, 60)
            time.sleep(0.5)
            processes = list(pool._processes.values())
            assert processes and all(p.is_alive() for p in processes)
            raised_at = time.monotonic()
            raise KeyboardInterrupt
    # leaving did not wait for the 60-s task to finish (a graceful shutdown would)
    assert time.monotonic() - raised_at < 30
    # ended: a worker's sentinel (a pipe the process holds until it exits) is ready. Not is_alive():
    # the pool's own thread may reap the process first, and is_alive() then reads True for a process
    # that no longer exists (seen under load: pid gone, sentinel ready, is_alive() True)
    for p in processes:
        assert wait([p.sentinel], timeout=10), f"worker {p.pid} still running 10 s after the interrupt"


@pytest.mark.parametrize("workers", [0, -1, 1.5, True])
def test_worker_count_must_be_at_least_one(workers):
    with pytest.raises(InputError, match="--workers"):
        with make_executor(workers=workers):
            pass


@pytest.mark.parametrize("seed", [-5, 1.5, None])
def test_a_bad_seed_or_run_count_writes_nothing(toy, tmp_path, seed):
    with pytest.raises(InputError, match="--seed"):
        run_experiment(toy, toy.Params(scale=2.0), 2, seed, tmp_path / "out")
    with pytest.raises(InputError, match="--runs"):
        run_experiment(toy, toy.Params(scale=2.0), 0, 1, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_a_corrupted_manifest_is_an_input_error_and_stays_untouched(toy, tmp_path):
    run_experiment(toy, toy.Params(scale=2.0), 2, 1, tmp_path)
    (tmp_path / "manifest.json").write_text("{\"experiment\": ")
    with pytest.raises(InputError, match="manifest.json is not a valid manifest"):
        run_experiment(toy, toy.Params(scale=2.0), 2, 1, tmp_path, resume=True)
    assert (tmp_path / "manifest.json").read_text() == "{\"experiment\": "


def test_results_list_their_timing_keys_at_any_depth():
    from gpfverify.experiments.runner import timing_keys

    class Module:
        TIMING_KEYS = ("wall",)

    body = {"rmse": [1.0], "time_per_run": {"a": 1.0},
            "groups": [{"seconds": 2.0, "rmse": 3.0, "fit_time_per_run": 1.0}], "wall": 0.1}
    assert timing_keys(Module, body) == ["fit_time_per_run", "seconds", "time_per_run", "wall"]
    assert without_timing({**body, "timing_keys": timing_keys(Module, body), "provenance": {}}) == \
        {"rmse": [1.0], "groups": [{"rmse": 3.0}], "timing_keys": timing_keys(Module, body)}


def test_machine_load_is_what_the_runs_met_not_the_load_at_recompute(toy, tmp_path, monkeypatch):
    """Each run records the load average when it ends; results.json gives the median over the
    runs, and a recomputation later (under another load) keeps it. Runs saved without a load give
    an empty (unknown) average, never the load at recompute time."""
    from gpfverify.experiments import runner

    loads = iter([[1.0, 2.0, 3.0], [5.0, 6.0, 7.0], [3.0, 1.0, 2.0]])
    monkeypatch.setattr(runner.os, "getloadavg", lambda: next(loads))
    out = tmp_path / "run"
    results = run_experiment(toy, toy.Params(scale=2.0), 3, 5, out)
    assert results["machine_load"]["load_average"] == [3.0, 2.0, 3.0]
    assert results["machine_load"]["runs_measured"] == 3
    monkeypatch.setattr(runner.os, "getloadavg", lambda: (9.0, 9.0, 9.0))
    assert runner.rewrite_results(out, toy)["machine_load"]["load_average"] == [3.0, 2.0, 3.0]
    for path in (out / "runs").glob("*.json"):
        record = json.loads(path.read_text())
        del record["machine_load"]
        path.write_text(json.dumps(record))
    unknown = runner.rewrite_results(out, toy)["machine_load"]
    assert unknown["load_average"] == [] and unknown["runs_measured"] == 0
