"""Proof search and checks around the kernel (:mod:`gpfverify.kernel`): the claims as formal
statements (:mod:`~gpfverify.symbolic.formal`), the search that writes their certificates
(:mod:`~gpfverify.symbolic.search`), identities at listed sizes by another route, and casadi graphs
of the same equations as a second implementation (:mod:`~gpfverify.symbolic.casadi_forms`).
Nothing here is trusted: a claim is proved only when the kernel accepts its certificate."""

from gpfverify.symbolic.certificate import Certificate, NumericalCheck
from gpfverify.symbolic.claims import CLAIMS, run_claim, run_claims

__all__ = ["CLAIMS", "Certificate", "NumericalCheck", "run_claim", "run_claims"]
