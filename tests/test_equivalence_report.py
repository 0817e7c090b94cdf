"""The equivalence report of ``gpfverify check`` and of a run audit: rendered from results alone,
summary counts computed from the arrays, the l_m > D sentence only where it applies, a
self-contained HTML page, no half-written files."""

from __future__ import annotations

import copy
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gpfverify.report.equivalence import (summary_paragraphs, write_equivalence_report,
                                          write_run_audit_report)

ROOT = Path(__file__).resolve().parents[1]
LM_GT_D = "l_m > D: the rank condition can never hold for this sensor"


def _check_results(system: str, steps: int = 8) -> dict:
    from gpfverify.experiments.check import params_for, run_one, summarize

    params = params_for(str(ROOT / "examples" / system), steps=steps)
    runs = [run_one(params, seed) for seed in np.random.SeedSequence(1).spawn(2)]
    # what the runner adds around summarize (gpfverify.experiments.runner.write_results)
    return json.loads(json.dumps({"experiment": "check", "runs": 2, "seed": 1, "params": params.to_json(), "runs_ok": 2,
                                  "failed_runs": [], **summarize(params, runs)}))


@pytest.fixture(scope="module")
def tracker() -> dict:
    return _check_results("three_sensor_system.py:tracker")


@pytest.fixture(scope="module")
def redundant() -> dict:
    return _check_results("redundant_sensor_system.py:system")


def _counts(results: dict) -> tuple[int, int]:
    """(steps judged exact, total steps) from the per-sensor arrays, independently of the report."""
    exact = np.asarray(results["exact"], bool)
    return int(exact.all(axis=2).sum()), exact.shape[0] * exact.shape[1]


def _assert_self_contained(html: str, out: Path) -> None:
    """Every figure of the folder embedded, nothing loaded from elsewhere."""
    sources = re.findall(r'src="([^"]*)"', html)
    assert len(sources) == len(list((out / "figures").glob("*.png")))
    assert all(s.startswith("data:image/png;base64,") for s in sources)
    assert "href=\"http" not in html and "<link" not in html and not re.search(r"<script[^>]*\bsrc=", html)
    assert html.count("<script>") == 1  # the one inline script: stacks a table too wide for the window


def _assert_complete(out: Path, pngs: list[str]) -> None:
    for name in ["README.md", "report.html"] + [f"figures/{p}" for p in pngs]:
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    leftovers = [p.name for p in out.iterdir() if p.name.startswith(".")]
    assert not leftovers, leftovers


def test_tracker_report(tracker, tmp_path):
    exact, total = _counts(tracker)
    assert exact == total  # every step of the tracker is exact (UKF, full rank)
    html_path = write_equivalence_report(tracker, tmp_path)
    assert html_path == tmp_path / "report.html"
    pngs = ["gap.png", "verdicts.png", "drift.png", "rmse.png", "consistency.png"]
    _assert_complete(tmp_path, pngs)
    first = summary_paragraphs(tracker)[0]
    assert first.startswith(f"DMF reproduced CMF at all {total} steps of 2 runs")
    readme = (tmp_path / "README.md").read_text(encoding="utf-8")
    assert first in readme
    assert LM_GT_D not in readme and "l_m > D:" not in readme
    assert "matrix_rank rule" in readme or "canonical" in readme  # the rule that decided, by name
    html = html_path.read_text(encoding="utf-8")
    _assert_self_contained(html, tmp_path)
    for png in pngs:
        assert f"figures/{png}" in readme
    canonical = tracker.get("min_canonical_correlation")
    if canonical is not None and any(v is not None for run in canonical for step in run for v in step):
        assert (tmp_path / "figures" / "canonical.png").is_file()
        assert "smallest canonical correlation" in readme.lower()


