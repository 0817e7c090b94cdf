"""One fusion step of several Monte Carlo runs at once (gpfverify.fusion.batched and the block
route of eq. 35, gpfverify.audit.block.block_dmf) against each run's step alone: the same bits for
every way of splitting the runs into batches (8, 1 × 8, 3 + 3 + 2, 5 + 3), and equal to the per-run
rules — dmf_update, cmf_update, convex_combination, the squared Mahalanobis distance — to
PER_RUN_RTOL relative to the size of what they combine (full-rank steps, steps where a sensor lost
rank, angle outputs and angle state components)."""

import dataclasses

import numpy as np
import pytest

from gpfverify.audit.block import block_dmf, cmf_update_block
from gpfverify.filters.records import Gaussian
from gpfverify.fusion.batched import convex_combination_batch, squared_mahalanobis_batch
from gpfverify.fusion.case import CentralPrediction, FusionCase, split_circular
from gpfverify.fusion.caseblock import CaseBlock, LocalBlock
from gpfverify.fusion.centralized import cmf_update
from gpfverify.fusion.convex import convex_combination
from gpfverify.fusion.distributed import dmf_update
from gpfverify.fusion.exactness import RankRule
from gpfverify.fusion.synthetic import random_case
from gpfverify.linalg import solve_spd
from gpfverify.tolerances import PER_RUN_RTOL

RUNS = 8
SPLITS = ((8,), (1,) * 8, (3, 3, 2), (5, 3))


def _with_angles(case: FusionCase, outputs=(), states=()) -> FusionCase:
    c = case.central
    central = CentralPrediction(c.mu_p, c.C_p, c.mu_y, c.C_y, c.C_xy, c.sizes, tuple(outputs), tuple(states))
    local = tuple(dataclasses.replace(r, circular=own)
                  for r, own in zip(case.locals, split_circular(central.circular, c.sizes)))
    return dataclasses.replace(case, central=central, locals=local)


def _cases(kind: str) -> list[FusionCase]:
    rng = np.random.default_rng({"full": 1, "lost": 2, "angles": 3}[kind])
    if kind == "full":
        return [random_case(rng, 4, (2, 3, 1)) for _ in range(RUNS)]
    if kind == "lost":
        return [random_case(rng, 4, (2, 3, 1), ranks=(2, 2, 1) if b % 2 else (1, 3, 0)) for b in range(RUNS)]
    return [_with_angles(random_case(rng, 4, (2, 3, 1)), outputs=(1, 4), states=(2,)) for _ in range(RUNS)]


def _block(cases: list[FusionCase]) -> CaseBlock:
    first = cases[0].central
    stack = lambda get: np.stack([get(c) for c in cases])  # noqa: E731
    locals_ = tuple(LocalBlock(*(stack(lambda c, m=m, f=f: getattr(c.locals[m], f))
                                 for f in ("mu_p", "mu_y", "C_y", "C_xy", "mu_e", "C_e")),
                               np.ones(len(cases), dtype=bool)) for m in range(len(first.sizes)))
    return CaseBlock(first.sizes, first.circular, *(stack(lambda c, f=f: getattr(c.central, f))
                                                    for f in ("mu_p", "C_p", "mu_y", "C_y", "C_xy")),
                     locals_, stack(lambda c: c.y), np.full(len(cases), np.nan), first.circular_state)


def _split(cases, fn, split):
    out, start = [], 0
    for size in split:
        out.append(fn(_block(cases[start:start + size])))
        start += size
    return np.concatenate(out)


def _assert_close(got, ref, scale, what):
    assert np.all(np.abs(got - ref) <= PER_RUN_RTOL * scale), (what, np.max(np.abs(got - ref) / scale))


@pytest.mark.parametrize("kind", ["full", "lost", "angles"])
@pytest.mark.parametrize("rule", [RankRule("canonical"), RankRule("numpy")], ids=["canonical", "numpy"])
def test_eq35_of_many_runs_is_each_runs_own(kind, rule):
    cases = _cases(kind)
    means = [_split(cases, lambda b: block_dmf(b, rule).mean, split) for split in SPLITS]
    covs = [_split(cases, lambda b: block_dmf(b, rule).cov, split) for split in SPLITS]
    for mean, cov in zip(means[1:], covs[1:]):
        np.testing.assert_array_equal(mean, means[0])
        np.testing.assert_array_equal(cov, covs[0])
    ranks = block_dmf(_block(cases), rule).sensors
    for b, case in enumerate(cases):
        alone = dmf_update(case, rank_rule=rule)
        assert [int(s.split.rank[b]) for s in ranks] == [s.split.rank.rank for s in alone.sensors]
        # eq. 35 sums μ_p and G's columns times the sensors' terms: rounding relative to their size
        scale = np.linalg.norm(case.central.mu_p) + np.linalg.norm(alone.mean) + np.linalg.norm(alone.mean
                                                                                                - case.central.mu_p)
        _assert_close(means[0][b], alone.mean, scale, "mean")
        _assert_close(covs[0][b], alone.cov, np.abs(case.central.C_p).max(), "cov")


@pytest.mark.parametrize("kind", ["full", "angles"])
def test_cmf_update_of_many_runs_is_each_runs_own(kind):
    cases = _cases(kind)
    means = [_split(cases, lambda b: cmf_update_block(b).mean, split) for split in SPLITS]
    for mean in means[1:]:
        np.testing.assert_array_equal(mean, means[0])
    for b, case in enumerate(cases):
        alone = cmf_update(case.central, case.y)
        _assert_close(means[0][b], alone.mean, np.linalg.norm(case.central.mu_p) + np.linalg.norm(alone.mean), "mean")


