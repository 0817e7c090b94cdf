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
  innovation) is then taken on the circle, wrapped to (−π, π] (:mod:`gpfverify.angles`).

Every check raises :class:`~gpfverify.errors.CaseFileError` naming the offending entry.

Numbers are strict JSON numbers: a string (``"1.0"``), a boolean, ``NaN``/``Infinity`` or a
null inside an array is refused, and so is any magnitude above :data:`MAX_MAGNITUDE` = 1e100
(an integer of any length included). Within that range the squares and quadratic forms the
fusion rules build stay inside the float range (checked for every method and the audit with
each entry, and each field scaled, at the bound: tests/test_error_boundary.py). Tiny entries are
accepted (a computed covariance holds rounding-sized ones); a case whose covariances are so
small that an inverse overflows is refused by the command line (``audit`` and ``fuse`` run with
floating-point overflow as an error). The file must be UTF-8 text and nested no deeper than the
format needs.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from typing import Any
from pathlib import Path

import numpy as np

from gpfverify.errors import CaseFileError, InputError
from gpfverify.validate import as_covariance, as_matrix, as_vector


def sensor_blocks(sizes) -> list[slice]:
    """Slice of every sensor's outputs in the stacked measurement (sensor order)."""
    ends = np.cumsum((0,) + tuple(sizes))
    return [slice(int(a), int(b)) for a, b in zip(ends[:-1], ends[1:])]


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
    ``circular`` the angle outputs of the stacked measurement (sorted 0-based indices)."""

    mu_p: np.ndarray
    C_p: np.ndarray
    mu_y: np.ndarray
    C_y: np.ndarray
    C_xy: np.ndarray
    sizes: tuple[int, ...]
    circular: tuple[int, ...] = ()

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

    @property
    def state_dim(self) -> int:
        return self.central.mu_p.shape[0]

    def local_measurement(self, m: int) -> np.ndarray:
        """y^m, sensor m's block of the stacked measurement (requires ``y``)."""
        if self.y is None:
            raise InputError("the case has no measurement y")
        return self.y[self.central.blocks[m]]


#: largest magnitude accepted for a number in a case file
MAX_MAGNITUDE = 1e100


def strict_numbers(value, where: str, depth: int = 2):
    """``value`` unchanged after checking it is a JSON number or nested lists (at most ``depth``
    levels) of JSON numbers, each finite, not a boolean, and of magnitude at most MAX_MAGNITUDE;
    CaseFileError naming ``where`` otherwise."""
    if isinstance(value, np.ndarray):  # arrays from a .npz run file: the same rules, vectorised
        if value.dtype.kind not in "iuf":
            raise CaseFileError(f"{where} must hold numbers, got an array of {value.dtype}")
        if value.ndim > depth:
            raise CaseFileError(f"{where} is nested too deeply")
        if value.size and not np.all(np.abs(value.astype(float)) <= MAX_MAGNITUDE):
            raise CaseFileError(f"{where} holds a NaN, an inf or a magnitude above {MAX_MAGNITUDE:g}")
        return value
    if isinstance(value, list):
        if depth == 0:
            raise CaseFileError(f"{where} is nested too deeply")
        for i, item in enumerate(value):
            strict_numbers(item, f"{where}[{i}]", depth - 1)
        return value
    if isinstance(value, (np.integer, np.floating)):
        value = value.item()
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        shown = json.dumps(value)[:40] if isinstance(value, (str, list, dict, type(None))) else type(value).__name__
        raise CaseFileError(f"{where} must be a number, got {shown}")
    if isinstance(value, float) and not np.isfinite(value):
        raise CaseFileError(f"{where} must be finite, got {value}")
    if abs(value) > MAX_MAGNITUDE:
        shown = f"{value:.3g}" if isinstance(value, float) else f"an integer of {len(str(abs(value)))} digits"
        raise CaseFileError(f"{where} = {shown} is outside the accepted range: magnitudes up to "
                            f"{MAX_MAGNITUDE:g}")
    return value


def _checked(build, what: str):
    try:
        return build()
    except CaseFileError:
        raise
    except InputError as exc:
        raise CaseFileError(str(exc)) from None
    except (TypeError, KeyError, AttributeError) as exc:
        raise CaseFileError(f"{what} is malformed ({type(exc).__name__}: {exc})") from None


def _field(obj, key: str, where: str):
    if not isinstance(obj, dict):
        raise CaseFileError(f"{where} must be a JSON object")
    if key not in obj:
        raise CaseFileError(f"{where} lacks the key '{key}'")
    return obj[key]


def _sizes(value) -> tuple[int, ...]:
    if not isinstance(value, list) or not value:
        raise CaseFileError("central.sizes must be a non-empty list of positive integers")
    if not all(isinstance(s, int) and not isinstance(s, bool) and s > 0 for s in value):
        raise CaseFileError(f"central.sizes must be positive integers, got {value}")
    return tuple(value)


