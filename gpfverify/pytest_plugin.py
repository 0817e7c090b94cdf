"""The ``gpfverify`` pytest plugin (entry point ``pytest11``): loaded by every pytest run once
gpfverify is installed, so it imports nothing but pytest and the standard library when it loads
and does nothing unless asked.

* ``--gpfverify-cases DIR``: write the shrunk counterexample of every failing gpfverify property
  (the suites of :mod:`gpfverify.testing`, and any property using
  :func:`gpfverify.strategies.saving_case_on_failure`) as a fusion case file in DIR, which
  ``gpfverify audit`` reads. Without it the case is printed in the failure report only. A DIR
  that cannot be resolved (a loop of symbolic links) or is not a folder is a usage error.
* Fixtures, each used only by a test that names it: ``gpfverify_strategies`` (the
  :mod:`gpfverify.strategies` module, for ``data.draw(...)`` inside a ``@given(st.data())`` test;
  session-scoped, so hypothesis accepts it) and ``gpfverify_cases`` (the folder given by
  ``--gpfverify-cases``, or None).

The property suites themselves are classes to subclass with your rule: ``from gpfverify.testing
import EstimateRuleSuite, CaseRuleSuite`` (docs/ecosystem.md). The plugin registers no hypothesis
profile (it would replace a project's own of the same name): a ``conftest.py`` that imports
:mod:`gpfverify.strategies.profiles` makes ``--hypothesis-profile ci|dev|thorough`` gpfverify's.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("gpfverify", "gpfverify property suites")
    group.addoption("--gpfverify-cases", metavar="DIR", default=None,
                    help="write the shrunk counterexample of each failing gpfverify property as a fusion case "
                         "file in DIR (gpfverify audit reads it)")


def _cases_folder(folder: str) -> Path:
    """``--gpfverify-cases DIR`` as an absolute path; a path that cannot be resolved (a loop of
    symbolic links) or names something other than a folder is a usage error, not an internal one."""
    try:
        path = Path(folder).resolve()
    except (OSError, RuntimeError) as exc:  # RuntimeError: Python < 3.13's "Symlink loop"
        raise pytest.UsageError(f"--gpfverify-cases {folder}: cannot be resolved ({exc})") from None
    if path.exists() and not path.is_dir():
        raise pytest.UsageError(f"--gpfverify-cases {folder}: exists and is not a folder")
    return path


def pytest_configure(config: pytest.Config) -> None:
    folder = config.getoption("gpfverify_cases", None)
    if folder:  # the folder reaches the properties (and worker processes) through the environment
        from gpfverify.strategies.counterexamples import ENVIRONMENT_VARIABLE

        os.environ[ENVIRONMENT_VARIABLE] = str(_cases_folder(folder))


@pytest.fixture(scope="session")
def gpfverify_strategies():
    """The :mod:`gpfverify.strategies` module (hypothesis strategies for correlated estimates,
    fusion cases, models)."""
    import gpfverify.strategies

    return gpfverify.strategies


@pytest.fixture(scope="session")
def gpfverify_cases(pytestconfig: pytest.Config) -> Path | None:
    """The folder failing gpfverify properties write their case files to (``--gpfverify-cases``)."""
    folder = pytestconfig.getoption("gpfverify_cases", None)
    return _cases_folder(folder) if folder else None
