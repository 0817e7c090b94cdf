"""A tiny typed experiment for runner, command-line and sensitivity tests: each run draws numbers
from its own stream; one claim ("the mean is near zero") whose verdict an interpretation flips."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gpfverify.contract import ClaimRecord, Params, PairedDifference, Profile, Setting, option
from gpfverify.contract.interpretations import InterpretationSpec
from gpfverify.usercode import Interrupted

NAME = "toy"
PAPER = "seed000"
DEFAULT_RUNS = 4


@dataclass(frozen=True)
class Params(Params):  # noqa: F811 - the experiment's own Params, as every experiment names it
    scale: float = option(1.0, "standard deviation of the draws", above=0.0)
    shift: float = option(0.0, "mean of the draws")
    fail_run: int = option(-1, "index of a run that raises (-1: none)")
    interrupt_run: int = option(-1, "index of a run that is interrupted as by Ctrl-C (-1: none)")
    limit: float = option(1.0, "the claim: each run's mean is below this")


@dataclass(frozen=True)
class RunRecord:
    x: tuple[float, ...]


PROFILES = {"quick": Profile(3, (Setting("", "default", Params()),)),
            "full": Profile(DEFAULT_RUNS, (Setting("", "default", Params()),))}
#: "wide-strict" reads the runs of "wide" with another limit (no runs of its own)
SUMMARY_FIELDS = frozenset({"limit"})
INTERPRETATIONS = (InterpretationSpec("shifted", {"shift": 10.0}, "draws centred at 10"),
                   InterpretationSpec("wide", {"scale": 3.0}, "draws three times wider"),
                   InterpretationSpec("wide-strict", {"scale": 3.0, "limit": -5.0}, "wide draws, a stricter claim"))


def run_one(params: Params, seed) -> RunRecord:
    if seed.spawn_key[-1] == params.fail_run:
        raise RuntimeError("planned failure")
    if seed.spawn_key[-1] == params.interrupt_run:
        raise Interrupted  # as gpfverify's signal handler raises it when the user presses Ctrl-C
    rng = np.random.default_rng(seed)
    return RunRecord(tuple((params.shift + params.scale * rng.standard_normal(3)).tolist()))


def summarize(params: Params, records: list[RunRecord]) -> dict:
    x = np.array([r.x for r in records])
    above = PairedDifference.of(x.mean(axis=1), np.full(len(records), params.limit))  # mean below the limit?
    claim = ClaimRecord("the draws' mean is below 1", "toy", above.verdict, above.mean, above.atol, above.n,
                        "paired difference of each run's mean and 1", id="toy/mean-below-1", paper=PAPER,
                        paper_n=DEFAULT_RUNS)
    timed = ClaimRecord("the toy is fast", "toy", "held", 0.0, 1.0, len(records), "no time at all", id="toy/time",
                        paper=PAPER, timing=True)
    return {"mean": x.mean(axis=0).tolist(), "time_per_run": {"toy": 0.0}, "claims": [timed, claim]}
