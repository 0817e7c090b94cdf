"""Sampled mutants classed equivalent: no input can tell them from the package as written.

Each entry is keyed by the module, the line as written and the line as mutated (so that it follows
the line when others move), and carries one line that a reader can check against the code. A
mutant is never classed equivalent to reach a goal: one that an input *could* tell apart, however
unlikely, is a survivor to answer with a test.
"""

from __future__ import annotations

from tests.mutation.draw import Drawn

#: (path, line as written, line as mutated) -> why no input tells the mutant from the original
EQUIVALENT: dict[tuple[str, str, str], str] = {
    ("gpfverify/audit/run.py", "SPOOL_BYTES = 32 << 20", "SPOOL_BYTES = 33 << 20"):
        "only max_size of the SpooledTemporaryFile in run.py's output file: where its bytes wait (memory or "
        "disk), not which bytes are read back",
    ("gpfverify/commands/audit.py", "if exact == total:", "if exact >= total:"):
        "verdict_line reads the run audit's summary, whose exact_steps counts a subset of its steps: "
        "exact ≥ total only when they are equal",
    ("gpfverify/runtime.py", "_controller_modules = -1", "_controller_modules = not 1"):
        "the first call finds _controller None and makes the controller whatever the count; afterwards the "
        "count is len(sys.modules) as set there",
}


def reason_for(mutant: Drawn) -> str | None:
    return EQUIVALENT.get((mutant.path, mutant.before, mutant.after))
