"""A thin iterator over a measurement sequence for any Gaussian step function."""

from __future__ import annotations

import inspect
from dataclasses import dataclass, fields
from typing import Callable

import numpy as np

from gpfverify.errors import InputError
from gpfverify.filters.records import Gaussian, StepRecord


@dataclass(frozen=True)
class FilterRun(StepRecord):
    """Every :class:`StepRecord` field stacked over time: mu_p (T, ..., D), C_p (T, ..., D, D),
    mu_y (T, ..., L), C_y (T, ..., L, L), C_xy (T, ..., D, L), mu_e (T, ..., D),
    C_e (T, ..., D, D), jitter (T,). ``posterior`` and ``prediction`` are the stacked beliefs."""

    def __len__(self) -> int:
        return self.mu_e.shape[0]

    def record(self, t: int) -> StepRecord:
        """The step record of time step ``t`` (0-based)."""
        return StepRecord(**{f.name: getattr(self, f.name)[t] for f in fields(self)})


def run_filter(step: Callable[..., StepRecord], belief0: Gaussian, ys, first_k: int = 1,
               **kw) -> FilterRun:
    """Run ``step`` over the measurements ``ys`` (T, ..., L) from the prior ``belief0``.

    Step t is called as ``step(belief, y=ys[t], **kw)``, with ``k=first_k + t`` as well when the
    step function has a parameter named ``k`` (time-varying models); each posterior is the next
    step's belief.
    """
    ys = np.asarray(ys, dtype=float)
    if ys.ndim < 2 or ys.shape[0] == 0:
        raise InputError(f"ys must have shape (T, ..., L) with T ≥ 1, got {ys.shape}")
    takes_time = "k" in inspect.signature(step).parameters
    records, belief = [], belief0
    for t, y in enumerate(ys):
        record = step(belief, y=y, **({"k": first_k + t} if takes_time else {}), **kw)
        records.append(record)
        belief = record.posterior
    return FilterRun(**{f.name: np.stack([np.asarray(getattr(r, f.name), dtype=float) for r in records])
                        for f in fields(FilterRun)})