def test_redundant_report(redundant, tmp_path):
    exact, total = _counts(redundant)
    assert exact < total
    write_equivalence_report(redundant, tmp_path)
    _assert_complete(tmp_path, ["gap.png", "verdicts.png", "drift.png", "rmse.png", "consistency.png"])
    paragraphs = summary_paragraphs(redundant)
    reproduced = redundant["reproduced_steps"]
    assert paragraphs[0].startswith(f"DMF differed from CMF beyond rounding at {total - reproduced} of {total} "
                                    f"steps of 2 runs ({total - exact} not exact")
    readme = (tmp_path / "README.md").read_text(encoding="utf-8")
    sensor_1 = [p for p in paragraphs if p.startswith("Sensor 1 (polar and sum) lost full column rank")]
    assert len(sensor_1) == 1 and LM_GT_D in sensor_1[0] and "3 outputs and the state 2" in sensor_1[0]
    assert readme.count(LM_GT_D) == 1  # sensor 0 (1 output) does not get it
    full = np.asarray(redundant["full_column_rank"], bool)
    lost = int((~full[:, :, 1]).sum())
    sensor_exact = np.asarray(redundant["exact"], bool)[:, :, 1]
    anyway = int((~full[:, :, 1] & sensor_exact).sum())
    expected = ("not exact at any of them" if anyway == 0 else f"exact anyway at all {lost} steps" if anyway == lost
                else f"exact anyway at {anyway} of those {lost} steps")
    assert expected in sensor_1[0]
    # every inexact step explained: one row per step judged not exact (or above its bound)
    gap, bound = np.asarray(redundant["gap_size"]), np.asarray(redundant["gap_bound"])
    flagged = int((~np.asarray(redundant["exact"], bool).all(axis=2) | (gap > bound)).sum())
    assert f"({flagged} of {total})" in readme
    assert "Every inexact step is explained" in readme
    _assert_self_contained((tmp_path / "report.html").read_text(encoding="utf-8"), tmp_path)


def test_report_replaces_previous_and_optional_fields(tracker, tmp_path):
    """A second render into the same folder replaces the first; a rank-rule object and canonical
    correlations are rendered when present; without the truth there is no RMSE figure."""
    write_equivalence_report(tracker, tmp_path)
    results = copy.deepcopy(tracker)
    results["rank_rule"] = {"name": "canonical", "tol": 1e-6}
    sizes = [s["outputs"] for s in results["sensors"]]
    runs, steps = np.asarray(results["gap_norm"]).shape
    results.pop("min_canonical_correlation", None)   # the ragged per-correlation form instead
    results["canonical_correlations"] = [[[[0.5 + 0.1 * j for j in range(l)] for l in sizes]
                                          for _ in range(steps)] for _ in range(runs)]
    results["truth_known"] = False
    for key in ("rmse", "local_rmse", "nees", "local_nees"):
        results.pop(key)
    write_equivalence_report(results, tmp_path)
    _assert_complete(tmp_path, ["gap.png", "verdicts.png", "drift.png", "consistency.png", "canonical.png"])
    assert not (tmp_path / "figures" / "rmse.png").exists()
    readme = (tmp_path / "README.md").read_text(encoding="utf-8")
    assert "canonical rank rule (tol = 1e-06)" in readme
    assert "smallest canonical correlation" in readme.lower() and "0.5" in readme
    assert "truth is not known" in readme


def _run_audit(model, steps: int = 6) -> dict:
    from gpfverify.audit.case import audit_to_dict
    from gpfverify.model_fusion import run_fusion
    from gpfverify.rng import generator

    _, ys = model.simulate(steps, generator(np.random.SeedSequence(4)))
    run = run_fusion(model, ys)
    records = [{"k": step.k, **audit_to_dict(step.audit)} for step in run.steps]
    summary = {"steps": len(records), "condition_held_steps": sum(r["condition_holds"] for r in records),
               "exact_steps": sum(r["exact"] for r in records), "rank_rule": records[0]["rank_rule"]}
    return {"steps": records, "summary": summary}


def test_run_audit_report(tmp_path):
    from gpfverify.scenarios.three_sensor import three_sensor_model
    from gpfverify.systems import load_system

    tracker_audit = _run_audit(three_sensor_model())
    out = tmp_path / "tracker"
    write_run_audit_report(tracker_audit, out)
    _assert_complete(out, ["gap.png", "verdicts.png", "singular-values.png"])
    assert json.loads((out / "audit.json").read_text(encoding="utf-8")) == tracker_audit
    readme = (out / "README.md").read_text(encoding="utf-8")
    assert all(step["reproduced"] for step in tracker_audit["steps"])
    assert f"DMF reproduced CMF at all {len(tracker_audit['steps'])} steps with y" in readme
    assert "l_m > D:" not in readme
    _assert_self_contained((out / "report.html").read_text(encoding="utf-8"), out)

    redundant_audit = _run_audit(load_system(str(ROOT / "examples" / "redundant_sensor_system.py:system")))
    out = tmp_path / "redundant"
    write_run_audit_report(redundant_audit, out)
    _assert_complete(out, ["gap.png", "verdicts.png", "repair.png", "singular-values.png"])
    readme = (out / "README.md").read_text(encoding="utf-8")
    assert readme.count(LM_GT_D) == 1
    inexact = sum(not s["exact"] for s in redundant_audit["steps"])
    differed = sum(not s["reproduced"] for s in redundant_audit["steps"])
    steps = len(redundant_audit["steps"])
    assert f"DMF differed from CMF beyond rounding at {differed} of the {steps} steps with y" in readme
    assert f"DMF was exact at {steps - inexact} of the {steps} steps" in readme
    _assert_self_contained((out / "report.html").read_text(encoding="utf-8"), out)


