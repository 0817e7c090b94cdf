"""Run files: many fusion steps in one file (CONTRACT.md, "Run files"; for users:
docs/run-file-format.md), read as a stream of validated blocks of steps.

Three forms, chosen by the file's suffix (case-insensitive):

* ``.jsonl`` (or ``.ndjson``): JSON Lines, one fusion case per line as in the case format
  (docs/fusion-case-format.md) plus an optional integer ``"k"`` (the step index), decoded as
  :class:`~gpfverify.fusion.caseformat.RunLine` (the type docs/schemas/run-line.schema.json is
  generated from); blank lines are refused.
* ``.npz``: the same quantities as arrays stacked over the T steps (``central_mu_p`` (T, D), …,
  ``local{m}_C_xy`` (T, D, l_m), ``sizes`` (N,), optional ``y``, ``k``, ``rank_tol``,
  ``circular{m}``); see :data:`NPZ_ARRAYS`. Every array's header is checked before any data is
  read (:mod:`gpfverify.userfiles`), and the stacked arrays are read a block of rows at a time.
* anything else: one fusion case (``.json``), as a run of one step.

:func:`open_run` gives a :class:`RunReader` whose :meth:`~RunReader.blocks` yields
:class:`RunBlock` s of at most :data:`BLOCK_STEPS` steps — never the whole run — each checked by
:mod:`gpfverify.fusion.caseblock` (the same rules as a single case). :func:`iter_steps` yields
(k, FusionCase) pairs from them; :func:`load_run` collects a whole (small) run.

Every problem raises :class:`~gpfverify.errors.CaseFileError` with one line that names the file
and the line (jsonl) or the array and step (npz); a file's first problem is the one reported.
:func:`write_run` writes the jsonl and npz forms.
"""

from __future__ import annotations

import json
import os
import re
import tempfile
from dataclasses import dataclass
from pathlib import Path
from collections.abc import Iterable, Iterator, Sequence

import numpy as np

from gpfverify.errors import CaseFileError, InputError
from gpfverify.fusion.case import FusionCase, case_to_dict, full_y, split_circular
from gpfverify.fusion.caseblock import (CaseBlock, StepError, agreed_circular, block_from_arrays, block_from_records,
                                        checked_indices, layout)
from gpfverify.fusion.caseformat import (CASE_DECODER, RUN_LINE_DECODER, RunLine, case_schema, decode, given,
                                         run_line_schema)
from gpfverify.userfiles import NpzArchive, human_bytes, memory_budget, open_regular

JSONL_SUFFIXES = (".jsonl", ".ndjson")
NPZ_SUFFIXES = (".npz",)
#: steps per block: the unit of reading, checking, auditing and spreading over workers (fixed,
#: so that results never depend on the number of workers)
BLOCK_STEPS = 256
#: bytes read from a JSON Lines file at a time
CHUNK_BYTES = 1 << 22

#: JSON Schema of one fusion case (docs/schemas/fusion-case.schema.json), generated from the reader's types
CASE_SCHEMA = case_schema()
#: JSON Schema of one line of a .jsonl run file (docs/schemas/run-line.schema.json)
RUN_LINE_SCHEMA = run_line_schema()


@dataclass(frozen=True)
class RunBlock:
    """Consecutive steps of a run: ``ks`` (B,) their step indices, ``block`` the checked arrays,
    ``first`` the 0-based position of the block's first step in the run."""

    ks: np.ndarray
    block: CaseBlock
    first: int

    def __len__(self) -> int:
        return len(self.ks)

    def steps(self) -> Iterator[tuple[int, FusionCase]]:
        for t, k in enumerate(self.ks):
            yield int(k), self.block.case(t)


