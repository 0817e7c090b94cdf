"""The proof kernel: the only code that decides "proved" and "refuted".

It reads a formal statement and a certificate (plain JSON), re-checks every step by the rules of
:mod:`~gpfverify.kernel.rules`, evaluates witnesses and counterexamples exactly
(:mod:`~gpfverify.kernel.instances`), and derives every word of a certificate record from its
formal content (:mod:`~gpfverify.kernel.verdict`, :mod:`~gpfverify.kernel.render`). It imports
nothing of gpfverify but :mod:`gpfverify.errors`; everything that finds proofs
(:mod:`gpfverify.symbolic`) only proposes them. docs/proofs.md states the rules and the trust base.
"""

from gpfverify.kernel.rules import check_proof
from gpfverify.kernel.terms import KernelError, read_statement
from gpfverify.kernel.verdict import check_record, derive, judge

__all__ = ["KernelError", "check_proof", "check_record", "derive", "judge", "read_statement"]
