"""DMF ≡ CMF for every measurement iff G_m C_y^m (I − P_m) = 0 for every sensor, for any dimension
and any number of sensors (both directions checked by the kernel; ⇒ instantiates "for every
measurement" at the basis directions that break it). Two weaker statements are refuted by exact
counterexamples the kernel evaluates: that full column rank is necessary, and that DMF is exact
without any condition.

Run: ``python proofs/prove_dmf_exact_iff_kernel_inclusion.py [small|large]`` (prints the
three certificates). Collected by pytest (small size)."""

import sys

from gpfverify.symbolic.claims import emit, run_claim

CLAIM = "dmf-exact-iff-kernel-inclusion"
REFUTED = ("full-column-rank-necessary", "dmf-exact-without-condition")


def test_kernel_inclusion_is_proved_at_small_size():
    certificate = run_claim(CLAIM, "small")
    assert certificate.status == "proved", certificate.detail


def test_full_rank_is_not_necessary():
    certificate = run_claim("full-column-rank-necessary", "small")
    assert certificate.status == "refuted", certificate.detail


def test_dmf_is_not_exact_without_the_condition():
    certificate = run_claim("dmf-exact-without-condition", "small")
    assert certificate.status == "refuted", certificate.detail


if __name__ == "__main__":
    for claim in (CLAIM, *REFUTED):
        emit(claim, sys.argv[1:])
