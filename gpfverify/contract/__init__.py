"""Typed contracts between the experiments, the command line and the report: parameters
(:mod:`.params`), method names (:mod:`.methods`), claim records (:mod:`.claims`), the papers
(:mod:`.papers`), profiles and section indexes (:mod:`.experiment`), and one JSON reader/writer
for all of them (:mod:`.serial`). Nothing here computes a result; the report imports these types
and never the experiments."""

from gpfverify.contract.claims import (VERDICTS, ClaimRecord, Interpretation, PairedDifference, PairedRatio,
                                       Verdict, combine, read_claims, verdict_of)
from gpfverify.contract.experiment import Profile, RunEntry, SectionRuns, Setting
from gpfverify.contract.methods import FAMILIES, Method
from gpfverify.contract.papers import PAPERS, Paper
from gpfverify.contract.params import Params, option
from gpfverify.contract.serial import from_json, to_json

__all__ = ["FAMILIES", "PAPERS", "VERDICTS", "ClaimRecord", "Interpretation", "Method", "PairedDifference",
           "PairedRatio", "Paper", "Params", "Profile", "RunEntry", "SectionRuns", "Setting", "Verdict", "combine",
           "from_json", "option", "read_claims", "to_json", "verdict_of"]
