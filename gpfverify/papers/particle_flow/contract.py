"""Types shared by the particle-flow paper's experiments (Zhou et al. 2020, ``pff1d`` and
``bearing``): the four filters as :class:`~gpfverify.contract.methods.Method` values, the
λ-step schedules of the flows and a filter variant (method, Δλ, schedule) with its one label.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from gpfverify.contract.methods import Method

#: the paper, a key of gpfverify.contract.papers.PAPERS
PAPER = "seed003"

#: bootstrap particle filter (SIR: systematic resampling at every step)
PF = Method("PF")
#: unscented particle filter (a UKF per particle as proposal)
UPF = Method("UPF")
#: Daum–Huang exact particle flow, the paper's "PFF"
EDH = Method("EDH")
#: the paper's innovation-error particle flow ("improved PFF")
IE_PFF = Method("IE-PFF")
#: the methods that integrate a flow in pseudo-time λ ∈ [0, 1]
FLOWS: tuple[Method, ...] = (EDH, IE_PFF)

#: λ-step schedule of a flow: the paper's equal steps, or the same number growing geometrically
Spacing = Literal["uniform", "exponential"]
SPACINGS: tuple[Spacing, ...] = ("uniform", "exponential")


@dataclass(frozen=True)
class Variant:
    """One filter as run: the method and, for a flow, its pseudo-time step Δλ and λ-step schedule
    (both None for the PF and the UPF)."""

    method: Method
    dlambda: float | None = None
    spacing: Spacing | None = None

    def __post_init__(self) -> None:
        from gpfverify.errors import InputError

        is_flow = self.method in FLOWS
        if is_flow != (self.dlambda is not None) or is_flow != (self.spacing is not None):
            raise InputError(f"a variant has Δλ and a λ-step schedule exactly when it is a flow: {self!r}")

    @property
    def is_flow(self) -> bool:
        return self.method in FLOWS

    @property
    def label(self) -> str:
        """"PF", or "IE-PFF Δλ=0.01 uniform" for a flow (the keys of ``results.json``'s "gamma")."""
        return self.method.key if self.dlambda is None else f"{self.method.key} Δλ={self.dlambda:g} {self.spacing}"
