"""The tbd experiment: results.json per CONTRACT.md, determinism, metrics against direct counts,
typed parameters and run records, claim records, the report page rendered from a stored
results.json, and command-line errors."""

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from gpfverify.cli import main
from gpfverify.contract import VERDICTS, ClaimRecord, from_json, read_claims, to_json
from gpfverify.papers.tbd.contract import PROFILES, MethodRun, Params, RunRecord, SnrRun, TbdMethod
from gpfverify.errors import InputError
from gpfverify.papers.tbd import experiment as tbd
from gpfverify.papers.tbd.claims import STATEMENTS
from gpfverify.experiments.runner import run_experiment, without_timing
from gpfverify.report.document import Figure, Paragraph, Section, Table
from gpfverify.report.inputs import load_section
from gpfverify.papers.tbd import section as tbd_section

FIXTURE = Path(__file__).parent / "fixtures" / "tbd"
SMALL = Params(snr=(4.0, 6.0, 9.0), particles=80, tpf_particles=(80, 40), zeta_sweep_particles=40,
               zeta_sweep=(1.0, 0.6, 0.4))


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("tbd")
    return run_experiment(tbd, SMALL, 3, 5, out, show_progress=False), out


@pytest.fixture(scope="module")
def small_results(small_run):
    return small_run[0]


def test_results_follow_the_contract(small_results):
    r = small_results
    assert r["experiment"] == "tbd" and r["runs"] == 3 and r["seed"] == 5 and r["runs_ok"] == 3
    keys = {"PFTBD-N80", "TPFTBD-N80", "TPFTBD-N40"}
    frames = r["params"]["frames"]
    assert set(r["existence_prob"]) == keys and set(r["rmse"]) == keys and set(r["roc"]) == keys
    for key in keys:
        assert len(r["existence_prob"][key]) == frames and len(r["rmse"][key]) == frames
        present = [v is not None for v in r["rmse"][key]]
        assert sum(present) == r["target_frames"] == 16 and present.index(True) == 6
        roc = r["roc"][key]
        assert len(roc["pfa"]) == len(roc["pd"]) and roc["pfa"][0] == 1.0 and roc["pd"][-1] == 0.0
        assert np.all(np.diff(roc["pfa"]) <= 0) and np.all(np.diff(roc["pd"]) <= 0)
        assert len(r["pd_vs_snr"][key]) == 3
    assert set(r["time_per_run"]) >= keys | {"TPFTBD-N40-1", "TPFTBD-N40-0.4"}
    assert all(t > 0 for t in r["time_per_run"].values())
    assert r["zeta_sweep"]["methods"] == ["PFTBD-N80", "TPFTBD-N40-1", "TPFTBD-N40-0.6", "TPFTBD-N40-0.4"]
    # the sweep's ζ = 0.6 method is the headline TPFTBD-N40, computed once
    assert r["zeta_sweep"]["existence_prob"]["TPFTBD-N40-0.6"] == r["existence_prob"]["TPFTBD-N40"]
    assert Params.from_json(r["params"]) == SMALL  # the parameters recorded once, read back typed
    json.dumps(r, allow_nan=False)  # strict JSON: absent frames are null, not NaN


def _deterministic(results: dict) -> dict:
    """The fields that must repeat exactly: without timing fields and without the claim records
    that rest on wall-clock timing (their statistic is a time ratio)."""
    out = without_timing(results)
    out["claims"] = [c for c in out["claims"] if not c["timing"]]  # timing claims are kept apart already
    return out


def test_same_numbers_for_the_same_seed(small_results, tmp_path):
    again = run_experiment(tbd, SMALL, 3, 5, tmp_path, show_progress=False)
    assert _deterministic(again) == _deterministic(small_results)
    assert [c["id"] for c in again["claims"]] == [c["id"] for c in small_results["claims"]]


def test_params_and_run_records_round_trip(small_run):
    for params in (SMALL, Params(), *(s.params for p in PROFILES.values() for s in p.settings)):
        assert from_json(Params, json.loads(json.dumps(to_json(params)))) == params
    saved = json.loads((small_run[1] / "runs" / "run-000000.json").read_text())
    record = from_json(RunRecord, saved["result"])
    assert isinstance(record, RunRecord) and isinstance(record.cases[0], SnrRun)
    assert isinstance(record.cases[0].methods["PFTBD-N80"], MethodRun)
    assert from_json(RunRecord, json.loads(json.dumps(to_json(record)))) == record
    assert [c.snr_db for c in record.cases] == list(SMALL.snr)


