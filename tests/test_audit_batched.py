"""The block route of the run-file audit (:mod:`gpfverify.audit.block`) against the per-step audit
(:func:`gpfverify.audit.case.audit_case`, the definition): every step of a block is the per-step audit
to each field's rounding (tests/audit_routes.py) under every rank rule — steps where a sensor lost
rank (exact anyway or not, down to rank 0, more outputs than states), steps without y, without the
sensors' C_e, in mixed units, with angle outputs (branch offsets included) and angle state
components; drawn cases of every cross-term design as well as fixed ones. A block whose
factorisations need jitter is left to the per-step route, and the command line's output is the
per-step audit whichever route a step took."""

from __future__ import annotations

import dataclasses
import io
import json
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gpfverify.audit.case import audit_case, audit_to_dict
from gpfverify.audit.block import block_audits
from gpfverify.fusion.case import CentralPrediction, FusionCase, split_circular
from gpfverify.fusion.exactness import RankRule, rescaled_case
from gpfverify.audit.runfile import open_run, write_run
from gpfverify.fusion.synthetic import random_case
from gpfverify.audit.run import stream_audit
from gpfverify.strategies.fusion import PRIORS, fusion_cases
from gpfverify.strategies.gaussians import FULL_COLUMN_RANK_KINDS, KINDS, size_range

sys.path.insert(0, str(Path(__file__).parent))  # the suite imports in importlib mode: the helper beside it
from audit_routes import assert_same_audit  # noqa: E402

RULES = (RankRule("canonical"), RankRule("numpy"), RankRule("absolute", 1e-9))


def _without_c_e(case):
    return dataclasses.replace(case, locals=tuple(dataclasses.replace(r, C_e=None) for r in case.locals))


def _with_angles(case: FusionCase, outputs=(), states=()) -> FusionCase:
    """The same step with the stacked outputs ``outputs`` and the state components ``states`` read
    as angles (radians)."""
    c = case.central
    central = CentralPrediction(c.mu_p, c.C_p, c.mu_y, c.C_y, c.C_xy, c.sizes, tuple(sorted(outputs)),
                                tuple(sorted(states)))
    local = tuple(dataclasses.replace(r, circular=own)
                  for r, own in zip(case.locals, split_circular(central.circular, c.sizes)))
    return dataclasses.replace(case, central=central, locals=local)


def _cases(seed: int = 0):
    """Full-rank steps, steps where a sensor lost rank (one direction, every direction, or one
    output uncorrelated with everything: rank lost yet exact), steps without y, steps without C_e and
    steps in mixed units (metres against micrometres, radians against degrees), in one run."""
    rng = np.random.default_rng(seed)
    full = [random_case(rng, 4, (2, 2, 2)) for _ in range(8)]
    lost = [random_case(rng, 4, (2, 2, 2), ranks=(2, 1, 2)) for _ in range(4)]
    none = [random_case(rng, 4, (2, 2, 2), ranks=(2, 2, 0)) for _ in range(2)]
    decoupled = [random_case(rng, 4, (2, 2, 2), decoupled=(3,)) for _ in range(2)]
    blind = [random_case(rng, 4, (2, 2, 2), with_y=False) for _ in range(2)]
    blind_lost = [random_case(rng, 4, (2, 2, 2), ranks=(1, 2, 2), with_y=False) for _ in range(2)]
    bare = [_without_c_e(random_case(rng, 4, (2, 2, 2), ranks=ranks)) for ranks in ((2, 2, 2), (2, 1, 2), (2, 2, 2))]
    units = ([1e6, 1.0, 1e-4, 1.0], [1.0, 1e3, 1e-3, 1.0, 57.3, 1.0])
    scaled = [rescaled_case(random_case(rng, 4, (2, 2, 2), ranks=ranks), *units)
              for ranks in ((2, 2, 2), (2, 2, 2), (2, 1, 2), (1, 2, 2))]
    mixed = [*full, *lost, *none, *decoupled, *blind, *blind_lost, *bare, *scaled]
    order = rng.permutation(len(mixed))
    return [mixed[i] for i in order]


