"""A sensor with more outputs than states (l_m > D) never has a full-column-rank C_xy^m: full
column rank gives D − l_m = tr((I − AA⁺)ᵀ(I − AA⁺)) ≥ 0 in every dimension.

Run: ``python proofs/prove_full_rank_needs_l_le_d.py [small|large]``. Collected by pytest."""

import sys

from gpfverify.symbolic.claims import emit, run_claim

CLAIM = "full-rank-needs-l-le-D"


def test_wide_cross_terms_are_rank_deficient():
    certificate = run_claim(CLAIM, "small")
    assert certificate.status == "proved", certificate.detail


if __name__ == "__main__":
    sys.exit(emit(CLAIM, sys.argv[1:]))
