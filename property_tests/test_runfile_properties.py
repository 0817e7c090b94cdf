"""Run files: what :func:`~gpfverify.audit.runfile.write_run` writes, the reader gives back.

Drawn runs of 1–6 steps of one layout (state dimension, sensors and their sizes, angle outputs of
every sensor and angle state components, drawn as random subsets), each step its own valid case
(the central joint covariance positive semidefinite, the C_y's definite), with the optional parts
drawn per step — the measurement y at some steps, C_e per sensor (at every step or none, which the
npz layout requires), rank_tol per step or none — and step indices k given (strictly increasing,
with gaps) or not. Written as JSON Lines and as npz, read back whole and in blocks of any size:
the same steps, bit for bit (JSON writes the shortest repr of each double, which reads back
exactly; npz stores the bits), k the given indices or the 0-based positions, and blocks that
partition the run in order.
"""

from pathlib import Path
from tempfile import TemporaryDirectory

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gpfverify.fusion.case import CentralPrediction, FusionCase, LocalReport, stack_circular
from gpfverify.audit.runfile import load_run, open_run, write_run
from gpfverify.strategies import scaled_examples, spd_matrices
from gpfverify.strategies.matrices import float_arrays, log_uniform


def subsets(size: int):
    return st.lists(st.booleans(), min_size=size, max_size=size).map(
        lambda flags: tuple(i for i, f in enumerate(flags) if f))


@st.composite
def runs(draw):
    """(cases, ks): a run of one layout with per-step optional parts."""
    dim = draw(st.integers(1, 3))
    sizes = tuple(draw(st.lists(st.integers(1, 3), min_size=1, max_size=3)))
    total = sum(sizes)
    local_circular = [draw(subsets(l)) for l in sizes]
    circular_state = draw(subsets(dim))
    steps = draw(st.integers(1, 6))
    explicit_k = draw(st.booleans())
    with_c_e = [draw(st.booleans()) for _ in sizes]
    shared_tol = draw(st.one_of(st.none(), log_uniform(1e-12, 1.0)))
    cases = []
    for _ in range(steps):
        joint = draw(spd_matrices(dim + total, 1e3, log_uniform(1e-3, 10.0)))
        central = CentralPrediction(draw(float_arrays((dim,), -10, 10)), joint[:dim, :dim],
                                    draw(float_arrays((total,), -10, 10)), joint[dim:, dim:], joint[:dim, dim:],
                                    sizes, stack_circular(local_circular, sizes), circular_state)
        reports = tuple(LocalReport(draw(float_arrays((dim,), -10, 10)), draw(float_arrays((l,), -10, 10)),
                                    draw(spd_matrices(l, 1e3, log_uniform(1e-3, 10.0))),
                                    draw(float_arrays((dim, l), -5, 5)), draw(float_arrays((dim,), -10, 10)),
                                    draw(spd_matrices(dim, 1e3, log_uniform(1e-3, 10.0))) if c_e else None, circ)
                        for l, c_e, circ in zip(sizes, with_c_e, local_circular))
        y = draw(st.one_of(st.none(), float_arrays((total,), -10, 10)))
        tol = draw(st.one_of(st.just(shared_tol), st.none(), log_uniform(1e-12, 1.0)))
        cases.append(FusionCase(central, reports, y, tol))
    gaps = np.array(draw(st.lists(st.integers(1, 5), min_size=steps, max_size=steps)))
    return cases, [int(k) for k in np.cumsum(gaps) - 1] if explicit_k else None


def assert_same_case(got: FusionCase, want: FusionCase, where: str) -> None:
    for name in ("mu_p", "C_p", "mu_y", "C_y", "C_xy"):
        np.testing.assert_array_equal(getattr(got.central, name), getattr(want.central, name),
                                      err_msg=f"{where} {name}")
    assert got.central.sizes == want.central.sizes and got.central.circular == want.central.circular, where
    assert got.circular_state == want.circular_state, where
    assert len(got.locals) == len(want.locals), where
    for m, (a, b) in enumerate(zip(got.locals, want.locals)):
        for name in ("mu_p", "mu_y", "C_y", "C_xy", "mu_e"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=f"{where} locals[{m}].{name}")
        assert (a.C_e is None) == (b.C_e is None), f"{where} locals[{m}].C_e"
        if b.C_e is not None:
            np.testing.assert_array_equal(a.C_e, b.C_e, err_msg=f"{where} locals[{m}].C_e")
        assert a.circular == b.circular, f"{where} locals[{m}].circular"
    assert (got.y is None) == (want.y is None), f"{where} y"
    if want.y is not None:
        np.testing.assert_array_equal(got.y, want.y, err_msg=f"{where} y")
    assert got.rank_tol == want.rank_tol, f"{where} rank_tol {got.rank_tol} != {want.rank_tol}"


SUFFIXES = {"jsonl": (".jsonl", ".ndjson"), "npz": (".npz", ".NPZ")}


@pytest.mark.parametrize("form", sorted(SUFFIXES))
@settings(max_examples=scaled_examples(0.5))
@given(run=runs(), block=st.integers(1, 3), data=st.data())
def test_a_written_run_reads_back_step_for_step_whole_and_in_blocks(form, run, block, data):
    cases, ks = run
    suffix = data.draw(st.sampled_from(SUFFIXES[form]), label="suffix")
    with TemporaryDirectory() as tmp:
        path = write_run(Path(tmp) / f"run{suffix}", cases, ks)
        read = load_run(path)
        assert read.format == form
        assert read.explicit_k == (ks is not None)
        want_ks = list(range(len(cases))) if ks is None else [int(k) for k in ks]
        assert read.ks == want_ks
        for t, (got, want) in enumerate(zip(read.cases, cases)):
            assert_same_case(got, want, f"step {t}")
        assert len(read) == len(cases)
        with open_run(path) as reader:
            blocks = list(reader.blocks(block))
            assert reader.explicit_k == (ks is not None)
        assert [b.first for b in blocks] == list(range(0, len(cases), block))
        assert all(1 <= len(b) <= block for b in blocks)
        steps = [step for b in blocks for step in b.steps()]
        assert [k for k, _ in steps] == want_ks
        for t, ((_, got), want) in enumerate(zip(steps, cases)):
            assert_same_case(got, want, f"block step {t}")
