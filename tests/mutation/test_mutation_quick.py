"""The quick subset of the mutation run (part of ``make test``, well under a minute): the mutant
list still applies to the working tree, the committed kill table covers it, and two mutants are
run end to end on a copy of the package and killed by a property."""

import json

import pytest

from tests.mutation.mutants import MUTANTS
from tests.mutation.run_mutants import ROOT, apply, make_copy, run_tests, verdict

pytestmark = pytest.mark.slow  # runs properties on mutated copies of the package

KILL_TABLE = ROOT / "reports" / "mutation" / "kill_table.json"


@pytest.mark.parametrize("mutant", MUTANTS, ids=[m.name for m in MUTANTS])
def test_every_mutant_snippet_occurs_exactly_once(mutant):
    text = (ROOT / mutant.path).read_text(encoding="utf-8")
    assert text.count(mutant.old) == 1, f"{mutant.name}: update tests/mutation/mutants.py"
    assert mutant.new != mutant.old and all((ROOT / t).exists() for t in mutant.tests)


def test_the_committed_kill_table_covers_every_mutant():
    table = json.loads(KILL_TABLE.read_text(encoding="utf-8"))
    assert {r["mutant"] for r in table["mutants"]} == {m.name for m in MUTANTS}
    assert len(MUTANTS) >= 100
    killed = sum(r["verdict"] == "killed (property)" for r in table["mutants"])
    assert killed >= 0.95 * len(MUTANTS), f"{killed} of {len(MUTANTS)} killed by a property"


def test_every_survivor_in_the_committed_kill_table_is_explained():
    table = json.loads(KILL_TABLE.read_text(encoding="utf-8"))
    notes = {m.name: m.note for m in MUTANTS}
    unexplained = [r["mutant"] for r in table["mutants"] if r["verdict"] != "killed (property)"
                   and not notes.get(r["mutant"])]
    assert not unexplained, f"explain these survivors in tests/mutation/mutants.py: {unexplained}"


QUICK = {"systematic resampling: searchsorted side left": "systematic_resampling",
         "Gaussian update: innovation sign flipped": "information_form and KF"}


@pytest.mark.parametrize("name", sorted(QUICK))
def test_quick_mutant_is_killed_by_a_property(name, tmp_path):
    mutant = next(m for m in MUTANTS if m.name == name)
    copy = make_copy(tmp_path)
    apply(mutant, copy)
    result = run_tests(copy, mutant.tests, timeout=120, extra=("-k", QUICK[name]))
    assert verdict(result) == "killed (property)", result


def test_the_unmutated_copy_passes_the_same_selection(tmp_path):
    copy = make_copy(tmp_path)
    result = run_tests(copy, ["property_tests/test_filter_properties.py"], timeout=120,
                       extra=("-k", " or ".join(QUICK.values())))
    assert verdict(result) == "survived" and result["code"] == 0, result
