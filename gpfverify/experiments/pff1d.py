"""Particle flow on 1-D nonlinear models (Zhou et al. 2020 §3.1): bootstrap PF, UPF, Daum–Huang
EDH flow and the innovation-error flow (IE-PFF) — the (Q, R, Δλ) grid of Table 1 on the UNGM and
the Γ(3, 2) process-noise case of Fig. 2 on the van der Merwe et al. (2000) benchmark (models in
:mod:`gpfverify.scenarios.growth`). N = 50 particles, T = 50 steps, 30 runs.

Each run draws one trajectory per (model, Q, R) and filters it with every method; the flows run
once per (Δλ, spacing): ``uniform`` is the paper's Euler scheme, ``exponential`` the same number of
geometrically growing steps. The truth and every filter start from the same prior.
A filter that breaks down is counted as diverged and left out of its RMSE (the count is reported).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from typing import Any

import numpy as np

from gpfverify.contract.claims import ClaimRecord, Verdict, combine
from gpfverify.contract.methods import Method
from gpfverify.contract.papers import PAPERS
from gpfverify.contract.particle_flow import EDH, FLOWS, IE_PFF, PAPER, PF, UPF, Variant
from gpfverify.contract.pff1d import (GAMMA_METHODS, NAME, PAPER_RUNS, PROFILES, TABLE_METHODS, Case,
                                      DivergenceCount, GammaEntry, Params, Prior, RunRecord, Table1Row,
                                      VariantRun)
from gpfverify.experiments.particle_methods import Comparison, child_rng, flow_steps, paired_comparison, run_method
from gpfverify.models import StateSpaceModel
from gpfverify.scenarios.growth import gamma_benchmark_model, ungm_model

__all__ = ["DEFAULT_RUNS", "NAME", "PAPER", "PROFILES", "Params", "RunRecord", "run_one", "summarize"]

DEFAULT_RUNS = PAPER_RUNS
#: two-sided level of the paired t-test that decides a claimed ordering
SIGNIFICANCE_LEVEL = 0.05


def _with_prior(model: StateSpaceModel, prior: Prior) -> StateSpaceModel:
    return dataclasses.replace(model, prior_mean=np.array([prior.mean]), prior_cov=np.array([[prior.var]]))


def _cases(params: Params) -> Iterator[tuple[Case, float, float, StateSpaceModel, tuple[Method, ...],
                                             tuple[float, ...]]]:
    """(case, Q, R, model, methods, Δλ values) in a fixed order; the truth's x₀ and every filter's
    initial particles come from the model's prior (an interpretation, see the report)."""
    for q in params.table_q:
        for r in params.table_r:
            yield "ungm", q, r, _with_prior(ungm_model(q, r), params.ungm_prior), TABLE_METHODS, params.dlambda
    for r in params.gamma_r:
        model = _with_prior(gamma_benchmark_model(r, params.gamma_shape, params.gamma_rate), params.gamma_prior)
        yield "gamma", float(np.asarray(model.process_cov)[0, 0]), r, model, GAMMA_METHODS, (params.gamma_dlambda,)


def _variants(methods: tuple[Method, ...], dlambdas: tuple[float, ...], params: Params) -> list[Variant]:
    out = [Variant(m) for m in methods if m not in FLOWS]
    return out + [Variant(m, d, s) for m in methods if m in FLOWS for d in dlambdas for s in params.spacings]


def run_one(params: Params, seed_seq: np.random.SeedSequence) -> RunRecord:
    records = []
    for c, (case, q, r, model, methods, dlambdas) in enumerate(_cases(params)):
        data_rng = child_rng(seed_seq, c, 0)
        x0 = data_rng.multivariate_normal(np.asarray(model.prior_mean, float), np.asarray(model.prior_cov, float))
        xs, ys = model.simulate(params.steps, data_rng, x0=x0)
        for v, variant in enumerate(_variants(methods, dlambdas, params)):
            steps = None
            if variant.dlambda is not None and variant.spacing is not None:
                steps = flow_steps(variant.dlambda, variant.spacing, params.exponential_ratio)
            out = run_method(variant.method, model, ys, params.particles, child_rng(seed_seq, c, 1 + v), steps)
            sq = None if out.estimates is None else tuple(((out.estimates - xs)[:, 0] ** 2).tolist())
            records.append(VariantRun(case, q, r, variant, sq, out.seconds))
    return RunRecord(tuple(records))


