"""Output folders (docs/output-and-errors.md): ``--out ''`` is refused; a folder holding anything
gpfverify did not write is refused before anything runs, and left byte for byte as it was; a
command that fails leaves the folder as it found it; an interrupted run keeps its saved runs for
``--resume``; ``check --out`` writes run files that ``audit`` reads. One test per command."""

from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gpfverify import cli
from gpfverify.experiments import EXPERIMENTS
from gpfverify.fusion.runfile import write_run
from gpfverify.outputs import FILE_LIST
from gpfverify.fusion.synthetic import random_case
from gpfverify.tolerances import algebra_rtol

pytestmark = pytest.mark.slow  # each test runs commands in subprocesses, some killed mid-run

HERE = Path(__file__).parent
LINEAR_SYSTEM = '''
import numpy as np
from gpfverify.models import linear_model
F = np.array([[1.0, 1.0], [0.0, 0.95]])
H = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.5, -1.0]])
Q = np.array([[0.2, 0.05], [0.05, 0.1]])
R = np.diag([0.5, 0.3, 0.4, 0.2])
system = linear_model(F, H, Q, R, prior_mean=[1.0, 0.5], prior_cov=np.eye(2), sizes=(2, 2))
'''


@pytest.fixture
def toy(monkeypatch):
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setitem(EXPERIMENTS, "toy", "toy_experiment")
    sys.modules.pop("toy_experiment", None)


def _main(argv, capsys):
    """(exit status, stdout, stderr) of the command line, usage errors included."""
    try:
        code = cli.main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _run_file(tmp_path: Path) -> Path:
    rng = np.random.default_rng(0)
    return write_run(tmp_path / "RUN.jsonl", [random_case(rng, 2, (2, 2)) for _ in range(3)])


def _system(tmp_path: Path) -> str:
    path = tmp_path / "linear.py"
    path.write_text(LINEAR_SYSTEM)
    return f"{path}:system"


def _commands(tmp_path: Path) -> dict[str, list]:
    """Every command that writes --out, with arguments that make it quick; the folder goes last."""
    return {
        "audit": ["audit", _run_file(tmp_path)],
        "check": ["check", _system(tmp_path), "--steps", "3", "--methods", "cmf,dmf"],
        "reproduce": ["reproduce", "toy", "--runs", "2"],
        "prove": ["prove", "--size", "small", "--only", "full-rank-needs-l-le-D"],
        "report": ["report", "--only", "moments"],
        "props": ["props"],
    }


@pytest.mark.parametrize("command", ["audit", "check", "reproduce", "prove", "report", "props"])
def test_an_empty_out_is_refused_and_the_current_folder_untouched(command, toy, tmp_path, capsys,
                                                                    monkeypatch):
    argv = _commands(tmp_path)[command]
    work = tmp_path / "work"
    (work / "figures").mkdir(parents=True)
    (work / "README.md").write_text("the user's notes")
    (work / "figures" / "x.png").write_bytes(b"user figure")
    before = _snapshot(work)
    monkeypatch.chdir(work)
    code, out, err = _main([*argv, "--out", ""], capsys)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err
    assert "empty" in err
    assert _snapshot(work) == before and sorted(os.listdir(work)) == ["README.md", "figures"]


@pytest.mark.parametrize("command", ["audit", "check", "reproduce", "prove", "report", "props"])
def test_a_folder_with_a_file_gpfverify_did_not_write_is_refused(command, toy, tmp_path, capsys):
    argv = _commands(tmp_path)[command]
    out_dir = tmp_path / "out"
    (out_dir / "figures").mkdir(parents=True)
    (out_dir / "figures" / "x.png").write_bytes(b"user figure")
    before = _snapshot(out_dir)
    code, out, err = _main([*argv, "--out", out_dir], capsys)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err
    assert "figures/x.png" in err and "did not write" in err
    assert _snapshot(out_dir) == before
    assert sorted(os.listdir(tmp_path)) == sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith("."))


def test_audit_rewrites_its_own_folder_and_lists_every_file(tmp_path, capsys):
    run, out_dir = _run_file(tmp_path), tmp_path / "out"
    assert _main(["audit", run, "--out", out_dir], capsys)[0] == 0
    listed = set((out_dir / FILE_LIST).read_text().split())
    assert listed == set(_snapshot(out_dir))
    assert {"audit.json", "README.md", "report.html"} <= listed
    assert _main(["audit", run, "--out", out_dir], capsys)[0] == 0  # its own files: rewritten
    (out_dir / "figures" / "mine.png").write_bytes(b"user figure")  # now a foreign file
    code, _, err = _main(["audit", run, "--out", out_dir], capsys)
    assert code == 2 and "figures/mine.png" in err
    assert (out_dir / "figures" / "mine.png").read_bytes() == b"user figure"


