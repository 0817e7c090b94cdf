"""The tbd experiment: results.json per CONTRACT.md, determinism, metrics against direct counts,
the report page, and CLI errors."""

import json

import numpy as np
import pytest

from gpfverify.cli import main
from gpfverify.errors import InputError
from gpfverify.experiments import tbd
from gpfverify.experiments.runner import run_experiment, without_timing
from gpfverify.report.document import Figure, Section, Table
from gpfverify.report.sections import tbd as tbd_section

SMALL = ("--snr", "4", "6", "9", "--particles", "80", "--tpf-particles", "80", "40",
         "--zeta-sweep-particles", "40", "--zeta-sweep", "1", "0.6", "0.4")


@pytest.fixture(scope="module")
def small_results(tmp_path_factory):
    params = tbd.default_params(SMALL)
    return run_experiment(tbd, params, 3, 5, tmp_path_factory.mktemp("tbd"), show_progress=False)


def _numbers(results):
    return without_timing(results)


def test_results_follow_the_contract(small_results):
    r = small_results
    assert r["experiment"] == "tbd" and r["runs"] == 3 and r["seed"] == 5 and r["runs_ok"] == 3
    keys = {"PFTBD-N80", "TPFTBD-N80", "TPFTBD-N40"}
    frames = r["params"]["scenario"]["frames"]
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
    json.dumps(r, allow_nan=False)  # strict JSON: absent frames are null, not NaN


def test_same_numbers_for_the_same_seed(small_results, tmp_path):
    again = run_experiment(tbd, tbd.default_params(SMALL), 3, 5, tmp_path, show_progress=False)
    assert _numbers(again) == _numbers(small_results)


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


def test_report_page_renders_from_results(small_results, tmp_path):
    section = tbd_section.render(small_results, tmp_path)
    assert isinstance(section, Section)
    figures = [b for b in section.blocks if isinstance(b, Figure)]
    assert len(figures) == 2 and all(f.path.exists() for f in figures)
    claims = [b for b in section.blocks if isinstance(b, Table) and b.caption.startswith("Claims")]
    assert len(claims) == 1 and len(claims[0].rows) == 6
    assert {row[1] for row in claims[0].rows} <= {"held", "NOT held", "undecided"}


def test_bad_options_are_input_errors(tmp_path, capsys):
    with pytest.raises(InputError, match="focus-snr"):
        tbd.default_params(("--snr", "3", "9", "--focus-snr", "6"))
    with pytest.raises(InputError, match="n_particles"):
        tbd.default_params(("--particles", "999"))
    code = main(["reproduce", "tbd", "--snr", "3", "--focus-snr", "6", "--runs", "1", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "focus-snr" in err