@dataclasses.dataclass(frozen=True)
class _Aggregate:
    """One (case, Q, R, variant) over the runs."""

    rmse: tuple[float, ...]
    diverged: int
    seconds: float
    run_rmse: tuple[float | None, ...]

    @property
    def mean_rmse(self) -> float:
        return float(np.mean(self.rmse))


def _aggregate(records: list[RunRecord], steps: int) -> dict[tuple[Case, float, float, Variant], _Aggregate]:
    """RMSE per step over the runs that did not diverge, divergence count, mean seconds and the
    per-run √(mean_t err²) (None where the filter diverged), per (case, Q, R, variant)."""
    groups: dict[tuple[Case, float, float, Variant], list[VariantRun]] = {}
    for run in records:
        for rec in run.records:
            groups.setdefault((rec.case, rec.q, rec.r, rec.variant), []).append(rec)
    out = {}
    for key, recs in groups.items():
        sq = [r.sq_err for r in recs if r.sq_err is not None]
        rmse = np.sqrt(np.mean(sq, axis=0)) if sq else np.full(steps, np.nan)
        out[key] = _Aggregate(tuple(rmse.tolist()), len(recs) - len(sq), float(np.mean([r.seconds for r in recs])),
                              tuple(None if r.sq_err is None else float(np.sqrt(np.mean(r.sq_err))) for r in recs))
    return out


def summarize(params: Params, records: list[RunRecord]) -> dict[str, Any]:
    agg = _aggregate(records, params.steps)
    runs = len(records)
    table = [Table1Row(q, r, v.method.key, v.dlambda, v.spacing, g.mean_rmse, g.diverged, runs, g.seconds,
                       g.rmse, g.run_rmse)
             for (case, q, r, v), g in agg.items() if case == "ungm"]
    gamma: dict[str, dict[str, GammaEntry]] = {}
    for (case, _q, r, v), g in agg.items():
        if case == "gamma":
            gamma.setdefault(f"{r:g}", {})[v.label] = GammaEntry(
                v.method.key, v.dlambda, v.spacing, g.rmse, g.mean_rmse, g.diverged, g.seconds, g.run_rmse)
    main_r, main_spacing = params.gamma_main_r, params.main_spacing
    main = {v.method: g for (case, _q, r, v), g in agg.items()
            if case == "gamma" and r == main_r and v.spacing in (None, main_spacing)}
    return {
        "rmse": {m.key: main[m].rmse for m in GAMMA_METHODS},
        "time_per_run": {m.key: main[m].seconds for m in GAMMA_METHODS},
        "diverged": {m.key: main[m].diverged for m in GAMMA_METHODS},
        "main_case": {"model": "gamma", "R": main_r, "dlambda": params.gamma_dlambda, "spacing": main_spacing},
        "table1": table,
        "gamma": gamma,
        "divergences": _divergences(params, table),
        "significance_level": SIGNIFICANCE_LEVEL,
        "claims": claims(params, table, gamma, runs),
    }


def _divergences(params: Params, table: list[Table1Row]) -> list[DivergenceCount]:
    """How often each flow diverged on the UNGM grid, per Δλ and λ-step schedule."""
    out = []
    for method in FLOWS:
        for dlam in params.dlambda:
            for spacing in params.spacings:
                rows = [r for r in table if r.variant == Variant(method, dlam, spacing)]
                out.append(DivergenceCount(method.key, dlam, spacing, sum(r.diverged for r in rows),
                                           sum(r.runs for r in rows)))
    return out


# ----------------------------------------------------------------------------- claims

SOURCE_TABLE1 = f"{PAPERS[PAPER].short}, §3.1, Fig. 1 and Table 1"
SOURCE_FIG2 = f"{PAPERS[PAPER].short}, §3.1, Fig. 2"
STATISTIC = ("statistic: the largest paired t statistic of the comparisons (mean per-run RMSE difference "
             "over its standard error; negative favours the claim); threshold: minus the two-sided "
             "Student quantile at level {level:g}")


