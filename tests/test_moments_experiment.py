"""The moments experiment: the closed-form GP moments at a Gaussian input against quadrature and
Monte Carlo as a typed experiment (parameters, run record, claims, command line), its claims on a
tiny seeded run and on a corrupted record (negative control), and the report page rendered from a
stored results.json."""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from gpfverify.cli import main
from gpfverify.contract.claims import read_claims
from gpfverify.contract.experiment import RunEntry, SectionRuns
from gpfverify.papers.fusion.moments_contract import (FULL_SAMPLES, PROFILES, QUICK_SAMPLES, CaseShape, Moments, Params,
                                        RunRecord)
from gpfverify.contract.serial import from_json, to_json
from gpfverify.errors import InputError
from gpfverify.papers import EXPERIMENTS
from gpfverify.papers.fusion import moments_experiment as moments
from gpfverify.experiments.runner import run_experiment
from gpfverify.report.inputs import SectionInput
from gpfverify.papers.fusion import moments_section as section
from gpfverify.tolerances import MONTE_CARLO_SIGMAS

FIXTURE = Path(__file__).parent / "fixtures" / "moments" / "results.json"
#: a tiny problem set: two cases, few samples, small quadrature grids
TINY = Params(cases=(CaseShape(1, 1), CaseShape(2, 2)), samples=2000, train_points=15, restarts=1,
              quadrature_max_nodes=2000)


def test_registered_as_an_experiment():
    assert EXPERIMENTS["moments"] == "gpfverify.papers.fusion.moments_experiment"
    assert moments.NAME == "moments" and moments.PAPER == "seed000"


def test_params_round_trip_and_validate():
    for params in (Params(), TINY):
        assert Params.from_json(json.loads(json.dumps(params.to_json()))) == params
    for option, bad in (("samples", 10), ("quadrature_rtol", 0.0), ("train_points", 1), ("restarts", 0),
                        ("input_cov_scale", -1.0), ("quadrature_max_nodes", 5)):
        with pytest.raises(InputError, match="--" + option.replace("_", "-")):
            Params(**{option: bad})
    for cases in ((), (CaseShape(5, 1),), (CaseShape(1, 0),)):
        with pytest.raises(InputError, match="cases"):
            Params(cases=cases)
    with pytest.raises(InputError, match="--samples"):
        TINY.replace(samples=1)


def test_profiles_keep_the_sample_counts():
    quick, full = PROFILES["quick"], PROFILES["full"]
    assert [s.params.samples for s in quick.settings] == [QUICK_SAMPLES]
    assert [s.params.samples for s in full.settings] == [FULL_SAMPLES] == [Params().samples]
    assert quick.runs <= full.runs == moments.DEFAULT_RUNS


@pytest.fixture(scope="module")
def tiny_record():
    return moments.run_one(TINY, np.random.SeedSequence(5))


def test_run_record_round_trips(tiny_record):
    assert isinstance(tiny_record, RunRecord)
    assert from_json(RunRecord, json.loads(json.dumps(to_json(tiny_record)))) == tiny_record
    assert [c.shape for c in tiny_record.cases] == list(TINY.cases)
    case = tiny_record.cases[1]
    assert np.shape(case.closed_form.cov) == (2, 2) and np.shape(case.closed_form.cross_cov) == (2, 2)
    assert sum(tiny_record.illustration.histogram_density) > 0


def test_run_depends_on_its_seed_alone(tiny_record):
    seed = np.random.SeedSequence(5)
    seed.spawn(4)  # a sequence that already spawned children gives the same run
    again = moments.run_one(TINY, seed)
    assert (again.cases, again.illustration) == (tiny_record.cases, tiny_record.illustration)


@pytest.fixture(scope="module")
def tiny_results(tmp_path_factory):
    return run_experiment(moments, TINY, runs=2, seed=1, out_dir=tmp_path_factory.mktemp("moments"),
                          show_progress=False)


def test_closed_form_agrees_with_both_oracles(tiny_results):
    records = {c.id: c for c in read_claims(tiny_results)}
    quad = records["moments/closed-form-equals-quadrature"]
    mc = records["moments/closed-form-equals-monte-carlo"]
    assert quad.verdict == "held" and quad.statistic <= quad.threshold == 1.0
    assert mc.verdict == "held" and mc.statistic <= mc.threshold == MONTE_CARLO_SIGMAS
    assert all(c.n == 2 and c.paper == "seed000" and c.paper_n is None for c in records.values())
    assert [c["label"] for c in tiny_results["cases"]] == ["D = 1, E = 1", "D = 2, E = 2"]
    assert max(c["max_z"] for c in tiny_results["cases"]) == mc.statistic
    assert set(tiny_results["time_per_run"]) == {"closed-form", "Gauss-Hermite", "Monte-Carlo"}


