"""The ``gpfverify`` pytest plugin and the property suites of :mod:`gpfverify.testing`, run by pytest
itself (pytester, in a child process where the plugin loads from its ``pytest11`` entry point):

* a user's suites with rules that break a property fail exactly those properties, and each prints
  its shrunk counterexample as a fusion case that ``gpfverify audit`` reads — printed in the report,
  and written as a file with ``--gpfverify-cases DIR``; a property a rule keeps passes (here the
  order of the sensors; examples/test_my_fusion_rule.py runs whole suites that pass);
* the plugin cannot break or slow another project's test run: loading it imports neither numpy nor
  hypothesis, and a test that names none of its fixtures gets none of them.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytest_plugins = ["pytester"]

USER_SUITES = '''
import numpy as np
from gpfverify.fusion import convex_combination
from gpfverify.fusion.distributed import dmf_update
from gpfverify.testing import CaseRuleSuite, EstimateRuleSuite


class TestIndependenceAssumed(EstimateRuleSuite):
    """The convex combination assumes independent local errors: not conservative under correlation."""
    rule = staticmethod(lambda estimates, circular_state=(): convex_combination(list(estimates), circular_state))


def forgetful_dmf(case):
    """Eq. 35 without its local-posterior term: the sensors' own updates are dropped."""
    from gpfverify.fusion.case import FusionCase, LocalReport
    reports = tuple(LocalReport(r.mu_p, r.mu_y, r.C_y, r.C_xy, r.mu_p, r.C_e, r.circular) for r in case.locals)
    return dmf_update(FusionCase(case.central, reports, case.y, case.rank_tol)).mean


class TestForgetfulDmf(CaseRuleSuite):
    rule = staticmethod(forgetful_dmf)
    angles = False
'''


def _run(pytester, *args):
    pytester.makepyfile(test_user_rules=USER_SUITES)
    return pytester.runpytest_subprocess("-p", "no:cacheprovider", "--hypothesis-profile=ci", "-q", *args)


def _audit(path: Path) -> dict:
    run = subprocess.run([sys.executable, "-m", "gpfverify", "audit", str(path), "--json"], capture_output=True,
                         text=True)
    assert run.returncode == 0, run.stderr
    return json.loads(run.stdout)


@pytest.mark.slow
def test_failing_properties_print_and_write_case_files_that_audit_reads(pytester):

    pytester.makeconftest("import gpfverify.strategies.profiles  # gpfverify's ci profile, as a user registers it\n")
    cases = pytester.path / "cases"
    # the two properties these rules break, and one the estimate rule keeps (whole suites that pass run
    # in examples/test_my_fusion_rule.py; a case suite's examples cost more, so one property of it here)
    result = _run(pytester, "--gpfverify-cases", str(cases), "-k", "conservative or cmf or Assumed and order")
    outcomes = result.parseoutcomes()
    failed = sorted(line.split("::", 1)[1].split(" ")[0] for line in result.outlines if line.startswith("FAILED"))
    assert failed == ["TestForgetfulDmf::test_reduces_to_cmf_when_the_rank_condition_holds",
                      "TestIndependenceAssumed::test_conservative_for_every_admissible_correlation"], result.outlines
    assert outcomes["passed"] == 1
    # printed: one line of JSON per failure, each a case the audit reads (counted in the failure reports:
    # where the CI variable is set, pytest's short summary repeats each failure's whole message)
    prefix = "gpfverify fusion case:"
    reports = result.outlines[:next(n for n, line in enumerate(result.outlines) if "short test summary" in line)]
    printed = [line.split(prefix, 1)[1] for line in reports if prefix in line]
    assert len(printed) == 2
    for n, text in enumerate(printed):
        path = pytester.path / f"printed-{n}.json"
        path.write_text(text.strip())
        assert "sensors" in _audit(path)
    # written: the same cases as files named after suite and property
    written = sorted(p.name for p in cases.glob("*.json"))
    assert written == ["TestForgetfulDmf-cmf.json", "TestIndependenceAssumed-conservative.json"]
    cmf_case = _audit(cases / "TestForgetfulDmf-cmf.json")
    assert cmf_case["condition_holds"]  # drawn with full column rank, as the property requires
    # the non-conservative rule's failure names the correlation that breaks it
    assert any("joint error covariance J" in line for line in result.outlines)


def test_loading_the_plugin_imports_nothing_heavy():
    run = subprocess.run([sys.executable, "-X", "importtime", "-c", "import gpfverify.pytest_plugin"],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    lines = [line for line in run.stderr.splitlines()[1:] if line.startswith("import time:")]
    modules = {line.rsplit("|", 1)[1].strip() for line in lines}
    assert "gpfverify.pytest_plugin" in modules
    assert not {m.split(".")[0] for m in modules} & {"numpy", "hypothesis", "scipy"}
    assert not {m for m in modules if m.startswith("gpfverify.") and m != "gpfverify.pytest_plugin"}


def test_a_test_that_names_no_fixture_of_the_plugin_gets_none(pytester):
    pytester.makepyfile(test_plain='''
def test_plain(request):
    assert request.fixturenames == ["request"]
''')
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", "-q", "--trace-config")
    result.assert_outcomes(passed=1)
    assert any("gpfverify.pytest_plugin" in line for line in result.outlines)  # it was loaded


@pytest.mark.parametrize("target", ["loop", "a-file"])
def test_a_cases_folder_that_cannot_be_one_is_a_usage_error_not_an_internal_one(pytester, target):
    """``--gpfverify-cases`` naming a loop of symbolic links (Path.resolve raised RuntimeError in
    pytest_configure: INTERNALERROR) or a file: pytest's usage error, exit status 4, one line."""
    pytester.makepyfile(test_plain="def test_plain():\n    pass\n")
    if target == "loop":
        (pytester.path / "loop-a").symlink_to("loop-b")
        (pytester.path / "loop-b").symlink_to("loop-a")
        name, said = "loop-a", "cannot be resolved"
    else:
        (pytester.path / "a-file").write_text("not a folder")
        name, said = "a-file", "exists and is not a folder"
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", "-q", "--gpfverify-cases", name)
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    assert "INTERNALERROR" not in result.stderr.str() and "Traceback" not in result.stderr.str()
    assert any(line.startswith(f"ERROR: --gpfverify-cases {name}: {said}") for line in result.stderr.lines), \
        result.stderr.str()