def _record(slug: str, claim: str, source: str, setting: str, parts: list[tuple[str, Comparison]],
            runs: int) -> ClaimRecord:
    """A claim made of paired comparisons: NOT held if any part is (a divergence where the other
    filter stayed finite loses the part), held if all are, undecided otherwise."""
    verdict: Verdict = combine([c.verdict for _, c in parts])
    decided = [c for _, c in parts if c.t is not None and c.critical is not None]
    worst = max(decided, key=lambda c: c.t if c.t is not None else -np.inf) if decided else None
    return ClaimRecord(
        claim=claim, source=source, verdict=verdict,
        statistic=None if worst is None else worst.t,
        threshold=None if worst is None or worst.critical is None else -worst.critical,
        n=runs, evidence="; ".join(f"{name}: {c.evidence}" for name, c in parts),
        caveats=(STATISTIC.format(level=SIGNIFICANCE_LEVEL),),
        id=f"{NAME}/{slug}", paper=PAPER, setting=setting, paper_n=PAPER_RUNS)


def _undecidable(slug: str, claim: str, source: str, why: str, runs: int) -> ClaimRecord:
    return ClaimRecord(claim=claim, source=source, verdict="not decidable", statistic=None, threshold=None,
                       n=runs, evidence=why, id=f"{NAME}/{slug}", paper=PAPER, paper_n=PAPER_RUNS)


def claims(params: Params, table: list[Table1Row], gamma: dict[str, dict[str, GammaEntry]],
           runs: int) -> list[ClaimRecord]:
    level = SIGNIFICANCE_LEVEL
    out = []
    q_max, spacing = max(params.table_q), params.main_spacing
    cells = {(row.Q, row.R, row.variant): row for row in table}
    for dlam in params.dlambda:
        parts = []
        for r in params.table_r:
            ie = cells[(q_max, r, Variant(IE_PFF, dlam, spacing))]
            for other in (Variant(PF), Variant(EDH, dlam, spacing)):
                parts.append((f"R = {r:g} vs {other.method.key}",
                              paired_comparison(ie.run_rmse, cells[(q_max, r, other)].run_rmse, level)))
        out.append(_record(f"ie-pff-beats-pf-and-edh-at-large-q/dlambda={dlam:g}",
                           "IE-PFF is more accurate than PF and PFF (EDH) at large process noise, at every R",
                           SOURCE_TABLE1, f"UNGM, Q = {q_max:g}, Δλ = {dlam:g}, {spacing} λ-steps", parts, runs))

    def entry(r: str, method: Method) -> GammaEntry:
        flow = method in FLOWS
        return gamma[r][Variant(method, params.gamma_dlambda if flow else None, spacing if flow else None).label]

    parts = [(f"R = {r}: {m.key} vs EDH", paired_comparison(entry(r, m).run_rmse, entry(r, EDH).run_rmse, level))
             for r in gamma for m in (PF, UPF, IE_PFF)]
    gamma_setting = (f"Γ({params.gamma_shape:g}, {params.gamma_rate:g}) process noise, "
                     f"Δλ = {params.gamma_dlambda:g}, {spacing} λ-steps")
    out.append(_record("gamma-edh-worst", "With gamma process noise the PFF (EDH) estimates worst of the four",
                       SOURCE_FIG2, f"{gamma_setting}, every R", parts, runs))
    r_small, r_large = min(gamma, key=float), max(gamma, key=float)
    small_claim = "Gamma noise, small R: UPF and IE-PFF are the most accurate"
    large_claim = "Gamma noise, large R: IE-PFF is the most accurate"
    if r_small == r_large:
        why = f"needs at least two measurement-noise variances R in the gamma case; this run has only R = {r_small}"
        out.append(_undecidable("gamma-small-r-upf-and-ie-pff-best", small_claim, SOURCE_FIG2, why, runs))
        out.append(_undecidable("gamma-large-r-ie-pff-best", large_claim, SOURCE_FIG2, why, runs))
        return out
    parts = [(f"{a.key} vs {b.key}", paired_comparison(entry(r_small, a).run_rmse, entry(r_small, b).run_rmse, level))
             for a in (UPF, IE_PFF) for b in (PF, EDH)]
    out.append(_record("gamma-small-r-upf-and-ie-pff-best", small_claim, SOURCE_FIG2,
                       f"{gamma_setting}, R = {r_small}", parts, runs))
    parts = [(f"vs {b.key}", paired_comparison(entry(r_large, IE_PFF).run_rmse, entry(r_large, b).run_rmse, level))
             for b in (PF, UPF, EDH)]
    out.append(_record("gamma-large-r-ie-pff-best", large_claim, SOURCE_FIG2,
                       f"{gamma_setting}, R = {r_large}", parts, runs))
    return out