def test_a_sensors_share_of_the_gap_is_in_the_gap_s_unit(redundant):
    """results.json's gap_share_size is in prior standard deviations, as gap_size: where one sensor
    alone is judged not exact (and no angle output has a branch offset) its share is the whole gap,
    so the two agree to rounding in any units, and the page reads 100 %."""
    share = np.asarray(redundant["gap_share_size"], float)         # (R, T, N)
    gap = np.asarray(redundant["gap_size"], float)                 # (R, T)
    exact = np.asarray(redundant["exact"], bool)
    alone = (~exact).sum(axis=2) == 1
    assert alone.any()
    for r, t in zip(*np.nonzero(alone)):
        m = int(np.flatnonzero(~exact[r, t])[0])
        assert share[r, t, m] == pytest.approx(gap[r, t], rel=1e-9)
    [explained] = [p for p in summary_paragraphs(redundant) if p.startswith("Every inexact step is explained")]
    spans = re.findall(r"its share of the gap: ([0-9]+) %(?: to ([0-9]+) %)?", explained)
    assert spans and all(low == "100" and high in ("", "100") for low, high in spans), explained


def _verdict(**counts) -> str:
    from gpfverify.contract.check import verdict_sentence

    results = {"runs_ok": 1, "branch_offset_steps": 0, "max_gap": 1.0, "max_gap_size": 1e-3, **counts}
    return verdict_sentence(results)


def test_the_headline_is_rendered_from_the_counts():
    """"exact anyway" only when every step was exact; a step reproduced without being exact is said
    so; a step that differed names how many were not exact."""
    assert "exact anyway" in _verdict(total_steps=50, condition_held_steps=0, exact_steps=50, reproduced_steps=50)
    quiet = _verdict(total_steps=50, condition_held_steps=0, exact_steps=0, reproduced_steps=50)
    assert "exact anyway" not in quiet and "DMF was exact at 0 of the 50" in quiet
    assert "the gap stayed within rounding" in quiet
    differed = _verdict(total_steps=50, condition_held_steps=0, exact_steps=0, reproduced_steps=0)
    assert differed.startswith("DMF differed from CMF beyond rounding at 50 of 50 steps (50 not exact)")
    assert "exact anyway" not in differed


def test_the_audit_page_draws_what_the_rule_in_force_decides_on(tmp_path, monkeypatch):
    """Under the canonical rule the decision figure is the canonical correlations with τ, and the
    singular values are drawn without a tolerance line; under numpy's rule the singular values with
    the tolerance that decided."""
    from gpfverify.audit.case import audit_to_dict
    from gpfverify.model_fusion import run_fusion
    from gpfverify.report import equivalence_figures as ef
    from gpfverify.rng import generator
    from gpfverify.systems import load_system

    model = load_system(str(ROOT / "examples" / "redundant_sensor_system.py:system"))
    _, ys = model.simulate(4, generator(np.random.SeedSequence(4)))
    drawn = {}
    original = ef.plot_min_per_sensor

    def spy(ks, values, labels, path, ylabel, title, threshold=None, threshold_label="threshold"):
        drawn[path.name] = threshold
        return original(ks, values, labels, path, ylabel, title, threshold, threshold_label)

    monkeypatch.setattr(ef, "plot_min_per_sensor", spy)
    for rule in ("canonical", "numpy"):
        run = run_fusion(model, ys, rank_rule=rule, methods=("cmf", "dmf"))
        records = [{"k": step.k, **audit_to_dict(step.audit)} for step in run.steps]
        audit = {"steps": records, "summary": {"rank_rule": records[0]["rank_rule"]}}
        drawn.clear()
        write_run_audit_report(audit, tmp_path / rule)
        readme = (tmp_path / rule / "README.md").read_text(encoding="utf-8")
        if rule == "canonical":
            assert drawn["canonical.png"] == pytest.approx(records[0]["rank_rule"]["tol"])
            assert drawn["singular-values.png"] is None
            assert "the canonical rank rule in force decides on these" in readme
            assert "below it the rank verdict drops" not in readme
        else:
            tols = [[x["tol"] for x in step["sensors"]] for step in records]
            np.testing.assert_array_equal(drawn["singular-values.png"], tols)
            assert drawn["canonical.png"] is None
            assert "the rank tolerance of the rule in force (dashed): below it the rank verdict drops" in readme


