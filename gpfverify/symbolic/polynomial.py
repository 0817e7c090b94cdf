"""Exact matrix algebra over the polynomial ring Q[entries] for symbolic identity checks.

A matrix identity between rational functions of generic matrix entries is proved by clearing
denominators: every inverse is written as adj(M)/det(M) (:func:`inverse`), so each expression
is a :class:`Fraction` — a polynomial matrix over a nonzero polynomial — and an identity holds
for all admissible entries iff the numerator of the difference is the zero polynomial. This
avoids symbolic inverses of 3×3 matrices (which make ``sympy.simplify`` blow up) while staying
exact: the arithmetic is sympy's sparse ``DomainMatrix`` over ``QQ[x_1, …, x_k]``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import sympy as sp
from sympy import QQ
from sympy.polys.matrices import DomainMatrix


def generic_matrix(name: str, rows: int, cols: int) -> sp.Matrix:
    """A rows×cols matrix of independent symbols ``name_i_j``."""
    return sp.Matrix(rows, cols, lambda i, j: sp.Symbol(f"{name}_{i}_{j}"))


def generic_symmetric(name: str, n: int) -> sp.Matrix:
    """An n×n symmetric matrix of independent symbols ``name_i_j`` (i ≤ j)."""
    return sp.Matrix(n, n, lambda i, j: sp.Symbol(f"{name}_{min(i, j)}_{max(i, j)}"))


def polynomial_ring(*matrices: sp.Matrix):
    """The ring Q[every free symbol of ``matrices``] (symbols sorted by name)."""
    symbols = sorted(set().union(*(m.free_symbols for m in matrices)), key=str)
    return QQ[tuple(symbols)] if symbols else QQ


def lift(matrix: sp.Matrix, ring) -> DomainMatrix:
    """``matrix`` as a DomainMatrix over ``ring``."""
    rows, cols = matrix.shape
    return DomainMatrix([[ring.from_sympy(matrix[i, j]) for j in range(cols)] for i in range(rows)],
                        (rows, cols), ring)


@dataclass(frozen=True)
class Fraction:
    """The rational matrix ``num / den``: ``num`` a polynomial DomainMatrix, ``den`` a nonzero
    ring element. Products and sums are formed exactly, with no cancellation."""

    num: DomainMatrix
    den: Any  # an element of num.domain (sympy ships no type information)

    @classmethod
    def of(cls, matrix: DomainMatrix) -> Fraction:
        return cls(matrix, matrix.domain.one)

    @property
    def shape(self) -> tuple[int, int]:
        return self.num.shape

    def __matmul__(self, other: Fraction) -> Fraction:
        return Fraction(self.num * other.num, self.den * other.den)

    def __add__(self, other: Fraction) -> Fraction:
        if self.den == other.den:
            return Fraction(self.num + other.num, self.den)
        return Fraction(self.num.mul(other.den) + other.num.mul(self.den), self.den * other.den)

    def __neg__(self) -> Fraction:
        return Fraction(-self.num, self.den)

    def __sub__(self, other: Fraction) -> Fraction:
        return self + (-other)

    @property
    def T(self) -> Fraction:
        return Fraction(self.num.transpose(), self.den)

    def is_zero(self) -> bool:
        """True iff the rational matrix is identically zero (numerator is the zero polynomial)."""
        return self.num.is_zero_matrix

    def term_count(self) -> int:
        """Number of monomials in the numerator: a measure of the size of the check."""
        return sum(len(e) for row in self.num.to_list() for e in row)

    def evaluate(self, values: dict) -> sp.Matrix:
        """The matrix at a point (``values`` maps symbols to numbers); the denominator must not
        vanish there."""
        den = sp.sympify(self.num.domain.to_sympy(self.den)).subs(values)
        if den == 0:
            raise ZeroDivisionError("denominator vanishes at the evaluation point")
        return self.num.to_Matrix().subs(values) / den


def identity(n: int, ring) -> Fraction:
    return Fraction.of(DomainMatrix.eye(n, ring))


def inverse(matrix: Fraction) -> Fraction:
    """M⁻¹ = den · adj(num) / det(num) for a square Fraction M = num/den with det(num) ≢ 0."""
    adj, det = matrix.num.adj_det()
    if not det:
        raise ZeroDivisionError("matrix is singular for every value of its entries")
    return Fraction(adj.mul(matrix.den), det)


def full_column_rank_pinv(a: Fraction) -> Fraction:
    """A⁺ = (AᵀA)⁻¹Aᵀ, the Moore–Penrose inverse of a full-column-rank A (det AᵀA ≠ 0)."""
    return inverse(a.T @ a) @ a.T


def factored_pinv(b: Fraction, f: Fraction) -> Fraction:
    """Moore–Penrose inverse of A = B Fᵀ with B (D×r) and F (l×r) of full column rank r:
    A⁺ = F (FᵀF)⁻¹ (BᵀB)⁻¹ Bᵀ (a full-rank factorisation; checked by :func:`penrose_residuals`)."""
    return f @ inverse(f.T @ f) @ inverse(b.T @ b) @ b.T


def penrose_residuals(a: Fraction, a_pinv: Fraction) -> dict[str, Fraction]:
    """The four Penrose conditions as differences that vanish iff ``a_pinv`` is A⁺:
    AXA − A, XAX − X, (AX)ᵀ − AX, (XA)ᵀ − XA."""
    ax, xa = a @ a_pinv, a_pinv @ a
    return {"AXA = A": ax @ a - a, "XAX = X": xa @ a_pinv - a_pinv,
            "(AX)' = AX": ax.T - ax, "(XA)' = XA": xa.T - xa}
