"""Interrupts (docs/output-and-errors.md, "Signals"), driven as a terminal sends them: Ctrl-C is
SIGINT to the whole process group. A timed sweep interrupts a command at random moments over its
whole life: exit status 130 with one line, never 0, never a traceback, and ``--out`` complete or as
it was. Then ``props`` interrupted, ``audit --workers 2`` interrupted (no "leaked semaphore"
lines), and a command stuck where no signal handler runs, which SIGTERM still stops."""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from gpfverify.audit.runfile import write_run
from gpfverify.fusion.synthetic import random_case
from gpfverify.outputs import foreign_entry
from gpfverify.supervise import STOP_SECONDS

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))  # the suite imports in importlib mode: the helper beside it
from processes import state, sweep_trials  # noqa: E402
from system_files import LINEAR_SYSTEM  # noqa: E402

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not sys.platform.startswith("linux"), reason="process groups and /proc")]

#: trials of the sweep (GPFVERIFY_SWEEP_TRIALS for more)
TRIALS = sweep_trials(8)
#: the first moment a trial may interrupt: before it, Python itself is starting, and a Ctrl-C there
#: is Python's (gpfverify's code has not run yet)
EARLIEST = 0.15


def _start(args, cwd: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "gpfverify", *args], cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)


def _ctrl_c_at(proc: subprocess.Popen, delay: float) -> bool:
    """Ctrl-C (SIGINT to the process group) ``delay`` seconds after the start; whether it was sent
    while gpfverify was still running."""
    deadline = time.monotonic() + delay
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            return False
        time.sleep(0.001)
    if state(proc.pid) in (None, "Z"):
        return False
    os.killpg(proc.pid, signal.SIGINT)
    return True


def test_ctrl_c_at_any_moment_is_130_and_one_line_never_0(tmp_path):
    (tmp_path / "system.py").write_text(LINEAR_SYSTEM)
    args = ["check", "system.py:system", "--steps", "3", "--methods", "cmf,dmf", "--json", "--out", "out"]
    started = time.monotonic()
    calibration = subprocess.run([sys.executable, "-m", "gpfverify", *args[:-1], "calibration"], cwd=tmp_path,
                                 capture_output=True, text=True, timeout=300)
    assert calibration.returncode == 0, calibration.stderr
    life = time.monotonic() - started
    rng = random.Random(0)
    interrupted = []
    for trial in range(TRIALS):
        folder = tmp_path / f"trial-{trial}"
        folder.mkdir()
        (folder / "system.py").write_text(LINEAR_SYSTEM)
        delay = EARLIEST + rng.uniform(0.0, 1.1 * life)  # the late ones land as the command ends
        proc = _start(args, folder)
        sent = _ctrl_c_at(proc, delay)
        out, err = proc.communicate(timeout=300)
        lines = err.splitlines()
        assert "Traceback" not in err and "Exception ignored" not in err, (trial, err)
        if not sent:
            assert proc.returncode == 0, (trial, err)
            continue
        interrupted.append(round(delay, 2))
        assert proc.returncode == 130, (trial, delay, proc.returncode, err)
        result = folder / "out"
        assert sorted(p.name for p in folder.iterdir() if p.name.startswith(".gpfverify-")) == [], trial
        if lines and lines[-1].endswith("interrupted as it ended; the command had completed and its output is "
                                        "complete"):
            # before the interrupt the completed command printed its note, as it does
            assert lines[:-1] in ([], ["gpfverify check: the report page: out/report.html"]), (trial, err)
            assert foreign_entry(result) is None and json.loads((result / "results.json").read_text())
        else:
            assert len(lines) == 1 and lines[0].startswith("gpfverify check: interrupted"), (trial, err)
            assert not result.exists() or foreign_entry(result) is None, (trial, os.listdir(result))
    print(f"{len(interrupted)} of {TRIALS} trials interrupted while running, at {interrupted} s "
          f"(a run takes {life:.2f} s)")


