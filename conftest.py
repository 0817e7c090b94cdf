"""Test-suite configuration shared by tests/, property_tests/ and proofs/.

Hypothesis profiles ``ci`` (derandomised, no deadline, moderate example counts — used by
``make test``), ``dev`` (random, fewer examples) and ``thorough`` (many examples, for users) are
defined in :mod:`gpfverify.strategies.profiles` (so ``gpfverify props`` uses the same ones).
Select with ``--hypothesis-profile NAME`` or the HYPOTHESIS_PROFILE environment variable.
"""

from gpfverify.strategies.profiles import load_profile

load_profile()
