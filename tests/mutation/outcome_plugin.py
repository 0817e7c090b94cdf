"""pytest plugin of the sampled mutation run: records, as JSON lines in $MUTATION_REPORT, which
package was imported (it must be the workspace's copy) and every test that failed in any phase
(a fixture's error is a failure as much as an assertion's).

It also makes ``CosmicRayTestingException`` a builtin: cosmic-ray's ExceptionReplacer writes
``except CosmicRayTestingException:`` in place of a handler's exception, meaning "a handler that no
longer catches"; without the name a raised exception would turn into a NameError instead.
"""

import builtins
import json
import os


def _write(record: dict) -> None:
    path = os.environ.get("MUTATION_REPORT")
    if path:
        with open(path, "a", encoding="utf-8") as out:
            out.write(json.dumps(record) + "\n")


def pytest_configure(config):
    from cosmic_ray.exceptions import CosmicRayTestingException

    builtins.CosmicRayTestingException = CosmicRayTestingException  # type: ignore[attr-defined]


def pytest_sessionstart(session):
    import gpfverify

    _write({"package": os.path.dirname(gpfverify.__file__)})


def pytest_runtest_logreport(report):
    if report.failed:
        _write({"test": report.nodeid, "when": report.when})


def pytest_collectreport(report):
    if report.failed:
        _write({"test": report.nodeid, "when": "collect"})
