"""Health records: what was checked of each filter a claim compares, as data a page renders.

A :class:`HealthCheck` is one check of one filter configuration (its ``subject``): weight collapse
of a particle filter, divergence, or NEES consistency (made by :mod:`gpfverify.health`). A claim
record carries one :class:`FilterHealth` per filter it compares, with every check run of it: a
filter with no checks is "no checks run", never "none failed".

Two kinds of check, told apart by name and never by a caveat's words:

* **gates** (weight collapse, divergence): a filter that fails one does not work here, so a verdict
  comparing it is withheld ("not decidable", :meth:`FilterHealth.failed`);
* **consistency findings** (:data:`CONSISTENCY_CHECKS`, NEES against its χ² band): an optimistic or
  pessimistic covariance is a property of the filter's error bars, reported apart on every page and
  never a reason to withhold a verdict on its errors, nor called a failed health check.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from gpfverify.contract.serial import from_json

#: the checks whose outcome is a consistency finding, reported apart from the health gates
CONSISTENCY_CHECKS = frozenset({"NEES"})


@dataclass(frozen=True)
class HealthCheck:
    """One check of one filter configuration: ``passed`` when ``statistic`` is on the healthy side
    of ``threshold`` (the side depends on the check; ``detail`` says it in words)."""

    name: str
    subject: str
    passed: bool
    statistic: float
    threshold: float
    detail: str

    @property
    def is_gate(self) -> bool:
        """A failed gate withholds a verdict; a consistency finding never does."""
        return self.name not in CONSISTENCY_CHECKS


@dataclass(frozen=True)
class FilterHealth:
    """The checks run of one filter a claim compares (``subject``: as the checks name it)."""

    subject: str
    checks: tuple[HealthCheck, ...] = ()

    @property
    def gates(self) -> tuple[HealthCheck, ...]:
        return tuple(c for c in self.checks if c.is_gate)

    @property
    def consistency(self) -> tuple[HealthCheck, ...]:
        return tuple(c for c in self.checks if not c.is_gate)

    @property
    def failed(self) -> tuple[HealthCheck, ...]:
        """The gates this filter failed."""
        return tuple(c for c in self.gates if not c.passed)


def filter_health(subjects: Iterable[str], checks: Iterable[HealthCheck]) -> tuple[FilterHealth, ...]:
    """One :class:`FilterHealth` per subject (in the order given, each once) with its checks among
    ``checks`` (none: no checks run)."""
    checks = list(checks)
    return tuple(FilterHealth(s, tuple(c for c in checks if c.subject == s)) for s in dict.fromkeys(subjects))



def stored_checks(data: Any, path: str = "health") -> tuple[HealthCheck, ...]:
    """Health checks as ``results.json`` stores them (a list of :class:`HealthCheck` objects)."""
    return tuple(from_json(list[HealthCheck], data, path))
