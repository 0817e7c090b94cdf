"""Test-suite configuration shared by tests/, property_tests/ and proofs/.

Hypothesis profiles: ``ci`` (derandomised, no deadline, moderate example counts — used by
``make test``), ``dev`` (random, fewer examples) and ``thorough`` (many examples, for users).
Select with ``--hypothesis-profile NAME`` or the HYPOTHESIS_PROFILE environment variable.
"""

import os

from hypothesis import HealthCheck, settings

settings.register_profile("ci", derandomize=True, deadline=None, max_examples=60,
                          print_blob=True, suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("dev", deadline=None, max_examples=25)
settings.register_profile("thorough", deadline=None, max_examples=1000,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "dev"))
