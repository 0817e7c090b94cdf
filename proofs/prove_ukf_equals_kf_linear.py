"""At the listed sizes, the unscented transform is exact for affine maps (symbolic sigma points),
so UKF = KF on linear models.

Run: ``python proofs/prove_ukf_equals_kf_linear.py [small|large]``. Collected by pytest."""

import sys

from gpfverify.symbolic.claims import emit, run_claim

CLAIM = "ukf-equals-kf-linear"


def test_unscented_transform_is_exact_for_affine_maps():
    certificate = run_claim(CLAIM, "small")
    assert certificate.status == "proved", certificate.detail


if __name__ == "__main__":
    sys.exit(emit(CLAIM, sys.argv[1:]))
