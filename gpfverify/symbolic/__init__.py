"""Symbolic forms of the filter and fusion equations: sympy proofs of the fusion claims
(:mod:`~gpfverify.symbolic.claims`) and casadi graphs of the same equations as a second,
independent implementation (:mod:`~gpfverify.symbolic.casadi_forms`)."""

from gpfverify.symbolic.certificate import Certificate
from gpfverify.symbolic.claims import CLAIMS, run_claim, run_claims

__all__ = ["CLAIMS", "Certificate", "run_claim", "run_claims"]
