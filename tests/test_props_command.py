"""``gpfverify props``: summary.json on a small suite with one holding and one failing property
(the failing one saves its shrunk counterexample as a case file), and the CLI error contract."""

import json
import os
import subprocess
import sys
import textwrap

import pytest

pytestmark = pytest.mark.slow  # runs the property suite in-process

SUITE = textwrap.dedent('''
    from hypothesis import given
    from gpfverify.strategies import fusion_cases, saving_case_on_failure


    @given(drawn=fusion_cases(state_dim=1, sensors=1, kinds="full"))
    def test_holds(drawn):
        assert drawn.case.state_dim == 1


    @given(drawn=fusion_cases(state_dim=1, sensors=1, kinds="full"))
    def test_fails(drawn):
        with saving_case_on_failure(drawn.case, "one-sensor"):
            assert len(drawn.case.locals) == 2
''')


def _props(*args, timeout=300):
    return subprocess.run([sys.executable, "-m", "gpfverify", "props", *args], capture_output=True,
                          text=True, timeout=timeout)


@pytest.fixture(scope="module")
def failing_run(tmp_path_factory):
    suite = tmp_path_factory.mktemp("suite")
    (suite / "test_toy_props.py").write_text(SUITE)
    out = tmp_path_factory.mktemp("out")
    proc = _props("--profile", "ci", "--out", str(out), "--suite", str(suite))
    return proc, json.loads((out / "summary.json").read_text()), out


def test_summary_lists_properties_examples_and_failures(failing_run):
    proc, summary, out = failing_run
    assert proc.returncode == 1
    assert summary["profile"] == "ci" and summary["passed"] is False
    by_name = {p["name"].split("::")[-1]: p for p in summary["properties"]}
    assert by_name["test_holds"]["outcome"] == "passed"
    assert by_name["test_holds"]["examples"] >= 60  # the ci profile's count, all phases
    failed = by_name["test_fails"]
    assert failed["outcome"] == "failed" and "assert" in failed["failure"]
    assert summary["totals"] == {"properties": 2, "passed": 1, "failed": 1,
                                 "examples": by_name["test_holds"]["examples"] + (failed["examples"] or 0)}


def test_failing_fusion_property_leaves_a_case_file_the_audit_reads(failing_run):
    _, summary, out = failing_run
    failed = next(p for p in summary["properties"] if p["name"].endswith("test_fails"))
    path = out / "counterexamples" / "one-sensor.json"
    assert failed["counterexample_files"] == [str(path.resolve())]
    proc = subprocess.run([sys.executable, "-m", "gpfverify", "audit", str(path), "--json"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and len(json.loads(proc.stdout)["sensors"]) == 1


@pytest.mark.parametrize("args", [["--out", "x", "--suite", "/nonexistent/suite"],
                                  ["--profile", "nope", "--out", "x"], []])
def test_usage_errors_exit_2_with_one_line(args, tmp_path):
    proc = _props(*[a if a != "x" else str(tmp_path / "o") for a in args], timeout=60)
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr


def test_a_suite_that_cannot_be_imported_says_why(tmp_path):
    """The cause (the module's import error), not pytest's ``==== ERRORS ====`` banner."""
    suite = tmp_path / "suite"
    suite.mkdir()
    (suite / "test_broken.py").write_text("import no_such_module_of_yours\n\ndef test_x():\n    pass\n")
    proc = _props("--suite", str(suite), "--out", str(tmp_path / "o"), timeout=120)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.splitlines() == [
        "gpfverify props: error: the property suite could not run (pytest exit status 2): suite/test_broken.py: "
        "ModuleNotFoundError: No module named 'no_such_module_of_yours'"], proc.stderr
    assert sorted(os.listdir(tmp_path)) == ["suite"]
