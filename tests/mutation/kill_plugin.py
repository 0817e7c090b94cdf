"""pytest plugin used inside a mutated copy: records every failing test and whether it is a
hypothesis property (``@given``), as JSON lines in $MUTATION_REPORT."""

import json
import os


def _is_property(item) -> bool:
    func = getattr(item, "obj", None)
    return bool(getattr(func, "is_hypothesis_test", False) or getattr(func, "hypothesis", None))


def pytest_runtest_makereport(item, call):
    if call.excinfo is None or call.when != "call":
        return
    path = os.environ.get("MUTATION_REPORT")
    if path:
        with open(path, "a", encoding="utf-8") as out:
            out.write(json.dumps({"test": item.nodeid, "property": _is_property(item)}) + "\n")


def pytest_sessionstart(session):
    import gpfverify

    path = os.environ.get("MUTATION_REPORT")
    if path:
        with open(path, "a", encoding="utf-8") as out:
            out.write(json.dumps({"package": os.path.dirname(gpfverify.__file__)}) + "\n")
