"""Claim records carry what a page says about them — the kind and exact source of a claim, the
health of every filter it compares, why a verdict was withheld or not judged — and every word is
rendered from those fields: a caveat's text never decides a health word, a diagnostic is never
counted as the paper's claim, a claim true by construction is never counted as evidence, a
favourable reading is never the headline, and every claim of the committed pages names its source.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gpfverify.contract.claims import (ACCURACY, AS_RUN, BY_CONSTRUCTION, DIAGNOSTIC, PROPOSITION_1, TIMING, Band,
                                       ClaimRecord, Interpretation, Statement, carry, read_claims)
from gpfverify.contract.health_records import FilterHealth, HealthCheck
from gpfverify.errors import InputError
from gpfverify.health import divergence_check, ess_check, nees_values_check
from gpfverify.papers.tbd.contract import (BIRTH_DETECTION_INTERPRETATIONS, BIRTH_INTERPRETATIONS,
                                           DETECTION_INTERPRETATIONS, IMAGE_EXIT_INTERPRETATIONS)
from gpfverify.report.claim_words import NO_CHECKS, health_summary, health_words, source_words, verdict_note
from gpfverify.report.document import claim_records_table, claim_tables, not_held_note
from gpfverify.report.inputs import VerdictCounts

REFERENCE = Path(__file__).resolve().parents[1] / "reports" / "reference"
COMMITTED = sorted(REFERENCE.rglob("results.json"))


def _record(verdict="held", **kw) -> ClaimRecord:
    fields = dict(claim="c", source="s", verdict=verdict, statistic=0.0, threshold=0.0, n=10, evidence="e", id="x/y")
    return ClaimRecord(**{**fields, **kw})


GOOD = ess_check("PF", np.full(10, 0.5), 100)
COLLAPSED = ess_check("UPF", np.full(10, 0.01), 100)
DIVERGED = divergence_check("IE-PFF", np.array([[0.0, np.nan], [0.0, 0.0]]), bound=1.0)
OPTIMISTIC = nees_values_check("PF", np.full((200, 20), 4.0), 2)


# ---- the gate and the words of health ----------------------------------------------------------------

def test_a_failed_gate_withholds_the_verdict_and_keeps_what_the_runs_gave():
    claim = _record("NOT held").checked(["PF", "UPF"], [GOOD, COLLAPSED])
    assert claim.verdict == "not decidable" and claim.would_be == "NOT held" and claim.runs_to_decide is None
    assert [h.subject for h in claim.failed_filters] == ["UPF"]
    assert "the runs gave 'NOT held'" in verdict_note(claim) and "UPF (weight collapse)" in verdict_note(claim)
    stands = _record("NOT held").checked(["PF"], [GOOD, COLLAPSED])
    assert stands.verdict == "NOT held" and stands.would_be is None and verdict_note(stands) == ""
    with pytest.raises(InputError, match="would_be"):
        _record("held", would_be="NOT held")


def test_a_theorem_and_a_claim_gated_part_by_part_are_not_withheld_whole():
    theorem = _record("held", theorem=PROPOSITION_1).checked(["UPF"], [COLLAPSED])
    assert theorem.verdict == "held" and theorem.failed_filters and "do not withhold" in health_words(theorem)
    parts = _record("NOT held", parts_gated=True).checked(["UPF", "PF"], [COLLAPSED, GOOD])
    assert parts.verdict == "NOT held" and "withheld each comparison" in health_words(parts)


def test_no_checks_run_is_not_none_failed():
    assert health_words(_record()) == NO_CHECKS and health_summary(_record()) == NO_CHECKS
    unchecked = _record().checked(["PF", "EKF"], [GOOD])
    assert unchecked.health[1] == FilterHealth("EKF", ())
    assert f"{NO_CHECKS} of EKF" in health_words(unchecked)
    assert "1 of the 2 compared filters passed every health gate" in health_words(unchecked)
    assert health_summary(unchecked).startswith(NO_CHECKS)


@pytest.mark.parametrize("caveat", ["health of the filters compared: every check passed", "NEES check failed",
                                    "a filter diverged", "N_eff collapsed", "health: fine"])
def test_health_words_come_from_the_records_never_from_a_caveats_words(caveat):
    failed = _record("NOT held", caveats=(caveat,)).checked(["UPF"], [COLLAPSED])
    passed = _record("NOT held", caveats=(caveat,)).checked(["PF"], [GOOD])
    assert "FAILED weight collapse" in health_words(failed) and health_summary(failed).startswith("a compared filter")
    assert "FAILED" not in health_words(passed) and "passed every health gate" in health_words(passed)
    assert not_held_note(passed).endswith("health: every compared filter passed its health gates")
    (row,) = claim_records_table([passed]).rows
    assert row[4] == health_words(passed) and caveat in row[5]


def test_nees_outside_its_band_is_a_consistency_finding_never_a_failed_gate():
    assert not OPTIMISTIC.passed and not OPTIMISTIC.is_gate
    claim = _record("held").checked(["PF"], [GOOD, OPTIMISTIC])
    assert claim.verdict == "held" and not claim.failed_filters
    words = health_words(claim)
    assert "FAILED" not in words and "consistency, not a gate" in words and "outside for PF" in words
    assert "NEES finding" in health_summary(claim) and "failed" not in health_summary(claim)


# ---- kinds, sources, groups and counts --------------------------------------------------------------

def test_a_paper_claim_names_its_sentence_or_its_figure_table_or_equation():
    with pytest.raises(InputError, match="names its sentence"):
        Statement("claim", "§3")
    assert Statement("claim", "§3, Table 1").quote == ""
    assert Statement("diagnostic", "the toolkit's own").kind == "diagnostic"
    quoted = Statement("claim", "§4.1, Fig. 4", "From Figure 4, we can see ...").applied(_record())
    assert source_words(quoted) == "§4.1, Fig. 4: “From Figure 4, we can see ...”"
    assert source_words(Statement("diagnostic", "not the paper's").applied(_record())).startswith("diagnostic")


def test_diagnostics_and_claims_true_by_construction_are_counted_apart_from_the_papers_claims():
    records = [_record("held"), _record("NOT held", timing=True), _record("held", kind="diagnostic"),
               _record("held", timing=True, by_construction="more λ-steps take more time"),
               _record("held", theorem=PROPOSITION_1), _record("NOT held", kind="diagnostic", timing=True)]
    assert [r.group for r in records] == [ACCURACY, TIMING, DIAGNOSTIC, BY_CONSTRUCTION, PROPOSITION_1, DIAGNOSTIC]
    counts = VerdictCounts.of(records)
    assert [g.group for g in counts.groups] == [ACCURACY, PROPOSITION_1, TIMING, BY_CONSTRUCTION, DIAGNOSTIC]
    assert counts.group(ACCURACY).counts["held"] == 1 and counts.group(TIMING).counts == \
        {"held": 0, "NOT held": 1, "undecided": 0, "not decidable": 0}
    assert counts.group(DIAGNOSTIC).total == 2 and counts.group(BY_CONSTRUCTION).total == 1
    captions = [t.caption for t in claim_tables(records, "Claims")]
    assert any("diagnostics" in c for c in captions) and any("by construction" in c for c in captions)
    assert "not counted as evidence" in verdict_note(records[3])


# ---- verdicts the records decide ---------------------------------------------------------------------

def test_a_band_is_held_inside_not_held_outside_and_says_the_runs_that_would_decide():
    assert Band.of(0.5, 0.1, 0.25, 0.75, 100).verdict == "held"
    assert Band.of(1.0, 0.1, 0.25, 0.75, 100).verdict == "NOT held"
    open_ = Band.of(0.7, 0.1, 0.25, 0.75, 100)
    assert open_.verdict == "undecided" and open_.runs_to_decide == 400  # margin 0.05: (0.1 / 0.05)² × 100
    assert Band.of(2.0, 0.1, 1.0, np.inf, 10).verdict == "held"  # one-sided: at least 1


def test_a_stored_verdict_is_carried_only_where_the_body_cannot_judge_and_is_gated_again():
    stored = _record("held", id="x/t", timing=True, caveats=("health of the filters compared: every check passed — x",),
                     interpretations=(Interpretation("detection-run", {"detection": "run"}, "held", 1.0, 10),
                                      Interpretation(AS_RUN, {}, "held", 1.0, 5),
                                      Interpretation("more-particles", {"particles": 9}, "NOT held", 2.0, 10)))
    pending = Statement("claim", "§3, Table 1", "quoted").applied(
        _record("not decidable", id="x/t", timing=True, needs="per-run times")).checked(["UPF"], [COLLAPSED])
    (carried,) = carry([pending], [stored], summary_fields={"detection"})
    assert carried.verdict == "not decidable" and carried.would_be == "held" and carried.quote == "quoted"
    assert carried.caveats == ()  # the earlier gate's words are not carried: the records say it
    # a timing claim keeps no verdict of a reading of the same runs: its CPU times are the same
    assert [i.name for i in carried.interpretations] == [AS_RUN, "more-particles"]
    fresh = _record("NOT held", id="x/a")
    (judged,) = carry([fresh], [_record("held", id="x/a", interpretations=stored.interpretations)])
    assert judged.verdict == "NOT held" and judged.interpretations == stored.interpretations


# ---- the committed pages -----------------------------------------------------------------------------

def _committed() -> list[tuple[Path, ClaimRecord]]:
    return [(p, c) for p in COMMITTED for c in read_claims(json.loads(p.read_text(encoding="utf-8")))]


def test_every_claim_of_the_committed_pages_names_its_exact_source():
    for path, claim in _committed():
        where = f"{path.relative_to(REFERENCE)}: {claim.id}"
        if claim.kind == "claim":
            assert claim.source.startswith("§") or "Table" in claim.source or "Fig" in claim.source, where
            assert claim.quote or any(w in claim.source for w in ("Fig", "Table", "eq.")), where
        else:
            assert claim.kind == "diagnostic" and claim.source, where


def test_the_committed_pages_count_what_their_records_hold():
    # a results.json inside a main run's folder is an interpretation's: its verdicts are the main claims' entries
    main = {p for p in COMMITTED if not any((f / "results.json").is_file() for f in p.parent.parents)}
    for page in sorted(p for p in REFERENCE.glob("*/README.md") if p.parent.name != "proofs"):
        claims = [c for path, c in _committed() if page.parent in path.parents and path in main]
        opening = next(line for line in page.read_text(encoding="utf-8").splitlines() if line.startswith("Verdicts"))
        assert opening.startswith(f"Verdicts on this page: {VerdictCounts.of(claims).groups_text()}."), page


def test_the_committed_pages_withhold_every_verdict_whose_filters_failed_a_gate():
    for path, claim in _committed():
        if claim.failed_filters and claim.gated:
            assert claim.verdict == "not decidable", f"{path}: {claim.id}"
        if claim.would_be is not None:
            assert claim.verdict == "not decidable"


def test_the_papers_supplementary_checks_and_the_1d_baselines_are_diagnostics():
    by_id = {c.id: c for _, c in _committed()}
    assert all(by_id[f"sins-gps/{k}-{q}"].kind == "diagnostic" for k in ("single-filter-reduction", "true-model-ceiling")
               for q in ("position", "velocity", "attitude"))
    assert by_id["sins-gps/reduction-position"].kind == "claim"
    baselines = [c for _, c in _committed() if c.id.startswith("ungm1d/") and "/fusion-beats-baselines/" in c.id]
    assert baselines and all(c.kind == "diagnostic" and c.group == DIAGNOSTIC for c in baselines)


def test_timing_claims_true_by_construction_are_labelled_and_not_counted_as_evidence():
    constructed = [c for _, c in _committed() if c.by_construction]
    assert constructed and all(c.group == BY_CONSTRUCTION and c.timing for c in constructed)
    assert {c.id.split("/")[1] for c in constructed} == {"flows-slower-than-pf", "flow-time-grows-as-dlambda-shrinks"}


def test_the_tbd_headline_is_the_verdict_as_run_and_the_favourable_readings_are_bounds():
    page = (REFERENCE / "tbd" / "README.md").read_text(encoding="utf-8")
    gain = next(c for _, c in _committed() if c.id == "tbd/snr-gain-equal-n")
    headline = next(line for line in page.splitlines() if line.startswith("The headline is the verdict as run"))
    assert f"{gain.statistic:.3g} dB, {gain.verdict}." in headline
    assert "a bound on what the paper's unstated choices can give, not a verdict" in headline
    readings = {*DETECTION_INTERPRETATIONS, *(s.name for s in (*BIRTH_INTERPRETATIONS, *IMAGE_EXIT_INTERPRETATIONS,
                                                                 *BIRTH_DETECTION_INTERPRETATIONS))}
    tried = 1 + sum(1 for i in gain.interpretations if i.name in readings)  # as run, and each reading
    assert f"The most favourable of the {tried} readings tried" in headline
    assert "Under the reading most favourable to the paper" not in page


def test_the_list_of_open_verdicts_is_what_the_committed_records_give():
    from gpfverify import undecided

    root = Path(__file__).resolve().parents[1]
    assert (root / undecided.DOC).read_text(encoding="utf-8") == undecided.markdown(root / undecided.REFERENCE), \
        "docs/undecided-claims.md is stale: python -m gpfverify.undecided"
    found = undecided.commands(root / undecided.REFERENCE)
    for command in found:
        assert command.text.startswith("gpfverify reproduce ") and f"--runs {command.runs} " in command.text
        for item in command.decides:
            assert item.needs or (item.estimate is not None and item.estimate <= undecided.LIMIT)
            assert item.needs or command.runs >= 2 * item.estimate  # planned at twice the estimate at least
    assert undecided.planned(2597, 2000) == 5200 and undecided.planned(40, 1000) == 1000
