"""The sampled mutation machinery on small inputs (the run itself takes hours: `make mutation`)."""

import json

import numpy as np
import pytest
import scipy.stats

from tests.mutation import draw, score, selection
from tests.mutation.workspace import ROOT

@pytest.mark.parametrize("k,n", [(0, 10), (3, 10), (10, 10), (381, 420), (1, 1)])
def test_wilson_interval_is_scipys(k, n):
    want = scipy.stats.binomtest(k, n).proportion_ci(0.95, method="wilson")
    np.testing.assert_allclose(score.wilson(k, n), (want.low, want.high), rtol=1e-9, atol=1e-12)


def test_annotations_are_not_mutated_and_every_mutant_changes_its_module(tmp_path):
    path = tmp_path / "module.py"
    path.write_text("from __future__ import annotations\n\n\n"
                    "def f(x: int | None = 1, *, y: list[int | str] = ()) -> int | None:\n"
                    "    z = x | 2\n"
                    "    w: int | None = z\n"
                    "    return w\n", encoding="utf-8")
    found = draw._enumerate(path, path.read_text(encoding="utf-8"), "digest")
    bit_or = sorted(site for site, ops in found.sites.items()
                    if any(op.startswith("core/ReplaceBinaryOperator_BitOr_") for op, _ in ops))
    assert bit_or == [(5, 10)]  # only `x | 2`: the `|` of the signature's annotations are left alone
    source = path.read_text(encoding="utf-8")
    for ops in found.sites.values():
        operator, occurrence = ops[0]
        assert draw.mutated_source(path, operator, occurrence) != source


def test_the_sample_is_seeded_and_proportional_to_statement_lines(monkeypatch):
    modules = [ROOT / "gpfverify" / name for name in ("tolerances.py", "angles.py", "rng.py")]
    monkeypatch.setattr(draw, "modules", lambda: modules)
    first = draw.draw(12, seed=5, log=lambda _: None)
    again = draw.draw(12, seed=5, log=lambda _: None)
    assert [d.key for d in first] == [d.key for d in again]
    enumerated = {str(m.relative_to(ROOT)): draw.enumerate_module(m) for m in modules}
    total = sum(e.weight for e in enumerated.values())
    for path, e in enumerated.items():
        count = sum(d.path == path for d in first)
        share = 12 * e.weight / total
        available = sum(len(ops) for ops in e.sites.values())
        # floor or ceil of the module's share, or every mutant it has when it has fewer
        assert count == available if available < share else abs(count - share) < 1, (path, count, share)


def test_the_committed_report_renders_its_record():
    record = json.loads((ROOT / "reports" / "mutation" / "sampled.json").read_text(encoding="utf-8"))
    page = (ROOT / "reports" / "mutation" / "sampled.md").read_text(encoding="utf-8")
    o = record["overall"]
    assert f"| whole suite | {o['killed_by_suite']} | {o['counted']} |" in page
    assert f"| property_tests alone | {o['killed_by_properties']} | {o['counted']} |" in page
    survivors = [r for r in record["rows"] if r["verdict"] not in score.KILLED]
    assert f"## Survivors ({len(survivors)})" in page
    assert o["killed_by_suite"] == sum(r["verdict"] in score.KILLED and not r["equivalent"] for r in record["rows"])


def test_a_module_changed_since_the_map_was_made_is_not_mapped():
    """The map's lines hold for the module contents they were recorded from, and for no other."""
    now = selection.module_digests()
    path = "gpfverify/errors.py"
    stale = {**now, path: "0" * 64}
    cmap = selection.CoverageMap("", "", {path: {1: ["tests/test_x.py::test_y"]}}, {}, [], 0.0, stale)
    assert not cmap.mapped(path)
    assert cmap.mapped("gpfverify/tolerances.py")
    assert selection.CoverageMap("", "", {}, {}, [], 0.0, now).mapped(path)
