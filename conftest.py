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