def test_method_names_are_values():
    for key in ("PFTBD-N2000", "TPFTBD-N1000", "TPFTBD-N1000-0.6", "TPFTBD-N250-1"):
        assert TbdMethod.parse(key).key == key
    assert TbdMethod.parse("TPFTBD-N1000-0.6") == TbdMethod("TPFTBD", 1000, 0.6)
    with pytest.raises(InputError, match="not a TBD method"):
        TbdMethod.parse("TPFTBD-1000")


def test_profiles_are_the_quick_settings_and_the_papers_counts():
    quick, full = PROFILES["quick"], PROFILES["full"]
    (q,), (f,) = quick.settings, full.settings
    assert quick.runs == 32 and q.params.snr == (2.0, 4.0, 6.0, 8.0)
    assert (q.params.particles, q.params.tpf_particles, q.params.zeta_sweep_particles) == (500, (500, 250), 250)
    assert full.runs == tbd.DEFAULT_RUNS == 3000 and f.params == Params()
    assert Params().snr == tuple(float(s) for s in range(1, 10)) and Params().focus_snr_db == 6.0


@pytest.mark.parametrize("changes, option", [
    ({"particles": 999}, "--particles"),
    ({"tpf_particles": (80, 41)}, "--tpf-particles"),
    ({"snr": (3.0, 9.0), "focus_snr": 6.0}, "--focus-snr"),
    ({"snr": (3.0, 3.0)}, "--snr"),
    ({"snr": ()}, "--snr"),
    ({"zeta": 1.5}, "--zeta"),
    ({"zeta_sweep": (0.6, -0.1)}, "--zeta-sweep"),
    ({"pfa": 1.0}, "--pfa"),
    ({"snr_convention": "mean"}, "--snr-convention"),
    ({"first_frame": 25}, "--first-frame"),
    ({"initial_state": (1.0, 2.0)}, "--initial-state"),
    ({"blur": 0.0}, "--blur"),
])
def test_invalid_params_name_the_option(changes, option):
    with pytest.raises(InputError, match=option):
        Params(**changes)


def test_claims_are_records_decided_from_the_data(small_run):
    small_results, out = small_run
    records = read_claims(small_results)
    # every claim of the catalogue but the one on SNRs at or below 3 dB, which these runs do not have
    assert sorted(c.id for c in records) == sorted(f"tbd/{slug}" for slug in STATEMENTS if slug != "gain-shrinks-low-snr")
    # the two resting on CPU times are kept apart from the claims that repeat exactly
    assert {c["id"] for c in small_results["timing_claims"]} == {"tbd/time-equal-n", "tbd/time-half-n"}
    by_id = {c.id: c for c in records}
    seconds = [json.loads(path.read_text())["result"]["seconds"] for path in sorted((out / "runs").glob("run-*.json"))]
    for slug, key, factor in (("time-equal-n", "TPFTBD-N80", 1.2), ("time-half-n", "TPFTBD-N40", 0.6)):
        # decided on the per-run CPU-time ratios, paired: log(t_A / t_PF) − log(factor), 5 standard errors
        claim = by_id[f"tbd/{slug}"]
        log_ratio = np.log(np.array([s[key] / s["PFTBD-N80"] for s in seconds]).ravel())
        d = log_ratio - math.log(factor)
        atol = 5.0 * d.std(ddof=1) / math.sqrt(d.size)
        assert claim.timing and claim.threshold == factor
        assert claim.statistic == pytest.approx(math.exp(log_ratio.mean()))
        assert claim.verdict == ("held" if d.mean() < -atol else "NOT held" if d.mean() > atol else "undecided")
        assert f"{key} / PFTBD-N80" in claim.evidence and f"below {factor:g}" in claim.evidence
    gain = small_results["snr_gain"]["TPFTBD-N80"]
    claim = by_id["tbd/snr-gain-equal-n"]
    assert claim.statistic == gain["mean_gain_db"]
    # decided by the bootstrap interval over runs: 5 standard errors around the paper's 1 dB
    atol = 5.0 * small_results["snr_gain_interval"]["TPFTBD-N80"]["se"]
    margin = gain["mean_gain_db"] - 1.0
    assert claim.verdict == ("held" if margin > atol else "NOT held" if margin < -atol else "undecided")
    assert claim.verdict != "undecided" or claim.runs_to_decide == math.ceil(3 * (atol / margin) ** 2)
    pd = small_results["pd_at_pfa"]
    assert by_id["tbd/half-n-detects-as-well"].statistic == pytest.approx(pd["TPFTBD-N40"] - pd["PFTBD-N80"])
    for c in records:
        assert c.paper == "seed004" and c.n == 3 and c.paper_n == 3000 and c.source.startswith("§3.") and c.quote
        assert not c.needs  # a run's summary keeps every per-run value the claims need
        assert any("3 runs" in caution for caution in c.cautions)  # fewer runs than the paper's 3000
        assert ClaimRecord.from_json(json.loads(json.dumps(c.to_json()))) == c


