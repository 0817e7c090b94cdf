"""The record a proof or cross-check emits (written to ``certificates.json``, see CONTRACT.md)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

STATUSES = ("proved", "refuted", "checked")
SIZES = ("small", "large")


@dataclass(frozen=True)
class Certificate:
    """``status``: "proved" (exact symbolic argument), "refuted" (an exact counterexample to the
    claim as stated), or "checked" (numerical agreement within a stated tolerance).
    ``detail`` says exactly what was shown, symbolic in which entries, for which sizes."""

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
    #: facts the argument uses and does not prove (textbook facts, each named), if any
    stated_facts: tuple = ()

    def __post_init__(self):
        if self.status not in STATUSES:
            raise ValueError(f"status must be one of {STATUSES}, got {self.status!r}")
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
        out = asdict(self)
        out["negative_controls"] = [dict(c) for c in self.negative_controls]
        if not self.scope:
            out.pop("scope")
        if not self.negative_controls:
            out.pop("negative_controls")
        out["stated_facts"] = list(self.stated_facts)
        if not self.stated_facts:
            out.pop("stated_facts")
        return out


def verdict(holds: bool, proved: str = "proved") -> str:
    """``proved`` (or ``checked``) when every check held, else ``refuted``."""
    return proved if holds else "refuted"
