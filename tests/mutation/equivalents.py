"""Sampled mutants classed equivalent: no input can tell them from the package as written.

Each entry is keyed by the module, the line as written and the line as mutated (so that it follows
the line when others move), and carries one line that a reader can check against the code. A
mutant is never classed equivalent to reach a goal: one that an input *could* tell apart, however
unlikely, is a survivor to answer with a test.
"""

from __future__ import annotations

from tests.mutation.draw import Drawn

#: (path, line as written, line as mutated) -> why no input tells the mutant from the original
EQUIVALENT: dict[tuple[str, str, str], str] = {}


def reason_for(mutant: Drawn) -> str | None:
    return EQUIVALENT.get((mutant.path, mutant.before, mutant.after))