def test_prove_writes_into_an_empty_folder_and_leaves_no_staging_folder(tmp_path, capsys):
    out_dir = tmp_path / "certs"
    out_dir.mkdir()
    code, _, _ = _main(["prove", "--size", "small", "--only", "full-rank-needs-l-le-D", "--out", out_dir], capsys)
    assert code == 0
    assert {"certificates.json", "README.md", FILE_LIST} == set(os.listdir(out_dir))
    assert os.listdir(tmp_path) == ["certs"]


def test_reproduce_that_fails_leaves_the_folder_as_it_found_it(toy, tmp_path, capsys):
    out_dir = tmp_path / "out"
    code, _, err = _main(["reproduce", "toy", "--runs", "1", "--fail-run", "0", "--out", out_dir], capsys)
    assert code == 2 and "every run of toy failed" in err
    assert os.listdir(tmp_path) == []  # no manifest.json, no runs/, no staging folder
    out_dir.mkdir()
    assert _main(["reproduce", "toy", "--runs", "1", "--fail-run", "0", "--out", out_dir], capsys)[0] == 2
    assert os.listdir(out_dir) == [] and os.listdir(tmp_path) == ["out"]


def test_an_interrupted_reproduce_keeps_its_saved_runs_for_resume(toy, tmp_path, capsys):
    out_dir = tmp_path / "out"
    argv = ["reproduce", "toy", "--runs", "3", "--interrupt-run", "2", "--out", out_dir]
    code, _, err = _main(argv, capsys)
    assert code == 130 and "interrupted" in err
    saved = {"manifest.json", "runs/run-000000.json", "runs/run-000001.json"}
    assert set(_snapshot(out_dir)) == saved | {FILE_LIST}
    assert set((out_dir / FILE_LIST).read_text().split()) == saved | {FILE_LIST}
    assert _main([*argv, "--resume"], capsys)[0] == 130  # accepted as gpfverify's own, interrupted again
    assert os.listdir(tmp_path) == ["out"]


def test_a_resumed_reproduce_adds_to_its_own_runs(toy, tmp_path, capsys):
    out_dir = tmp_path / "out"
    assert _main(["reproduce", "toy", "--runs", "2", "--out", out_dir], capsys)[0] == 0
    first = json.loads((out_dir / "runs" / "run-000000.json").read_text())
    assert _main(["reproduce", "toy", "--runs", "2", "--out", out_dir], capsys)[0] == 2  # no --resume
    assert _main(["reproduce", "toy", "--runs", "2", "--out", out_dir, "--resume"], capsys)[0] == 0
    assert json.loads((out_dir / "runs" / "run-000000.json").read_text()) == first


@pytest.mark.parametrize("runs", [1, 2])
def test_check_writes_run_files_that_audit_reads(tmp_path, capsys, runs):
    out_dir = tmp_path / "out"
    code, _, err = _main(["check", _system(tmp_path), "--steps", "4", "--runs", runs, "--methods", "cmf,dmf",
                          "--out", out_dir], capsys)
    assert code == 0, err
    results = json.loads((out_dir / "results.json").read_text())
    names = ["run.jsonl"] if runs == 1 else [f"run-{i:03d}.jsonl" for i in range(runs)]
    assert sorted(p.name for p in out_dir.glob("run*.jsonl")) == names
    for i, name in enumerate(names):
        code, out, err = _main(["audit", out_dir / name, "--json", "--rank-rule", "canonical"], capsys)
        assert code == 0, err
        audit = json.loads(out)
        assert [s["k"] for s in audit["steps"]] == results["k"]
        check_gaps = np.array(results["gap_norm"][i])
        audit_gaps = np.array([np.linalg.norm(s["gap"]) for s in audit["steps"]])
        scale = max(1.0, float(np.abs(check_gaps).max()))
        np.testing.assert_allclose(audit_gaps, check_gaps, rtol=0, atol=algebra_rtol() * scale)
        # the same rank decisions and exactness per sensor and step as the check recorded
        assert [[x["rank"] for x in s["sensors"]] for s in audit["steps"]] == results["rank"][i]
        assert [[x["exact"] for x in s["sensors"]] for s in audit["steps"]] == results["exact"][i]


