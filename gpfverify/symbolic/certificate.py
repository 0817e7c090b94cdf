"""The records ``gpfverify prove`` writes to ``certificates.json`` (see CONTRACT.md and docs/proofs.md).

A :class:`Certificate` holds formal content only — statements, proofs, witnesses,
counterexamples, mutated statements, checks at listed sizes — and a title shown apart. Its
status, statement text, hypotheses, scope, method and detail are derived from that content by
the kernel (:func:`gpfverify.kernel.verdict.derive`): nobody writes them, and ``gpfverify prove
--check`` derives them again from the file. A :class:`NumericalCheck` (two implementations
agreeing to rounding) is always "checked".
"""

from __future__ import annotations

from dataclasses import dataclass, field

from gpfverify.kernel.terms import thawed
from gpfverify.kernel.verdict import control_outcomes, derive

STATUSES = ("proved", "refuted", "checked")
SIZES = ("small", "large")


@dataclass(frozen=True)
class Part:
    """One formal statement with its proof and witness, or with a counterexample."""

    statement: dict
    proof: dict | None = None
    witness: dict | None = None
    refutation: dict | None = None

    def json(self) -> dict:
        out = {"statement": thawed(self.statement)}
        for name in ("proof", "witness", "refutation"):
            if getattr(self, name) is not None:
                out[name] = thawed(getattr(self, name))
        return out


@dataclass(frozen=True)
class Control:
    """A mutated statement: the search's attempt at proving it, and an instance that refutes it."""

    mutant: str
    statement: dict
    proof: dict | None
    instance: dict

    def json(self) -> dict:
        return {"mutant": self.mutant, "statement": thawed(self.statement),
                "proof": thawed(self.proof) if self.proof is not None else None, "instance": thawed(self.instance)}


@dataclass(frozen=True)
class ListedCheck:
    """An identity verified by another route at listed sizes (exact, not a proof); ``domain`` the
    conditions under which both sides are defined (every denominator nonzero)."""

    what: str
    sizes: tuple
    domain: tuple
    holds: bool

    def json(self) -> dict:
        return {"what": self.what, "sizes": list(self.sizes), "domain": list(self.domain), "holds": self.holds}


class Certificate:
    """A claim's record: formal content in, every word derived by the kernel. ``expected`` is the
    status its author means it to get, for a statement made to be refuted (a false variant of a
    theorem whose refutation is the result: "full column rank is necessary" is not): the page says
    so, and a certificate that does not get it fails (:attr:`failures`, ``prove --check``)."""

    def __init__(self, claim: str, title: str, parts=(), controls=(), checks=(), seconds: float = 0.0,
                 expected: str | None = None):
        core: dict = {"claim": claim, "title": title, "formal": [p.json() for p in parts]}
        if expected is not None:
            core["expected"] = expected
        if not parts:
            del core["formal"]
        if checks:
            core["checks"] = [c.json() for c in checks]
        if controls:
            core["negative_controls"] = [c.json() for c in controls]
            for entry, (_, rejected, false) in zip(core["negative_controls"], control_outcomes(core)):
                entry["rejected"], entry["false_on_instance"] = rejected, false
        self.record = {**core, **derive(core), "seconds": seconds}

    def __getattr__(self, name):
        if name in ("claim", "title", "status", "statement", "scope", "method", "detail", "hypotheses", "seconds"):
            return self.record.get(name)
        raise AttributeError(name)

    @property
    def negative_controls(self) -> list:
        return self.record.get("negative_controls", [])

    @property
    def failures(self) -> list[str]:
        """What makes ``gpfverify prove`` exit non-zero: a control the kernel accepted or could not
        show false, a check at listed sizes that fails."""
        out = [f"negative control {c['mutant']!r} was {'accepted' if not c['rejected'] else 'not shown false'}"
               for c in self.negative_controls if not (c["rejected"] and c["false_on_instance"])]
        out += [f"the check '{c['what']}' fails" for c in self.record.get("checks", ()) if not c["holds"]]
        if self.record.get("expected", self.status) != self.status:
            out.append(f"meant to be {self.record['expected']}, the kernel derives {self.status}")
        return out

    def to_json(self) -> dict:
        return dict(self.record)


@dataclass(frozen=True)
class NumericalCheck:
    """Two implementations agreeing within a stated tolerance: status "checked", never a proof."""

    claim: str
    statement: str
    method: str
    holds: bool
    detail: str
    seconds: float = 0.0
    scope: str = field(default="the random inputs listed in the detail")

    status = "checked"
    negative_controls: tuple = ()

    @property
    def failures(self) -> list[str]:
        return [] if self.holds else [f"{self.claim}: the two implementations disagree"]

    def to_json(self) -> dict:
        return {"claim": self.claim, "statement": self.statement, "method": self.method, "status": self.status,
                "holds": self.holds, "scope": self.scope,
                "detail": ("" if self.holds else "FAILED: ") + self.detail, "seconds": self.seconds}
