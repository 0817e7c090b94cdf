"""Rank decisions, exactness verdicts and repair messages under every rank rule (numpy, absolute,
canonical), each checked against what the test computes itself — never against a tolerance or
residual the code reports.

* Rank: the numpy rule (σ_i > σ_max · max(D, l) · eps) and the absolute rule (σ_i > tol) on cross
  covariances with known singular values (a scaled, signed permutation of a diagonal: its singular
  values are the diagonal to a few ulps), some placed between σ_max·min(D, l)·eps and
  σ_max·max(D, l)·eps; the canonical rule (ρ_i > τ) against canonical correlations computed here
  from eigendecomposition square roots, ρ = σ(C_p^{-1/2} C_xy C_y^{-1/2}), with C_p^m recovered
  from the report as C_e^m + C_xy^m (C_y^m)⁻¹ C_xy^mᵀ; the reported correlations are these ρ. Values within a
  relative band of the threshold that the two routes' rounding could cross are not decided.
* Exactness: the gap map of eq. 35 against CMF, T_m = G_m C_y^m (A_m C_xy^m − I), is formed here
  with numpy's pinv at the rank the test decides, and measured in prior standard deviations per
  unit whitened innovation, ‖C_p^{-1/2} T_m (C_y^m)^{1/2}‖₂. A gap above the exact-algebra
  tolerance of the problem's condition is never called exact; a sensor exact by design is.
* Repair: DMF with every sensor's repair message equals CMF = μ_p + C_xy C_y⁻¹ (y − μ_y), computed
  here, under every rule.
"""

import numpy as np
from hypothesis import event, given
from hypothesis import strategies as st

from gpfverify.fusion.case import FusionCase
from gpfverify.fusion.distributed import dmf_update
from gpfverify.fusion.exactness import RankRule, kernel_split, repair_message, sensor_split
from gpfverify.strategies import fusion_cases
from gpfverify.strategies.matrices import float_arrays, log_uniform
from gpfverify.tolerances import EPS, algebra_rtol

#: relative band around a rank threshold inside which two routes' rounding may decide differently
UNDECIDED_BAND = 1e-6


def _power(cov: np.ndarray, exponent: float) -> np.ndarray:
    values, vectors = np.linalg.eigh(cov)
    return (vectors * values**exponent) @ vectors.T


def _decided(values: np.ndarray, threshold: float, band: float) -> bool:
    return not np.any(np.abs(values - threshold) <= band * max(threshold, np.finfo(float).tiny))


@st.composite
def known_singular_values(draw):
    """(C, s): C (D, l) a scaled signed permutation of diag(s); one value of s may sit near
    σ_max · k · eps for k from 0.1 to 20 (across numpy's max(D, l) factor)."""
    d, l = draw(st.integers(1, 5)), draw(st.integers(1, 5))
    k = min(d, l)
    s = draw(float_arrays((k,), 0.1, 10.0))
    s[0] = 10.0
    if k > 1:
        s[draw(st.integers(1, k - 1))] = 10.0 * EPS * draw(log_uniform(0.1, 20.0))
    scale = draw(log_uniform(1e-6, 1e6))
    matrix = np.zeros((d, l))
    matrix[np.arange(k), np.arange(k)] = scale * s
    rows = draw(st.permutations(range(d)))
    cols = draw(st.permutations(range(l)))
    signs = np.array(draw(st.lists(st.sampled_from((-1.0, 1.0)), min_size=l, max_size=l)))
    return matrix[rows][:, cols] * signs, scale * s


@given(drawn=known_singular_values(), absolute=st.booleans(), data=st.data())
def test_svd_rank_rules_decide_as_the_rule_computed_here(drawn, absolute, data):
    matrix, s = drawn
    if absolute:
        tol = float(s[data.draw(st.integers(0, s.size - 1), label="near")] * data.draw(log_uniform(0.5, 2.0)))
        split = kernel_split(matrix, tol)
    else:
        tol = float(s.max() * max(matrix.shape) * EPS)
        split = kernel_split(matrix)
    event(f"{'absolute' if absolute else 'numpy'}: rank {int(np.sum(s > tol))} of {s.size}")
    if _decided(s, tol, UNDECIDED_BAND):
        assert split.rank.rank == int(np.sum(s > tol)), (s, tol, split.rank.rank)
        assert split.kernel_basis.shape[1] == matrix.shape[1] - split.rank.rank


@given(drawn=fusion_cases(kinds=st.sampled_from(("nearly", "full", "deficient")),
                          sigma_min=log_uniform(1e-12, 1e-3), sensors=st.integers(1, 2)),
       tau=st.one_of(st.none(), log_uniform(1e-10, 1e-2)))
