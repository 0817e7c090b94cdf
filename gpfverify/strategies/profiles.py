"""Hypothesis settings profiles shared by the test suites and ``gpfverify props``.

* ``ci`` — derandomised (the same examples on every run), no deadline, 60 examples per property,
  the falsifying blob printed; what ``make test`` and ``gpfverify props --profile ci`` use.
* ``dev`` — random, no deadline, 25 examples: quick exploration while editing.
* ``thorough`` — random, no deadline, 1000 examples: for users hunting counterexamples (minutes).
* ``mutation`` — ``ci``'s examples without the explicit ``@example`` s and without shrinking: what
  ``tests/mutation`` runs on mutated copies (a kill must come from a generated example, and the
  first failure is enough).

Properties that are expensive per example scale their own count with :func:`scaled_examples`,
so every profile keeps its meaning (``thorough`` still tries many more than ``ci``).
Importing this module registers the profiles; :func:`load_profile` selects one (default: the
``HYPOTHESIS_PROFILE`` environment variable, else ``dev``).
"""

from __future__ import annotations

import os

from hypothesis import HealthCheck, Phase, settings

PROFILES: dict[str, dict] = {
    "ci": dict(derandomize=True, deadline=None, max_examples=60, print_blob=True,
               suppress_health_check=[HealthCheck.too_slow]),
    "dev": dict(deadline=None, max_examples=25),
    "thorough": dict(deadline=None, max_examples=1000, suppress_health_check=[HealthCheck.too_slow]),
    "mutation": dict(derandomize=True, deadline=None, max_examples=60, print_blob=False, database=None,
                     phases=(Phase.generate,), suppress_health_check=[HealthCheck.too_slow]),
}
DEFAULT_PROFILE = "dev"


def register_profiles() -> None:
    """Register every profile of :data:`PROFILES` with hypothesis (idempotent)."""
    for name, options in PROFILES.items():
        settings.register_profile(name, **options)


def load_profile(name: str | None = None) -> str:
    """Load profile ``name`` (default ``$HYPOTHESIS_PROFILE`` or ``dev``); returns the name."""
    chosen = name or os.environ.get("HYPOTHESIS_PROFILE", DEFAULT_PROFILE)
    settings.load_profile(chosen)
    return chosen


def scaled_examples(fraction: float, minimum: int = 5) -> int:
    """``fraction`` of the active profile's ``max_examples`` (at least ``minimum``): for a property
    whose examples are expensive, e.g. ``@settings(max_examples=scaled_examples(0.5))``."""
    active = settings.default
    assert active is not None  # hypothesis always has an active profile
    return max(minimum, int(round(fraction * active.max_examples)))


register_profiles()