def _blocks(cases, directory: Path):
    """The blocks a run file of ``cases`` is read in (C_e on some steps only, y on some)."""
    with open_run(write_run(directory / "run.jsonl", cases)) as reader:
        return [b.block for b in reader.blocks()]


def _assert_routes_agree(cases, rule: RankRule, directory: Path) -> None:
    [block] = _blocks(cases, directory)
    batched = block_audits(block, rule)
    assert len(batched) == len(cases)
    for audit, case in zip(batched, cases):
        assert audit is not None
        expected = json.loads(json.dumps(audit_to_dict(audit_case(case, rank_rule=rule))))
        assert_same_audit(expected, json.loads(json.dumps(audit_to_dict(audit))), case)


@pytest.mark.parametrize("rule", RULES, ids=str)
def test_every_step_of_a_block_is_the_per_step_audit(tmp_path, rule):
    cases = _cases()
    audits = [audit_case(c, rank_rule=rule) for c in cases]
    # the fixture exercises what the block route has to get right
    assert sum(not a.condition_holds for a in audits) >= 10 and sum(a.cmf_mean is None for a in audits) == 4
    assert any(a.exact and not a.condition_holds for a in audits)
    assert any(not a.exact for a in audits)
    _assert_routes_agree(cases, rule, tmp_path)


def _branching(case: FusionCase) -> FusionCase:
    """``case`` with sensor 0's second output an angle whose two wrapped DMF terms, 3.0 and 1.9 rad,
    sum beyond π (branch offset +1), and state component 2 an angle."""
    angled = _with_angles(case, outputs=(1,), states=(2,))
    c, local = angled.central, angled.locals[0]
    mu_y, local_mu_y, y = c.mu_y.copy(), local.mu_y.copy(), angled.y.copy()
    mu_y[1], local_mu_y[1], y[1] = -2.0, 1.0, 2.9
    return dataclasses.replace(angled, central=dataclasses.replace(c, mu_y=mu_y),
                               locals=(dataclasses.replace(local, mu_y=local_mu_y), *angled.locals[1:]), y=y)


@pytest.mark.parametrize("rule", RULES, ids=str)
def test_angle_outputs_and_states_are_audited_by_the_block_route_as_per_step(tmp_path, rule):
    rng = np.random.default_rng(3)
    cases = [_branching(random_case(rng, 4, (2, 2), ranks=ranks)) for ranks in ((2, 2), (2, 1), (1, 2), (2, 2))]
    cases.append(_with_angles(random_case(rng, 4, (2, 2), with_y=False), outputs=(1,), states=(2,)))
    expected = audit_case(cases[0], rank_rule=rule)
    assert expected.sensors[0].branch_offsets.tolist() == [0, 1]       # the fixture branches
    _assert_routes_agree(cases, rule, tmp_path)


@st.composite
def _drawn_blocks(draw):
    """(cases of one layout, rule): each step's cross terms of drawn designs (full, nearly full,
    deficient, zero, decoupled) around a shared or independent local prior, y on some steps, C_e
    dropped by some sensors, angle outputs and angle state components, and the other components
    in drawn units."""
    dim = draw(st.integers(1, 4))
    sizes = draw(st.lists(st.integers(1, dim + 1), min_size=1, max_size=3))
    outputs = draw(st.sets(st.integers(0, sum(sizes) - 1), max_size=2))
    states = draw(st.sets(st.integers(0, dim - 1), max_size=1))
    cases = []
    for _ in range(draw(st.integers(1, 4))):
        kinds = [draw(st.sampled_from([k for k in KINDS if size_range(k, dim, size + 1)[0] <= size
                                       and (k not in FULL_COLUMN_RANK_KINDS or size <= dim)])) for size in sizes]
        case = draw(fusion_cases(state_dim=dim, sizes=sizes, kinds=kinds, prior=st.sampled_from(PRIORS),
                                 with_y=draw(st.booleans()))).case
        bare = draw(st.lists(st.booleans(), min_size=len(sizes), max_size=len(sizes)))
        case = dataclasses.replace(case, locals=tuple(dataclasses.replace(r, C_e=None) if drop else r
                                                       for r, drop in zip(case.locals, bare)))
        exponents = draw(st.lists(st.integers(-4, 4), min_size=dim + sum(sizes), max_size=dim + sum(sizes)))
        scale = 10.0 ** np.array(exponents, dtype=float)
        scale[list(states)] = 1.0
        scale[[dim + j for j in outputs]] = 1.0
        cases.append(_with_angles(rescaled_case(case, scale[:dim], scale[dim:]), outputs, states))
    return cases, draw(st.sampled_from(RULES))


