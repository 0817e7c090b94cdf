"""Registry of the claims: claim id -> function(size) -> Certificate.

``size`` sets only the listed sizes of the checks by another route: ``small`` in the test suite
(seconds), ``large`` in ``gpfverify prove --size large``. The kernel's proofs are the same at both.
The casadi cross-checks are added by :mod:`gpfverify.symbolic.crosscheck`.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from functools import cache

from gpfverify.errors import InputError
from gpfverify.symbolic.certificate import SIZES, Certificate

#: claim id -> "module:function"; order is the order of the certificates.
CLAIMS: dict[str, str] = {
    "prop1-full-column-rank": "gpfverify.symbolic.fusion_claims:prove_prop1",
    "dmf-gap-formula": "gpfverify.symbolic.fusion_claims:prove_gap_formula",
    "dmf-exact-iff-kernel-inclusion": "gpfverify.symbolic.fusion_claims:prove_kernel_inclusion",
    "full-column-rank-necessary": "gpfverify.symbolic.fusion_claims:refute_full_rank_necessary",
    "dmf-exact-without-condition": "gpfverify.symbolic.fusion_claims:refute_exact_without_condition",
    "full-rank-needs-l-le-D": "gpfverify.symbolic.fusion_claims:prove_full_rank_needs_l_le_d",
    "gp-moment-integrals": "gpfverify.symbolic.gp_claims:prove_gp_moment_integrals",
    "ukf-equals-kf-linear": "gpfverify.symbolic.ukf_claims:prove_ukf_equals_kf",
}


def claim_function(claim: str) -> Callable[[str], Certificate]:
    if claim not in CLAIMS:
        raise InputError(f"unknown claim {claim!r}; choose from {list(CLAIMS)}")
    module, name = CLAIMS[claim].split(":")
    return getattr(importlib.import_module(module), name)


def run_claim(claim: str, size: str = "small") -> Certificate:
    """Run one claim's proof (or check) at ``size`` and return its certificate (computed once per
    process and keyed by the claim's name and size: the search is deterministic)."""
    if size not in SIZES:
        raise InputError(f"size must be one of {SIZES}, got {size!r}")
    claim_function(claim)  # an unknown claim is an InputError, not a cached failure
    return _run(claim, size)


@cache
def _run(claim: str, size: str) -> Certificate:
    certificate = claim_function(claim)(size)
    if certificate.claim != claim:  # a registry entry pointing at the wrong function
        raise InputError(f"claim {claim!r} produced a certificate for {certificate.claim!r}")
    return certificate


def run_claims(size: str = "small", only: list[str] | None = None, progress=None) -> list[Certificate]:
    """Certificates of every registered claim (or of ``only``), in registry order."""
    names = list(CLAIMS) if not only else only
    certificates = []
    for name in names:
        if progress:
            progress(f"[prove] {name} ({size}) ...")
        certificates.append(run_claim(name, size))
    return certificates


def emit(claim: str, argv: list[str]) -> int:
    """Script entry point of ``proofs/prove_*.py``: run ``claim`` at the size given as the first
    argument (default large) and print its certificate as JSON (the status is in the JSON)."""
    import json

    size = argv[0] if argv else "large"
    certificate = run_claim(claim, size)
    print(json.dumps(certificate.to_json(), indent=2, ensure_ascii=False))
    return 0
