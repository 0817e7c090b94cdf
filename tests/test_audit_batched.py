"""The block route of the run-file audit (:mod:`gpfverify.blockaudit`) against the per-step audit
(:func:`gpfverify.audit.audit_case`, the definition): every step the block route audits is the
per-step audit to each field's rounding (tests/audit_routes.py), under every rank rule, with and
without the sensors' C_e, in mixed units; the steps it leaves (a sensor that lost rank, no y,
angles) are exactly those off the common path, and the command line's output is the per-step
audit whichever route a step took."""

from __future__ import annotations

import dataclasses
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from gpfverify.audit import audit_case, audit_to_dict
from gpfverify.blockaudit import block_audits
from gpfverify.fusion.exactness import RankRule, rescaled_case
from gpfverify.fusion.runfile import open_run, write_run
from gpfverify.fusion.synthetic import random_case
from gpfverify.runaudit import stream_audit

sys.path.insert(0, str(Path(__file__).parent))  # the suite imports in importlib mode: the helper beside it
from audit_routes import assert_same_audit  # noqa: E402

RULES = (RankRule("canonical"), RankRule("numpy"), RankRule("absolute", 1e-9))


def _without_c_e(case):
    return dataclasses.replace(case, locals=tuple(dataclasses.replace(r, C_e=None) for r in case.locals))


def _cases(seed: int = 0):
    """Full-rank steps, steps where a sensor lost rank, steps without y, steps without C_e and
    steps in mixed units (metres against micrometres, radians against degrees), in one run."""
    rng = np.random.default_rng(seed)
    full = [random_case(rng, 4, (2, 2, 2)) for _ in range(12)]
    lost = [random_case(rng, 4, (2, 2, 2), ranks=(2, 1, 2)) for _ in range(4)]
    blind = [random_case(rng, 4, (2, 2, 2), with_y=False) for _ in range(3)]
    bare = [_without_c_e(random_case(rng, 4, (2, 2, 2))) for _ in range(4)]
    scaled = [rescaled_case(random_case(rng, 4, (2, 2, 2)), [1e6, 1.0, 1e-4, 1.0], [1.0, 1e3, 1e-3, 1.0, 57.3, 1.0])
              for _ in range(4)]
    mixed = [*full, *lost, *blind, *bare, *scaled]
    order = rng.permutation(len(mixed))
    return [mixed[i] for i in order]


def _block(tmp_path, cases):
    with open_run(write_run(tmp_path / "run.jsonl", cases)) as reader:  # C_e on some steps only
        [block] = list(reader.blocks())
    return block


def _on_common_path(audit) -> bool:
    return audit.cmf_mean is not None and audit.condition_holds


@pytest.mark.parametrize("rule", RULES, ids=str)
def test_every_step_the_block_route_audits_is_the_per_step_audit(tmp_path, rule):
    cases = _cases()
    block = _block(tmp_path, cases)
    batched = block_audits(block.block, rule)
    covered = 0
    for audit, case in zip(batched, cases):
        expected = audit_case(case, rank_rule=rule)
        # the block route takes exactly the common path: y given, every sensor full column rank
        assert (audit is not None) == _on_common_path(expected)
        if audit is not None:
            covered += 1
            assert_same_audit(json.loads(json.dumps(audit_to_dict(expected))),
                              json.loads(json.dumps(audit_to_dict(audit))), case)
    assert covered >= 20  # the fixture exercises the block route (full, bare and scaled steps)


def test_a_block_with_angle_outputs_is_left_to_the_per_step_route(tmp_path):
    rng = np.random.default_rng(3)
    cases = [dataclasses.replace(c, central=dataclasses.replace(c.central, circular=(1,)),
                                 locals=(dataclasses.replace(c.locals[0], circular=(1,)), *c.locals[1:]))
             for c in (random_case(rng, 4, (2, 2)) for _ in range(3))]
    assert block_audits(_block(tmp_path, cases).block, RankRule("canonical")) == [None] * 3


def test_the_command_line_audit_is_the_per_step_audit_whichever_route(tmp_path):
    cases = _cases(seed=5)
    import io

    out = io.BytesIO()
    stream_audit(write_run(tmp_path / "run.jsonl", cases), out)
    steps = json.loads(out.getvalue())["steps"]
    assert len(steps) == len(cases)
    for k, (step, case) in enumerate(zip(steps, cases)):
        assert step["k"] == k
        expected = {"k": k, **json.loads(json.dumps(audit_to_dict(audit_case(case))))}
        assert_same_audit(expected, step, case)