def _circular_entry(obj, count: int, where: str) -> tuple[int, ...] | None:
    """The optional ``circular`` list of ``obj`` (None when absent): distinct integers in
    [0, count), returned sorted."""
    value = obj.get("circular") if isinstance(obj, dict) else None
    if value is None:
        return None
    if not isinstance(value, list):
        raise CaseFileError(f"{where} must be a list of 0-based output indices, got {value!r}")
    for i in value:
        if isinstance(i, bool) or not isinstance(i, int):
            raise CaseFileError(f"{where} must hold integers, got {i!r}")
        if not 0 <= i < count:
            raise CaseFileError(f"{where} index {i} is out of range for {count} output(s)")
    if len(set(value)) != len(value):
        raise CaseFileError(f"{where} lists an index twice: {value}")
    return tuple(sorted(value))


def _agreed_circular(central, per_sensor, sizes) -> tuple[int, ...]:
    """The stacked angle outputs from ``central.circular`` and the ``locals[m].circular`` (None
    where absent); when both kinds are present, an absent local entry means no angles and every
    sensor's block must agree."""
    if central is None:
        return stack_circular([c or () for c in per_sensor], sizes)
    if all(c is None for c in per_sensor):
        return central
    for m, (expected, given) in enumerate(zip(split_circular(central, sizes), per_sensor)):
        if expected != (given or ()):
            raise CaseFileError(f"locals[{m}].circular {list(given or ())} disagrees with "
                                f"central.circular {list(central)} (sensor {m}'s outputs there: "
                                f"{list(expected)})")
    return central


def _numeric_field(obj, key: str, where: str, depth: int):
    return strict_numbers(_field(obj, key, where), f"{where}.{key}", depth)


def central_from_dict(data) -> CentralPrediction:
    where = "central"
    sizes = _sizes(_field(data, "sizes", where))
    mu_p = _checked(lambda: as_vector(_numeric_field(data, "mu_p", where, 1), "central.mu_p"), "central.mu_p")
    d, total = mu_p.shape[0], sum(sizes)
    if d == 0:
        raise CaseFileError("central.mu_p must not be empty")
    return CentralPrediction(
        mu_p=mu_p,
        C_p=_checked(lambda: as_covariance(_numeric_field(data, "C_p", where, 2), "central.C_p", d), "central.C_p"),
        mu_y=_checked(lambda: as_vector(_numeric_field(data, "mu_y", where, 1), "central.mu_y", total),
                      "central.mu_y"),
        C_y=_checked(lambda: as_covariance(_numeric_field(data, "C_y", where, 2), "central.C_y", total,
                                           definite=True), "central.C_y"),
        C_xy=_checked(lambda: as_matrix(_numeric_field(data, "C_xy", where, 2), "central.C_xy", d, total),
                      "central.C_xy"),
        sizes=sizes,
    )


def local_from_dict(data, m: int, d: int, size: int) -> LocalReport:
    where = f"locals[{m}]"

    def get(key, check):
        depth = 2 if key.startswith("C_") else 1
        return _checked(lambda: check(_numeric_field(data, key, where, depth), f"{where}.{key}"),
                        f"{where}.{key}")

    c_e = None
    if isinstance(data, dict) and data.get("C_e") is not None:
        c_e = get("C_e", lambda v, n: as_covariance(v, n, d))
    return LocalReport(
        mu_p=get("mu_p", lambda v, n: as_vector(v, n, d)),
        mu_y=get("mu_y", lambda v, n: as_vector(v, n, size)),
        C_y=get("C_y", lambda v, n: as_covariance(v, n, size, definite=True)),
        C_xy=get("C_xy", lambda v, n: as_matrix(v, n, d, size)),
        mu_e=get("mu_e", lambda v, n: as_vector(v, n, d)),
        C_e=c_e,
    )


def case_from_dict(data) -> FusionCase:
    """Validate a decoded case file; raises :class:`CaseFileError` naming what is wrong."""
    if not isinstance(data, dict):
        raise CaseFileError("a fusion case must be a JSON object")
    central = central_from_dict(_field(data, "central", "the case"))
    reports = _field(data, "locals", "the case")
    if not isinstance(reports, list):
        raise CaseFileError("locals must be a list of objects")
    if len(reports) != len(central.sizes):
        raise CaseFileError(f"locals has {len(reports)} entries but central.sizes lists "
                            f"{len(central.sizes)} sensors")
    d = central.mu_p.shape[0]
    local = tuple(local_from_dict(r, m, d, s) for m, (r, s) in enumerate(zip(reports, central.sizes)))
    circular = _agreed_circular(
        _circular_entry(data["central"], sum(central.sizes), "central.circular"),
        [_circular_entry(r, s, f"locals[{m}].circular") for m, (r, s) in enumerate(zip(reports, central.sizes))],
        central.sizes)
    central = replace(central, circular=circular)
    local = tuple(replace(r, circular=c) for r, c in zip(local, split_circular(circular, central.sizes)))
    y = None
    if data.get("y") is not None:
        y = _checked(lambda: as_vector(strict_numbers(data["y"], "y", 1), "y", sum(central.sizes)), "y")
    rank_tol = data.get("rank_tol")
    if rank_tol is not None:
        if isinstance(rank_tol, bool) or not isinstance(rank_tol, (int, float)) \
                or not np.isfinite(rank_tol) or rank_tol < 0:
            raise CaseFileError(f"rank_tol must be a finite number >= 0, got {json.dumps(rank_tol)[:40]}")
        rank_tol = float(strict_numbers(rank_tol, "rank_tol", 0))
    return FusionCase(central, local, y, rank_tol)


