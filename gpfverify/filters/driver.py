"""A thin iterator over a measurement sequence for any step function of the common protocol
``step(belief, model, y, *, k, **params) -> record`` whose record has ``.posterior``."""

from __future__ import annotations

from dataclasses import dataclass, fields
from collections.abc import Callable
from typing import Any

import numpy as np

from gpfverify.errors import InputError
from gpfverify.filters.records import StepRecord
from gpfverify.runtime import one_blas_thread


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


@one_blas_thread
def run_filter(step: Callable, model, belief0, ys, *, first_k: int = 1, **params):
    """Run ``step`` over the measurements ``ys`` (T, ..., L) from the prior ``belief0``: step t is
    ``step(belief, model, ys[t], k=first_k + t, **params)`` and its record's ``posterior`` is the
    next belief. Returns a :class:`FilterRun` when the records are :class:`StepRecord`\\ s (the
    Gaussian filters), else the list of records."""
    ys = np.asarray(ys, dtype=float)
    if ys.ndim < 2 or ys.shape[0] == 0:
        raise InputError(f"ys must have shape (T, ..., L) with T ≥ 1, got {ys.shape}")
    records, belief = [], belief0
    for t, y in enumerate(ys):
        record = step(belief, model, y, k=first_k + t, **params)
        records.append(record)
        belief = record.posterior
    if not all(type(r) is StepRecord for r in records):
        return records
    # every field stacked over time, jitter included (a (T,) array, not StepRecord's float)
    stacked: dict[str, Any] = {f.name: np.stack([np.asarray(getattr(r, f.name), dtype=float) for r in records])
                               for f in fields(FilterRun)}
    return FilterRun(**stacked)
