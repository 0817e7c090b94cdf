"""The closed-form DMF − CMF gap, Σ_m G_m C_y^m (P_m − I)(C_y^m)⁻¹(y^m − μ_y^m), for
C_xy^m of any rank, for any dimension and any number of sensors (checked by the kernel).

Run: ``python proofs/prove_dmf_gap_formula.py [small|large]``. Collected by pytest (small size)."""

import sys

from gpfverify.symbolic.claims import emit, run_claim

CLAIM = "dmf-gap-formula"


def test_gap_formula_is_proved_at_small_size():
    certificate = run_claim(CLAIM, "small")
    assert certificate.status == "proved", certificate.detail


if __name__ == "__main__":
    sys.exit(emit(CLAIM, sys.argv[1:]))
