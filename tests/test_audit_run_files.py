"""Run files (.jsonl, .npz) for ``gpfverify audit``: the run audit equals the single-case audit
step by step, both layouts agree, k round-trips, the schemas in docs/schemas/ are the ones the
reader validates against, and every malformed run file exits 2 with one line naming the line or
array, writing nothing. An audit never imports cvxpy."""

import dataclasses
import io
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))  # the suite imports in importlib mode: the helper beside it
from audit_routes import assert_same_audit  # noqa: E402

from gpfverify.audit.case import audit_case, audit_to_dict
from gpfverify.cli import main
from gpfverify.commands.audit import audit_run_file
from gpfverify.model_fusion import run_fusion
from gpfverify.errors import CaseFileError
from gpfverify.fusion.case import case_to_dict
from gpfverify.fusion.caseblock import case_from_dict
from gpfverify.audit.runfile import CASE_SCHEMA, RUN_LINE_SCHEMA, load_run, write_run
from gpfverify.fusion.synthetic import random_case
from gpfverify.scenarios.three_sensor import three_sensor_model

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def three_sensor_run():
    """(ks, cases) of a short three-sensor DMF run whose bearing crosses ±π (k ≈ 10)."""
    model = three_sensor_model()
    _, ys = model.simulate(14, np.random.default_rng(3))
    run = run_fusion(model, ys, methods=("cmf", "dmf"), audit=False)
    return [s.k for s in run.steps], [s.dmf.case for s in run.steps]


def _synthetic_cases():
    """Rank loss not exact / rank loss but exact / full rank / no y; sizes (2, 2), D = 2."""
    rng = np.random.default_rng(0)
    return [random_case(rng, 2, (2, 2), ranks=(1, 2)), random_case(rng, 2, (2, 2), ranks=(1, 2), decoupled=(1,)),
            random_case(rng, 2, (2, 2)), random_case(rng, 2, (2, 2), ranks=(2, 1), with_y=False)]


def _expected(case, k):
    return json.loads(json.dumps({"k": k, **audit_to_dict(audit_case(case))}))


