"""Test-suite configuration shared by tests/, property_tests/ and proofs/.

Hypothesis profiles ``ci`` (derandomised, no deadline, moderate example counts — used by
``make test``), ``dev`` (random, fewer examples) and ``thorough`` (many examples, for users) are
defined in :mod:`gpfverify.strategies.profiles` (so ``gpfverify props`` uses the same ones).
Select with ``--hypothesis-profile NAME`` or the HYPOTHESIS_PROFILE environment variable.
"""

from gpfverify.runtime import default_single_blas_thread

default_single_blas_thread()  # before numpy loads its BLAS (see gpfverify.runtime)

from gpfverify.strategies.profiles import load_profile  # noqa: E402

load_profile()


import gc  # noqa: E402

import pytest  # noqa: E402

from gpfverify.gp import fused  # noqa: E402

#: the moment-matching paths a test can ask for: the fused kernel (when numba is installed) and
#: the numpy reference
MOMENT_PATHS = ("fused", "numpy") if fused.AVAILABLE else ("numpy",)


@pytest.fixture(scope="module", params=MOMENT_PATHS)
def moment_path(request):
    """Run a module's tests once per moment-matching path (module scope, so that hypothesis tests
    may use it): ``pytestmark = pytest.mark.usefixtures("moment_path")``."""
    saved = fused.enabled
    fused.enabled = request.param == "fused"
    yield request.param
    fused.enabled = saved


#: the tests deselected in this session (``-m "not slow"``, ``-k``), for tests/test_readme_counts.py
DESELECTED: pytest.StashKey[list] = pytest.StashKey()


def pytest_deselected(items):
    if items:
        items[0].config.stash.setdefault(DESELECTED, []).extend(items)


@pytest.fixture
def deselected_tests(request) -> list:
    """The tests this session deselected (``-m``, ``-k``)."""
    return request.config.stash.get(DESELECTED, [])


def pytest_sessionfinish(session):
    """In a pytest-xdist worker, collect the session's garbage and freeze what is left before the worker
    reports that it has finished. pytest's last full collection (when it unconfigures, to report
    unraisable exceptions) then has nothing to walk; before, on a busy machine, that collection of a
    long session's heap outlasted the 5 s execnet waits for a worker to stop before it sends it a SIGINT,
    and the KeyboardInterrupt landed in a weakref callback: a stray traceback after every test passed."""
    if hasattr(session.config, "workerinput"):
        gc.collect()
        gc.freeze()
