"""One fusion step as a typed record, and its JSON form (CONTRACT.md, "Fusion-case files"; for
users: docs/fusion-case-format.md).

A fusion case holds what the fusion centre knows at time k (seed 000 §3):

* the centre's own prediction from the previous fused posterior (``central``): μ_p (D,),
  C_p (D, D) and the stacked measurement moments μ_y (L,), C_y (L, L), C_xy (D, L), with
  ``sizes`` = (l_1, …, l_N), L = Σ l_m, blocks in sensor order;
* what each sensor m sends (``locals[m]``): μ_p^m, μ_y^m, C_y^m, C_xy^m, μ_e^m (eq. 32–34) and,
  for the covariance-based baselines, C_e^m;
* optionally the stacked raw measurement y (needed for CMF and for the actual gap) and an absolute
  singular-value tolerance ``rank_tol`` for the rank decisions;
* optionally which outputs are angles in radians: ``locals[m].circular`` (0-based indices into
  sensor m's outputs) and/or ``central.circular`` (indices into the stacked measurement); when both
  are given they must agree. Every difference of an angle output (y − μ_y, μ_y^m − μ_y(m), the CMF
  innovation) is then taken on the circle, wrapped to (−π, π] (:mod:`gpfverify.angles`);
* optionally which state components are angles: top-level ``circular_state`` (0-based indices);
  μ_e^m − μ_p^m in eq. 35, the fused means and the gap are then taken on the circle.

Every check raises :class:`~gpfverify.errors.CaseFileError` naming the offending entry.

Reading (:func:`~gpfverify.fusion.caseblock.load_case`, :func:`~gpfverify.fusion.caseblock.case_from_dict`,
:func:`~gpfverify.fusion.caseblock.case_from_records`: a block of one step) goes through the typed JSON records of
:mod:`gpfverify.fusion.caseformat` (strict numbers of magnitude at most :data:`MAX_MAGNITUDE`
= 1e100, no unknown or duplicate keys, nesting fixed by the types) and the checks of
:mod:`gpfverify.fusion.caseblock` (shapes, symmetry, definiteness), the same route as every
step of a run file. Within the magnitude bound the squares and quadratic forms the fusion rules
build stay inside the float range (checked for every method and the audit with each entry, and
each field scaled, at the bound: tests/test_error_boundary.py). Tiny entries are accepted (a
computed covariance holds rounding-sized ones); a case whose covariances are so small that an
inverse overflows is refused by the command line (``audit`` and ``fuse`` run with
floating-point overflow as an error). A case file must be a regular file of UTF-8 text.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gpfverify.errors import InputError
from gpfverify.fusion.caseformat import MAX_MAGNITUDE

__all__ = ["MAX_MAGNITUDE", "CentralPrediction", "LocalReport", "FusionCase", "case_to_dict", "cases_to_dicts",
           "sensor_blocks", "stack_circular", "split_circular"]


@functools.lru_cache(maxsize=256)
def _blocks(sizes: tuple[int, ...]) -> tuple[slice, ...]:
    ends = np.cumsum((0,) + sizes)
    return tuple(slice(int(a), int(b)) for a, b in zip(ends[:-1], ends[1:]))


def sensor_blocks(sizes) -> list[slice]:
    """Slice of every sensor's outputs in the stacked measurement (sensor order)."""
    return list(_blocks(tuple(int(s) for s in sizes)))


def stack_circular(per_sensor, sizes) -> tuple[int, ...]:
    """Sensor-local angle indices (one sequence per sensor) as indices into the stacked measurement."""
    return tuple(int(b.start) + int(i) for b, c in zip(sensor_blocks(sizes), per_sensor) for i in sorted(c))


def split_circular(stacked, sizes) -> tuple[tuple[int, ...], ...]:
    """Stacked angle indices as each sensor's local indices (inverse of :func:`stack_circular`)."""
    return tuple(tuple(int(i) - b.start for i in sorted(stacked) if b.start <= i < b.stop)
                 for b in sensor_blocks(sizes))


@dataclass(frozen=True)
class CentralPrediction:
    """The fusion centre's prediction: mu_p (D,), C_p (D, D), mu_y (L,), C_y (L, L) positive
    definite, C_xy (D, L); ``sizes`` the measurement dimension of each sensor (Σ = L);
    ``circular`` the angle outputs of the stacked measurement and ``circular_state`` the angle
    components of the state (sorted 0-based indices; a case file's top-level ``circular_state``)."""

    mu_p: np.ndarray
    C_p: np.ndarray
    mu_y: np.ndarray
    C_y: np.ndarray
    C_xy: np.ndarray
    sizes: tuple[int, ...]
    circular: tuple[int, ...] = ()
    circular_state: tuple[int, ...] = ()

    @property
    def blocks(self) -> list[slice]:
        """Slice of sensor m's rows/columns in the stacked measurement."""
        return sensor_blocks(self.sizes)


