"""Fusion steps of one layout stacked over steps, validated at once (one rule for a single case,
a JSON Lines run and an npz run).

A :class:`CaseBlock` holds B steps with the same state dimension D, the same sensor sizes and the
same angle outputs: the centre's arrays ``mu_p`` (B, D), ``C_p`` (B, D, D), ``mu_y`` (B, L),
``C_y`` (B, L, L), ``C_xy`` (B, D, L); per sensor a :class:`LocalBlock`; ``y`` (B, L) with a row
of NaN where a step has no y, ``rank_tol`` (B,) with NaN where a step has none.
``block.case(t)`` is step t as a :class:`~gpfverify.fusion.case.FusionCase`.

:func:`block_from_records` stacks decoded JSON records (:mod:`gpfverify.fusion.caseformat`) and
:func:`block_from_arrays` takes arrays (an npz run file); both end in :func:`check_block`, which
applies the case format's rules to every step at once: finite numbers of magnitude at most
1e100, covariances symmetric and positive semidefinite (C_y and C_y^m positive definite; the rule
of :func:`~gpfverify.validate.covariance_defects`, which has no units), and the centre's joint
covariance [[C_p, C_xy], [C_xyᵀ, C_y]] of (x, y) positive semidefinite by the same rule (a C_xy
implying a correlation above one is impossible). A sensor's joint with its own prior C_p^m, which
is not sent, is implied as C_p^m = C_e^m + C_xy^m (C_y^m)⁻¹ C_xy^mᵀ; it is positive semidefinite
exactly when C_e^m is (Schur complement), which is checked. The first step that breaks a rule raises
:class:`StepError` with that step's position and the entry's name, so a file's first problem is
the one reported, whatever the block size.

One fusion case is read as a block of one step: :func:`case_from_dict`, :func:`load_case` and
:func:`case_from_records` (the types are :mod:`gpfverify.fusion.case`'s).
"""

from __future__ import annotations

from dataclasses import dataclass
from collections.abc import Sequence

import numpy as np

from gpfverify.errors import CaseFileError
from gpfverify.userfiles import read_regular
from gpfverify.fusion.case import CentralPrediction, FusionCase, LocalReport, split_circular, stack_circular
from gpfverify.fusion.caseformat import MAX_MAGNITUDE, Case, decode, from_python, given
from gpfverify.validate import covariance_defects


class StepError(CaseFileError):
    """A rule broken at step ``step`` (0-based position in the block) by the entry the message
    names."""

    def __init__(self, step: int, message: str):
        super().__init__(message)
        self.step = step


@dataclass(frozen=True)
class LocalBlock:
    """Sensor m's reports over B steps: mu_p (B, D), mu_y (B, l), C_y (B, l, l), C_xy (B, D, l),
    mu_e (B, D) and C_e (B, D, D) or None; ``has_C_e`` (B,) where C_e was given."""

    mu_p: np.ndarray
    mu_y: np.ndarray
    C_y: np.ndarray
    C_xy: np.ndarray
    mu_e: np.ndarray
    C_e: np.ndarray | None
    has_C_e: np.ndarray


