"""CONTRACT.md, "Provenance": the record's shape, and that results.json, manifest.json and every
report page carry it with the command that produced them."""

import json
import re
import subprocess
import sys
import tomllib
from datetime import datetime, timezone
from pathlib import Path

import pytest

import gpfverify
from gpfverify import cli, provenance
from gpfverify.papers import EXPERIMENTS
from gpfverify.report.document import Paragraph, Section
from gpfverify.report.render import write_report

HERE = Path(__file__).parent
ROOT = HERE.parent
KEYS = {"gpfverify", "git_commit", "python", "packages", "platform", "created", "command"}


def check_record(record: dict, command: list[str]) -> None:
    assert set(record) == KEYS
    assert record["gpfverify"] == gpfverify.__version__
    assert record["git_commit"] is None or re.fullmatch(r"[0-9a-f]{40}(\+dirty)?", record["git_commit"])
    assert record["python"] == ".".join(map(str, sys.version_info[:3]))
    assert {"numpy", "scipy", "cvxpy"} <= set(record["packages"])
    assert all(isinstance(v, str) for v in record["packages"].values())
    assert isinstance(record["platform"], str) and record["platform"]
    created = datetime.fromisoformat(record["created"].replace("Z", "+00:00"))
    assert created.utcoffset().total_seconds() == 0
    assert abs((datetime.now(timezone.utc) - created).total_seconds()) < 600
    assert record["command"] == command


def test_record_shape_and_command():
    record = provenance.provenance(["prove", "--out", "DIR"])
    check_record(record, ["gpfverify", "prove", "--out", "DIR"])
    json.dumps(record)  # JSON-able


def test_git_commit_in_a_checkout():
    if not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    provenance.git_commit.cache_clear()  # cached per process; HEAD may have moved since
    recorded = provenance.git_commit()
    head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True,
                          text=True).stdout.strip()
    assert recorded.split("+")[0] == head


def test_results_and_manifest_carry_provenance(monkeypatch, tmp_path):
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setitem(EXPERIMENTS, "toy", "toy_experiment")
    args = ["reproduce", "toy", "--runs", "2", "--seed", "3", "--out", str(tmp_path)]
    assert cli.main(args) == 0
    results = json.loads((tmp_path / "results.json").read_text())
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    check_record(results["provenance"], ["gpfverify", *args])
    check_record(manifest["provenance"], ["gpfverify", *args])
    assert results["timing_keys"] == ["machine_load", "time_per_run", "timing_claims"]
    resumed = [*args, "--resume"]  # resuming records the command that finished the run
    assert cli.main(resumed) == 0
    check_record(json.loads((tmp_path / "results.json").read_text())["provenance"], ["gpfverify", *resumed])


def test_every_report_page_and_the_index_carry_provenance(tmp_path):
    record = provenance.provenance(["report", "--only", "a"])
    write_report([Section("a", "Page A").add(Paragraph("x")), Section("b", "Page B")], tmp_path,
                 "T", "pre", order=["a", "b"], provenance=record)
    for page in (tmp_path / "a" / "README.md", tmp_path / "b" / "README.md", tmp_path / "README.md"):
        text = page.read_text()
        assert "What produced this page" in text and record["created"] in text
        assert "gpfverify report --only a" in text and record["packages"]["numpy"] in text
    html = (tmp_path / "report.html").read_text()
    assert html.count("What produced this page") == 3 and record["created"] in html


def test_property_testing_is_a_runtime_dependency():
    """props and gpfverify.strategies need hypothesis (and props pytest) after a plain install."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    names = {re.split(r"[<>=!~\[ ]", d, maxsplit=1)[0].lower() for d in project["dependencies"]}
    assert {"hypothesis", "pytest"} <= names
    import gpfverify.strategies  # noqa: F401


def test_the_run_audit_report_carries_provenance(tmp_path, capsys):
    import numpy as np

    from gpfverify.fusion.case import case_to_dict
    from gpfverify.fusion.synthetic import random_case

    case = case_to_dict(random_case(np.random.default_rng(0), 2, (1, 2)))
    run = tmp_path / "run.jsonl"
    run.write_text("".join(json.dumps({**case, "k": k}) + "\n" for k in range(2)))
    args = ["audit", str(run), "--out", str(tmp_path / "report")]
    assert cli.main(args) == 0
    for page in ("README.md", "report.html"):
        text = (tmp_path / "report" / page).read_text()
        assert "What produced this page" in text and " ".join(["gpfverify", *args]) in text


def test_certificates_and_the_props_summary_carry_provenance(tmp_path):
    args = ["prove", "--out", str(tmp_path / "proofs"), "--size", "small", "--only", "full-rank-needs-l-le-D",
            "--no-casadi"]
    assert cli.main(args) == 0
    records = json.loads((tmp_path / "proofs" / "certificates.json").read_text())
    assert records  # a list, as the contract says: every certificate carries the provenance
    for record in records:
        check_record(record["provenance"], ["gpfverify", *args])
    suite = tmp_path / "suite"
    suite.mkdir()
    (suite / "test_one.py").write_text("from hypothesis import given, strategies as st\n\n"
                                       "@given(st.integers())\ndef test_holds(n):\n    assert n == n\n")
    out = tmp_path / "props"
    command = ["props", "--profile", "dev", "--out", str(out), "--suite", str(suite)]
    proc = subprocess.run([sys.executable, "-m", "gpfverify", *command], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    check_record(json.loads((out / "summary.json").read_text())["provenance"], ["gpfverify", *command])