def test_resume_adopts_the_runs_of_a_killed_command(toy, tmp_path, capsys):
    done = tmp_path / "done"
    assert _main(["reproduce", "toy", "--runs", "2", "--out", done], capsys)[0] == 0
    child = subprocess.Popen(["true"])
    child.wait()  # its process id is now free: the "killed" command
    orphan = tmp_path / f".gpfverify-partial-out-{child.pid}"
    (orphan / "runs").mkdir(parents=True)
    for name in ("manifest.json", "runs/run-000000.json"):
        (orphan / name).write_bytes((done / name).read_bytes())
    out_dir = tmp_path / "out"
    assert _main(["reproduce", "toy", "--runs", "2", "--out", out_dir], capsys)[0] == 2  # not without --resume
    assert orphan.is_dir() and not out_dir.exists()
    assert _main(["reproduce", "toy", "--runs", "2", "--out", out_dir, "--resume"], capsys)[0] == 0
    # run 0 is the killed command's file (its own timing), run 1 was computed now
    assert (out_dir / "runs" / "run-000000.json").read_bytes() == (done / "runs" / "run-000000.json").read_bytes()
    assert not orphan.exists()


# ---- a full disk, a failing system, a damaged folder: nothing half-written ----------------------

def _enospc(*_args, **_kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def _fails_after_a_partial_write(original, name):
    """``original(path, ...)`` that, for a file called ``name``, leaves a partial file then fails as
    on a full disk."""
    def write(self_or_path, *args, **kwargs):
        path = Path(self_or_path)
        if path.name == name or path.name.startswith(name + ".tmp"):
            Path(str(path) + f".tmp{os.getpid()}").write_bytes(b"")
            path.write_bytes(b"")
            _enospc()
        return original(self_or_path, *args, **kwargs)
    return write


def _assert_full_disk(code, err, tmp_path, kept):
    last = err.strip().splitlines()[-1]  # after any progress lines
    assert code == 2 and "error: No space left on device" in last and "Traceback" not in err, err
    assert sorted(os.listdir(tmp_path)) == sorted(kept)  # no staging folder, no partial file


def test_reproduce_on_a_full_disk_leaves_no_partial_file(toy, tmp_path, capsys, monkeypatch):
    from gpfverify.experiments import runner

    monkeypatch.setattr(runner, "_atomic_write_json",
                        _fails_after_a_partial_write(runner._atomic_write_json, "results.json"))
    code, _, err = _main(["reproduce", "toy", "--runs", "2", "--out", tmp_path / "out"], capsys)
    _assert_full_disk(code, err, tmp_path, [])


def test_prove_on_a_full_disk_leaves_no_empty_readme(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(Path, "write_text", _fails_after_a_partial_write(Path.write_text, "README.md"))
    code, _, err = _main(["prove", "--size", "small", "--only", "full-rank-needs-l-le-D", "--out",
                          tmp_path / "out"], capsys)
    _assert_full_disk(code, err, tmp_path, [])


def test_audit_on_a_full_disk_leaves_no_empty_folder(tmp_path, capsys, monkeypatch):
    from gpfverify.report import equivalence

    run = _run_file(tmp_path)
    monkeypatch.setattr(equivalence, "to_html", _enospc)
    code, _, err = _main(["audit", run, "--out", tmp_path / "out"], capsys)
    _assert_full_disk(code, err, tmp_path, [run.name])


def test_check_on_a_full_disk_keeps_the_folder_it_found(tmp_path, capsys, monkeypatch):
    from gpfverify.report import equivalence

    system, out_dir = _system(tmp_path), tmp_path / "out"
    argv = ["check", system, "--steps", "3", "--methods", "cmf,dmf", "--out", out_dir]
    assert _main(argv, capsys)[0] == 0
    before = _snapshot(out_dir)
    monkeypatch.setattr(equivalence, "to_html", _enospc)  # results.json written, its report not
    code, _, err = _main([*argv, "--runs", "2", "--resume"], capsys)
    assert code == 2 and "No space left on device" in err
    assert _snapshot(out_dir) == before
    assert sorted(os.listdir(tmp_path)) == ["linear.py", "out"]


RAISING_SYSTEM = '''
import numpy as np
from gpfverify.models import Sensor, StateSpaceModel
calls = [0]
def broken(x):
    calls[0] += 1
    if calls[0] > 4:
        raise RuntimeError("the sensor model broke")
    return x[:, :1]
system = StateSpaceModel(transition=np.eye(2), process_cov=0.1 * np.eye(2),
                         sensors=[Sensor(np.eye(2), np.eye(2)), Sensor(broken, [[1.0]])],
                         prior_mean=[0.0, 0.0], prior_cov=np.eye(2))
'''


def test_a_measurement_function_raising_mid_run_leaves_nothing(tmp_path, capsys):
    (tmp_path / "raising.py").write_text(RAISING_SYSTEM)
    code, out, err = _main(["check", f"{tmp_path / 'raising.py'}:system", "--steps", "5", "--methods", "cmf,dmf",
                            "--out", tmp_path / "out"], capsys)
    assert code == 2 and "the sensor model broke" in err and len(err.strip().splitlines()) == 1, err
    assert sorted(os.listdir(tmp_path)) == ["raising.py"]  # no manifest.json, no runs/


def test_resume_with_a_damaged_manifest_refuses_and_changes_nothing(toy, tmp_path, capsys):
    out_dir = tmp_path / "out"
    assert _main(["reproduce", "toy", "--runs", "2", "--out", out_dir], capsys)[0] == 0
    (out_dir / "manifest.json").write_text('{"experiment": "toy", "se')
    (out_dir / "runs" / "run-000001.json").unlink()
    before = _snapshot(out_dir)
    code, _, err = _main(["reproduce", "toy", "--runs", "2", "--out", out_dir, "--resume"], capsys)
    assert code == 2 and "manifest" in err
    assert _snapshot(out_dir) == before


@pytest.mark.parametrize("damage", ['{"status": "ok"}', "[1, 2]", '{"index": 1, "status": "error"}', "{"])
def test_resume_runs_a_damaged_saved_run_again(toy, tmp_path, capsys, damage):
    out_dir = tmp_path / "out"
    assert _main(["reproduce", "toy", "--runs", "2", "--out", out_dir], capsys)[0] == 0
    first = json.loads((out_dir / "results.json").read_text())
    (out_dir / "runs" / "run-000001.json").write_text(damage)
    assert _main(["reproduce", "toy", "--runs", "2", "--out", out_dir, "--resume"], capsys)[0] == 0
    again = json.loads((out_dir / "results.json").read_text())
    assert again["mean"] == first["mean"] and again["runs_ok"] == 2


def test_props_refusing_its_arguments_writes_nothing_anywhere(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    proc = subprocess.run([sys.executable, "-m", "gpfverify", "props", "--out", "o", "-k", "bad("],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and proc.stdout == "" and len(proc.stderr.strip().splitlines()) == 1
    assert os.listdir(tmp_path) == []  # no .hypothesis/, no o/


# ---- the user's system file cannot end gpfverify or print into its output -------------------------

EXITING_SYSTEM = '''
import os, sys
import numpy as np
from gpfverify.models import Sensor, StateSpaceModel
calls = [0]
{at_import}
def h(x):
    calls[0] += 1
    if calls[0] > {after}:
        {in_measurement}
    return x[:, :1]
system = StateSpaceModel(transition=np.eye(2), process_cov=0.1 * np.eye(2),
                         sensors=[Sensor(np.eye(2), np.eye(2)), Sensor(h, [[1.0]])],
                         prior_mean=[0.0, 0.0], prior_cov=np.eye(2))
'''


def _check_system(tmp_path, *extra, **parts):
    parts = {"at_import": "", "in_measurement": "pass", "after": 0, **parts}
    (tmp_path / "system.py").write_text(EXITING_SYSTEM.format(**parts))
    return subprocess.run([sys.executable, "-m", "gpfverify", "check", "system.py:system", "--steps", "4",
                           "--methods", "cmf,dmf", "--json", "--out", "out", *extra],
                          capture_output=True, text=True, cwd=tmp_path, timeout=120)


@pytest.mark.parametrize("call", ["sys.exit(0)", "os._exit(0)", "sys.exit(3)", "exit()"])
@pytest.mark.parametrize("where", ["at_import", "in_measurement"])
def test_an_exit_in_the_system_file_is_an_error_of_that_file(tmp_path, call, where):
    # in_measurement: after a few calls, i.e. while the runs are under way
    proc = _check_system(tmp_path, **{where: call, "after": 6})
    assert proc.returncode == 2 and proc.stdout == "", proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "the system file system.py called" in lines[0] and "exit(" in lines[0], lines
    assert sorted(os.listdir(tmp_path)) == ["system.py"]  # no manifest.json, no runs/


def test_an_exit_in_a_worker_process_is_an_error_of_the_system_file(tmp_path):
    proc = _check_system(tmp_path, "--workers", "2", "--runs", "2", in_measurement="os._exit(0)", after=6)
    assert proc.returncode == 2 and proc.stdout == ""
    assert "the system file system.py called os._exit(0)" in proc.stderr.strip().splitlines()[-1]
    assert sorted(os.listdir(tmp_path)) == ["system.py"]


@pytest.mark.parametrize("workers", ["1", "2"])
def test_print_in_the_system_file_goes_to_stderr(tmp_path, workers):
    proc = _check_system(tmp_path, "--workers", workers, at_import="print('loading my system')",
                         in_measurement="print('measuring')")
    assert proc.returncode == 0, proc.stderr
    results = json.loads(proc.stdout)  # stdout is the results and nothing else
    assert results["experiment"] == "check"
    assert "loading my system" in proc.stderr and "measuring" in proc.stderr


# ---- signals: a second Ctrl-C, a killed worker ---------------------------------------------------

SLOW_SYSTEM = '''
import time
import numpy as np
from gpfverify.models import Sensor, StateSpaceModel
def h(x):
    time.sleep(0.05)
    return x[:, :1]
system = StateSpaceModel(transition=np.eye(2), process_cov=0.1 * np.eye(2),
                         sensors=[Sensor(np.eye(2), np.eye(2)), Sensor(h, [[1.0]])],
                         prior_mean=[0.0, 0.0], prior_cov=np.eye(2))
'''


def _slow_check(tmp_path):
    """A check with two workers whose runs take seconds, started in its own process; returns once a
    worker is running."""
    (tmp_path / "slow.py").write_text(SLOW_SYSTEM)
    proc = subprocess.Popen([sys.executable, "-m", "gpfverify", "check", "slow.py:system", "--steps", "400",
                             "--runs", "4", "--workers", "2", "--methods", "cmf,dmf", "--out", "out"],
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    import time

    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and len(_workers(proc.pid)) < 2:
        time.sleep(0.1)
    time.sleep(1.0)  # the workers are inside their first runs
    return proc


def _workers(pid: int) -> list[int]:
    try:
        children = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
    except OSError:
        return []
    return [int(c) for c in children if "spawn_main" in Path(f"/proc/{c}/cmdline").read_text(errors="replace")]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_second_ctrl_c_prints_no_traceback(tmp_path):
    import signal
    import time

    proc = _slow_check(tmp_path)
    proc.send_signal(signal.SIGINT)
    time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and err.strip().splitlines()[-1] == "gpfverify check: interrupted", err


def test_from_the_first_interrupt_on_further_ones_are_ignored():
    """The command line's handler: the first SIGINT or SIGTERM raises KeyboardInterrupt and makes
    both signals ignored, so a second one arriving during the clean-up (stopping the workers, moving
    the saved runs into --out) cannot cut it short; a test of the handler itself, because a real
    second Ctrl-C lands in that window only now and then."""
    import signal

    from gpfverify import cli

    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        signal.signal(signal.SIGINT, cli._interrupt)
        signal.signal(signal.SIGTERM, cli._interrupt)
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)  # the handler runs as os.kill returns
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
        assert signal.getsignal(signal.SIGTERM) is signal.SIG_IGN
        os.kill(os.getpid(), signal.SIGINT)  # ignored: nothing raised
        os.kill(os.getpid(), signal.SIGTERM)
    finally:
        for number, handler in saved.items():
            signal.signal(number, handler)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_killed_worker_is_one_line_and_no_leaked_semaphore_warning(tmp_path):
    import signal

    proc = _slow_check(tmp_path)
    os.kill(_workers(proc.pid)[0], signal.SIGKILL)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 2 and out == "", err
    assert err.strip().splitlines() == ["gpfverify check: error: a worker process ended abruptly (killed by a "
                                        "signal or out of memory); no run had finished, nothing was written to "
                                        "--out: run the command again"], err
    assert sorted(os.listdir(tmp_path)) == ["slow.py"]
