"""Keep the counterexample of a failing fusion property as a case file ``gpfverify audit`` reads.

Wrap the body of a property in :func:`saving_case_on_failure`::

    @given(drawn=fusion_cases())
    def test_my_rule(drawn):
        with saving_case_on_failure(drawn.case, "my-rule"):
            ...assertions...

When the body raises on hypothesis's *final* replay (the shrunk counterexample), the case is
written as ``<dir>/<name>.json`` in the CONTRACT.md format and its path is attached to the
failure report with :func:`hypothesis.note`. The directory is the ``GPFVERIFY_COUNTEREXAMPLES``
environment variable (``gpfverify props --out DIR`` sets it to ``DIR/counterexamples``); when it
is unset nothing is written, only noted. Outside a hypothesis test (e.g. replaying a saved
regression case) the case is written on every failure.
"""

from __future__ import annotations

import json
import os
from contextlib import contextmanager
from pathlib import Path

from hypothesis import note
from hypothesis.control import current_build_context

from gpfverify.fusion.case import FusionCase, case_to_dict

#: the folder counterexamples are written to; set by ``pytest --gpfverify-cases DIR``
#: (:mod:`gpfverify.pytest_plugin`) and by ``gpfverify props --out DIR``
ENVIRONMENT_VARIABLE = "GPFVERIFY_COUNTEREXAMPLES"
#: what precedes a counterexample case's JSON in a failure report (``show=True``)
CASE_PREFIX = "gpfverify fusion case:"


def counterexample_dir() -> Path | None:
    value = os.environ.get(ENVIRONMENT_VARIABLE)
    return Path(value) if value else None


def _final_or_outside_hypothesis() -> bool:
    try:
        return current_build_context().is_final
    except Exception:  # no build context: not inside a hypothesis test
        return True


def write_case(case: FusionCase, name: str, directory: Path) -> Path:
    """Write ``case`` as ``directory/name.json`` (CONTRACT.md format); returns the path."""
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{name}.json"
    path.write_text(json.dumps(case_to_dict(case)) + "\n")
    return path


@contextmanager
def saving_case_on_failure(case: FusionCase, name: str, show: bool = False):
    """Save ``case`` as a counterexample file when the wrapped block raises (see module docstring);
    with ``show``, also note the case itself, one line of JSON after ``gpfverify fusion case:``, in
    the failure report (so that it reaches the user when no directory is set)."""
    try:
        yield
    except BaseException:
        if _final_or_outside_hypothesis():
            if show:
                try:
                    note(f"{CASE_PREFIX} {json.dumps(case_to_dict(case))}")
                except Exception:  # outside a hypothesis test there is nothing to note to
                    pass
            directory = counterexample_dir()
            if directory is not None:
                path = write_case(case, name, directory)
                try:
                    note(f"counterexample case file: {path}")
                except Exception:  # outside a hypothesis test there is nothing to note to
                    pass
        raise
