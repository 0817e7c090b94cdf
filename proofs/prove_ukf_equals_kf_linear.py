"""The unscented transform is exact for affine maps, so the UKF equals the KF on linear models, for
any D and l and every choice of sigma-point parameters (checked by the kernel); also checked with
sympy at listed (D, l).

Run: ``python proofs/prove_ukf_equals_kf_linear.py [small|large]``. Collected by pytest."""

import sys

from gpfverify.symbolic.claims import emit, run_claim

CLAIM = "ukf-equals-kf-linear"


def test_ukf_equals_kf_in_any_dimension():
    certificate = run_claim(CLAIM, "small")
    assert certificate.status == "proved", certificate.detail


if __name__ == "__main__":
    sys.exit(emit(CLAIM, sys.argv[1:]))
