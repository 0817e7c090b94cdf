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

    def __post_init__(self):
        if self.status not in STATUSES:
            raise ValueError(f"status must be one of {STATUSES}, got {self.status!r}")

    def to_json(self) -> dict:
        return asdict(self)


def verdict(holds: bool, proved: str = "proved") -> str:
    """``proved`` (or ``checked``) when every check held, else ``refuted``."""
    return proved if holds else "refuted"
