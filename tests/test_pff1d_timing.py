"""The running-time claims of seed 003's Table 1 (pff1d): the flows take more time than the PF and
a smaller Δλ takes more time (both true by construction: counted apart, never evidence), IE-PFF's
time within SIMILAR_TIME × EDH's either way at the same Δλ. Each is decided on per-run CPU seconds
built here with known ratios, so the expected geometric means are computed independently of the
code under test, over the cells whose filters passed their health gates."""

import numpy as np
import pytest

from gpfverify.contract.claims import BY_CONSTRUCTION, TIMING, read_claims
from gpfverify.health import divergence_check
from gpfverify.papers.particle_flow.contract import EDH, IE_PFF, PF, Variant
from gpfverify.papers.particle_flow import pff1d_experiment as pff1d
from gpfverify.experiments.runner import run_experiment

RUNS = 12
CELLS = ((0.1, 0.1), (10.0, 1.0))
PARAMS = pff1d.Params(table_q=(0.1, 10.0), table_r=(0.1, 1.0), dlambda=(0.1, 0.01), spacings=("uniform",))


def _times(base: float, spread: np.random.Generator) -> tuple[float, ...]:
    """Per-run seconds scattered by a few per cent about ``base``."""
    return tuple((base * np.exp(spread.normal(0.0, 0.03, RUNS))).tolist())


def _aggregates(seconds_of, broken=frozenset()) -> dict:
    """Rows of the grid (the main spacing only) with per-run seconds ``seconds_of(method, dlambda)``
    and each filter's divergence check; ``broken`` holds (method, dlambda, q, r, run) where that
    filter broke down."""
    spread = np.random.default_rng(5)
    variants = [Variant(PF)] + [Variant(m, d, "uniform") for m in (EDH, IE_PFF) for d in PARAMS.dlambda]
    rows, checks = {}, []
    for q, r in CELLS:
        for v in variants:
            rmse = tuple(None if (v.method, v.dlambda, q, r, i) in broken else 1.0 for i in range(RUNS))
            rows[(q, r, v)] = pff1d.Table1Row(q, r, v.method.key, v.dlambda, v.spacing, 1.0, 0, RUNS, 0.0, (), rmse,
                                              _times(seconds_of(v.method, v.dlambda), spread))
            errors = np.array([[np.nan if e is None else 0.0] for e in rmse])
            checks.append(divergence_check(pff1d._subject("ungm", q, r, v), errors, bound=1.0))
    return rows, checks


def _claims(agg) -> dict:
    rows, checks = agg
    return {c.id.removeprefix("pff1d/"): c for c in pff1d.timing_claims(PARAMS, list(rows.values()), RUNS, checks)}


def flow_cost(method, dlambda):
    """Seconds the paper's reading predicts: a PF 0.02 s, a flow 1/Δλ λ-steps of 0.01 s (IE-PFF 0.9 × EDH)."""
    if method == PF:
        return 0.02
    return (1.0 if method == EDH else 0.9) * 0.01 / dlambda


def test_the_papers_ordering_of_times_is_held():
    claims = _claims(_aggregates(flow_cost))
    assert {c.verdict for c in claims.values()} == {"held"}
    assert set(claims) == {"flows-slower-than-pf/dlambda=0.1", "flows-slower-than-pf/dlambda=0.01",
                           "ie-pff-time-similar-to-edh/dlambda=0.1", "ie-pff-time-similar-to-edh/dlambda=0.01",
                           "flow-time-grows-as-dlambda-shrinks"}
    assert all(c.timing for c in claims.values())
    assert {k for k, c in claims.items() if c.group == BY_CONSTRUCTION} == {
        "flows-slower-than-pf/dlambda=0.1", "flows-slower-than-pf/dlambda=0.01", "flow-time-grows-as-dlambda-shrinks"}
    assert {k for k, c in claims.items() if c.group == TIMING} == {
        "ie-pff-time-similar-to-edh/dlambda=0.1", "ie-pff-time-similar-to-edh/dlambda=0.01"}


def test_the_ratio_is_the_geometric_mean_of_the_summed_per_run_times():
    agg = _aggregates(flow_cost)
    ie = [agg[0][(q, r, Variant(IE_PFF, 0.01, "uniform"))].run_seconds for q, r in CELLS]
    edh = [agg[0][(q, r, Variant(EDH, 0.01, "uniform"))].run_seconds for q, r in CELLS]
    expected = np.exp(np.mean(np.log(np.sum(ie, axis=0)) - np.log(np.sum(edh, axis=0))))
    claim = _claims(agg)["ie-pff-time-similar-to-edh/dlambda=0.01"]
    assert claim.statistic == pytest.approx(expected, rel=1e-12)
    assert claim.threshold == pff1d.SIMILAR_TIME


