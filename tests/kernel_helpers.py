"""Small statements, proofs and instances for the kernel's tests (tests/test_kernel.py and
tests/test_false_claims.py). Every verdict here is the kernel's (:mod:`gpfverify.kernel`)."""

from __future__ import annotations

import json

import sympy as sp

from gpfverify.kernel.instances import Instance, refutes
from gpfverify.kernel.terms import KernelError, frozen, read_statement, thawed
from gpfverify.kernel.verdict import check_record, judge
from gpfverify.symbolic.witness import Builder


def outcome(statement: dict, proof: dict | None, witness: dict | None) -> str:
    """The kernel's verdict on a proof of ``statement`` ("proved", "vacuous" or "not proved")."""
    return judge({"statement": statement, "proof": proof or {"steps": []}, "witness": witness or {}}).outcome


def is_refuted(statement: dict, instance: dict) -> bool:
    """The kernel evaluates ``instance``: every hypothesis holds and a conclusion fails."""
    try:
        st = read_statement(frozen(statement))
        return refutes(st, Instance(st, frozen(instance))) == ""
    except KernelError:
        return False


def instance(sizes: dict, values: dict, **extra) -> dict:
    """An instance from sympy matrices (and lists of them for families)."""
    b = Builder(0, sizes, extra.get("indexed_sizes"), extra.get("params"), extra.get("free_indices"))
    for name, value in values.items():
        b.set(name, value)
    return b.json()


def matrix(rows) -> sp.Matrix:
    return sp.Matrix(rows)


def roundtrip(record: dict) -> dict:
    """A record as it is read back from certificates.json."""
    return json.loads(json.dumps(thawed(record), ensure_ascii=False))


def problems(record: dict) -> list[str]:
    return check_record(roundtrip(record))