def _fixture_section(tmp_path) -> Section:
    shutil.copytree(FIXTURE, tmp_path / "tbd")
    return tbd_section.render_section(load_section(tmp_path, "tbd"))


def test_report_page_renders_from_a_stored_results_file(tmp_path):
    section = _fixture_section(tmp_path)
    assert isinstance(section, Section) and "Chen et al. 2015" in section.title
    figures = [b for b in section.blocks if isinstance(b, Figure)]
    assert len(figures) == 2 and all(f.path.exists() and f.path.parent == tmp_path / "tbd" for f in figures)
    claims = [b for b in section.blocks if isinstance(b, Table) and b.caption.startswith("Claims")]
    # the accuracy claims and the timing claims in tables of their own, each in the records' order
    assert len(claims) == 2 and [len(t.rows) for t in claims] == [4, 2] and "CPU times" in claims[1].caption
    stored = json.loads((FIXTURE / "tbd-small" / "results.json").read_text())
    rows = [row for t in claims for row in t.rows]
    assert [_verdict(row) for row in rows] == [c.verdict for c in read_claims(stored)]
    assert all(row[0].startswith(c.claim) for row, c in zip(rows, read_claims(stored)))
    assert all("the paper used 3000" in _cautions(row) for row in rows)  # a caution on every row


def _verdict(row) -> str:
    cell = next(c for c in row if str(getattr(c, "verdict", c)) in VERDICTS)
    return str(getattr(cell, "verdict", cell))


def _cautions(row) -> str:
    return " ".join(" ".join(getattr(c, "cautions", ())) + " " + str(c) for c in row)


def test_the_renderer_runs_no_experiment():
    source = Path(tbd_section.__file__).read_text()
    assert "gpfverify.experiments" not in source and "run_for_report" not in source
    assert not hasattr(tbd_section, "build")


def test_reproduce_offers_the_generated_options(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["reproduce", "tbd", "--help"])
    out = capsys.readouterr().out
    assert exit_info.value.code == 0
    for option in ("--snr", "--focus-snr", "--snr-convention", "--particles", "--tpf-particles", "--zeta-sweep",
                   "--patch-radius", "--grid-size", "--runs", "--out"):
        assert option in out