def test_interrupted_props_is_130(tmp_path):
    suite = tmp_path / "suite"
    suite.mkdir()
    (suite / "test_slow.py").write_text("import time\ndef test_slow():\n    open('started', 'w').close()\n"
                                        "    time.sleep(120)\n")
    proc = _start(["props", "--suite", str(suite), "--out", "out"], tmp_path)
    deadline = time.monotonic() + 120
    while not (tmp_path / "started").exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGINT)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 130 and out == "", err
    assert err.splitlines() == [f"gpfverify props: interrupted; nothing was written to {tmp_path / 'out'}"], err
    assert sorted(os.listdir(tmp_path)) == ["started", "suite"]


def test_interrupted_audit_with_two_workers_is_one_line_without_leaked_semaphores(tmp_path):
    rng = np.random.default_rng(0)
    write_run(tmp_path / "RUN.jsonl", [random_case(rng, 4, (2, 2, 2)) for _ in range(8000)])
    for trial in range(2):
        proc = _start(["audit", "RUN.jsonl", "--workers", "2", "--out", "out"], tmp_path)
        time.sleep(2.0 + trial)  # the workers are auditing blocks
        os.killpg(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=120)
        assert proc.returncode == 130, err
        assert err.splitlines() == [f"gpfverify audit: interrupted; nothing was written to {tmp_path / 'out'}"], err
        assert sorted(os.listdir(tmp_path)) == ["RUN.jsonl"]


#: a measurement function that blocks SIGINT and SIGTERM and never returns: like compiled code,
#: no Python signal handler runs in its process
STUCK = '''
import signal, time
import numpy as np
from gpfverify.models import Sensor, StateSpaceModel
calls = [0]
def h(x):
    calls[0] += 1
    if calls[0] > 8:
        open("stuck", "w").close()
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
        while True:
            time.sleep(1)
    return x[:, :1]
system = StateSpaceModel(transition=np.eye(2), process_cov=0.1 * np.eye(2),
                         sensors=[Sensor(np.eye(2), np.eye(2)), Sensor(h, [[1.0]])],
                         prior_mean=[0.0, 0.0], prior_cov=np.eye(2))
'''


def test_a_command_stuck_where_no_handler_runs_still_obeys_sigterm(tmp_path):
    (tmp_path / "stuck.py").write_text(STUCK)
    proc = subprocess.Popen([sys.executable, "-m", "gpfverify", "check", "stuck.py:system", "--steps", "5",
                             "--out", "out"], cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not (tmp_path / "stuck").exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    sent = time.monotonic()
    proc.send_signal(signal.SIGTERM)  # kill PID: gpfverify's own process passes it on (Ctrl-C is the same path)
    out, err = proc.communicate(timeout=STOP_SECONDS + 60)
    assert time.monotonic() - sent < STOP_SECONDS + 30
    assert proc.returncode == 130 and out == "", err
    assert err.splitlines() == [
        f"gpfverify check: interrupted; the process running the command did not stop within {STOP_SECONDS:.0f} s "
        f"(stuck where no signal reaches it, such as compiled code) and was killed; nothing was written to "
        f"{tmp_path / 'out'}"], err
    assert sorted(os.listdir(tmp_path)) == ["stuck", "stuck.py"]


@pytest.mark.parametrize("code, noted", [(0, True), (2, False)])
def test_a_finished_command_leaves_a_lingering_thread_with_a_note_only_when_it_succeeded(monkeypatch, capsys,
                                                                                       code, noted):
    """supervise.finish: threads that are not daemons get the grace period, then the process ends
    without them with the command's own status; a success says so on stderr (a failure has already said
    its one line)."""
    import threading

    from gpfverify import supervise

    exits: list[int] = []
    monkeypatch.setattr(supervise, "THREAD_GRACE_SECONDS", 0.0)
    monkeypatch.setattr(supervise, "HARD_EXIT", exits.append)
    release = threading.Event()
    lingering = threading.Thread(target=release.wait, name="lingering-writer")
    lingering.start()
    try:
        supervise.finish("audit", code)
    finally:
        release.set()
        lingering.join()
    assert exits == [code]
    err = capsys.readouterr().err
    assert ("not waiting for 1 thread(s) still running (lingering-writer)" in err) == noted, err