def test_a_pf_slower_than_a_flow_is_not_held():
    claims = _claims(_aggregates(lambda m, d: 0.5 if m == PF else flow_cost(m, d)))
    assert claims["flows-slower-than-pf/dlambda=0.1"].verdict == "NOT held"    # flows 0.1 and 0.08 s
    assert claims["flows-slower-than-pf/dlambda=0.1"].statistic > 1
    assert claims["flows-slower-than-pf/dlambda=0.01"].verdict == "held"       # flows 1 and 0.8 s


@pytest.mark.parametrize("factor, verdict", [(1.1, "held"), (0.95, "held"), (1.6, "NOT held"), (0.5, "NOT held")])
def test_ie_pff_is_held_similar_up_to_the_stated_multiple_of_edh(factor, verdict):
    claims = _claims(_aggregates(lambda m, d: flow_cost(EDH, d) * factor if m == IE_PFF else flow_cost(m, d)))
    assert claims["ie-pff-time-similar-to-edh/dlambda=0.1"].verdict == verdict
    assert claims["ie-pff-time-similar-to-edh/dlambda=0.01"].verdict == verdict


def test_a_flow_whose_time_does_not_grow_as_dlambda_shrinks_is_not_held():
    claims = _claims(_aggregates(lambda m, d: flow_cost(m, 0.1 if d == 0.01 else 0.01) if m == EDH
                                 else flow_cost(m, d)))
    assert claims["flow-time-grows-as-dlambda-shrinks"].verdict == "NOT held"


def test_a_cell_where_a_filter_failed_its_health_gate_is_left_out():
    """A broken-down filter's time is not its algorithm's (it may have stopped at an exception): a
    cell in which a filter of the pair failed its divergence gate leaves the claim, whatever the
    times recorded there, and the evidence names it; with no cell left the claim is not decidable."""
    broken = {(IE_PFF, 0.01, 10.0, 1.0, 3)}
    rows, checks = _aggregates(flow_cost, broken)
    key = (10.0, 1.0, Variant(IE_PFF, 0.01, "uniform"))  # the broken cell reports absurd times: they must not count
    rows[key] = pff1d.Table1Row(*[getattr(rows[key], f) for f in ("Q", "R", "method", "dlambda", "spacing",
                                                                  "mean_rmse", "diverged", "runs", "time_per_run",
                                                                  "rmse", "run_rmse")], (1e6,) * RUNS)
    claim = _claims((rows, checks))["ie-pff-time-similar-to-edh/dlambda=0.01"]
    ie = np.array(rows[(0.1, 0.1, Variant(IE_PFF, 0.01, "uniform"))].run_seconds)
    edh = np.array(rows[(0.1, 0.1, Variant(EDH, 0.01, "uniform"))].run_seconds)
    assert claim.statistic == pytest.approx(np.exp(np.mean(np.log(ie / edh))), rel=1e-12)
    assert claim.verdict == "held" and f"geometric mean of {RUNS} paired per-run ratios" in claim.evidence
    assert "1 cell(s) left out where a filter failed its health gate (UNGM Q = 10, R = 1)" in claim.evidence
    assert claim.parts_gated and "IE-PFF Δλ=0.01 uniform (UNGM Q = 10, R = 1)" in {h.subject for h in
                                                                                   claim.failed_filters}
    everywhere = {(IE_PFF, 0.1, q, r, 0) for q, r in CELLS}
    stopped = _claims(_aggregates(flow_cost, everywhere))["ie-pff-time-similar-to-edh/dlambda=0.1"]
    assert stopped.verdict == "not decidable" and "every cell had a filter fail its health gate" in stopped.evidence


def test_the_runner_files_the_timing_claims_apart_from_the_accuracy_claims(tmp_path):
    params = pff1d.Params(steps=4, particles=10, table_q=(0.1,), table_r=(0.1,), gamma_r=(0.1,), gamma_dlambda=0.1,
                          dlambda=(0.1, 0.05), spacings=("uniform",))
    res = run_experiment(pff1d, params, 2, 1, tmp_path, show_progress=False)
    assert "timing_claims" in res["timing_keys"]
    assert {c["id"].split("/")[1] for c in res["timing_claims"]} == {
        "flows-slower-than-pf", "ie-pff-time-similar-to-edh", "flow-time-grows-as-dlambda-shrinks"}
    assert not any(c["id"].split("/")[1].startswith(("flows-slower", "flow-time", "ie-pff-time"))
                   for c in res["claims"])
    assert len(read_claims(res)) == len(res["claims"]) + len(res["timing_claims"])
