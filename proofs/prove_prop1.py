"""Proposition 1 (seed 000): DMF ≡ CMF when every C_xy^m has full column rank, for any dimension
and any number N of sensors (checked by the kernel).

Run: ``python proofs/prove_prop1.py [small|large]`` prints the certificate. Collected by pytest
(small size)."""

import sys

from gpfverify.symbolic.claims import emit, run_claim

CLAIM = "prop1-full-column-rank"


def test_prop1_is_proved_at_small_size():
    certificate = run_claim(CLAIM, "small")
    assert certificate.status == "proved", certificate.detail


if __name__ == "__main__":
    sys.exit(emit(CLAIM, sys.argv[1:]))