def test_bad_options_are_input_errors(tmp_path, capsys):
    code = main(["reproduce", "tbd", "--snr", "3", "--focus-snr", "6", "--runs", "1", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "focus-snr" in err
    with pytest.raises(SystemExit) as exit_info:  # argparse refuses a value outside the choices
        main(["reproduce", "tbd", "--snr-convention", "mean", "--runs", "1", "--out", str(tmp_path)])
    assert exit_info.value.code == 2 and "--snr-convention" in capsys.readouterr().err
    assert not (tmp_path / "results.json").exists()


def test_pd_at_pfa_matches_a_direct_count():
    rng = np.random.default_rng(0)
    absent = rng.random((50, 30))
    present = rng.random((50, 16)) ** 0.3
    pd, se, tau = tbd.pd_at_pfa(present, absent, 0.05)
    assert (absent > tau).mean() <= 0.05 < (absent >= tau).mean()  # smallest τ with P_fa ≤ 0.05
    assert pd == (present > tau).mean()
    assert se == pytest.approx((present > tau).mean(axis=1).std(ddof=1) / np.sqrt(50))
    roc = tbd.roc_curve(present, absent)
    for i in (1, len(roc["threshold"]) // 2, len(roc["threshold"]) - 2):
        t = roc["threshold"][i]
        assert roc["pd"][i] == sum(v > t for v in present.ravel()) / present.size
        assert roc["pfa"][i] == sum(v > t for v in absent.ravel()) / absent.size


def test_snr_gain_of_a_shifted_curve():
    snrs = np.arange(1.0, 10.0)
    curve = 1 / (1 + np.exp(-(snrs - 5.0)))
    shifted = 1 / (1 + np.exp(-(snrs - 3.5)))  # the same curve 1.5 dB to the left
    gain = tbd.snr_gain(snrs, shifted, curve, levels=11)
    # linear interpolation of a logistic between grid points: exact only at the knots; the shift is
    # 1.5 dB at every level up to the interpolation error of a 1-dB grid
    assert np.all(np.abs(np.array(gain["gain_db"]) - 1.5) < 0.5)
    assert gain["mean_gain_db"] == pytest.approx(np.mean(gain["gain_db"]))
    assert tbd.snr_gain(snrs, np.ones(9), np.zeros(9)) is None


def _records(present, absent, sq_error) -> list[RunRecord]:
    """Run records of one method at one SNR from per-run existence (present / absent frames) and
    squared position errors in the target frames."""
    return [RunRecord((SnrRun(6.0, {"PFTBD-N2": MethodRun(tuple(p), tuple(a), tuple(e))}),), {"PFTBD-N2": 0.0})
            for p, a, e in zip(present, absent, sq_error)]


def test_each_detection_definition_counts_what_it_says():
    """A 6-frame scenario, target in frames 2–5: the statistics each definition compares with τ,
    written out by hand."""
    params = Params(snr=(6.0,), particles=2, tpf_particles=(2,), zeta_sweep=(), frames=6, first_frame=2,
                    last_frame=5, settle_frames=2, detection_gate=1.5)
    present = [[0.1, 0.2, 0.9, 0.8, 0.7, 0.3], [0.0, 0.6, 0.1, 0.95, 0.2, 0.1]]
    absent = [[0.1, 0.3, 0.2, 0.4, 0.1, 0.0], [0.2, 0.1, 0.5, 0.1, 0.3, 0.2]]
    sq_error = [[0.25, 4.0, 1.0, 9.0], [1.0, 0.0, 0.25, 16.0]]  # frames 2–5: error 0.5, 2, 1, 3 / 1, 0, 0.5, 4
    records = _records(present, absent, sq_error)

    def data(**changes):
        return tbd._detection_data(params.replace(**changes), records, 0, "PFTBD-N2")

    target, empty = data(detection="frames")
    assert target.tolist() == [[0.2, 0.9, 0.8, 0.7], [0.6, 0.1, 0.95, 0.2]] and empty.tolist() == absent
    target, empty = data(detection="settled")
    assert target.tolist() == [[0.8, 0.7], [0.95, 0.2]] and empty.tolist() == absent
    target, empty = data(detection="last-frame")
    assert target.tolist() == [[0.7], [0.2]] and empty.tolist() == [[0.1], [0.3]]
    target, empty = data(detection="run")
    assert target.tolist() == [[0.9], [0.95]] and empty.tolist() == [[0.4], [0.5]]
    target, empty = data(detection="track")  # errors above 1.5 cells never count as detections
    assert target.tolist() == [[0.2, -1.0, 0.8, -1.0], [0.6, 0.1, 0.95, -1.0]] and empty.tolist() == absent


def test_detection_definitions_are_summary_only_interpretations(small_run, tmp_path):
    """The detection readings need no runs of their own: their results are the main run's saved
    runs summarised under the changed parameters, at the main run's count."""
    from gpfverify.experiments.sensitivity import run_interpretations, select, summary_only
    from gpfverify.experiments.runner import make_executor

    results, out = small_run
    work = tmp_path / "run"
    shutil.copytree(out, work)
    specs = select(tbd, ",".join(PROFILES["quick"].interpretations))
    assert specs and all(summary_only(tbd, s) for s in specs)
    assert not summary_only(tbd, select(tbd, "snr-energy")[0])
    with make_executor(1) as executor:
        merged = run_interpretations(tbd, SMALL, specs, 3, 5, work, executor)
    assert not any((work / "interpretations" / s.name / "runs").exists() for s in specs)
    run_level = json.loads((work / "interpretations" / "detection-run" / "results.json").read_text())
    assert run_level["params"]["detection"] == "run" and run_level["runs_ok"] == 3
    again = tbd.summarize(SMALL.replace(detection="run"),
                          [from_json(RunRecord, json.loads(p.read_text())["result"])
                           for p in sorted((out / "runs").glob("run-*.json"))])
    assert run_level["pd_at_pfa"] == again["pd_at_pfa"] != results["pd_at_pfa"]
    gain = next(c for c in read_claims(merged) if c.id == "tbd/snr-gain-equal-n")
    assert {i.name for i in gain.interpretations} == {s.name for s in specs}
    assert all(i.n == 3 for i in gain.interpretations)


def test_the_gain_claim_is_shown_under_every_birth_proposal_and_detection_reading():
    """The grid of the SNR-gain claim: one row per birth proposal (the run's own first), one column
    per detection definition, each cell the reading's gain and verdict from the claim record, and the
    verdict under the largest gain named as the one most favourable to the paper; the other
    interpretations (an SNR convention, the verdict as run on fewer runs) stay out of it, and the
    birth × detection readings stay out of the sensitivity table."""
    from gpfverify.contract.claims import AS_RUN, Interpretation

    uniform = {"birth_uniform_share": 1.0, "tpf_particles": [2000], "zeta_sweep": []}
    gain = ClaimRecord("At equal N = 2000, TPFTBD gains at least 1 dB", "src", "NOT held", 0.57, 1.0, 3000, "e",
                       id="tbd/snr-gain-equal-n", interpretations=(
                           Interpretation("detection-last-frame", {"detection": "last-frame"}, "undecided", 1.11, 3000,
                                          19000),
                           Interpretation("birth-uniform", uniform, "undecided", 0.9, 2000, 7000),
                           Interpretation("birth-uniform-detection-last-frame", {**uniform, "detection": "last-frame"},
                                          "held", 1.4, 2000),
                           Interpretation("detection-settled-3", {"detection": "settled", "settle_frames": 3},
                                          "NOT held", 0.7, 3000),
                           Interpretation("detection-settled-5", {"detection": "settled", "settle_frames": 5},
                                          "NOT held", 0.86, 3000),
                           Interpretation(AS_RUN, {}, "NOT held", 0.55, 2000),
                           Interpretation("snr-energy", {"snr_convention": "energy"}, "NOT held", 0.47, 200)))
    blocks = tbd_section._detection_blocks(Params(), [gain])
    grid = next(b for b in blocks if isinstance(b, Table))
    # the two settled readings (3 and 5 frames left out) are two columns
    assert grid.headers == ["birth proposal", "detection 'frames'", "detection 'last-frame'",
                            "detection 'settled, 3 frames'", "detection 'settled, 5 frames'"]
    assert grid.rows == [
        ["cells above 1σ, 10 % uniform (3000 runs)", "0.57 dB: NOT held",
         "1.11 dB: undecided, about 19000 runs would decide", "0.7 dB: NOT held", "0.86 dB: NOT held"],
        ["uniform over the image (2000 runs)", "0.9 dB: undecided, about 7000 runs would decide", "1.4 dB: held",
         "—", "—"]]
    # the headline is the verdict as run; the largest reading's gain is a bound, said with how many readings there are
    favourable = next(b.text for b in blocks if isinstance(b, Paragraph) and "most favourable" in b.text)
    assert favourable.startswith("The headline is the verdict as run — birth proposal 'cells above 1σ, 10 % uniform', "
                                 "detection 'frames': 0.57 dB, NOT held.")
    assert ("The most favourable of the 6 readings tried reaches 1.4 dB (birth proposal 'uniform over the image', "
            "detection 'last-frame', 2000 runs; that reading alone: held): a bound") in favourable
    sensitivity = tbd_section._sensitivity_blocks([gain])
    shown = {name for block in sensitivity if isinstance(block, Table) for row in block.rows for name in row[:1]}
    assert "birth-uniform" in shown and "birth-uniform-detection-last-frame" not in shown
