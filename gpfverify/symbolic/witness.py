"""Exact instances for the kernel to check: witnesses (every hypothesis holds) and counterexamples.

Untrusted: the kernel evaluates every instance itself (:mod:`gpfverify.kernel.instances`).
Values are small random integers from a seeded generator; a letter can be drawn symmetric
positive definite (MMᵀ + I), of full column rank, of a given rank, or given outright.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import sympy as sp

from gpfverify.kernel.instances import Instance, refutes
from gpfverify.kernel.terms import frozen, read_statement, show_number

ENTRY = 3


def _rows(m: sp.Matrix) -> list:
    return [[show_number(Fraction(int(sp.fraction(x)[0]), int(sp.fraction(x)[1]))) for x in m.row(i)]
            for i in range(m.rows)]


def _integers(rng, rows: int, cols: int) -> sp.Matrix:
    return sp.Matrix(rows, cols, lambda i, j: int(rng.integers(-ENTRY, ENTRY + 1)))


def draw(rng, rows: int, cols: int, kind: str = "general") -> sp.Matrix:
    """A random integer matrix: "general", "spd", "fcr" (full column rank) or "rank-k"."""
    if kind == "spd":
        m = _integers(rng, rows, rows)
        return m * m.T + sp.eye(rows)
    if kind == "fcr":
        while True:
            m = _integers(rng, rows, cols)
            if m.rank() == cols:
                return m
    if kind.startswith("rank-"):
        rank = int(kind[5:])
        while True:
            m = _integers(rng, rows, rank) * _integers(rng, cols, rank).T
            if m.rank() == rank:
                return m
    return _integers(rng, rows, cols)


class Builder:
    """An instance under construction: sizes first, then values (name -> Matrix, or list per member)."""

    def __init__(self, seed: int, sizes: dict, indexed_sizes: dict | None = None, params: dict | None = None,
                 free_indices: dict | None = None):
        self.rng = np.random.default_rng(seed)
        self.sizes, self.indexed = dict(sizes), dict(indexed_sizes or {})
        self.params, self.free = dict(params or {}), dict(free_indices or {})
        self.values: dict = {}

    def set(self, name: str, value) -> None:
        self.values[name] = value

    def draw(self, name: str, rows: int, cols: int, kind: str = "general") -> sp.Matrix:
        self.values[name] = draw(self.rng, rows, cols, kind)
        return self.values[name]

    def draw_family(self, name: str, shapes: list, kind: str = "general") -> list:
        self.values[name] = [draw(self.rng, r, c, kind) for r, c in shapes]
        return self.values[name]

    def json(self) -> dict:
        def matrix(v):
            return [matrix(x) for x in v] if isinstance(v, list) else _rows(v)

        return {"sizes": self.sizes, "indexed_sizes": self.indexed,
                "params": {k: show_number(Fraction(v)) for k, v in self.params.items()},
                "free_indices": self.free, "values": {k: matrix(v) for k, v in self.values.items()}}


def refuting(statement: dict, make, seeds=range(20)) -> dict:
    """The first of make(seed) that the kernel finds refutes ``statement`` (random small integers
    can make a generic difference vanish by chance), else the last one tried."""
    st = read_statement(frozen(statement))
    for seed in seeds:
        candidate = make(seed)
        if not refutes(st, Instance(st, frozen(candidate))):
            return candidate
    return candidate