@dataclass(frozen=True)
class CaseBlock:
    """B validated steps of one layout (module docstring)."""

    sizes: tuple[int, ...]
    circular: tuple[int, ...]
    mu_p: np.ndarray
    C_p: np.ndarray
    mu_y: np.ndarray
    C_y: np.ndarray
    C_xy: np.ndarray
    locals: tuple[LocalBlock, ...]
    y: np.ndarray | None
    rank_tol: np.ndarray
    circular_state: tuple[int, ...] = ()

    def __len__(self) -> int:
        return self.mu_p.shape[0]

    @property
    def state_dim(self) -> int:
        return self.mu_p.shape[1]

    @property
    def has_y(self) -> np.ndarray:
        if self.y is None:
            return np.zeros(len(self), dtype=bool)
        return ~np.all(np.isnan(self.y), axis=1)

    def take(self, steps) -> CaseBlock:
        """The block of the steps ``steps`` (a slice or index array)."""
        local = tuple(LocalBlock(r.mu_p[steps], r.mu_y[steps], r.C_y[steps], r.C_xy[steps], r.mu_e[steps],
                                 None if r.C_e is None else r.C_e[steps], r.has_C_e[steps]) for r in self.locals)
        return CaseBlock(self.sizes, self.circular, self.mu_p[steps], self.C_p[steps], self.mu_y[steps],
                         self.C_y[steps], self.C_xy[steps], local, None if self.y is None else self.y[steps],
                         self.rank_tol[steps], self.circular_state)

    def case(self, t: int) -> FusionCase:
        """Step t as a FusionCase (its arrays are views of the block's)."""
        central = CentralPrediction(self.mu_p[t], self.C_p[t], self.mu_y[t], self.C_y[t], self.C_xy[t],
                                    self.sizes, self.circular, self.circular_state)
        local_circular = split_circular(self.circular, self.sizes)
        reports = tuple(LocalReport(r.mu_p[t], r.mu_y[t], r.C_y[t], r.C_xy[t], r.mu_e[t],
                                    r.C_e[t] if r.C_e is not None and r.has_C_e[t] else None, c)
                        for r, c in zip(self.locals, local_circular))
        y = self.y[t] if self.y is not None and not np.all(np.isnan(self.y[t])) else None
        tol = float(self.rank_tol[t])
        return FusionCase(central, reports, y, None if np.isnan(tol) else tol)


# --------------------------------------------------------------------------------------------
# numeric rules over a block
# --------------------------------------------------------------------------------------------