def test_the_check_page_says_what_depends_on_units(redundant):
    """The Moore–Penrose DMF's unit dependence at rank-deficient steps, with its size from
    results.json; CI's trace criterion; the determinant criterion said to be unit-free."""
    paragraphs = summary_paragraphs(redundant)
    dependence = [v for run in redundant["unit_dependence"] for v in run if v is not None]
    assert dependence and redundant["max_unit_dependence"] == max(dependence)
    [units] = [p for p in paragraphs if "Moore–Penrose inverse depends on the units" in p]
    assert f"up to {max(dependence):.2g} prior standard deviations" in units
    assert any("trace criterion" in p and "--ci-criterion det" in p for p in paragraphs)
    det = copy.deepcopy(redundant)
    det["params"]["ci_criterion"] = "det"
    assert any("determinant criterion, which does not depend on units" in p for p in summary_paragraphs(det))


def test_every_key_check_writes_is_documented(tmp_path):
    """docs/check-format.md names every key of results.json and of a saved run's step entry
    (``means`` included), so a user can tell one-step numbers from recursive ones; the page says
    which are which."""
    doc = (ROOT / "docs" / "check-format.md").read_text(encoding="utf-8")
    proc = subprocess.run([sys.executable, "-m", "gpfverify", "check",
                           str(ROOT / "examples" / "three_sensor_system.py:tracker"), "--steps", "2",
                           "--out", str(tmp_path / "o")], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    results = json.loads((tmp_path / "o" / "results.json").read_text(encoding="utf-8"))
    run = json.loads(next((tmp_path / "o" / "runs").glob("run-*.json")).read_text(encoding="utf-8"))
    keys = set(results) | set(run["result"]["steps"][0])
    undocumented = sorted(k for k in keys if f"`{k}`" not in doc)
    assert not undocumented, undocumented
    readme = (tmp_path / "o" / "README.md").read_text(encoding="utf-8")
    assert "One-step numbers" in readme and "Recursive numbers" in readme and '("means")' in readme


def test_a_fusion_run_shown_as_a_page_names_its_ci_criterion():
    """run_fusion's ci_criterion travels with the run to the results a notebook renders."""
    from gpfverify.experiments.check import results_of_run
    from gpfverify.model_fusion import run_fusion
    from gpfverify.rng import generator
    from gpfverify.scenarios.three_sensor import three_sensor_model

    model = three_sensor_model()
    _, ys = model.simulate(2, generator(np.random.SeedSequence(4)))
    for criterion in ("trace", "det"):
        run = run_fusion(model, ys, methods=("cmf", "dmf", "ci"), ci_criterion=criterion)
        results = results_of_run(run)
        assert results["params"]["ci_criterion"] == criterion
        words = "trace criterion" if criterion == "trace" else "determinant criterion"
        assert any(words in p for p in summary_paragraphs(results))


def test_html_in_user_supplied_text_is_shown_as_text_on_the_markdown_page(tmp_path):
    """A system file, a sensor and a run's error carrying HTML: the Markdown page escapes it as the
    HTML page does (a viewer that renders Markdown would otherwise run it), inside `code` spans
    too nothing is interpreted, and comparisons such as ``p < 0.05`` stay as they are."""
    from gpfverify.report.render import md_escaped

    name = "<img src=x onerror=alert(1)>.py"
    (tmp_path / name).write_text(
        "import numpy as np\nfrom gpfverify.models import Sensor, StateSpaceModel\n"
        "system = StateSpaceModel(transition=np.eye(2), process_cov=0.1 * np.eye(2), "
        "sensors=[Sensor(np.eye(2), np.eye(2), name='<script>alert(2)</script>'), Sensor([[1.0, 1.0]], [[1.0]])], "
        "prior_mean=[0.0, 0.0], prior_cov=np.eye(2))\n")
    proc = subprocess.run([sys.executable, "-m", "gpfverify", "check", f"{name}:system", "--steps", "3",
                           "--methods", "cmf,dmf", "--out", "out"], cwd=tmp_path, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    html = (tmp_path / "out" / "report.html").read_text(encoding="utf-8")
    assert "<img src=x" not in html and "<script>alert" not in html and "&lt;img src=x onerror=alert(1)&gt;" in html
    markdown = (tmp_path / "out" / "README.md").read_text(encoding="utf-8")
    outside_code = re.sub(r"`[^`\n]+`", "", markdown)  # a code span shows its text literally
    assert "<img" not in outside_code and "<script" not in outside_code
    assert "&lt;img src=x onerror=alert(1)>" in outside_code and "&lt;script>alert(2)&lt;/script>" in outside_code
    assert md_escaped("p < 0.05 & q <= 1, <b>bold</b> &amp; `<i>code</i>`") == \
        "p < 0.05 & q <= 1, &lt;b>bold&lt;/b> &amp;amp; `<i>code</i>`"
