"""The typed contracts: JSON round trips, strict reading, options generated from Params, method
names and claim records."""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass
from typing import Literal

import pytest
from hypothesis import given
from hypothesis import strategies as st

from gpfverify.contract import (FAMILIES, ClaimRecord, Interpretation, Method, PairedDifference, Params,
                                SectionRuns, combine, from_json, option, to_json)
from gpfverify.contract.params import add_arguments, from_arguments
from gpfverify.errors import InputError


@dataclass(frozen=True)
class Example(Params):
    kappa: int = option(300, "training samples", minimum=3)
    omega: float = option(0.0698, "turn rate, rad/s", above=0.0)
    positions: tuple[tuple[float, float], ...] = option(((-200.0, 200.0), (200.0, 200.0)), "sensor positions")
    tol: float | None = option(None, "rank tolerance")
    convention: Literal["peak", "total"] = option("peak", "SNR convention")
    weighted: bool = option(False, "weight the runs")

    def check(self) -> None:
        if self.kappa > 10_000:
            raise InputError("--kappa above 10000 is not supported")


def test_params_round_trip_through_json_text():
    p = Example(kappa=30, tol=1e-3, convention="total", positions=((1.0, 2.0),))
    again = Example.from_json(json.loads(json.dumps(p.to_json())))
    assert again == p and isinstance(again.positions, tuple) and isinstance(again.positions[0], tuple)


@pytest.mark.parametrize("changes, message", [
    ({"kappa": 2}, "--kappa must be at least 3"),
    ({"omega": 0.0}, "--omega must be greater than 0"),
    ({"omega": float("nan")}, "--omega must be finite"),
    ({"kappa": 3.5}, "--kappa must be an integer"),
    ({"kappa": True}, "--kappa must be an integer"),
    ({"convention": "mean"}, "--convention must be one of"),
    ({"kappa": 20_000}, "above 10000"),
    ({"positions": ((1.0,),)}, "--positions[0] must be a list of 2"),
])
def test_invalid_params_name_the_option(changes, message):
    with pytest.raises(InputError, match=message.replace("[", r"\[").replace("]", r"\]")):
        Example(**changes)


def test_from_json_rejects_unknown_and_mistyped_fields():
    with pytest.raises(InputError, match="unknown field"):
        Example.from_json({"kappa": 30, "kapa": 3})
    with pytest.raises(InputError, match="params.omega must be a number"):
        Example.from_json({"omega": "0.5"})
    assert Example.from_json({}) == Example()


def test_command_line_options_come_from_the_fields():
    parser = argparse.ArgumentParser()
    add_arguments(parser, Example)
    args = parser.parse_args(["--kappa", "30", "--tol", "1e-3", "--convention", "total", "--weighted"])
    assert from_arguments(Example, args) == Example(kappa=30, tol=1e-3, convention="total", weighted=True)
    assert from_arguments(Example, parser.parse_args([])) == Example()
    assert "--positions" not in parser.format_help()  # tuple fields are not offered
    assert "training samples (default 300)" in parser.format_help()
    with pytest.raises(SystemExit):
        parser.parse_args(["--convention", "mean"])


families = st.sampled_from((None, *FAMILIES))
rules = st.sampled_from(("CMF", "DMF", "RCC-CI", "CW", "PF", "UPF", "IE-PFF", "GPSR-UPF", "PF-TBD"))
methods = st.one_of(st.builds(Method, rules, families),
                    st.builds(Method.sensor_filter, st.integers(1, 99), families))


@given(methods)
def test_method_key_parses_back(method):
    assert Method.parse(method.key) == method


def test_method_keys_are_the_contract_names():
    assert Method.sensor_filter(2, "GP-UKF").key == "Sensor2-GP-UKF"
    assert Method("RCC-CI", "GP-ADF").key == "RCC-CI-GP-ADF"
    assert Method.parse("CMF-SR-UKF") == Method("CMF", "SR-UKF")
    with pytest.raises(InputError):
        Method("CMF", "gp-adf")  # one spelling
    with pytest.raises(InputError):
        Method("Sensor", "GP-ADF")  # a sensor filter needs its number


def test_claim_record_round_trip_and_cautions():
    claim = ClaimRecord("DMF = CMF", "Liao et al. 2019, Prop. 1", "held", 1e-15, 1e-12, 3, "gap within rounding",
                        caveats=("quick profile",), interpretations=(
                            Interpretation("numpy rank rule", {"rank_rule": "numpy"}, "NOT held", 0.02),),
                        id="ct2d/dmf-equals-cmf/GP-ADF", paper="seed000", paper_n=1000, timing=True)
    assert ClaimRecord.from_json(json.loads(json.dumps(claim.to_json()))) == claim
    assert claim.cautions[0] == "rests on 3 runs; the paper used 1000" and "CPU times" in claim.cautions[1]
    assert len(claim.cautions) == 2
    assert ClaimRecord("c", "s", "held", 0.0, 0.0, 1000, "e", paper_n=1000).cautions == []
    with pytest.raises(InputError, match="verdict must be one of"):
        ClaimRecord.from_json({**claim.to_json(), "verdict": "maybe"})


def test_paired_difference_decides_by_five_standard_errors():
    assert PairedDifference.of([1.0, 2.0, 3.0, 4.0], [3.0, 4.1, 5.0, 6.1]).verdict == "held"
    assert PairedDifference.of([3.0, 4.1, 5.0, 6.1], [1.0, 2.0, 3.0, 4.0]).verdict == "NOT held"
    assert PairedDifference.of([1.0, 2.0, 3.0, 4.0], [1.1, 1.9, 3.1, 3.9]).verdict == "undecided"
    assert PairedDifference.of([1.0], [2.0]).atol is None
    close = PairedDifference.of([1.0, 2.0, 3.0, 4.0], [1.1, 1.9, 3.1, 3.9])
    assert close.runs_to_decide is None  # mean difference exactly 0
    undecided = PairedDifference.of([1.0, 2.0, 3.0, 4.0, 5.0], [1.3, 1.9, 3.3, 3.9, 5.3])
    assert undecided.verdict == "undecided"
    more = undecided.runs_to_decide
    assert more is not None and more > undecided.n
    # at that many runs with the same mean and spread the interval excludes zero
    assert undecided.atol * (undecided.n / more) ** 0.5 <= abs(undecided.mean) + 1e-12
    assert combine(["held", "undecided"]) == "undecided" and combine(["held", "NOT held"]) == "NOT held"
    assert combine(["held", "held"]) == "held"


def test_section_runs_round_trip():
    runs = from_json(SectionRuns, to_json(SectionRuns("ct2d", "quick", 1, ())))
    assert runs == SectionRuns("ct2d", "quick", 1, ())
