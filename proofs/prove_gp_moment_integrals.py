"""The uncertain-input kernel integrals of GP moment matching (seed 000 eq. 8–11, 20) with a full
input covariance, by exact iterated integration against the Gaussian for D = 1, 2 (and 3 in the
large size), with the matrix identities behind the closed forms proved for a symbolic D.

Run: ``python proofs/prove_gp_moment_integrals.py [small|large]``. Collected by pytest."""

import sys

from gpfverify.symbolic.claims import emit, run_claim

CLAIM = "gp-moment-integrals"


def test_moment_integrals_are_proved_at_small_size():
    certificate = run_claim(CLAIM, "small")
    assert certificate.status == "proved", certificate.detail


if __name__ == "__main__":
    sys.exit(emit(CLAIM, sys.argv[1:]))