@dataclass(frozen=True)
class RunFile:
    """A run file read and validated: ``steps`` are (k, case) pairs in file order; ``format`` is
    ``"json"`` (a single case), ``"jsonl"`` or ``"npz"``; ``explicit_k`` whether the file gave the
    step indices (otherwise k is the 0-based position)."""

    path: str
    format: str
    steps: tuple[tuple[int, FusionCase], ...]
    explicit_k: bool = False

    @property
    def ks(self) -> list[int]:
        return [k for k, _ in self.steps]

    @property
    def cases(self) -> list[FusionCase]:
        return [c for _, c in self.steps]

    def __len__(self) -> int:
        return len(self.steps)


def run_format(path) -> str:
    """``"jsonl"``, ``"npz"`` or ``"json"`` (everything else: one fusion case) from the suffix."""
    suffix = Path(path).suffix.lower()
    if suffix in JSONL_SUFFIXES:
        return "jsonl"
    if suffix in NPZ_SUFFIXES:
        return "npz"
    return "json"


class RunReader:
    """An opened run file (module docstring). ``steps`` is T when the file declares it (npz, a
    single case), else None; ``explicit_k`` whether the file gives step indices (known for a
    JSON Lines file once its first line is read)."""

    def __init__(self, path):
        self.path = Path(path)
        self.format = run_format(path)
        self.explicit_k = False
        self.steps: int | None = 1 if self.format == "json" else None
        self._npz: _NpzLayout | None = None
        if self.format == "npz":
            self._npz = _NpzLayout(self.path)
            self.steps, self.explicit_k = self._npz.T, self._npz.explicit_k

    def __enter__(self) -> RunReader:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        if self._npz is not None:
            self._npz.close()

    def blocks(self, size: int = BLOCK_STEPS) -> Iterator[RunBlock]:
        """The run's steps, checked, in blocks of ``size`` (the last may be shorter)."""
        if self.format == "jsonl":
            yield from self._jsonl_blocks(size)
        elif self.format == "npz":
            assert self._npz is not None
            yield from self._npz.blocks(size)
        else:
            yield RunBlock(np.zeros(1, dtype=np.int64), _single_case_block(self.path), 0)

    def _jsonl_blocks(self, size: int) -> Iterator[RunBlock]:
        state = _JsonlState(self.path)
        pending: list[RunLine] = []
        numbers: list[int] = []
        for number, raw in _lines(self.path):
            record = state.accept(number, raw, pending, numbers)
            self.explicit_k = bool(state.has_k)
            pending.append(record)
            numbers.append(number)
            if len(pending) == size:
                yield state.block(pending, numbers)
                pending, numbers = [], []
        if pending:
            yield state.block(pending, numbers)
        elif state.count == 0:
            raise CaseFileError(f"{self.path} is empty: a run file holds one fusion case (a JSON object) per line")


def open_run(path) -> RunReader:
    """Open a run file (or a single case file, as a run of one step) for reading in blocks.
    Raises :class:`CaseFileError` with one line naming the file."""
    return RunReader(path)


def iter_steps(path, size: int = BLOCK_STEPS) -> Iterator[tuple[int, FusionCase]]:
    """(k, case) for every step of a run file, read a block at a time."""
    with open_run(path) as reader:
        for block in reader.blocks(size):
            yield from block.steps()


def load_run(path) -> RunFile:
    """Read a whole run file (or a single case file, as a run of one step); see the module
    docstring. For long runs prefer :func:`open_run` / :func:`iter_steps`, which never hold the
    whole run. Raises :class:`CaseFileError` with one line naming the file and the line or array."""
    with open_run(path) as reader:
        steps = tuple(step for block in reader.blocks() for step in block.steps())
        return RunFile(str(path), reader.format, steps, reader.explicit_k)


def _one_line(message: object) -> str:
    return " ".join(str(message).split())


def _single_case_block(path: Path) -> CaseBlock:
    from gpfverify.userfiles import read_regular

    raw = read_regular(path)
    try:
        record = decode(raw, CASE_DECODER)
        layout(record)
        return block_from_records([record])
    except CaseFileError as exc:
        raise CaseFileError(f"{path}: {exc}") from None


# ------------------------------------------------------------------------------- JSON Lines