def _finite(arr: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """(B,) True where the step's entries are all finite with magnitude <= MAX_MAGNITUDE."""
    ok = np.abs(arr.reshape(arr.shape[0], -1)) <= MAX_MAGNITUDE
    good = ok.all(axis=1) if ok.shape[1] else np.ones(arr.shape[0], dtype=bool)
    return good if mask is None else good | ~mask


def _first_problem(checks) -> StepError | None:
    """The earliest step's first broken rule among ``checks`` = [(bad (B,), why(t)), ...] in the
    format's order of entries."""
    firsts = [(int(np.argmax(bad)), i) for i, (bad, _) in enumerate(checks) if bad.any()]
    if not firsts:
        return None
    t, i = min(firsts)
    return StepError(t, checks[i][1](t))


def check_block(block: CaseBlock) -> CaseBlock:
    """``block`` with its covariances symmetrised, after the format's numeric rules (module
    docstring); raises :class:`StepError` for the first step that breaks one."""
    checks: list = []
    sym: dict[str, np.ndarray] = {}

    def finite(entry: str, arr: np.ndarray, mask=None):
        checks.append((~_finite(arr, mask), lambda t: f"{entry} holds a NaN, an inf or a magnitude above "
                                                      f"{MAX_MAGNITUDE:g}"))

    def covariance(entry: str, arr: np.ndarray, definite: bool, mask=None):
        finite(entry, arr, mask)
        clean = np.where(_finite(arr)[:, None, None], arr, 0.0)
        s, bad, why = covariance_defects(clean, definite)
        if mask is not None:
            bad = bad & mask
        sym[entry] = s
        checks.append((bad, lambda t: f"{entry} {why(t)}"))

    def joint_psd(b: CaseBlock):
        parts = [b.C_p, b.C_xy, b.C_y]
        ok = np.logical_and.reduce([_finite(a) for a in parts])
        c_p, c_xy, c_y = (np.where(ok[:, None, None], a, 0.0) for a in parts)
        joint = np.block([[c_p, c_xy], [np.swapaxes(c_xy, -1, -2), c_y]])
        _, bad, why = covariance_defects(joint)
        checks.append((bad & ok, lambda t: f"central joint covariance [[C_p, C_xy], [C_xyᵀ, C_y]] {why(t)}"))

    finite("central.mu_p", block.mu_p)
    covariance("central.C_p", block.C_p, False)
    finite("central.mu_y", block.mu_y)
    covariance("central.C_y", block.C_y, True)
    finite("central.C_xy", block.C_xy)
    joint_psd(block)
    for m, r in enumerate(block.locals):
        where = f"locals[{m}]"
        finite(f"{where}.mu_p", r.mu_p)
        finite(f"{where}.mu_y", r.mu_y)
        covariance(f"{where}.C_y", r.C_y, True)
        finite(f"{where}.C_xy", r.C_xy)
        finite(f"{where}.mu_e", r.mu_e)
        if r.C_e is not None:
            covariance(f"{where}.C_e", r.C_e, False, r.has_C_e)
    if block.y is not None:
        has_y = block.has_y
        finite("y", np.where(has_y[:, None], block.y, 0.0))
    tol = block.rank_tol
    checks.append((~np.isnan(tol) & ~((tol >= 0) & (tol <= MAX_MAGNITUDE)),
                   lambda t: f"rank_tol must be a number >= 0 of magnitude at most {MAX_MAGNITUDE:g}, "
                             f"got {tol[t]:g}"))
    problem = _first_problem(checks)
    if problem is not None:
        raise problem
    return CaseBlock(
        block.sizes, block.circular, block.mu_p, sym["central.C_p"], block.mu_y, sym["central.C_y"], block.C_xy,
        tuple(LocalBlock(r.mu_p, r.mu_y, sym[f"locals[{m}].C_y"], r.C_xy, r.mu_e,
                         None if r.C_e is None else sym[f"locals[{m}].C_e"], r.has_C_e)
              for m, r in enumerate(block.locals)),
        block.y, block.rank_tol, block.circular_state)


# --------------------------------------------------------------------------------------------
# from decoded JSON records
# --------------------------------------------------------------------------------------------

def checked_indices(value, count: int, entry: str) -> tuple[int, ...] | None:
    if value is None:
        return None
    for i in value:
        if not 0 <= i < count:
            what = "state component(s)" if entry == "circular_state" else "output(s)"
            raise CaseFileError(f"{entry} index {i} is out of range for {count} {what}")
    if len(set(value)) != len(value):
        raise CaseFileError(f"{entry} lists an index twice: {list(value)}")
    return tuple(sorted(value))


def agreed_circular(central, per_sensor, sizes) -> tuple[int, ...]:
    """The stacked angle outputs from ``central.circular`` and the ``locals[m].circular`` (None
    where absent); when both kinds are present, an absent local entry means no angles and every
    sensor's block must agree (docs/fusion-case-format.md, "Angles")."""
    if central is None:
        return stack_circular([c or () for c in per_sensor], sizes)
    if all(c is None for c in per_sensor):
        return central
    for m, (expected, given_m) in enumerate(zip(split_circular(central, sizes), per_sensor)):
        if expected != (given_m or ()):
            raise CaseFileError(f"locals[{m}].circular {list(given_m or ())} disagrees with "
                                f"central.circular {list(central)} (sensor {m}'s outputs there: "
                                f"{list(expected)})")
    return central


def layout(record: Case) -> tuple[int, tuple[int, ...], tuple[int, ...], tuple[int, ...]]:
    """(D, sizes, stacked angle outputs, angle state components) of a decoded record;
    CaseFileError when the record's own sensors, sizes and angle lists disagree."""
    sizes = tuple(record.central.sizes)
    if len(record.locals) != len(sizes):
        raise CaseFileError(f"locals has {len(record.locals)} entries but central.sizes lists "
                            f"{len(sizes)} sensors")
    central = checked_indices(given(record.central.circular), sum(sizes), "central.circular")
    per_sensor = [checked_indices(given(r.circular), s, f"locals[{m}].circular")
                  for m, (r, s) in enumerate(zip(record.locals, sizes))]
    d = len(record.central.mu_p)
    states = checked_indices(given(record.circular_state), d, "circular_state") or ()
    return d, sizes, agreed_circular(central, per_sensor, sizes), states


def _shape_problem(value, shape: tuple[int, ...], entry: str) -> str | None:
    try:
        arr = np.array(value, dtype=float)
    except ValueError:
        return f"{entry} must be a matrix (every row of the same length)"
    if arr.shape != shape:
        return f"{entry} must have shape {shape}, got {arr.shape}"
    return None


def _stacked(values: list, shape: tuple[int, ...]) -> np.ndarray | None:
    """``values`` stacked as (B,) + shape, or None when some step has another shape."""
    try:
        arr = np.array(values, dtype=float)
    except ValueError:
        return None
    return arr if arr.shape == (len(values),) + shape else None


def block_from_records(records: Sequence[Case]) -> CaseBlock:
    """Stack and check decoded records that share one layout (:func:`layout`, checked by the
    caller); raises :class:`StepError` for the first step that breaks a rule."""
    first = records[0]
    d, sizes, circular, circular_state = layout(first)
    total = sum(sizes)
    fields = [("central.mu_p", lambda r: r.central.mu_p, (d,)), ("central.C_p", lambda r: r.central.C_p, (d, d)),
              ("central.mu_y", lambda r: r.central.mu_y, (total,)),
              ("central.C_y", lambda r: r.central.C_y, (total, total)),
              ("central.C_xy", lambda r: r.central.C_xy, (d, total))]
    for m, l in enumerate(sizes):
        def getter(key, m=m):
            return lambda r: getattr(r.locals[m], key)
        fields += [(f"locals[{m}].mu_p", getter("mu_p"), (d,)), (f"locals[{m}].mu_y", getter("mu_y"), (l,)),
                   (f"locals[{m}].C_y", getter("C_y"), (l, l)), (f"locals[{m}].C_xy", getter("C_xy"), (d, l)),
                   (f"locals[{m}].mu_e", getter("mu_e"), (d,))]
    arrays: dict[str, np.ndarray] = {}
    bad_step = len(records)
    for entry, get, shape in fields:
        arr = _stacked([get(r) for r in records], shape)
        if arr is None:
            bad_step = min(bad_step, next(t for t, r in enumerate(records)
                                          if _shape_problem(get(r), shape, entry) is not None))
        else:
            arrays[entry] = arr
    optional: dict[str, tuple[list, tuple[int, ...]]] = {
        f"locals[{m}].C_e": ([given(r.locals[m].C_e) for r in records], (d, d)) for m in range(len(sizes))}
    optional["y"] = ([given(r.y) for r in records], (total,))
    for entry, (values, shape) in optional.items():
        present = [v for v in values if v is not None]
        if present and _stacked(present, shape) is None:
            bad_step = min(bad_step, next(t for t, v in enumerate(values)
                                          if v is not None and _shape_problem(v, shape, entry) is not None))
    if bad_step < len(records):
        _raise_shape_problem(records, bad_step, fields, optional)
    filler = {"y": np.full(total, np.nan), **{f"locals[{m}].C_e": np.zeros((d, d)) for m in range(len(sizes))}}
    stacked_optional = {}
    for entry, (values, _) in optional.items():
        if any(v is not None for v in values):
            stacked_optional[entry] = np.array([filler[entry] if v is None else v for v in values], dtype=float)
    locals_ = tuple(LocalBlock(
        arrays[f"locals[{m}].mu_p"], arrays[f"locals[{m}].mu_y"], arrays[f"locals[{m}].C_y"],
        arrays[f"locals[{m}].C_xy"], arrays[f"locals[{m}].mu_e"], stacked_optional.get(f"locals[{m}].C_e"),
        np.array([v is not None for v in optional[f"locals[{m}].C_e"][0]]))
        for m in range(len(sizes)))
    rank_tol = np.array([np.nan if given(r.rank_tol) is None else r.rank_tol for r in records], dtype=float)
    return check_block(CaseBlock(sizes, circular, arrays["central.mu_p"], arrays["central.C_p"],
                                 arrays["central.mu_y"], arrays["central.C_y"], arrays["central.C_xy"],
                                 locals_, stacked_optional.get("y"), rank_tol, circular_state))


def _raise_shape_problem(records, t: int, fields, optional) -> None:
    """Raise the first problem of the steps up to ``t`` (step t has a shape problem): a numeric
    one of an earlier step first, then step t's first entry in the format's order."""
    if t > 0:
        block_from_records(records[:t])
    record = records[t]
    for entry, get, shape in fields:
        problem = _shape_problem(get(record), shape, entry)
        if problem is not None:
            raise StepError(t, problem)
    for entry, (values, shape) in optional.items():
        if values[t] is not None and (problem := _shape_problem(values[t], shape, entry)) is not None:
            raise StepError(t, problem)
    raise AssertionError("no shape problem at the step named")  # pragma: no cover


def block_from_arrays(sizes: Sequence[int], circular: Sequence[int], central: dict[str, np.ndarray],
                      local: Sequence[dict[str, np.ndarray | None]], y: np.ndarray | None,
                      rank_tol: np.ndarray, circular_state: Sequence[int] = ()) -> CaseBlock:
    """A checked block from arrays already of the right shapes (an npz run file's rows):
    ``central`` with keys mu_p, C_p, mu_y, C_y, C_xy; ``local[m]`` with mu_p, mu_y, C_y, C_xy,
    mu_e and C_e (or None); ``y`` with NaN rows where a step has none; ``rank_tol`` NaN for none."""
    B = central["mu_p"].shape[0]
    f = {k: np.asarray(v, dtype=float) for k, v in central.items()}
    locals_ = []
    for r in local:
        c_e = r.get("C_e")
        mu_p, mu_y, c_y, c_xy, mu_e = (np.asarray(r[k], dtype=float) for k in ("mu_p", "mu_y", "C_y", "C_xy", "mu_e"))
        locals_.append(LocalBlock(mu_p, mu_y, c_y, c_xy, mu_e, None if c_e is None else np.asarray(c_e, dtype=float),
                                  np.full(B, c_e is not None)))
    return check_block(CaseBlock(tuple(int(s) for s in sizes), tuple(int(i) for i in circular), f["mu_p"],
                                 f["C_p"], f["mu_y"], f["C_y"], f["C_xy"], tuple(locals_),
                                 None if y is None else np.asarray(y, dtype=float),
                                 np.asarray(rank_tol, dtype=float), tuple(int(i) for i in circular_state)))


# ---- one case: a block of one step ----------------------------------------------------------------

def case_from_dict(data) -> FusionCase:
    """Validate a decoded case (dicts and lists, as ``json.loads`` gives them) by the rules of the
    case format (module docstring); raises :class:`CaseFileError` naming what is wrong."""
    record = from_python(data)
    layout(record)
    return block_from_records([record]).case(0)


def load_case(path) -> FusionCase:
    """Read and validate a fusion-case JSON file (a regular file, strict JSON: module docstring);
    CaseFileError naming the file and the entry."""
    raw = read_regular(path)
    try:
        record = decode(raw)
        layout(record)
        return block_from_records([record]).case(0)
    except CaseFileError as exc:
        raise CaseFileError(f"{path}: {exc}") from None


def case_from_records(central, local_records, sizes, y=None, rank_tol=None, circular=(),
                      circular_state=()) -> FusionCase:
    """A case from filter records: ``central`` has the centre's mu_p, C_p, mu_y, C_y, C_xy
    (e.g. the CMF :class:`~gpfverify.filters.records.StepRecord`); ``local_records`` are the
    sensors' step records (their mu_e and C_e are what they send); ``circular`` the angle outputs
    of the stacked measurement (e.g. a model's ``circular``), ``circular_state`` the angle state
    components (a model's ``circular_state``)."""
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
        "circular_state": [int(i) for i in circular_state],
    })