@pytest.mark.parametrize("states", [(), (1,)])
def test_baselines_and_distances_of_many_runs_are_each_runs_own(states):
    rng = np.random.default_rng(4)
    means = rng.normal(size=(RUNS, 3, 4)) * 3.0
    a = rng.normal(size=(RUNS, 3, 4, 4))
    covs = a @ np.swapaxes(a, -1, -2) + 0.2 * np.eye(4)
    truth = rng.normal(size=(RUNS, 4))
    fused = [np.concatenate([convex_combination_batch(means[s], covs[s], states).mean for s in _slices(split)])
             for split in SPLITS]
    distances = [np.concatenate([squared_mahalanobis_batch(truth[s], means[s, 0], covs[s, 0]) for s in _slices(split)])
                 for split in SPLITS]
    for f, d in zip(fused[1:], distances[1:]):
        np.testing.assert_array_equal(f, fused[0])
        np.testing.assert_array_equal(d, distances[0])
    for b in range(RUNS):
        alone = convex_combination([Gaussian(m, c) for m, c in zip(means[b], covs[b])], states)
        cond = np.linalg.cond(np.linalg.inv(alone.cov))
        _assert_close(fused[0][b], alone.mean, cond * np.abs(means[b]).max(), "cc mean")
        err = truth[b] - means[b, 0]
        ref = float(err @ solve_spd(covs[b, 0], err))
        _assert_close(distances[0][b], ref, np.linalg.cond(covs[b, 0]) * ref, "mahalanobis")


def _slices(split):
    start = 0
    for size in split:
        yield slice(start, start + size)
        start += size


@pytest.mark.parametrize("spread", [0.5, 6.0])
def test_rcc_ci_of_many_runs_is_each_runs_own(spread):
    """RCC-CI's data formed for all runs and each run solved alone: the same bits for every split,
    and the per-run rcc_ci's estimate to PER_RUN_RTOL (its weights are Clarabel's duals for the same data), also
    where the ellipsoids miss and the size is enlarged (``spread`` 6: most runs)."""
    from gpfverify.fusion.rcc_ci import rcc_ci, rcc_ci_batch

    rng = np.random.default_rng(11)
    means = rng.normal(size=(RUNS, 2, 3)) * spread
    a = rng.normal(size=(RUNS, 2, 3, 3))
    covs = a @ np.swapaxes(a, -1, -2) + 0.3 * np.eye(3)
    results = [[rcc_ci_batch(means[s], covs[s]) for s in _slices(split)] for split in SPLITS]
    joined = [{f: np.concatenate([getattr(r, f) for r in parts]) for f in ("mean", "cov", "weights", "c", "enlarged")}
              for parts in results]
    for other in joined[1:]:
        for f, v in other.items():
            np.testing.assert_array_equal(v, joined[0][f], err_msg=f)
    for b in range(RUNS):
        alone = rcc_ci([Gaussian(m, c) for m, c in zip(means[b], covs[b])], on_empty="enlarge")
        assert bool(joined[0]["enlarged"][b]) == alone.enlarged
        np.testing.assert_allclose(joined[0]["c"][b], alone.c, rtol=PER_RUN_RTOL)
        np.testing.assert_allclose(joined[0]["weights"][b], alone.weights, rtol=PER_RUN_RTOL)
        cond = np.linalg.cond(np.linalg.inv(alone.cov))
        _assert_close(joined[0]["mean"][b], alone.mean, cond * np.abs(means[b]).max(), "rcc-ci mean")
    assert joined[0]["enlarged"].any() == (spread > 1)


@pytest.mark.parametrize("criterion", ["trace", "det"])
def test_ci_of_many_runs_is_each_runs_own(criterion):
    """CI of three estimates by Newton's method over the runs at once, each run with its own
    iterates: the same bits for every split, and as covariance_intersection of each run alone."""
    from gpfverify.fusion.ci import covariance_intersection, covariance_intersection_batch

    rng = np.random.default_rng(12)
    means = rng.normal(size=(RUNS, 3, 4))
    q = np.linalg.qr(rng.normal(size=(RUNS, 3, 4, 4)))[0]
    covs = (q * np.geomspace(1.0, 20.0, 4)[..., None, :]) @ np.swapaxes(q, -1, -2)
    results = [[covariance_intersection_batch(means[s], covs[s], criterion) for s in _slices(split)] for split in SPLITS]
    joined = [{f: np.concatenate([getattr(r, f) for r in parts]) for f in ("mean", "cov", "weights")}
              for parts in results]
    for other in joined[1:]:
        for f, v in other.items():
            np.testing.assert_array_equal(v, joined[0][f], err_msg=f)
    for b in range(RUNS):
        alone = covariance_intersection([Gaussian(m, c) for m, c in zip(means[b], covs[b])], criterion)
        np.testing.assert_allclose(joined[0]["weights"][b], alone.weights, rtol=PER_RUN_RTOL, atol=PER_RUN_RTOL)
        _assert_close(joined[0]["mean"][b], alone.mean, np.linalg.cond(alone.cov) * np.abs(means[b]).max(), "ci mean")
    assert all(f is None for parts in results for r in parts for f in r.failures)
