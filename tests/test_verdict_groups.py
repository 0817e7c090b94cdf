"""Verdicts counted in groups — accuracy (the headline), a theorem checked on the runs
(Proposition 1), timing — and timing claims decided on paired per-run CPU-time ratios measured on
the process's CPU clock: the ratio rule against an independent computation and its invariance to a
slower machine, the group of every fusion-paper claim, the one counting record and what renders
it, the interpretations of timing claims, and the runs-needed table of the reference pages."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from gpfverify.contract import ClaimRecord, PairedDifference, PairedRatio
from gpfverify.contract.claims import ACCURACY, DIAGNOSTIC, PROPOSITION_1, TIMING, VERDICTS, Interpretation
from gpfverify.health import divergence_check
from gpfverify.papers.fusion.contract import FAMILIES
from gpfverify.contract.interpretations import InterpretationSpec
from gpfverify.errors import InputError
from gpfverify.papers.fusion import ct2d_experiment as ct2d
from gpfverify.papers.fusion import run as fusion_run
from gpfverify.experiments.sensitivity import merge
from gpfverify.report.document import claim_tables
from gpfverify.report.inputs import VerdictCounts
from gpfverify.tolerances import MONTE_CARLO_SIGMAS

TINY = {"kappa": 12, "test_steps": 3, "fit_points": 12}


# ---- the ratio rule ---------------------------------------------------------------------------------

def test_paired_ratio_is_the_geometric_mean_of_the_per_run_ratios_decided_on_the_log_scale():
    rng = np.random.default_rng(3)
    b = rng.uniform(0.5, 2.0, 200)
    for factor, bound in ((0.8, 1.0), (1.3, 1.0), (1.0, 1.0), (1.1, 1.2)):
        a = factor * b * np.exp(rng.normal(0.0, 0.05, b.size))
        r = PairedRatio.of(a, b, bound)
        log_ratio = np.log(a / b)  # the independent route: logs of the ratios, mean ± 5 standard errors
        atol = MONTE_CARLO_SIGMAS * log_ratio.std(ddof=1) / math.sqrt(b.size)
        centre = log_ratio.mean()
        assert r.ratio == pytest.approx(math.exp(centre), rel=1e-12)
        assert (r.low, r.high) == pytest.approx((math.exp(centre - atol), math.exp(centre + atol)), rel=1e-12)
        d = centre - math.log(bound)
        assert r.verdict == ("held" if d < -atol else "NOT held" if d > atol else "undecided")
        assert r.n == b.size and r.bound == bound and r.dropped == 0
    assert PairedRatio.of(0.8 * b, b).verdict == "held" and PairedRatio.of(1.3 * b, b).verdict == "NOT held"


def test_a_slower_machine_moves_a_difference_of_seconds_but_not_the_ratio():
    rng = np.random.default_rng(5)
    b = rng.uniform(0.9, 1.1, 300)
    a = 0.9 * b * np.exp(rng.normal(0.0, 0.02, b.size))
    slowdown = rng.uniform(1.0, 6.0, b.size)  # each run on a busier machine, both methods alike
    calm, busy = PairedRatio.of(a, b), PairedRatio.of(a * slowdown, b * slowdown)
    assert busy.ratio == pytest.approx(calm.ratio, rel=1e-12) and busy.verdict == calm.verdict == "held"
    # the same data read as seconds: the difference grows with the load
    assert PairedDifference.of(a * slowdown, b * slowdown).mean < 2 * PairedDifference.of(a, b).mean


def test_paired_ratio_leaves_out_times_below_the_clock_resolution_and_says_so():
    r = PairedRatio.of([1.0, 0.0, 2.0, 4.0], [2.0, 1.0, 4.0, 8.0])
    assert r.dropped == 1 and r.n == 3 and r.ratio == pytest.approx(0.5)
    assert "1 run(s) left out" in r.evidence("A", "B")
    with pytest.raises(ValueError):
        PairedRatio.of([1.0, 2.0], [1.0], 1.0)
    undecided = PairedRatio.of([1.0, 1.2, 0.9, 1.1], [1.0, 1.0, 1.0, 1.0])
    assert undecided.verdict == "undecided" and undecided.runs_to_decide == undecided.log_difference.runs_to_decide


# ---- groups -----------------------------------------------------------------------------------------

def _record(verdict="held", timing=False, theorem="", ident="x/y", n=10, **kw) -> ClaimRecord:
    return ClaimRecord("c", "s", verdict, 0.0, 0.0, n, "e", id=ident, timing=timing, theorem=theorem, **kw)


def test_a_claim_is_counted_in_one_group():
    assert _record().group == ACCURACY
    assert _record(timing=True).group == TIMING
    assert _record(theorem=PROPOSITION_1).group == PROPOSITION_1
    with pytest.raises(InputError, match="checks no theorem"):
        _record(timing=True, theorem=PROPOSITION_1)


def test_every_fusion_paper_claim_is_in_its_group():
    params = ct2d.Params(**TINY)
    runs = [ct2d.run_one(params.replace(kappa=30), np.random.SeedSequence(s)) for s in (1, 2)]
    body = ct2d.summarize(params.replace(kappa=30), runs)
    groups = {c.id.split("/", 1)[1]: c.group for c in [*body["claims"], *body["timing_claims"]]}
    for family in FAMILIES:
        assert groups[f"dmf-equals-cmf/{family}"] == PROPOSITION_1
        # at κ = 30 the paper shows CMF and DMF alone (Figs. 12–15): the comparisons with the sensors, the
        # baselines and the other rules' times are the toolkit's own, counted apart
        assert groups[f"fusion-beats-sensors/{family}"] == groups[f"fusion-beats-baselines/{family}"] == DIAGNOSTIC
        for name in ("dmf-cheaper-than-cmf", "dmf-update-cheaper-than-cmf", "rcc-ci-costs-most", "cw-fastest"):
            assert groups[f"{name}/{family}"] == DIAGNOSTIC
    assert groups["gp-ukf-loses-full-rank"] == groups["gp-ukf-equivalence-broken"] == PROPOSITION_1
    assert groups["gp-ukf-fusion-vs-gp-adf"] == ACCURACY and groups["gp-ukf-fusion-time-vs-gp-adf"] == TIMING


def test_one_record_counts_every_group_and_the_parts_add_up():
    rng = np.random.default_rng(1)
    claims = [_record(str(rng.choice(VERDICTS)), timing=bool(t == 2), theorem=PROPOSITION_1 if t == 1 else "",
                      ident=f"x/{i}", paper_n=20 if i % 3 else None)
              for i, t in enumerate(rng.integers(0, 3, 40))]
    counts = VerdictCounts.of(claims, ["proved", "checked", "proved"])
    assert [g.group for g in counts.groups] == [ACCURACY, PROPOSITION_1, TIMING]
    for g in counts.groups:
        mine = [c for c in claims if c.group == g.group]
        assert g.counts == {v: sum(c.verdict == v for c in mine) for v in VERDICTS} and g.total == len(mine)
    assert counts.proofs == {"proved": 2, "refuted": 0, "checked": 1}
    assert counts.cautioned == sum(1 for c in claims if c.cautions)
    halves = VerdictCounts.total([VerdictCounts.of(claims[:17], ["proved"]),
                                  VerdictCounts.of(claims[17:], ["checked", "proved"])])
    assert halves == counts
    assert VerdictCounts.from_json(counts.to_json()) == counts
    line = counts.line()
    assert line.startswith("accuracy: ") and line.index("Proposition 1: ") < line.index("timing: ")
    assert "proofs: 2 proved, 0 refuted, 1 checked" in line
    # a page without accuracy claims still states the headline group, with zeros
    assert VerdictCounts.of([_record(timing=True)]).line().startswith("accuracy: 0 held, 0 NOT held")


def test_a_page_shows_each_group_in_a_table_of_its_own():
    claims = [_record(ident="x/a"), _record(timing=True, ident="x/t"), _record(theorem=PROPOSITION_1, ident="x/p"),
              _record("NOT held", ident="x/b")]
    tables = claim_tables(claims, "Claims")
    assert [len(t.rows) for t in tables] == [2, 1, 1]
    assert [t.row_ids for t in tables] == [("claim-x-a", "claim-x-b"), ("claim-x-p",), ("claim-x-t",)]
    assert "Proposition 1" in tables[1].caption and "CPU times" in tables[2].caption
    (only,) = claim_tables(claims[:1] + claims[3:], "Claims")  # accuracy alone: one table, its caption
    assert only.caption == "Claims"


# ---- the CPU clock -----------------------------------------------------------------------------------

def test_the_fusion_experiments_time_cpu_not_a_waiting_process(monkeypatch):
    """A method that waits (as on a machine busy with other processes) costs no CPU time: the
    convex combination is made to sleep 30 ms per step; its recorded time stays far below that,
    and with a wall clock in place of the CPU clock it does not (the test can fail)."""
    original = fusion_run.convex_combination

    def sleepy(*args, **kwargs):
        time.sleep(0.03)
        return original(*args, **kwargs)

    monkeypatch.setattr(fusion_run, "convex_combination", sleepy)
    params = ct2d.Params(**TINY)
    cpu = ct2d.run_one(params, np.random.SeedSequence(2))
    monkeypatch.setattr(fusion_run, "CPU_CLOCK", time.perf_counter)
    wall = ct2d.run_one(params, np.random.SeedSequence(2))
    for family in FAMILIES:
        key = f"CW-{family}"
        assert max(cpu.families[family].seconds[key]) < 0.015
        assert min(wall.families[family].seconds[key]) >= 0.03


# ---- interpretations of timing claims -----------------------------------------------------------------

def test_timing_claims_carry_the_verdicts_under_each_interpretation():
    def results(runs, verdict, timed):
        return {"runs": runs, "claims": [_record(verdict, ident="x/acc", n=runs).to_json()],
                "timing_claims": [_record(timed, timing=True, ident="x/time", n=runs).to_json()]}

    main = results(100, "held", "NOT held")
    spec = InterpretationSpec("numpy-rank", {"rank_rule": "numpy"}, "why")
    merged = merge(main, [(spec, results(20, "undecided", "held"))], [results(20, "held", "undecided")])
    (timed,) = [ClaimRecord.from_json(c) for c in merged["timing_claims"]]
    assert timed.interpretations == (Interpretation("numpy-rank", {"rank_rule": "numpy"}, "held", 0.0, 20),
                                     Interpretation("as run", {}, "undecided", 0.0, 20))
    (accuracy,) = [ClaimRecord.from_json(c) for c in merged["claims"]]
    assert [i.verdict for i in accuracy.interpretations] == ["undecided", "held"]


# ---- the runs each claim needed (reference pages) ------------------------------------------------------

def test_the_runs_needed_table_reads_the_verdicts_at_each_run_count():
    from gpfverify.reference_pages import runs_needed_table
    final = [_record("held", ident="x/early", n=1000, paper_n=1000),
             _record("NOT held", ident="x/late", n=1000, paper_n=1000),
             _record("undecided", ident="x/open", n=1000, paper_n=1000, runs_to_decide=4200)]
    earlier = {40: [_record("held", ident="x/early"), _record("undecided", ident="x/late"),
                    _record("undecided", ident="x/open")],
               200: [_record("held", ident="x/early"), _record("held", ident="x/late"),
                     _record("undecided", ident="x/open")]}
    results = {"runs_ok": 1000, "claims": [c.to_json() for c in final]}
    table = runs_needed_table(results, earlier, "caption")
    assert table.headers[2:5] == ["first 40 runs", "first 200 runs", "all 1000 runs"]
    rows = [row[-1] for row in table.rows]
    assert rows[0] == "40 or fewer"
    assert rows[1] == "more than 200, at most 1000"  # it was another verdict (held) at 200
    assert rows[2] == "undecided: about 4200 runs would decide it, more than the paper's 1000"


def test_every_not_held_row_names_the_interpretations_tried_and_the_health_of_the_filters():
    tried = (Interpretation("numpy-rank", {"rank_rule": "numpy"}, "NOT held", 1.0),
             Interpretation("rmse", {"metric": "squared-error"}, "held", -1.0))
    passed = divergence_check("CMF-GP-UKF", np.zeros((3, 2)), bound=1.0)
    claims = [_record("NOT held", ident="x/a", interpretations=tried,
                      caveats=("NEES check failed: CMF-GP-UKF optimistic",)).checked(["CMF-GP-UKF"], [passed]),
              _record("NOT held", ident="x/b"), _record("NOT held", timing=True, ident="x/t"),
              _record("held", ident="x/h", interpretations=tried)]
    rows = {row_id: row for table in claim_tables(claims, "Claims") for row_id, row in zip(table.row_ids, table.rows)}
    first = rows["claim-x-a"][-1]
    # the health words come from the health records, whatever a caveat's text says
    assert "interpretations tried: depends on the interpretation: NOT held under as run, numpy-rank; held under " \
           "rmse" in first and first.endswith("health: every compared filter passed its health gates")
    assert "no other documented reading was tried" in rows["claim-x-b"][-1]
    assert rows["claim-x-b"][-1].endswith("health: no checks run")  # nothing checked is not "none failed"
    assert rows["claim-x-t"][-1].endswith("health: no checks run")
    assert "interpretations tried" not in rows["claim-x-h"][-1]  # only NOT held verdicts carry the note