def test_canonical_rank_rule_decides_as_the_correlations_computed_here(drawn, tau):
    """τ drawn, or the documented default τ = sqrt(eps) (docs/fusion-definitions.md) when None."""
    case = drawn.case
    rule = RankRule("canonical") if tau is None else RankRule("canonical", tau)
    tau = float(np.sqrt(EPS)) if tau is None else tau
    for local in case.locals:
        split = sensor_split(local, rule, case.central.C_p)
        c_p = case.central.C_p if local.C_e is None else (
            local.C_e + local.C_xy @ np.linalg.solve(local.C_y, local.C_xy.T))
        rho = np.linalg.svd(_power(c_p, -0.5) @ local.C_xy @ _power(local.C_y, -0.5), compute_uv=False)
        cond = np.linalg.cond(c_p) * np.linalg.cond(local.C_y)
        band = algebra_rtol(cond) / tau
        if _decided(rho, tau, band):
            assert split.rank.rank == int(np.sum(rho > tau)), (rho, tau, split.rank.rank)
        if split.covariance == "local C_p from C_e" or local.C_e is None:
            np.testing.assert_allclose(split.correlations, rho[: split.correlations.size], rtol=0,
                                       atol=algebra_rtol(cond))


RULES = st.sampled_from(("numpy", "absolute", "canonical"))


def _rule(name: str, case: FusionCase, data) -> RankRule:
    if name == "absolute":
        return RankRule("absolute", data.draw(log_uniform(1e-14, 1e-10), label="absolute tol"))
    return RankRule(name)


def _rank_here(local, rule: RankRule, c_p: np.ndarray) -> int:
    s = np.linalg.svd(local.C_xy, compute_uv=False)
    if rule.name == "numpy":
        return int(np.sum(s > s.max(initial=0.0) * max(local.C_xy.shape) * EPS))
    if rule.name == "absolute":
        return int(np.sum(s > rule.tol))
    rho = np.linalg.svd(_power(c_p, -0.5) @ local.C_xy @ _power(local.C_y, -0.5), compute_uv=False)
    return int(np.sum(rho > rule.tol))


def _truncated_pinv(matrix: np.ndarray, rank: int) -> np.ndarray:
    u, s, vt = np.linalg.svd(matrix, full_matrices=False)
    return (vt[:rank].T / s[:rank]) @ u[:, :rank].T


@given(leak=st.one_of(st.just(0.0), log_uniform(1e-8, 1e-2)), rule_name=RULES, data=st.data())
def test_exactness_verdict_follows_the_gap_measured_here(leak, rule_name, data):
    """Full-rank and decoupled sensors whose decoupled noise leaks by ε (0 or 1e-8 … 1e-2) into the
    other sensor's: a measured gap above rounding is never exact; with ε = 0 a full-rank sensor is."""
    drawn = data.draw(fusion_cases(kinds=("full", "decoupled"), sensors=2, prior="shared", correlated_noise=True,
                                   state_dim=st.integers(2, 4), decoupled_leak=leak), label="case")
    case = drawn.case
    rule = _rule(rule_name, case, data)
    c = case.central
    gain = np.linalg.solve(c.C_y, c.C_xy.T).T
    whiten = _power(c.C_p, -0.5)
    result = dmf_update(case, rank_rule=rule)
    for m, (block, local) in enumerate(zip(c.blocks, case.locals)):
        rank = _rank_here(local, rule, local.C_e + local.C_xy @ np.linalg.solve(local.C_y, local.C_xy.T))
        if rank != result.sensors[m].split.rank.rank:
            continue  # a rank the two routes decide differently (covered by the rank properties)
        projector = _truncated_pinv(local.C_xy, rank) @ local.C_xy
        gap_map = gain[:, block] @ local.C_y @ (projector - np.eye(projector.shape[0]))
        measured = np.linalg.norm(whiten @ gap_map @ _power(local.C_y, 0.5), 2)
        cond = np.linalg.cond(c.C_p) * np.linalg.cond(c.C_y) * np.linalg.cond(local.C_y)
        event(f"{rule_name}: measured gap 10^{int(np.floor(np.log10(max(measured, 1e-300))))}")
        if measured > algebra_rtol(cond):
            assert not result.sensors[m].exact, (rule, measured)
        if leak == 0.0 and rank == local.C_xy.shape[1]:
            assert result.sensors[m].exact, (rule, measured)


@given(drawn=fusion_cases(sensors=st.integers(1, 3)), rule_name=RULES, data=st.data())
def test_repair_messages_restore_the_cmf_computed_here_under_every_rule(drawn, rule_name, data):
    case = drawn.case
    rule = _rule(rule_name, case, data)
    c = case.central
    messages = [repair_message(local, case.y[block], rank_rule=rule, prior_cov=c.C_p)
                for block, local in zip(c.blocks, case.locals)]
    repaired = dmf_update(case, messages, rank_rule=rule).mean
    cmf = c.mu_p + c.C_xy @ np.linalg.solve(c.C_y, case.y - c.mu_y)
    whiten = _power(c.C_p, -0.5)
    cond = np.linalg.cond(c.C_p) * np.linalg.cond(c.C_y) * max(np.linalg.cond(r.C_y) for r in case.locals)
    innovation = np.linalg.solve(np.linalg.cholesky(c.C_y), case.y - c.mu_y)
    size = 1.0 + np.linalg.norm(whiten @ c.mu_p) + np.linalg.norm(innovation)
    for split in (sensor_split(r, rule, c.C_p) for r in case.locals):
        s = split.rank.singular_values[: split.rank.rank]
        cond *= float(s[0] / s[-1]) if s.size else 1.0
    assert np.linalg.norm(whiten @ (repaired - cmf)) <= algebra_rtol(cond) * size, (repaired, cmf)