def _shift(m: Moments, field: str, delta: float) -> Moments:
    value = np.array(getattr(m, field), dtype=float)
    value.flat[0] += delta
    return dataclasses.replace(m, **{field: tuple(value.tolist()) if value.ndim == 1 else
                                     tuple(tuple(row) for row in value.tolist())})


def test_a_wrong_closed_form_is_caught(tiny_record):
    """Negative control: a closed-form mean off by 1e-6 of the covariance scale fails the
    quadrature claim but not Monte Carlo; off by 20 standard errors it fails Monte Carlo too."""
    case = tiny_record.cases[0]
    scale = float(np.max(np.abs(case.quadrature.cov)))
    small = dataclasses.replace(case, closed_form=_shift(case.closed_form, "mean", 1e-6 * scale))
    large = dataclasses.replace(case, closed_form=_shift(case.closed_form, "mean",
                                                         20 * case.monte_carlo_se.mean[0]))
    for bad, expected in ((small, ("NOT held", "held")), (large, ("NOT held", "NOT held"))):
        record = dataclasses.replace(tiny_record, cases=(bad, *tiny_record.cases[1:]))
        assert tuple(c.verdict for c in moments.claims(TINY, [record])) == expected


def test_a_quadrature_without_an_error_estimate_cannot_decide(tiny_record):
    case = dataclasses.replace(tiny_record.cases[0], quadrature_change=float("inf"))
    record = dataclasses.replace(tiny_record, cases=(case, *tiny_record.cases[1:]))
    quad = moments.claims(TINY, [record])[0]
    assert quad.verdict == "not decidable" and any("no error estimate" in c for c in quad.caveats)


def test_report_page_renders_from_a_stored_results_file(tmp_path):
    """The page from the committed fixture (2 runs, 2000 samples): no experiment runs."""
    results = json.loads(FIXTURE.read_text(encoding="utf-8"))
    runs = SectionRuns("moments", "quick", results["seed"],
                       (RunEntry("moments", "", "default", "moments-default/run/results.json"),))
    page = section.render_section(SectionInput("moments", tmp_path, runs, (results,)))
    assert (tmp_path / "moment_matching.png").stat().st_size > 0
    tables = [b for b in page.blocks if hasattr(b, "rows")]
    claims = [t for t in tables if t.caption.startswith("Claims")]
    assert len(claims) == 1 and len(claims[0].rows) == len(results["claims"]) == 2
    cases = [t for t in tables if t.caption.startswith("Closed form")]
    assert [row[0] for row in cases[0].rows] == [c["label"] for c in results["cases"]]
    text = " ".join(b.text for b in page.blocks if hasattr(b, "text"))
    assert "Liao et al. 2019" in text and f"{results['params']['samples']} samples" in text
    assert "_" not in text.replace("E[f]", "")  # no internal identifiers in the prose


def test_report_section_imports_no_experiment():
    source = Path(section.__file__).read_text(encoding="utf-8")
    assert "gpfverify.experiments" not in source and "gpfverify.gp" not in source
    assert not hasattr(section, "build")


def test_reproduce_lists_and_runs_moments(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["reproduce", "--help"])
    assert exit_info.value.code == 0 and "moments" in capsys.readouterr().out
    with pytest.raises(SystemExit) as exit_info:
        main(["reproduce", "moments", "--help"])
    out = capsys.readouterr().out
    for option in ("--samples", "--quadrature-rtol", "--quadrature-max-nodes", "--train-points", "--restarts"):
        assert option in out
    out_dir = tmp_path / "cli"
    assert main(["reproduce", "moments", "--runs", "1", "--samples", "500", "--train-points", "12",
                 "--restarts", "1", "--quadrature-max-nodes", "1000", "--out", str(out_dir)]) == 0
    results = json.loads((out_dir / "results.json").read_text())
    assert results["experiment"] == "moments" and results["params"]["samples"] == 500
    assert len(results["claims"]) == 2
    capsys.readouterr()
    assert main(["reproduce", "moments", "--samples", "3", "--out", str(tmp_path / "bad")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--samples" in err[0]
    assert not (tmp_path / "bad").exists()