def _cli(argv, capsys):
    try:
        code = main(argv)
    except SystemExit as exc:  # usage errors found by the parser (a malformed --rank-rule)
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def test_cli_run_audit_equals_single_case_audit_step_by_step(tmp_path, three_sensor_run):
    ks, cases = three_sensor_run
    path = write_run(tmp_path / "run.jsonl", cases, ks)
    proc = subprocess.run([sys.executable, "-m", "gpfverify", "audit", str(path), "--json"],
                          capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 0 and proc.stderr == ""
    data = json.loads(proc.stdout)
    assert len(data["steps"]) == len(cases)
    for k, case, step in zip(ks, cases, data["steps"]):
        assert_same_audit(_expected(case, k), step, case)
    summary = data["summary"]
    assert summary["steps"] == len(cases) and summary["condition_held_steps"] == summary["exact_steps"] == len(cases)
    gaps = [s["gap_norm"] for s in data["steps"]]
    assert summary["max_gap_norm"] == max(gaps) and summary["max_gap_k"] == ks[int(np.argmax(gaps))]
    assert data["rank_rule"] == summary["rank_rule"] == data["steps"][0]["rank_rule"]
    assert [s["rank_lost_steps"] for s in summary["sensors"]] == [[], [], []]


def test_npz_layout_gives_the_same_audit(tmp_path, three_sensor_run):
    ks, cases = three_sensor_run
    jsonl = audit_run_file(write_run(tmp_path / "run.jsonl", cases, ks))
    npz = audit_run_file(write_run(tmp_path / "run.npz", cases, ks))
    assert json.dumps(npz[1:]) == json.dumps(jsonl[1:])
    with np.load(tmp_path / "run.npz") as z:
        assert z["central_mu_p"].shape == (len(cases), 4) and z["local1_C_xy"].shape == (len(cases), 4, 2)
        assert z["circular1"].tolist() == [1] and z["k"].tolist() == ks


def test_summary_names_the_steps_where_a_sensor_lost_rank(tmp_path, capsys):
    cases, ks = _synthetic_cases(), [2, 5, 6, 9]
    audits = [audit_case(c) for c in cases]
    lost = [[k for k, a in zip(ks, audits) if not a.sensors[m].full_column_rank] for m in range(2)]
    inexact = [[k for k, a in zip(ks, audits) if not a.sensors[m].exact] for m in range(2)]
    assert lost == [[2, 5], [9]] and inexact[0] == [2]  # the fixture covers what it claims
    for name in ("run.jsonl", "run.npz"):
        code, out, err = _cli(["audit", str(write_run(tmp_path / name, cases, ks)), "--json"], capsys)
        assert code == 0 and err == ""
        data = json.loads(out)
        for s, c, k in zip(data["steps"], cases, ks):
            assert_same_audit(_expected(c, k), s, c)
        summary = data["summary"]
        assert summary["steps"] == 4 and summary["steps_with_y"] == 3
        assert summary["condition_held_steps"] == sum(a.condition_holds for a in audits)
        assert summary["exact_steps"] == sum(a.exact for a in audits)
        assert [s["rank_lost_steps"] for s in summary["sensors"]] == lost
        assert [s["rank_lost_not_exact_steps"] for s in summary["sensors"]] == inexact
        gaps = [s["gap_norm"] for s in data["steps"] if "gap_norm" in s]   # the steps' own, checked above
        assert len(gaps) == 3 and summary["max_gap_norm"] == max(gaps)
        assert summary["max_gap_k"] == ks[int(np.argmax([np.linalg.norm(a.gap) for a in audits[:3]]))]
    code, out, _ = _cli(["audit", str(tmp_path / "run.jsonl"), "--table"], capsys)
    assert code == 0 and "sensor 0: lost full column rank at k = 2, 5; not exact at k = 2" in out
    assert "steps: 4;" in out and f"at k = {ks[int(np.argmax(gaps))]}" in out
    assert len(out.splitlines()) > 4 + 3  # the per-step table and the summary
    # without --table: the one verdict line, the same counts (summary above, counted here from the audits)
    code, out, _ = _cli(["audit", str(tmp_path / "run.jsonl")], capsys)
    inexact_steps = 4 - sum(a.exact for a in audits)
    held = sum(a.condition_holds for a in audits)
    assert code == 0 and len(out.splitlines()) == 1
    assert out.startswith(f"DMF NOT exact at {inexact_steps} of 4 steps (the rank condition held at {held}; "
                          if inexact_steps else "DMF exact at all 4 steps")
    assert "sensor 0 lost full column rank at k = 2, 5, not exact at k = 2" in out
    assert f"largest |DMF - CMF| {max(gaps):.3g} at k = {ks[int(np.argmax(gaps))]} (3 step(s) with y)" in out


@pytest.mark.parametrize("name", ["run.jsonl", "run.npz"])
def test_k_round_trips(tmp_path, name):
    cases = _synthetic_cases()
    given = load_run(write_run(tmp_path / name, cases, [0, 3, 4, 10]))
    assert given.ks == [0, 3, 4, 10] and given.explicit_k and given.format == name.split(".")[1]
    default = load_run(write_run(tmp_path / name, cases))
    assert default.ks == [0, 1, 2, 3] and not default.explicit_k
    for a, b in zip(given.cases, cases):
        assert json.dumps(case_to_dict(a)) == json.dumps(case_to_dict(b))


def test_single_case_file_is_a_run_of_one_and_keeps_its_output(tmp_path, capsys):
    case = _synthetic_cases()[0]
    path = tmp_path / "case.json"
    path.write_text(json.dumps(case_to_dict(case)))
    run = load_run(path)
    assert run.format == "json" and run.ks == [0]
    code, out, _ = _cli(["audit", str(path), "--json"], capsys)
    assert code == 0
    assert_same_audit({key: v for key, v in _expected(case, 0).items() if key != "k"}, json.loads(out), case)
    [step] = audit_run_file(path)[1]
    assert_same_audit(_expected(case, 0), step, case)


def test_schemas_in_docs_are_the_ones_generated_from_the_reader_types():
    for name, schema in (("fusion-case", CASE_SCHEMA), ("run-line", RUN_LINE_SCHEMA)):
        assert json.loads((ROOT / "docs" / "schemas" / f"{name}.schema.json").read_text()) == schema
    assert "k" in json.dumps(RUN_LINE_SCHEMA) and '"k"' not in json.dumps(CASE_SCHEMA)


def test_schemas_are_valid_json_schema_and_agree_with_the_reader():
    jsonschema = pytest.importorskip("jsonschema")
    case = case_to_dict(_synthetic_cases()[0])
    variants = {"good": case, "string": json.loads(json.dumps(case)), "unknown key": {**case, "Y": [1.0]},
                "boolean": json.loads(json.dumps(case)), "huge": json.loads(json.dumps(case))}
    variants["string"]["locals"][0]["C_y"][0][0] = "a"
    variants["boolean"]["central"]["mu_p"][0] = True
    variants["huge"]["y"][0] = 1e101
    for schema, extra in ((CASE_SCHEMA, {}), (RUN_LINE_SCHEMA, {"k": 1})):
        jsonschema.Draft202012Validator.check_schema(schema)
        validator = jsonschema.Draft202012Validator(schema)
        for name, data in variants.items():
            data = {**extra, **data}
            try:
                case_from_dict({key: v for key, v in data.items() if key != "k"})
                read = True
            except CaseFileError:
                read = False
            assert validator.is_valid(data) == read == (name == "good"), name


def _good_lines(n=3):
    return [json.dumps({"k": k, **case_to_dict(c)}) for k, c in enumerate(_synthetic_cases()[:n])]


def _edit(line, change):
    obj = json.loads(line)
    change(obj)
    return json.dumps(obj)


def _not_pd(obj):
    obj["locals"][1]["C_y"] = [[1.0, 0.0], [0.0, -1.0]]


def _jsonl_cases():
    good = _good_lines()
    other = json.dumps({"k": 5, **case_to_dict(random_case(np.random.default_rng(1), 3, (2, 2)))})
    return {
        "not positive definite": ("\n".join([good[0], good[1], _edit(good[2], _not_pd)]) + "\n",
                                  "line 3: locals[1].C_y is not positive"),
        "invalid utf-8": (good[0].encode() + b"\n" + b'{"k": 1, "\xff": 2}\n', "line 2: not valid UTF-8"),
        "empty": ("", "is empty"),
        "only whitespace": ("\n  \n", "line 1: blank line"),
        "blank line": (good[0] + "\n\n" + good[1] + "\n", "line 2: blank line"),
        "not an object": (good[0] + "\n[1, 2]\n", "line 2: a fusion case must be a JSON object, got a list"),
        "not json": (good[0] + "\n" + good[1][:-5] + "\n", "line 2: not valid JSON"),
        "NaN literal": (good[0].replace("[[", "[[NaN, ", 1) + "\n",
                        f"line 1: not valid JSON: invalid character at column {good[0].index('[[') + 3} (NaN and "
                        "Infinity are not JSON numbers)"),
        "number overflow": (_edit(good[0], lambda o: o.update(y=[1.0, 2.0, 3.0, 4.0])).replace("4.0", "1e999")
                            + "\n", "line 1: y[3] is outside the float range"),
        "string in a matrix": (_edit(good[0], lambda o: o["locals"][0]["C_y"][0].__setitem__(0, "a")) + "\n",
                               'line 1: locals[0].C_y[0][0] must be a number, got a string'),
        "missing key": (good[0] + "\n" + _edit(good[1], lambda o: o["locals"][1].pop("mu_e")) + "\n",
                        "line 2: locals[1] lacks the key 'mu_e'"),
        "other dimensions": (good[0] + "\n" + other + "\n", "line 2: state dimension D 3 differs from line 1's 2"),
        "k on some lines": (good[0] + "\n" + _edit(good[1], lambda o: o.pop("k")) + "\n",
                            "line 2: lacks \"k\" but line 1 has it"),
        "k not increasing": (good[1] + "\n" + good[0] + "\n", "line 2: k = 0 does not increase"),
        "k negative": (_edit(good[0], lambda o: o.update(k=-1)) + "\n", "line 1: k must be an integer >= 0"),
        "k not an integer": (_edit(good[0], lambda o: o.update(k=True)) + "\n",
                             "line 1: k must be an integer, got a boolean"),
    }


@pytest.mark.parametrize("name", list(_jsonl_cases()))
def test_malformed_jsonl_exits_2_with_one_line(tmp_path, capsys, name):
    content, expected = _jsonl_cases()[name]
    path = tmp_path / "RUN.jsonl"
    path.write_bytes(content if isinstance(content, bytes) else content.encode())
    before = sorted(tmp_path.iterdir())
    code, out, err = _cli(["audit", str(path), "--json"], capsys)
    assert code == 2 and out == "" and sorted(tmp_path.iterdir()) == before
    assert err.count("\n") == 1 and err.startswith(f"gpfverify audit: error: {path}")
    assert expected in err and "Traceback" not in err


def _npz_cases(tmp_path):
    cases = _synthetic_cases()[:3]
    write_run(tmp_path / "good.npz", cases, [1, 2, 3])
    with np.load(tmp_path / "good.npz") as z:
        good = dict(z)

    def variant(**changes):
        arrays = {k: v for k, v in good.items() if changes.get(k, 0) is not None}
        arrays.update({k: v for k, v in changes.items() if v is not None})
        return arrays

    c_y = good["local1_C_y"].copy()
    c_y[2] = [[1.0, 0.0], [0.0, -1.0]]
    return {
        "missing array": (variant(local1_mu_e=None), "missing array local1_mu_e"),
        "wrong shape": (variant(central_C_xy=good["central_C_xy"][:, :, :3]),
                        "array central_C_xy has shape (3, 2, 3), expected (T, D, L) = (3, 2, 4)"),
        "wrong step count": (variant(y=good["y"][:2]), "array y has shape (2, 4)"),
        "unknown array": (variant(local0_Ce=good["local0_C_e"]), "unknown array(s) local0_Ce"),
        "not positive definite": (variant(local1_C_y=c_y), "step 2 (k = 3): local1_C_y is not positive"),
        "strings": (variant(central_mu_p=good["central_mu_p"].astype(str)),
                    "array central_mu_p must hold real numbers"),
        "float sizes": (variant(sizes=np.array([2.0, 2.0])), "array sizes must hold integers"),
        "k not increasing": (variant(k=np.array([1, 1, 2])), "array k entry 1: k = 1 does not increase"),
        "object array": (variant(y=np.array([None] * 3, dtype=object)), "array y cannot be read"),
        "not an npz": (b"central_mu_p = 1\n", "is not an npz archive"),
        "npy not npz": ("npy", "is not an npz archive"),
    }


@pytest.mark.parametrize("name", ["missing array", "wrong shape", "wrong step count", "unknown array",
                                  "not positive definite", "strings", "float sizes", "k not increasing",
                                  "object array", "not an npz", "npy not npz"])
def test_malformed_npz_exits_2_with_one_line(tmp_path, capsys, name):
    content, expected = _npz_cases(tmp_path)[name]
    path = tmp_path / "RUN.npz"
    if isinstance(content, bytes):
        path.write_bytes(content)
    elif content == "npy":
        with open(path, "wb") as fh:
            np.save(fh, np.zeros(3))
    else:
        np.savez(path, **content)
    before = sorted(tmp_path.iterdir())
    code, out, err = _cli(["audit", str(path), "--json"], capsys)
    assert code == 2 and out == "" and sorted(tmp_path.iterdir()) == before
    assert err.count("\n") == 1 and err.startswith(f"gpfverify audit: error: {path}")
    assert expected in err and "Traceback" not in err


def test_truncated_npz_is_refused(tmp_path, capsys):
    write_run(tmp_path / "good.npz", _synthetic_cases()[:2])
    data = (tmp_path / "good.npz").read_bytes()
    (tmp_path / "RUN.npz").write_bytes(data[: len(data) // 2])
    code, out, err = _cli(["audit", str(tmp_path / "RUN.npz")], capsys)
    assert code == 2 and out == "" and err.count("\n") == 1 and "RUN.npz" in err


def test_missing_run_file(tmp_path, capsys):
    for name in ("none.jsonl", "none.npz"):
        code, out, err = _cli(["audit", str(tmp_path / name)], capsys)
        assert code == 2 and out == "" and err.count("\n") == 1 and "cannot read" in err


def test_writer_refuses_what_the_reader_would(tmp_path):
    cases = _synthetic_cases()
    with pytest.raises(ValueError, match="strictly increasing"):
        write_run(tmp_path / "r.jsonl", cases, [0, 2, 2, 3])
    with pytest.raises(ValueError, match="other dimensions"):
        write_run(tmp_path / "r.npz", cases + [random_case(np.random.default_rng(2), 3, (2, 2))])
    with pytest.raises(ValueError, match=".jsonl, .ndjson or .npz"):
        write_run(tmp_path / "r.json", cases)
    assert not list(tmp_path.iterdir())


def test_help_points_to_the_format_documents(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["audit", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert exit_.value.code == 0
    assert "docs/run-file-format.md" in out and "docs/fusion-case-format.md" in out
    for doc in ("run-file-format.md", "fusion-case-format.md"):
        assert (ROOT / "docs" / doc).is_file()


def test_rank_rule_option_and_mixed_rules(tmp_path, capsys):
    cases = _synthetic_cases()
    path = write_run(tmp_path / "run.jsonl", cases)
    code, out, err = _cli(["audit", str(path), "--rank-rule", "absolute:1e-9", "--json"], capsys)
    assert code == 0 and err == ""
    data = json.loads(out)
    for k, (s, c) in enumerate(zip(data["steps"], cases)):
        assert_same_audit(_expected_with(c, k, "absolute:1e-9"), s, c)
    assert data["summary"]["rank_rule"]["name"] == "absolute" and data["summary"]["rank_rule"]["tol"] == 1e-9
    for argv in (["--rank-rule", "sometimes"], ["--rank-rule", "numpy", "--rank-tol", "1e-9"]):
        code, out, err = _cli(["audit", str(path), *argv], capsys)
        assert code == 2 and out == "" and err.count("\n") == 1
    mixed = [dataclasses.replace(c, rank_tol=1e-3) if t == 1 else c for t, c in enumerate(cases)]
    summary = audit_run_file(write_run(tmp_path / "mixed.jsonl", mixed))[2]
    assert isinstance(summary["rank_rule"], list) and len(summary["rank_rule"]) == 2


def _expected_with(case, k, rule):
    return json.loads(json.dumps({"k": k, **audit_to_dict(audit_case(case, rank_rule=rule))}))


def test_audit_of_a_run_never_imports_cvxpy(tmp_path):
    path = write_run(tmp_path / "run.jsonl", _synthetic_cases())
    npz = write_run(tmp_path / "run.npz", _synthetic_cases())
    code = ("import contextlib, io, sys\n"
            "from gpfverify.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            f"    codes = [main(['audit', {str(path)!r}, '--json']), main(['audit', {str(npz)!r}])]\n"
            "print(codes, 'cvxpy' in sys.modules)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert proc.stdout.strip() == "[0, 0] False"


def test_malformed_run_file_in_a_real_process(tmp_path):
    path = tmp_path / "RUN.jsonl"
    path.write_text("\n".join(_good_lines(2)[:1] + ["[]"]) + "\n")
    proc = subprocess.run([sys.executable, "-m", "gpfverify", "audit", str(path), "--json"],
                          capture_output=True, text=True)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.count("\n") == 1 and "line 2" in proc.stderr and "Traceback" not in proc.stderr


def test_out_writes_the_run_report_with_the_json_it_renders(tmp_path, capsys, three_sensor_run):
    ks, cases = three_sensor_run
    path = write_run(tmp_path / "run.jsonl", cases, ks)
    code, out, err = _cli(["audit", str(path), "--json", "--out", str(tmp_path / "report")], capsys)
    assert code == 0 and err == f"gpfverify audit: the report page: {tmp_path / 'report' / 'report.html'}\n"
    report = tmp_path / "report"
    assert {"report.html", "README.md", "audit.json"} <= {p.name for p in report.iterdir()}
    assert json.loads((report / "audit.json").read_text()) == json.loads(out)
    (tmp_path / "one.json").write_text(json.dumps(case_to_dict(cases[0])))
    code, out, err = _cli(["audit", str(tmp_path / "one.json"), "--out", str(tmp_path / "x")], capsys)
    assert code == 2 and err.count("\n") == 1 and "run file" in err and not (tmp_path / "x").exists()


def _long_run(tmp_path, steps: int, bad_last: bool = False):
    """A run of ``steps`` lines (the synthetic cases repeated), the last one broken on request."""
    lines = [json.dumps({"k": k, **case_to_dict(_synthetic_cases()[k % 4])}) for k in range(steps)]
    if bad_last:
        lines[-1] = _edit(lines[-1], _not_pd)
    path = tmp_path / "long.jsonl"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_stream_gives_the_same_bytes_for_any_blocks_and_workers(tmp_path):
    from gpfverify.experiments.runner import make_executor
    from gpfverify.audit.run import stream_audit

    path = _long_run(tmp_path, 24)
    outputs = []
    for block_steps, workers in ((256, 1), (5, 1), (5, 2)):
        out = io.BytesIO()
        with make_executor(workers) as executor:
            stream_audit(path, out, executor=executor if workers > 1 else None, in_flight=4,
                         block_steps=block_steps)
        outputs.append(out.getvalue())
    assert outputs[0] == outputs[1] == outputs[2]
    data = json.loads(outputs[0])
    assert [s["k"] for s in data["steps"]] == list(range(24))
    for k, c in enumerate(_synthetic_cases()):
        assert_same_audit(_expected(c, k), data["steps"][k], c)
    assert data["summary"] == audit_run_file(path)[2]


def test_cli_workers_give_the_output_of_one_process(tmp_path):
    path = _long_run(tmp_path, 6)
    runs = [subprocess.run([sys.executable, "-m", "gpfverify", "audit", str(path), "--json", *extra],
                           capture_output=True, cwd=tmp_path) for extra in ([], ["--workers", "2"])]
    assert [r.returncode for r in runs] == [0, 0] and runs[0].stdout == runs[1].stdout
    assert len(json.loads(runs[0].stdout)["steps"]) == 6


def test_a_bad_line_after_the_first_blocks_leaves_stdout_empty(tmp_path, capsys):
    from gpfverify.audit.runfile import BLOCK_STEPS

    path = _long_run(tmp_path, BLOCK_STEPS + 3, bad_last=True)
    for extra in ([], ["--json"]):
        code, out, err = _cli(["audit", str(path), *extra], capsys)
        assert code == 2 and out == "" and err.count("\n") == 1
        assert f"line {BLOCK_STEPS + 3}: locals[1].C_y is not positive" in err


def test_step_index_lists_are_spooled_and_written_as_the_same_json(tmp_path, monkeypatch):
    """Lists of step indices that outgrow memory move to disk and are written a chunk at a time:
    the same bytes as with everything in memory (here both limits at a few indices)."""
    import gpfverify.audit.run as runaudit

    path = _long_run(tmp_path, 60)
    in_memory = io.BytesIO()
    runaudit.stream_audit(path, in_memory)
    monkeypatch.setattr(runaudit, "INDEX_SPOOL_BYTES", 16)
    monkeypatch.setattr(runaudit, "INDEX_CHUNK", 3)
    spooled = io.BytesIO()
    summary, _, _ = runaudit.stream_audit(path, spooled, block_steps=7)
    assert spooled.getvalue() == in_memory.getvalue()
    lost = summary["sensors"][0]["rank_lost_steps"]
    assert isinstance(lost, runaudit.StepIndices) and lost._file._rolled  # on disk
    assert list(lost) == lost.tolist() == [k for k in range(60) if k % 4 in (0, 1)]
    assert lost[-1] == 57 and lost[1:3] == [1, 4] and len(lost) == 30
    assert json.loads(spooled.getvalue())["summary"] == audit_run_file(path)[2]


def test_the_summary_of_a_long_run_holds_no_list_that_grows_with_it():
    """10⁶ steps at which both sensors lost rank (every step listed twice per sensor): the summary
    and its JSON fit in a few MB of traced memory, where 4·10⁶ indices would take 32 MB as arrays
    and more as Python ints."""
    import tracemalloc

    from gpfverify.audit.run import BlockAudit, RunSummary, write_summary_json

    steps, block = 1_000_000, 10_000
    lost = np.zeros((block, 2), bool)
    sink = open(os.devnull, "wb")
    tracemalloc.start()
    try:
        summary = RunSummary()
        for start in range(0, steps, block):
            summary.add(BlockAudit(ks=np.arange(start, start + block), condition_holds=lost[:, 0],
                                   exact=lost[:, 0], full_column_rank=lost, sensor_exact=lost,
                                   gap_norm=np.full(block, np.nan), rank_rules=["canonical"]))
        write_summary_json(sink, summary.result(spooled=True))
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
        sink.close()
    assert summary.steps == steps and len(summary.lost[1]) == steps
    assert peak < 12e6, f"{peak / 1e6:.1f} MB traced"


def test_a_summary_line_shows_the_first_ranges_and_how_many_in_all(tmp_path, capsys):
    from gpfverify.commands.audit import RANGES_SHOWN

    path = _long_run(tmp_path, 400)  # sensor 0 lost rank at k ≡ 0, 1 (mod 4): 100 ranges
    code, out, _ = _cli(["audit", str(path)], capsys)
    shown = ", ".join(f"{k}-{k + 1}" for k in range(0, 4 * RANGES_SHOWN, 4))
    assert code == 0 and len(out.splitlines()) == 1
    assert f"sensor 0 lost full column rank at k = {shown}, … (200 in all)" in out


def test_npz_step_indices_and_rank_tols_are_streamed_block_by_block(tmp_path):
    """k and a per-step rank_tol are read with the other stacked arrays, a block at a time: a k
    that stops increasing across two blocks is found with the message of one that does within a
    block, and per-step rank_tols give the audit of the same steps as lines."""
    from gpfverify.audit.runfile import open_run

    cases = [dataclasses.replace(c, rank_tol=1e-3) if t % 2 else c for t, c in enumerate(_synthetic_cases())]
    write_run(tmp_path / "good.npz", cases, [1, 2, 5, 7])
    with np.load(tmp_path / "good.npz") as z:
        good = dict(z)
    assert good["rank_tol"].shape == (4,)  # stored per step
    with open_run(tmp_path / "good.npz") as reader:
        blocks = list(reader.blocks(2))
    assert [b.ks.tolist() for b in blocks] == [[1, 2], [5, 7]]
    assert [blocks[1].block.case(t).rank_tol for t in range(2)] == [None, 1e-3]
    with open_run(write_run(tmp_path / "default.npz", cases)) as reader:  # no k: the positions, block by block
        assert [b.ks.tolist() for b in reader.blocks(3)] == [[0, 1, 2], [3]]
    by_lines = audit_run_file(write_run(tmp_path / "good.jsonl", cases, [1, 2, 5, 7]))[2]
    assert audit_run_file(tmp_path / "good.npz")[2] == by_lines
    for k, message in (([1, 2, 2, 7], "array k entry 2: k = 2 does not increase (previous k = 2)"),
                       ([1, 2, 3, -1], "array k must hold step indices >= 0, got -1")):
        np.savez(tmp_path / "bad.npz", **{**good, "k": np.array(k)})
        with open_run(tmp_path / "bad.npz") as reader, pytest.raises(CaseFileError, match=re.escape(message)):
            list(reader.blocks(2))