@settings(max_examples=40)
@given(drawn=_drawn_blocks())
def test_drawn_blocks_are_audited_as_per_step(drawn):
    cases, rule = drawn
    with tempfile.TemporaryDirectory() as directory:
        _assert_routes_agree(cases, rule, Path(directory))


def test_outputs_of_very_different_scales_are_audited_as_per_step(tmp_path):
    """C_y's variances span 1e-9 to 2e7 (a drawn case): the block route's G = C_xy C_y⁻¹ solves with
    C_y's equilibrated Cholesky factor, as accurate as the per-step route's Cholesky solve (an LU
    solve of C_y itself left a gap gain of 2.5e-12 on a sensor that lost rank, 1e5 times the
    per-step route's and beyond its bound: "not exact" where the per-step route says exact)."""
    from gpfverify.fusion.caseblock import load_case

    case = load_case(Path(__file__).parent / "fixtures" / "cases" / "badly_scaled_outputs.json")
    variances = np.diag(case.central.C_y)
    assert variances.max() / variances.min() > 1e15  # the fixture is what it says
    rule = RankRule("canonical")
    expected = audit_case(case, rank_rule=rule)
    assert not all(s.full_column_rank for s in expected.sensors) and expected.exact
    _assert_routes_agree([case], rule, tmp_path)


def _known_component(case: FusionCase, i: int) -> FusionCase:
    """``case`` with state component i known exactly by the centre and every sensor (its rows and
    columns of every state covariance and cross covariance zero): C_p is singular."""
    keep = np.ones(case.state_dim)
    keep[i] = 0.0
    c = case.central
    central = dataclasses.replace(c, C_p=c.C_p * np.outer(keep, keep), C_xy=c.C_xy * keep[:, None])
    local = tuple(dataclasses.replace(r, C_xy=r.C_xy * keep[:, None], C_e=r.C_e * np.outer(keep, keep))
                  for r in case.locals)
    return dataclasses.replace(case, central=central, locals=local)


def test_a_block_that_needs_jitter_is_left_to_the_per_step_route(tmp_path):
    """A singular C_p (a state component the prediction knows exactly): its equilibrated Cholesky
    factor needs jitter, which only the per-step route adds; the command line audits such a block
    step by step (the same computation as audit_case's, so the same numbers)."""
    rng = np.random.default_rng(4)
    cases = [random_case(rng, 3, (2, 1)) for _ in range(3)]
    cases[1] = _known_component(cases[1], 0)
    [block] = _blocks(cases, tmp_path)
    assert block_audits(block, RankRule("canonical")) == [None] * 3
    out = io.BytesIO()
    stream_audit(tmp_path / "run.jsonl", out)
    for step, case in zip(json.loads(out.getvalue())["steps"], cases):
        assert step == {"k": step["k"], **json.loads(json.dumps(audit_to_dict(audit_case(case))))}


def test_the_command_line_audit_is_the_per_step_audit_whichever_route(tmp_path):
    cases = _cases(seed=5)
    out = io.BytesIO()
    stream_audit(write_run(tmp_path / "run.jsonl", cases), out)
    steps = json.loads(out.getvalue())["steps"]
    assert len(steps) == len(cases)
    for k, (step, case) in enumerate(zip(steps, cases)):
        assert step["k"] == k
        expected = {"k": k, **json.loads(json.dumps(audit_to_dict(audit_case(case))))}
        assert_same_audit(expected, step, case)