def _refuse_constant(name: str):
    raise CaseFileError(f"{name} is not a JSON number (NaN and Infinity are refused)")


def parse_json_text(text: str, where: str):
    """Strict JSON: NaN/Infinity refused, integers of any size parsed as text first (so an
    out-of-range one is reported, not overflowed), deep nesting reported; CaseFileError naming
    ``where`` (a file, or a file and line) for every failure."""
    try:
        return json.loads(text, parse_constant=_refuse_constant)
    except CaseFileError as exc:
        raise CaseFileError(f"{where}: {exc}") from None
    except json.JSONDecodeError as exc:
        raise CaseFileError(f"{where} is not valid JSON: {exc.msg} at line {exc.lineno}") from None
    except RecursionError:
        raise CaseFileError(f"{where} is nested too deeply to be a fusion case") from None
    except ValueError as exc:  # e.g. an integer longer than Python's digit limit
        raise CaseFileError(f"{where} is not valid JSON: {' '.join(str(exc).split())[:120]}") from None


def read_text_file(path) -> str:
    """The UTF-8 text of ``path``; CaseFileError when it cannot be read or is not UTF-8."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise CaseFileError(f"cannot read {path}: {exc.strerror or exc}") from None
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise CaseFileError(f"{path} is not UTF-8 text (invalid byte at offset {exc.start})") from None


def load_case(path) -> FusionCase:
    """Read and validate a fusion-case JSON file (strict numbers: module docstring)."""
    return case_from_dict(parse_json_text(read_text_file(path), str(path)))


def case_to_dict(case: FusionCase) -> dict:
    """The JSON-able form read back by :func:`case_from_dict`."""
    c = case.central
    out: dict[str, Any] = {"central": {"mu_p": c.mu_p.tolist(), "C_p": c.C_p.tolist(), "mu_y": c.mu_y.tolist(),
                       "C_y": c.C_y.tolist(), "C_xy": c.C_xy.tolist(), "sizes": list(c.sizes)},
           "locals": []}
    if c.circular:
        out["central"]["circular"] = list(c.circular)
    for r in case.locals:
        entry = {"mu_p": r.mu_p.tolist(), "mu_y": r.mu_y.tolist(), "C_y": r.C_y.tolist(),
                 "C_xy": r.C_xy.tolist(), "mu_e": r.mu_e.tolist()}
        if r.C_e is not None:
            entry["C_e"] = r.C_e.tolist()
        if r.circular:
            entry["circular"] = list(r.circular)
        out["locals"].append(entry)
    if case.y is not None:
        out["y"] = case.y.tolist()
    if case.rank_tol is not None:
        out["rank_tol"] = case.rank_tol
    return out


def case_from_records(central, local_records, sizes, y=None, rank_tol=None, circular=()) -> FusionCase:
    """A case from filter records: ``central`` has the centre's mu_p, C_p, mu_y, C_y, C_xy
    (e.g. the CMF :class:`~gpfverify.filters.records.StepRecord`); ``local_records`` are the
    sensors' step records (their mu_e and C_e are what they send); ``circular`` the angle outputs
    of the stacked measurement (e.g. a model's ``circular``)."""
    return case_from_dict({
        "central": {"mu_p": np.asarray(central.mu_p).tolist(), "C_p": np.asarray(central.C_p).tolist(),
                    "mu_y": np.asarray(central.mu_y).tolist(), "C_y": np.asarray(central.C_y).tolist(),
                    "C_xy": np.asarray(central.C_xy).tolist(), "sizes": [int(s) for s in sizes],
                    "circular": [int(i) for i in circular]},
        "locals": [{"mu_p": np.asarray(r.mu_p).tolist(), "mu_y": np.asarray(r.mu_y).tolist(),
                    "C_y": np.asarray(r.C_y).tolist(), "C_xy": np.asarray(r.C_xy).tolist(),
                    "mu_e": np.asarray(r.mu_e).tolist(), "C_e": np.asarray(r.C_e).tolist()}
                   for r in local_records],
        "y": None if y is None else np.asarray(y, dtype=float).tolist(),
        "rank_tol": rank_tol,
    })
