"""The fusion paper's experiments as typed contracts: Params, run records and claims round-trip
through JSON; invalid parameters name the option; the command line is generated from Params; the
profiles hold the paper's settings; method keys are Method values."""

import json
import subprocess
import sys

import numpy as np
import pytest

from gpfverify.contract import ClaimRecord, Method, from_json, to_json
from gpfverify.papers.fusion import ct2d_contract
from gpfverify.papers.fusion import ungm1d_contract
from gpfverify.papers.fusion.contract import FAMILIES, LOCAL_FILTERS, METHODS, FusionRun
from gpfverify.errors import InputError
from gpfverify.papers.fusion import ct2d_experiment as ct2d
from gpfverify.papers.fusion import ungm1d_experiment as ungm1d


def _round_trip(tp, value):
    return from_json(tp, json.loads(json.dumps(to_json(value))))


@pytest.mark.parametrize("params", [ct2d.Params(), ct2d.Params(kappa=30, omega=0.5, rank_tol=1e-3,
                                                                perturbation_mean=5.0, rcc_size=9.0),
                                    ungm1d.Params(), ungm1d.Params(sweep=(), system_noise_var=2.0)],
                         ids=["ct2d", "ct2d-overrides", "ungm1d", "ungm1d-no-sweep"])
def test_params_round_trip(params):
    assert _round_trip(type(params), params) == params
    assert type(params).from_json(json.loads(json.dumps(params.to_json()))) == params


def test_run_records_and_claims_round_trip():
    record = ct2d.run_one(ct2d.Params(kappa=10, test_steps=2, fit_points=10), np.random.SeedSequence(5))
    assert isinstance(record, FusionRun) and _round_trip(ct2d.RunRecord, record) == record
    both = ungm1d.run_one(ungm1d.Params(train=10, test_steps=2, fit_points=10, sweep=(2.0,)),
                          np.random.SeedSequence(5))
    assert set(both.settings) == {"1.0", "2.0"} and _round_trip(ungm1d.RunRecord, both) == both
    body = ct2d.summarize(ct2d.Params(kappa=10, test_steps=2, fit_points=10), [record])
    for claim in body["claims"]:
        assert ClaimRecord.from_json(json.loads(json.dumps(to_json(claim)))) == claim
    # one run: every paired verdict is undecided, never a decision from one sample
    assert all(c.verdict == "undecided" for c in body["claims"] if "beats" in c.id)


@pytest.mark.parametrize("make, option", [
    (lambda: ct2d.Params(kappa=2), "--train-points"),
    (lambda: ct2d.Params(test_steps=0), "--test-steps"),
    (lambda: ct2d.Params(fit_points=2), "--fit-points"),
    (lambda: ct2d.Params(process_noise_var=-1.0), "--process-noise-var"),
    (lambda: ct2d.Params(rcc_size=0.0), "--rcc-size"),
    (lambda: ct2d.Params().replace(perturbation_std=-1.0), "--perturbation-std"),
    (lambda: ct2d.Params(sensor_positions=((0.0, 1.0),)), "sensor_positions"),
    (lambda: ungm1d.Params(sweep=(1.0, float("inf"))), "--sweep"),
    (lambda: ungm1d.Params(system_noise_var=0.0), "--system-noise-var"),
    (lambda: ungm1d.Params(train=2), "--train-points"),
    (lambda: ungm1d.Params(measurement_noise_var=-0.01), "--measurement-noise-var"),
])
def test_invalid_params_name_the_option(make, option):
    with pytest.raises(InputError, match=option):
        make()


@pytest.mark.parametrize("name, options", [
    ("ct2d", ["--train-points", "--kappa", "--omega", "--test-steps", "--perturbation-mean", "--perturbation-std", "--rank-tol",
              "--fit-points", "--rcc-size", "--sigma-kappa", "--process-noise-var", "--bearing-noise-var"]),
    ("ungm1d", ["--system-noise-var", "--sweep", "--measurement-noise-var", "--prior-var", "--train-points",
                "--test-steps", "--fit-points"]),
])
def test_reproduce_help_shows_the_generated_options(name, options):
    out = subprocess.run([sys.executable, "-m", "gpfverify", "reproduce", name, "--help"], capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    for option in options:
        assert option in out.stdout


def test_profiles_hold_the_papers_settings():
    full = ct2d_contract.PROFILES["full"]
    assert full.runs == 1000
    assert [(s.params.kappa, s.params.omega) for s in full.settings] == list(ct2d_contract.PAPER_SETTINGS)
    assert [s.label for s in full.settings] == ["κ = 300, Ω = 2π/90", "κ = 300, Ω = 0.5", "κ = 30, Ω = 2π/90",
                                                "κ = 60, Ω = 2π/90"]
    assert [s.tag for s in full.settings] == ["k300-w0.0698", "k300-w0.5000", "k30-w0.0698", "k60-w0.0698"]
    quick = ct2d_contract.PROFILES["quick"]
    assert quick.runs < full.runs and [s.params.kappa for s in quick.settings] == [300, 30]
    u = ungm1d_contract.PROFILES
    assert u["full"].runs == 1000 and u["full"].settings[0].params.noise_vars == (0.5, 1.0, 2.0, 3.0)
    assert u["quick"].settings[0].params.noise_vars == (1.0, 2.0)


def test_methods_are_values_with_the_contract_keys():
    assert [m.key for m in METHODS[:6]] == ["Sensor1-GP-ADF", "Sensor2-GP-ADF", "CMF-GP-ADF", "DMF-GP-ADF",
                                            "RCC-CI-GP-ADF", "CW-GP-ADF"]
    assert all(Method.parse(m.key) == m for m in METHODS)
    assert {m.family for m in METHODS} == set(FAMILIES) and all(m.is_sensor for m in LOCAL_FILTERS)


def test_report_sections_import_nothing_from_the_experiments():
    code = ("import sys; import gpfverify.papers.fusion.ct2d_section, gpfverify.papers.fusion.ungm1d_section; "
            "print(sorted(m for m in sys.modules if m.startswith('gpfverify.experiments')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"