@dataclass(frozen=True)
class LocalReport:
    """What sensor m sends: mu_p (D,), mu_y (l,), C_y (l, l) positive definite, C_xy (D, l),
    mu_e (D,) and optionally C_e (D, D); ``circular`` its angle outputs (sorted 0-based indices
    into its own l outputs)."""

    mu_p: np.ndarray
    mu_y: np.ndarray
    C_y: np.ndarray
    C_xy: np.ndarray
    mu_e: np.ndarray
    C_e: np.ndarray | None = None
    circular: tuple[int, ...] = ()


@dataclass(frozen=True)
class FusionCase:
    """One fusion step: central prediction, the sensors' reports, optional y (L,) and rank_tol.
    The central and local angle outputs must agree (InputError otherwise)."""

    central: CentralPrediction
    locals: tuple[LocalReport, ...]
    y: np.ndarray | None = None
    rank_tol: float | None = None

    def __post_init__(self):
        stacked = stack_circular([r.circular for r in self.locals], self.central.sizes)
        if stacked != tuple(self.central.circular):
            raise InputError(f"central.circular {list(self.central.circular)} disagrees with the "
                             f"sensors' circular outputs (stacked: {list(stacked)})")
        states = self.central.circular_state
        if len(set(states)) != len(states) or any(not 0 <= i < self.state_dim for i in states):
            raise InputError(f"circular_state {list(states)} must be distinct state indices in "
                             f"[0, {self.state_dim - 1}]")

    @property
    def circular_state(self) -> tuple[int, ...]:
        """The angle components of the state (radians): every difference and mean of them in eq. 35,
        CMF and the audit is taken on the circle."""
        return self.central.circular_state

    @property
    def state_dim(self) -> int:
        return self.central.mu_p.shape[0]

    def local_measurement(self, m: int) -> np.ndarray:
        """y^m, sensor m's block of the stacked measurement (requires ``y``)."""
        if self.y is None:
            raise InputError("the case has no measurement y")
        return self.y[self.central.blocks[m]]


def case_to_dict(case: FusionCase) -> dict:
    """The JSON-able form read back by :func:`~gpfverify.fusion.caseblock.case_from_dict`."""
    return cases_to_dicts([case])[0]


def cases_to_dicts(cases: Sequence[FusionCase]) -> list[dict]:
    """:func:`case_to_dict` of many cases: the cases of one layout (state dimension, sizes, angles,
    which optional fields they have) stacked field by field, each field turned into lists once
    (a run's steps, or many runs', at the cost of a few numpy calls instead of a few per case)."""
    if not cases:
        return []
    layout = {_layout(c) for c in cases}
    if len(layout) > 1:
        return [d for c in cases for d in cases_to_dicts([c])]
    first = cases[0]

    def listed(get) -> list:
        return np.array([get(c) for c in cases]).tolist()

    central = {f: listed(lambda c, f=f: getattr(c.central, f)) for f in ("mu_p", "C_p", "mu_y", "C_y", "C_xy")}
    local = [{f: listed(lambda c, m=m, f=f: getattr(c.locals[m], f)) for f in _local_fields(r)}
             for m, r in enumerate(first.locals)]
    ys = listed(lambda c: c.y) if first.y is not None else None
    out = []
    for t, case in enumerate(cases):
        head = {f: v[t] for f, v in central.items()}
        entry: dict[str, Any] = {"central": {**head, "sizes": list(first.central.sizes)}, "locals": []}
        if first.central.circular:
            entry["central"]["circular"] = list(first.central.circular)
        for m, r in enumerate(first.locals):
            item = {f: v[t] for f, v in local[m].items()}
            if r.circular:
                item["circular"] = list(r.circular)
            entry["locals"].append(item)
        if ys is not None:
            entry["y"] = ys[t]
        if case.rank_tol is not None:
            entry["rank_tol"] = case.rank_tol
        if first.circular_state:
            entry["circular_state"] = list(first.circular_state)
        out.append(entry)
    return out


def _local_fields(report: LocalReport) -> tuple[str, ...]:
    """The fields of a sensor's report a case file holds, in the file's order."""
    return ("mu_p", "mu_y", "C_y", "C_xy", "mu_e") + (("C_e",) if report.C_e is not None else ())


def _layout(case: FusionCase) -> tuple:
    """What two cases must share to be listed together by :func:`cases_to_dicts`."""
    return (case.central.mu_p.shape, case.central.sizes, case.central.circular, case.circular_state, case.y is None,
            tuple((r.C_e is None, r.circular) for r in case.locals))


#END
