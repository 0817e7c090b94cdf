"""The record a proof or cross-check emits (written to ``certificates.json``, see CONTRACT.md)."""

from __future__ import annotations

from dataclasses import dataclass, field

STATUSES = ("proved", "refuted", "checked")
SIZES = ("small", "large")


@dataclass(frozen=True)
class Certificate:
    """``status``: "proved" (exact symbolic argument), "refuted" (an exact counterexample to the
    claim as stated), or "checked" (agreement on instances or within a stated tolerance).
    ``detail`` says exactly what was shown, symbolic in which entries, for which sizes.

    A "proved" certificate exists only with ``evidence``, the verdict of
    :class:`~gpfverify.symbolic.argument.Argument` that computed that status: an author cannot
    declare a claim proved."""

    claim: str
    statement: str
    method: str
    status: str
    detail: str
    seconds: float = 0.0
    #: "any dimension" or the sizes covered (CONTRACT.md, Certificates)
    scope: str = ""
    #: ({"mutant": str, "rejected": bool, ...}, ...): mutated statements the proof must reject
    negative_controls: tuple = ()
    #: facts the argument uses and does not prove, each with the engine's check of it
    stated_facts: tuple = ()
    #: the hypotheses the conclusions rest on (each is also written into the statement)
    hypotheses: tuple = ()
    #: the engine's instance checks: ({"rule", "kind", "instances", "holds"}, ...)
    checks: tuple = ()
    evidence: object = field(default=None, compare=False, repr=False)

    def __post_init__(self):
        if self.status not in STATUSES:
            raise ValueError(f"status must be one of {STATUSES}, got {self.status!r}")
        if self.status == "proved" and (getattr(self.evidence, "status", None) != "proved"
                                        or getattr(self.evidence, "claim", None) != self.claim):
            raise ValueError(f"{self.claim}: a certificate is proved only by the engine's verdict on its own claim")
        if self.status == "proved" and not self.controls_rejected:
            # a proof that accepts a mutated statement is not a proof: demote it and say so
            accepted = [c["mutant"] for c in self.negative_controls if not c["rejected"]]
            object.__setattr__(self, "status", "checked")
            object.__setattr__(self, "detail", "NOT A PROOF: negative controls accepted ("
                               + "; ".join(accepted) + "). " + self.detail)

    @property
    def controls_rejected(self) -> bool:
        """Every negative control was rejected (vacuously true without controls)."""
        return all(c["rejected"] for c in self.negative_controls)

    def to_json(self) -> dict:
        out = {"claim": self.claim, "statement": self.statement, "method": self.method, "status": self.status,
               "detail": self.detail, "seconds": self.seconds}
        if self.scope:
            out["scope"] = self.scope
        if self.negative_controls:
            out["negative_controls"] = [dict(c) for c in self.negative_controls]
        for name in ("stated_facts", "hypotheses", "checks"):
            value = getattr(self, name)
            if value:
                out[name] = [dict(v) if isinstance(v, dict) else v for v in value]
        return out


def verdict(holds: bool, proved: str = "checked") -> str:
    """``checked`` (or the given word) when every numerical check held, else ``refuted``."""
    return proved if holds else "refuted"