def _lines(path: Path) -> Iterator[tuple[int, bytes]]:
    """(1-based line number, line without its end) of a regular file, read in chunks; a line
    longer than the memory budget allows is refused."""
    limit = max(CHUNK_BYTES, memory_budget() // 8)
    number = 0
    rest = b""
    with open_regular(path) as fh:
        while True:
            chunk = fh.read(CHUNK_BYTES)
            if not chunk:
                break
            parts = (rest + chunk).split(b"\n") if rest else chunk.split(b"\n")
            rest = parts.pop()
            if len(rest) > limit:
                raise CaseFileError(f"{path} line {number + len(parts) + 1} is longer than "
                                    f"{human_bytes(limit)}, more than this machine can decode now")
            for line in parts:
                number += 1
                yield number, line[:-1] if line.endswith(b"\r") else line
    if rest:
        yield number + 1, rest[:-1] if rest.endswith(b"\r") else rest


def _signature_difference(sig, first) -> str:
    names = ("state dimension D", "central.sizes", "angle outputs (central.circular)",
             "angle state components (circular_state)")

    def shown(v):
        return list(v) if isinstance(v, tuple) else v

    for name, a, b in zip(names, sig, first):
        if a != b:
            return f"{name} {shown(a)} differs from line 1's {shown(b)}"
    return "the layout differs from line 1's"  # pragma: no cover


class _JsonlState:
    """The run-level rules of a JSON Lines file, line by line: no blank lines, "k" on every line
    or none and strictly increasing, every line with line 1's layout."""

    def __init__(self, path: Path):
        self.path = path
        self.count = 0
        self.has_k: bool | None = None
        self.last_k: int | None = None
        self.first_layout: tuple | None = None
        self._raw_layout: tuple | None = None

    def _layout(self, record: RunLine):
        """(D, sizes, circular) of a record; the first line's computed once and reused for lines
        that write the same sizes and angle lists."""
        raw = _raw_layout(record)
        if raw == self._raw_layout:
            return self.first_layout
        return layout(record)

    def accept(self, number: int, raw: bytes, pending, numbers) -> RunLine:
        """The decoded line, after the run-level rules; a problem found here is reported after the
        earlier pending lines are checked (the file's first problem wins)."""
        where = f"{self.path} line {number}"

        def refuse(message: str, record: RunLine | None = None):
            if pending:
                self._checked(pending, numbers)  # an earlier line's problem first
            if record is not None:
                self._checked([record], [number])  # then this line's own case problems
            raise CaseFileError(f"{where}: {message}")

        self.count += 1
        if not raw.strip():
            refuse("blank line (blank lines are not allowed in a run file)")
        try:
            record = decode(raw, RUN_LINE_DECODER)
            sig = self._layout(record)
        except CaseFileError as exc:
            refuse(_one_line(exc))
        line_has_k = given(record.k) is not None
        if self.has_k is None:
            self.has_k = line_has_k
        elif line_has_k != self.has_k:
            refuse(("has \"k\" but line 1 does not" if line_has_k else "lacks \"k\" but line 1 has it")
                   + " (give the step index on every line or on none)", record)
        if self.first_layout is None:
            self.first_layout = sig
            self._raw_layout = _raw_layout(record)
        elif sig != self.first_layout:
            refuse(f"{_signature_difference(sig, self.first_layout)} (every step of a run has the same "
                   f"dimensions and angle outputs)", record)
        k = record.k if line_has_k else number - 1
        if self.last_k is not None and k <= self.last_k:
            refuse(f"k = {k} does not increase (previous k = {self.last_k}); step indices must be strictly "
                   f"increasing", record)
        self.last_k = k
        return record

    def _checked(self, records: list[RunLine], numbers: list[int]) -> CaseBlock:
        try:
            return block_from_records(records)
        except StepError as exc:
            raise CaseFileError(f"{self.path} line {numbers[exc.step]}: {_one_line(exc)}") from None

    def block(self, records: list[RunLine], numbers: list[int]) -> RunBlock:
        block = self._checked(records, numbers)
        ks = np.array([r.k if self.has_k else n - 1 for r, n in zip(records, numbers)], dtype=np.int64)
        return RunBlock(ks, block, numbers[0] - 1)


# ------------------------------------------------------------------------------------- npz

#: The .npz layout: name -> (shape in terms of T, D, L, l_m, N; required). ``{m}`` is the
#: 0-based sensor index. docs/run-file-format.md documents the same table.
NPZ_ARRAYS = {
    "sizes": ("(N,)", True),
    "central_mu_p": ("(T, D)", True),
    "central_C_p": ("(T, D, D)", True),
    "central_mu_y": ("(T, L)", True),
    "central_C_y": ("(T, L, L)", True),
    "central_C_xy": ("(T, D, L)", True),
    "local{m}_mu_p": ("(T, D)", True),
    "local{m}_mu_y": ("(T, l_m)", True),
    "local{m}_C_y": ("(T, l_m, l_m)", True),
    "local{m}_C_xy": ("(T, D, l_m)", True),
    "local{m}_mu_e": ("(T, D)", True),
    "local{m}_C_e": ("(T, D, D)", False),
    "circular{m}": ("(n_m,)", False),
    "central_circular": ("(n,)", False),
    "circular_state": ("(n,)", False),
    "y": ("(T, L)", False),
    "k": ("(T,)", False),
    "rank_tol": ("() or (T,)", False),
}

_LOCAL_KEYS = ("mu_p", "mu_y", "C_y", "C_xy", "mu_e", "C_e")
_CENTRAL_KEYS = ("mu_p", "C_p", "mu_y", "C_y", "C_xy")


def _npz_name(message: str) -> str:
    """The case format's entry names as npz array names."""
    message = re.sub(r"locals\[(\d+)\]\.circular", r"circular\1", message)
    message = re.sub(r"locals\[(\d+)\]\.(\w+)", r"local\1_\2", message)
    message = message.replace("central.sizes", "sizes")
    return re.sub(r"central\.(\w+)", r"central_\1", message)


class _NpzLayout:
    """An npz run file whose layout (names, dtypes, shapes from T, D, L and ``sizes``) is checked
    from the array headers alone; the small arrays are read, the stacked ones streamed."""

    def __init__(self, path: Path):
        self.path = path
        self.archive = NpzArchive(path)
        try:
            self._check()
        except BaseException:
            self.archive.close()
            raise

    def close(self) -> None:
        self.archive.close()

    def _kind(self, name: str, integer: bool = False) -> None:
        dtype = self.archive.headers[name].dtype
        if dtype.kind not in ("iu" if integer else "fiu"):
            want = "integers" if integer else "real numbers"
            raise CaseFileError(f"{self.path}: array {name} must hold {want}, got dtype {dtype}")

    def _small(self, name: str, integer: bool = True) -> np.ndarray:
        self._kind(name, integer)
        return self.archive.read(name)

    def _check(self) -> None:
        path, headers = self.path, self.archive.headers
        if "sizes" not in headers and "central_mu_p" not in headers and "y" in headers:
            raise CaseFileError(f"{path} looks like a measurements file for 'gpfverify check --measurements' "
                                "(arrays y and x); audit expects a run file of fusion cases (arrays sizes, "
                                "central_mu_p, ...; docs/run-file-format.md)")
        for name in ("sizes", "central_mu_p"):
            if name not in headers:
                raise CaseFileError(f"{path}: missing array {name}: audit expects a run file of fusion cases "
                                    "(layout in docs/run-file-format.md)")
        if len(headers["sizes"].shape) != 1 or headers["sizes"].shape[0] > 1 << 20:
            raise CaseFileError(f"{path}: array sizes must be (N,) positive integers, got shape "
                                f"{headers['sizes'].shape}")
        sizes_arr = self._small("sizes")
        if sizes_arr.size == 0 or np.any(sizes_arr <= 0):
            raise CaseFileError(f"{path}: array sizes must be (N,) positive integers, got {sizes_arr.tolist()}")
        self.sizes = [int(s) for s in sizes_arr]
        self._kind("central_mu_p")
        shape = headers["central_mu_p"].shape
        if len(shape) != 2 or 0 in shape:
            raise CaseFileError(f"{path}: array central_mu_p has shape {shape}, expected (T, D) with T, D >= 1")
        T, D = shape
        L = sum(self.sizes)
        expected = {"central_mu_p": ((T, D), "(T, D)"), "central_C_p": ((T, D, D), "(T, D, D)"),
                    "central_mu_y": ((T, L), "(T, L)"), "central_C_y": ((T, L, L), "(T, L, L)"),
                    "central_C_xy": ((T, D, L), "(T, D, L)")}
        optional = {"y": ((T, L), "(T, L)"), "k": ((T,), "(T,)")}
        for m, l in enumerate(self.sizes):
            expected.update({f"local{m}_mu_p": ((T, D), "(T, D)"), f"local{m}_mu_y": ((T, l), f"(T, l_{m})"),
                             f"local{m}_C_y": ((T, l, l), f"(T, l_{m}, l_{m})"),
                             f"local{m}_C_xy": ((T, D, l), f"(T, D, l_{m})"), f"local{m}_mu_e": ((T, D), "(T, D)")})
            optional[f"local{m}_C_e"] = ((T, D, D), "(T, D, D)")
        circular_names = ["central_circular"] + [f"circular{m}" for m in range(len(self.sizes))]
        known = set(expected) | set(optional) | {"sizes", "rank_tol", "circular_state"} | set(circular_names)
        unknown = sorted(set(headers) - known)
        if unknown:
            raise CaseFileError(f"{path}: unknown array(s) {', '.join(unknown)} (N = {len(self.sizes)} sensors "
                                f"from sizes; layout in docs/run-file-format.md)")
        for name, (_, what) in expected.items():
            if name not in headers:
                raise CaseFileError(f"{path}: missing array {name} {what} (layout in docs/run-file-format.md)")
        for name, (want, what) in {**expected, **{k: v for k, v in optional.items() if k in headers}}.items():
            self._kind(name, integer=name == "k")
            if headers[name].shape != want:
                raise CaseFileError(f"{path}: array {name} has shape {headers[name].shape}, expected {what} = "
                                    f"{want}")
        self.T, self.explicit_k = T, "k" in headers
        # per-step arrays (k, a rank_tol per step) are streamed with the rest: nothing read here
        # grows with T
        self.rank_tol: float | None = np.nan
        if "rank_tol" in headers:
            self._kind("rank_tol")
            if headers["rank_tol"].shape not in ((), (T,)):
                raise CaseFileError(f"{path}: array rank_tol has shape {headers['rank_tol'].shape}, expected () "
                                    f"or (T,) = ({T},)")
            self.rank_tol = float(self.archive.read("rank_tol")) if headers["rank_tol"].shape == () else None
        given_circular = {}
        for name in circular_names:
            if name in headers:
                if len(headers[name].shape) != 1 or headers[name].shape[0] > L:
                    raise CaseFileError(f"{path}: array {name} must be a list of at most {L} output indices, "
                                        f"got shape {headers[name].shape}")
                given_circular[name] = [int(i) for i in self._small(name)]
        try:
            self.circular = _npz_circular(given_circular, self.sizes)
            self.circular_state: tuple[int, ...] = ()
            if "circular_state" in headers:
                if len(headers["circular_state"].shape) != 1 or headers["circular_state"].shape[0] > D:
                    raise CaseFileError(f"array circular_state must be a list of at most {D} state indices, "
                                        f"got shape {headers['circular_state'].shape}")
                self.circular_state = checked_indices([int(i) for i in self._small("circular_state")], D,
                                                      "circular_state") or ()
        except CaseFileError as exc:
            raise CaseFileError(f"{path}: {_npz_name(_one_line(exc))}") from None
        self.streamed = [n for n in headers if n in expected or n in optional or (n == "rank_tol"
                                                                                  and self.rank_tol is None)]

    def _step_indices(self, k: np.ndarray, start: int, previous: int | None) -> np.ndarray:
        """The block's given step indices (entries ``start`` on of array k), checked: >= 0 and
        increasing from ``previous``, the last block's last."""
        if np.any(k < 0):
            raise CaseFileError(f"{self.path}: array k must hold step indices >= 0, got {int(k.min())}")
        joined = k if previous is None else np.concatenate([[previous], k])
        down = np.flatnonzero(np.diff(joined) <= 0)
        if down.size:
            i = int(down[0]) + 1
            raise CaseFileError(f"{self.path}: array k entry {start + i - (previous is not None)}: k = "
                                f"{int(joined[i])} does not increase (previous k = {int(joined[i - 1])}); step "
                                "indices must be strictly increasing")
        return k.astype(np.int64)

    def blocks(self, size: int) -> Iterator[RunBlock]:
        readers = {n: self.archive.row_reader(n) for n in self.streamed}
        previous = None
        try:
            for start in range(0, self.T, size):
                rows = {n: r.take(size) for n, r in readers.items()}
                stop = start + len(rows["central_mu_p"])
                ks = (self._step_indices(rows["k"], start, previous) if self.explicit_k
                      else np.arange(start, stop, dtype=np.int64))
                previous = int(ks[-1])
                rank_tol = (rows["rank_tol"].astype(float) if self.rank_tol is None
                            else np.full(stop - start, self.rank_tol))
                central = {key: rows[f"central_{key}"] for key in _CENTRAL_KEYS}
                local = [{key: rows.get(f"local{m}_{key}") for key in _LOCAL_KEYS} for m in range(len(self.sizes))]
                try:
                    block = block_from_arrays(self.sizes, self.circular, central, local, rows.get("y"),
                                              rank_tol, self.circular_state)
                except StepError as exc:
                    raise CaseFileError(f"{self.path} step {start + exc.step} (k = {int(ks[exc.step])}): "
                                        f"{_npz_name(_one_line(exc))}") from None
                yield RunBlock(ks, block, start)
        finally:
            for r in readers.values():
                r.close()


def _npz_circular(given_circular: dict[str, list[int]], sizes: list[int]) -> tuple[int, ...]:
    central = given_circular.get("central_circular")
    central_t = None if central is None else checked_indices(central, sum(sizes), "central.circular")
    per_sensor = [None if f"circular{m}" not in given_circular else
                  checked_indices(given_circular[f"circular{m}"], s, f"locals[{m}].circular")
                  for m, s in enumerate(sizes)]
    return agreed_circular(central_t, per_sensor, sizes)


# ----------------------------------------------------------------------------------- writing

def _checked_ks(ks, count: int) -> list[int] | None:
    if ks is None:
        return None
    ks = list(ks)
    if len(ks) != count:
        raise InputError(f"ks has {len(ks)} entries for {count} cases")
    if not all(isinstance(k, (int, np.integer)) and not isinstance(k, bool) and k >= 0 for k in ks):
        raise InputError(f"ks must be integers >= 0, got {ks}")
    ks = [int(k) for k in ks]
    if any(b <= a for a, b in zip(ks, ks[1:])):
        raise InputError(f"ks must be strictly increasing, got {ks}")
    return ks


def _atomic_write(path: Path, write) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    mask = os.umask(0)
    os.umask(mask)
    try:
        os.fchmod(fd, 0o666 & ~mask)  # as open() would create it, not mkstemp's 0600
        with os.fdopen(fd, "wb") as fh:
            write(fh)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def write_run(path, cases: Iterable[FusionCase], ks: Sequence[int] | None = None) -> Path:
    """Write fusion cases as a run file that :func:`load_run` reads back: JSON Lines for ``.jsonl``
    / ``.ndjson`` (one ``case_to_dict`` object per line, ``"k"`` first when ``ks`` is given), the
    array layout for ``.npz`` (every case with the same dimensions; C_e per sensor at every step
    or none). ``ks``: strictly increasing step indices >= 0 (default: none written, so k reads
    back as the position). Written atomically; returns the path."""
    path = Path(path)
    cases = list(cases)
    if not cases:
        raise InputError("write_run needs at least one case")
    ks = _checked_ks(ks, len(cases))
    fmt = run_format(path)
    if fmt == "jsonl":
        def write(fh):
            for t, case in enumerate(cases):
                obj = case_to_dict(case) if ks is None else {"k": ks[t], **case_to_dict(case)}
                fh.write(json.dumps(obj, allow_nan=False).encode("utf-8") + b"\n")
    elif fmt == "npz":
        arrays = _npz_arrays(cases, ks)

        def write(fh):
            np.savez_compressed(fh, **arrays)
    else:
        raise InputError(f"write_run writes .jsonl, .ndjson or .npz files, not {path.name}")
    _atomic_write(path, write)
    return path


def _whole(case: FusionCase):
    """The centre's prediction of every sensor of the run (also of those that did not report)."""
    return case.missing.central if case.missing is not None else case.central


def _raw_layout(record: RunLine) -> tuple:
    """What a line writes of its layout (D, sizes, angle lists), compared before it is checked."""
    return (len(record.central.mu_p), record.central.sizes, given(record.central.circular),
            [None if r is None else given(r.circular) for r in record.locals], given(record.circular_state))


def _shape_signature(case: FusionCase) -> tuple:
    whole = _whole(case)
    return case.state_dim, tuple(whole.sizes), tuple(whole.circular), tuple(case.circular_state)


def _npz_arrays(cases: list[FusionCase], ks) -> dict[str, np.ndarray]:
    first = _shape_signature(cases[0])
    for t, case in enumerate(cases):
        if _shape_signature(case) != first:
            raise InputError(f"case {t} has other dimensions or angle outputs than case 0: "
                             f"{_shape_signature(case)} vs {first}")
    whole = _whole(cases[0])
    sizes = whole.sizes
    out = {"sizes": np.array(sizes, dtype=np.int64)}
    for key in ("mu_p", "C_p", "mu_y", "C_y", "C_xy"):
        out[f"central_{key}"] = np.stack([getattr(_whole(c), key) for c in cases])
    # each case's reports by sensor index; a sensor that did not report: NaN rows (docs/run-file-format.md)
    reports = [dict(zip(c.sensor_ids, c.locals)) for c in cases]
    d = cases[0].state_dim
    circulars = split_circular(whole.circular, sizes)
    for m, l in enumerate(sizes):
        shapes: dict[str, tuple[int, ...]] = {"mu_p": (d,), "mu_y": (l,), "C_y": (l, l), "C_xy": (d, l), "mu_e": (d,)}
        for key in _LOCAL_KEYS[:-1]:
            out[f"local{m}_{key}"] = np.stack([getattr(r[m], key) if m in r else np.full(shapes[key], np.nan)
                                               for r in reports])
        c_e = [r[m].C_e for r in reports if m in r]
        given = [v for v in c_e if v is not None]
        if given and len(given) == len(c_e):
            out[f"local{m}_C_e"] = np.stack([np.full((d, d), np.nan) if m not in r else np.asarray(r[m].C_e)
                                             for r in reports])
        elif given:
            raise InputError(f"locals[{m}].C_e must be given at every step or at none for an npz run file")
        if circulars[m]:
            out[f"circular{m}"] = np.array(circulars[m], dtype=np.int64)
    if cases[0].circular_state:
        out["circular_state"] = np.array(cases[0].circular_state, dtype=np.int64)
    if any(c.y is not None for c in cases):
        nan = np.full(sum(sizes), np.nan)
        out["y"] = np.stack([nan if c.y is None else full_y(c) for c in cases])
    tols = [c.rank_tol for c in cases]
    if any(v is not None for v in tols):
        out["rank_tol"] = (np.array(tols[0]) if len(set(tols)) == 1
                           else np.array([np.nan if v is None else v for v in tols]))
    if ks is not None:
        out["k"] = np.array(ks, dtype=np.int64)
    return out
