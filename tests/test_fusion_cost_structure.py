"""The cost structure of every fusion rule and of the per-step audit along the state dimension,
without timing anything (issue 57 §4; benchmarks/bench_batch.py measures the times).

* Operation counts: the number of Python-level and builtin calls one step of each rule makes
  (counted with ``sys.setprofile``) on the benchmark's system — D states, three sensors of D/2
  outputs — does not grow with D: the arithmetic is whole-matrix LAPACK/BLAS calls, not a loop over
  state components, a sensor's outputs or matrix entries. From D = 64 to D = 128 a loop over the
  state components would add at least 64 calls and one over a sensor's outputs at least 32; the
  count may grow by fewer than 32 (ICI's pairwise roots take a step more or less with the data;
  CI's Newton iterations are the same at both sizes on this system).
* Independent routes at D = 64 and 128: CC and CI (three estimates: the Newton route, whose
  factorisations are LAPACK ``potrf``/``trtri`` per matrix) against explicit inverses in numpy, and
  CI's weights against the optimality condition on the simplex computed with explicit inverses, to
  a tolerance from the condition number of the fused information.
"""

from __future__ import annotations

import functools
import sys

import numpy as np
import pytest

from gpfverify.audit.case import audit_case, audit_to_dict
from gpfverify.fusion.ci import covariance_intersection
from gpfverify.fusion.convex import convex_combination
from gpfverify.fusion.distributed import dmf_update
from gpfverify.fusion.exactness import parse_rank_rule
from gpfverify.model_fusion import _baselines, cmf_step, dmf_step, run_fusion
from gpfverify.models import linear_model
from gpfverify.tolerances import algebra_rtol, kkt_reject_tol

RULES = ("cmf", "dmf", "cc", "ci", "ei", "ici", "audit")
#: the sizes compared, and the growth of a count that a loop over a sensor's D/2 outputs would reach
SMALL, LARGE = 64, 128
SLACK = (LARGE - SMALL) // 2


def _system(d: int, rng: np.random.Generator):
    """benchmarks/bench_batch.py's system: a random orthogonal transition times 0.95, three sensors
    of D/2 outputs each."""
    f = 0.95 * np.linalg.qr(rng.normal(size=(d, d)))[0]
    h = rng.normal(size=(3 * d // 2, d)) / np.sqrt(d)
    return linear_model(f, h, 0.1 * np.eye(d), 0.5 * np.eye(3 * d // 2), sizes=(d // 2,) * 3)


@functools.cache
def _step(d: int):
    """Each rule's one step at the last step of a four-step run, as a call without arguments."""
    rng = np.random.default_rng(d)
    model = _system(d, rng)
    _, ys = model.simulate(4, rng)
    methods = ("cmf", "dmf", "cc", "ci", "ei", "ici")
    fused = run_fusion(model, ys, family="kf", methods=methods, audit=False)
    before, step, y = fused.steps[-2], fused.steps[-1], ys[-1]
    calls = {"cmf": functools.partial(cmf_step, before.estimate("cmf"), model, y, k=step.k, family="kf"),
             "dmf": functools.partial(dmf_step, before.estimate("dmf"), model, y, local_records=step.local,
                                      k=step.k, family="kf"),
             "audit": functools.partial(audit_case, step.dmf.case, rank_rule=step.dmf.result.rank_rule)}
    beliefs = [r.posterior for r in step.local]
    for name, rule in _baselines(methods, None, (), "trace").items():
        calls[name] = functools.partial(rule, beliefs)
    return calls, beliefs


def _calls_made(fn) -> int:
    """The Python-level and builtin (C) calls ``fn()`` makes, after one call outside the count
    (imports and caches)."""
    fn()
    count = 0

    def profile(frame, event, arg):
        nonlocal count
        if event in ("call", "c_call"):
            count += 1

    previous = sys.getprofile()
    sys.setprofile(profile)
    try:
        fn()
    finally:
        sys.setprofile(previous)
    return count


@pytest.mark.parametrize("rule", RULES)
def test_a_rules_operation_count_does_not_grow_with_the_state_dimension(rule):
    small, large = _calls_made(_step(SMALL)[0][rule]), _calls_made(_step(LARGE)[0][rule])
    assert large - small < SLACK, (rule, small, large)


def _ci_reference(covs: list[np.ndarray], weights: np.ndarray) -> tuple[np.ndarray, float]:
    """CI's covariance at ``weights`` by explicit inverses, and the condition number of its information."""
    info = sum(w * np.linalg.inv(c) for w, c in zip(weights, covs))
    return np.linalg.inv(info), float(np.linalg.cond(info))


@pytest.mark.parametrize("d", [64, 128])
def test_cc_and_ci_agree_with_explicit_inverses_at_large_dimension(d):
    beliefs = _step(d)[1]
    covs = [b.cov for b in beliefs]
    means = [b.mean for b in beliefs]

    cc = convex_combination(beliefs)
    ref, cond = _ci_reference(covs, np.ones(3))
    ref_mean = ref @ sum(np.linalg.solve(c, m) for c, m in zip(covs, means))
    rtol = algebra_rtol(cond * max(np.linalg.cond(c) for c in covs))
    np.testing.assert_allclose(cc.cov, ref, rtol=rtol, atol=rtol * np.abs(ref).max())
    np.testing.assert_allclose(cc.mean, ref_mean, rtol=rtol, atol=rtol * np.abs(ref_mean).max())

    ci = covariance_intersection(beliefs)  # three estimates: the Newton route
    w = np.asarray(ci.weights)
    assert w.min() >= 0.0 and abs(w.sum() - 1.0) <= 1e-12
    ref, cond = _ci_reference(covs, w)
    ref_mean = ref @ sum(wm * np.linalg.solve(c, m) for wm, c, m in zip(w, covs, means))
    rtol = algebra_rtol(cond * max(np.linalg.cond(c) for c in covs))
    np.testing.assert_allclose(ci.cov, ref, rtol=rtol, atol=rtol * np.abs(ref).max())
    np.testing.assert_allclose(ci.mean, ref_mean, rtol=rtol, atol=rtol * np.abs(ref_mean).max())
    # trace optimality on the simplex: g_m = tr(S⁻¹ I_m S⁻¹) ≤ Σ_k ω_k g_k (equal where ω_m > 0)
    grads = np.array([np.trace(ref @ np.linalg.inv(c) @ ref) for c in covs])
    assert grads.max() / (w @ grads) - 1.0 <= kkt_reject_tol(cond), (w, grads)
    # and no vertex (a single estimate) has a smaller trace
    assert np.trace(ci.cov) <= min(np.trace(c) for c in covs) * (1.0 + rtol)


@pytest.mark.parametrize("d", [8, 64])
def test_the_audit_given_the_steps_dmf_is_the_audit_that_computes_it(d):
    """run_fusion's audit reuses the step's eq. 35 (``dmf=``) instead of solving it again; a result
    under another rule is not reused. The audit's fields are the same bits either way."""
    audit = _step(d)[0]["audit"]
    case, rule = audit.args[0], audit.keywords["rank_rule"]
    alone = audit_to_dict(audit_case(case, rank_rule=rule))
    assert audit_to_dict(audit_case(case, rank_rule=rule, dmf=dmf_update(case, rank_rule=rule))) == alone
    other = dmf_update(case, rank_rule=parse_rank_rule("numpy"))
    assert audit_to_dict(audit_case(case, rank_rule=rule, dmf=other)) == alone
