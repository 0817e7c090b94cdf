"""Run files: many fusion steps in one file (CONTRACT.md, "Run files"; for users:
docs/run-file-format.md).

Three forms, chosen by the file's suffix (case-insensitive):

* ``.jsonl`` (or ``.ndjson``): JSON Lines, one fusion case per line as in the case format
  (docs/fusion-case-format.md) plus an optional integer ``"k"`` (the step index). Every line is
  checked against :data:`RUN_LINE_SCHEMA` (docs/schemas/run-line.schema.json) and then by
  :func:`~gpfverify.fusion.case.case_from_dict`; blank lines are refused.
* ``.npz``: the same quantities as arrays stacked over the T steps (``central_mu_p`` (T, D), …,
  ``local{m}_C_xy`` (T, D, l_m), ``sizes`` (N,), optional ``y``, ``k``, ``rank_tol``,
  ``circular{m}``); see :data:`NPZ_ARRAYS` and docs/run-file-format.md.
* anything else: one fusion case (``.json``), read by :func:`~gpfverify.fusion.case.load_case`
  exactly as before, as a run of one step.

Every problem raises :class:`~gpfverify.errors.CaseFileError` with one line that names the file
and the line (jsonl) or the array and step (npz). :func:`write_run` writes the jsonl and npz
forms. This module imports numpy and the case reader only.
"""

from __future__ import annotations

import json
import math
import os
import re
import tempfile
import zipfile
from dataclasses import dataclass
from typing import Any
from pathlib import Path
from collections.abc import Iterable, Sequence

import numpy as np

from gpfverify.errors import CaseFileError, InputError
from gpfverify.fusion.case import FusionCase, case_from_dict, case_to_dict, load_case

JSONL_SUFFIXES = (".jsonl", ".ndjson")
NPZ_SUFFIXES = (".npz",)

# --------------------------------------------------------------------------------------------
# JSON Schemas (the source of docs/schemas/*.json; tests check that the files equal these)
# --------------------------------------------------------------------------------------------

_SCHEMA_URI = "https://json-schema.org/draft/2020-12/schema"

_DEFS = {
    "number": {"type": "number", "description": "a finite number (NaN and Infinity are not JSON)"},
    "vector": {"type": "array", "minItems": 1, "items": {"$ref": "#/$defs/number"}},
    "matrix": {"type": "array", "minItems": 1, "items": {"$ref": "#/$defs/vector"},
               "description": "list of rows"},
    "indices": {"type": ["array", "null"], "uniqueItems": True,
                "items": {"type": "integer", "minimum": 0},
                "description": "0-based output indices of angle outputs (radians)"},
    "central": {
        "type": "object",
        "required": ["mu_p", "C_p", "mu_y", "C_y", "C_xy", "sizes"],
        "properties": {
            "mu_p": {"$ref": "#/$defs/vector", "description": "(D,)"},
            "C_p": {"$ref": "#/$defs/matrix", "description": "(D, D)"},
            "mu_y": {"$ref": "#/$defs/vector", "description": "(L,), stacked in sensor order"},
            "C_y": {"$ref": "#/$defs/matrix", "description": "(L, L), positive definite"},
            "C_xy": {"$ref": "#/$defs/matrix", "description": "(D, L)"},
            "sizes": {"type": "array", "minItems": 1, "items": {"type": "integer", "minimum": 1},
                      "description": "l_1, ..., l_N (sum L)"},
            "circular": {"$ref": "#/$defs/indices", "description": "indices into the stacked measurement"},
        },
    },
    "local": {
        "type": "object",
        "required": ["mu_p", "mu_y", "C_y", "C_xy", "mu_e"],
        "properties": {
            "mu_p": {"$ref": "#/$defs/vector", "description": "(D,)"},
            "mu_y": {"$ref": "#/$defs/vector", "description": "(l_m,)"},
            "C_y": {"$ref": "#/$defs/matrix", "description": "(l_m, l_m), positive definite"},
            "C_xy": {"$ref": "#/$defs/matrix", "description": "(D, l_m)"},
            "mu_e": {"$ref": "#/$defs/vector", "description": "(D,), the sensor's posterior mean"},
            "C_e": {"type": ["array", "null"], "minItems": 1, "items": {"$ref": "#/$defs/vector"},
                    "description": "(D, D), optional posterior covariance"},
            "circular": {"$ref": "#/$defs/indices", "description": "indices into the sensor's own outputs"},
        },
    },
}

_CASE_PROPERTIES = {
    "central": {"$ref": "#/$defs/central"},
    "locals": {"type": "array", "minItems": 1, "items": {"$ref": "#/$defs/local"},
               "description": "one entry per sensor, in the order of central.sizes"},
    "y": {"type": ["array", "null"], "minItems": 1, "items": {"$ref": "#/$defs/number"},
          "description": "(L,), optional stacked raw measurement"},
    "rank_tol": {"type": ["number", "null"], "minimum": 0,
                 "description": "optional absolute singular-value tolerance for rank(C_xy^m)"},
}

_SHAPES_NOTE = ("Structure only: the shapes implied by D and central.sizes, symmetry and positive "
                "(semi)definiteness, finiteness and the agreement of central/locals circular are "
                "checked by gpfverify.fusion.case_from_dict. Keys not listed here are ignored.")

#: JSON Schema of one fusion case (docs/schemas/fusion-case.schema.json).
CASE_SCHEMA = {
    "$schema": _SCHEMA_URI,
    "title": "gpfverify fusion case",
    "description": "One fusion step (docs/fusion-case-format.md). " + _SHAPES_NOTE,
    "type": "object",
    "required": ["central", "locals"],
    "properties": _CASE_PROPERTIES,
    "$defs": _DEFS,
}

#: JSON Schema of one line of a .jsonl run file (docs/schemas/run-line.schema.json).
RUN_LINE_SCHEMA = {
    "$schema": _SCHEMA_URI,
    "title": "gpfverify run-file line",
    "description": ("One line of a JSON Lines run file (docs/run-file-format.md): a fusion case plus an "
                    "optional step index k. " + _SHAPES_NOTE),
    "type": "object",
    "required": ["central", "locals"],
    "properties": {**_CASE_PROPERTIES,
                   "k": {"type": "integer", "minimum": 0,
                         "description": "step index; given on every line or on none, strictly increasing"}},
    "$defs": _DEFS,
}

_ANNOTATIONS = {"$schema", "$id", "title", "description", "$comment", "$defs"}
_SUPPORTED = _ANNOTATIONS | {"$ref", "type", "properties", "required", "items", "minItems", "minimum",
                             "uniqueItems"}
_TYPE_NAMES = {dict: "an object", list: "an array", str: "a string", bool: "a boolean",
               type(None): "null", int: "an integer", float: "a number"}


def _is_type(value, name: str) -> bool:
    if name == "number":
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if name == "integer":  # stricter than JSON Schema (1.0 is refused), as case_from_dict is
        return isinstance(value, int) and not isinstance(value, bool)
    return isinstance(value, {"object": dict, "array": list, "string": str, "boolean": bool,
                              "null": type(None)}[name])


def _resolve(root: dict, ref: str) -> dict:
    if not ref.startswith("#/$defs/"):
        raise ValueError(f"unsupported $ref {ref!r}")
    return root["$defs"][ref[len("#/$defs/"):]]


def _validate(value, schema: dict, root: dict, where: str) -> None:
    unknown = set(schema) - _SUPPORTED
    if unknown:
        raise ValueError(f"schema keyword(s) {sorted(unknown)} not supported by this validator")
    if "$ref" in schema:
        _validate(value, _resolve(root, schema["$ref"]), root, where)
    if "type" in schema:
        types = schema["type"] if isinstance(schema["type"], list) else [schema["type"]]
        if not any(_is_type(value, t) for t in types):
            want = " or ".join({"number": "a number", "integer": "an integer", "object": "an object",
                                "array": "a list", "null": "null", "string": "a string",
                                "boolean": "a boolean"}[t] for t in types)
            got = _TYPE_NAMES.get(type(value), type(value).__name__)
            shown = "" if isinstance(value, (dict, list)) else f" {json.dumps(value)[:40]}"
            raise CaseFileError(f"{where} must be {want}, got {got}{shown}")
    if isinstance(value, dict):
        for key in schema.get("required", ()):
            if key not in value:
                raise CaseFileError(f"{where} lacks the key '{key}'")
        for key, sub in schema.get("properties", {}).items():
            if key in value:
                _validate(value[key], sub, root, f"{where}.{key}" if where != "the line" else key)
    elif isinstance(value, list):
        if len(value) < schema.get("minItems", 0):
            raise CaseFileError(f"{where} must have at least {schema['minItems']} entr"
                                f"{'y' if schema['minItems'] == 1 else 'ies'}, got {len(value)}")
        if schema.get("uniqueItems") and len({json.dumps(v) for v in value}) != len(value):
            raise CaseFileError(f"{where} lists an entry twice: {json.dumps(value)[:60]}")
        if "items" in schema:
            for i, v in enumerate(value):
                _validate(v, schema["items"], root, f"{where}[{i}]")
    elif _is_type(value, "number") and "minimum" in schema and value < schema["minimum"]:
        raise CaseFileError(f"{where} must be >= {schema['minimum']}, got {value!r}")


def validate_against_schema(data, schema: dict = RUN_LINE_SCHEMA) -> None:
    """Check decoded JSON against one of this module's schemas; raises :class:`CaseFileError`
    naming the entry (``locals[1].C_y[0][1] must be a number, got a string "a"``).

    A small validator for the keywords these schemas use ($ref into $defs, type, properties,
    required, items, minItems, minimum, uniqueItems); it refuses a schema with any other keyword.
    Unlike JSON Schema, an integer must be written without a fraction (``2``, not ``2.0``)."""
    _validate(data, schema, schema, "the line")


# --------------------------------------------------------------------------------------------
# The loaded run
# --------------------------------------------------------------------------------------------

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


def load_run(path) -> RunFile:
    """Read a run file (or a single case file, as a run of one step); see the module docstring.
    Raises :class:`CaseFileError` with one line naming the file and the line or array."""
    fmt = run_format(path)
    if fmt == "jsonl":
        return _load_jsonl(Path(path))
    if fmt == "npz":
        return _load_npz(Path(path))
    return RunFile(str(path), "json", ((0, load_case(path)),), False)


def _one_line(message: object) -> str:
    return " ".join(str(message).split())


def _read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as exc:
        raise CaseFileError(f"cannot read {path}: {exc.strerror or exc}") from None


def _check_ks(ks: Sequence[int], name) -> None:
    for i in range(1, len(ks)):
        if ks[i] <= ks[i - 1]:
            raise CaseFileError(f"{name(i)}: k = {ks[i]} does not increase (previous k = {ks[i - 1]}); "
                                f"step indices must be strictly increasing")


# ------------------------------------------------------------------------------- JSON Lines

def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"the number {text} is outside the float range")
    return value


def _float_int(text: str) -> int:
    value = int(text)
    try:
        float(value)
    except OverflowError:
        raise ValueError(f"the integer {text[:20]}... is outside the float range") from None
    return value


def _no_constant(text: str):
    raise ValueError(f"{text} is not valid JSON (numbers must be finite)")


def _decode_line(raw: bytes):
    """One line as JSON: strict UTF-8, finite numbers only."""
    text = raw.decode("utf-8")  # UnicodeDecodeError handled by the caller
    return json.loads(text, parse_float=_finite_float, parse_int=_float_int, parse_constant=_no_constant)


def _shape_signature(case: FusionCase) -> tuple:
    return case.state_dim, tuple(case.central.sizes), tuple(case.central.circular)


def _load_jsonl(path: Path) -> RunFile:
    data = _read_bytes(path)
    if not data.strip():
        raise CaseFileError(f"{path} is empty: a run file holds one fusion case (a JSON object) per line")
    lines = data.split(b"\n")
    if lines[-1] == b"":  # the final line's terminator, not a blank line
        lines.pop()
    steps, first_sig, has_k = [], None, None
    for n, raw in enumerate(lines, start=1):
        where = f"{path} line {n}"
        if not raw.strip():
            raise CaseFileError(f"{where}: blank line (blank lines are not allowed in a run file)")
        try:
            obj = _decode_line(raw)
        except UnicodeDecodeError as exc:
            raise CaseFileError(f"{where}: not valid UTF-8 (byte 0x{raw[exc.start]:02x} at column "
                                f"{exc.start + 1})") from None
        except json.JSONDecodeError as exc:
            raise CaseFileError(f"{where}: not valid JSON: {exc.msg} at column {exc.colno}") from None
        except (ValueError, RecursionError) as exc:
            raise CaseFileError(f"{where}: {_one_line(exc) if isinstance(exc, ValueError) else 'nested too deeply'}") \
                from None
        if not isinstance(obj, dict):
            got = _TYPE_NAMES.get(type(obj), type(obj).__name__)
            raise CaseFileError(f"{where}: must be a JSON object (one fusion case), got {got}")
        try:
            validate_against_schema(obj, RUN_LINE_SCHEMA)
            case = case_from_dict(obj)
        except InputError as exc:
            raise CaseFileError(f"{where}: {_one_line(exc)}") from None
        line_has_k = "k" in obj
        if has_k is None:
            has_k = line_has_k
        elif line_has_k != has_k:
            raise CaseFileError(f"{where}: " + ("has \"k\" but line 1 does not" if line_has_k else
                                                 "lacks \"k\" but line 1 has it")
                                + " (give the step index on every line or on none)")
        sig = _shape_signature(case)
        if first_sig is None:
            first_sig = sig
        elif sig != first_sig:
            raise CaseFileError(f"{where}: {_signature_difference(sig, first_sig)} (every step of a "
                                f"run has the same dimensions and angle outputs)")
        steps.append((obj["k"] if has_k else n - 1, case))
    _check_ks([k for k, _ in steps], lambda i: f"{path} line {i + 1}")
    return RunFile(str(path), "jsonl", tuple(steps), bool(has_k))


def _signature_difference(sig, first) -> str:
    names = ("state dimension D", "central.sizes", "angle outputs (central.circular)")
    def shown(v):
        return list(v) if isinstance(v, tuple) else v

    for name, a, b in zip(names, sig, first):
        if a != b:
            return f"{name} {shown(a)} differs from line 1's {shown(b)}"
    return "the layout differs from line 1's"  # pragma: no cover


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
    "y": ("(T, L)", False),
    "k": ("(T,)", False),
    "rank_tol": ("() or (T,)", False),
}

_LOCAL_KEYS = ("mu_p", "mu_y", "C_y", "C_xy", "mu_e", "C_e")


def _npz_name(message: str) -> str:
    """case_from_dict's entry names as npz array names."""
    message = re.sub(r"locals\[(\d+)\]\.circular", r"circular\1", message)
    message = re.sub(r"locals\[(\d+)\]\.(\w+)", r"local\1_\2", message)
    message = message.replace("central.sizes", "sizes")
    return re.sub(r"central\.(\w+)", r"central_\1", message)


def _read_npz(path: Path) -> dict[str, np.ndarray]:
    if not path.is_file():
        _read_bytes(path)  # the OS's reason
        raise CaseFileError(f"cannot read {path}")
    if not zipfile.is_zipfile(path):
        raise CaseFileError(f"{path} is not an npz archive (numpy.savez / numpy.savez_compressed)")
    try:
        archive = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise CaseFileError(f"{path} is not a readable npz archive: {_one_line(exc)}") from None
    if not isinstance(archive, np.lib.npyio.NpzFile):
        raise CaseFileError(f"{path} is not an npz archive (numpy.savez / numpy.savez_compressed)")
    arrays = {}
    with archive:
        for name in archive.files:
            try:
                arrays[name] = archive[name]
            except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, NotImplementedError) as exc:
                raise CaseFileError(f"{path}: array {name} cannot be read: {_one_line(exc)}") from None
    return arrays


def _numeric(path, name: str, arr: np.ndarray, integer: bool = False) -> np.ndarray:
    kinds = "iu" if integer else "fiu"
    if arr.dtype.kind not in kinds:
        want = "integers" if integer else "real numbers"
        raise CaseFileError(f"{path}: array {name} must hold {want}, got dtype {arr.dtype}")
    return arr


def _shaped(path, name: str, arr: np.ndarray, shape: tuple, what: str) -> np.ndarray:
    _numeric(path, name, arr)
    if arr.shape != shape:
        raise CaseFileError(f"{path}: array {name} has shape {arr.shape}, expected {what} = {shape}")
    return arr


def _load_npz(path: Path) -> RunFile:
    arrays = _read_npz(path)
    for name in ("sizes", "central_mu_p"):
        if name not in arrays:
            raise CaseFileError(f"{path}: missing array {name} (layout in docs/run-file-format.md)")
    sizes_arr = _numeric(path, "sizes", arrays["sizes"], integer=True)
    if sizes_arr.ndim != 1 or sizes_arr.size == 0 or np.any(sizes_arr <= 0):
        raise CaseFileError(f"{path}: array sizes must be (N,) positive integers, got {sizes_arr.tolist()}")
    sizes = [int(s) for s in sizes_arr]
    mu_p = _numeric(path, "central_mu_p", arrays["central_mu_p"])
    if mu_p.ndim != 2 or 0 in mu_p.shape:
        raise CaseFileError(f"{path}: array central_mu_p has shape {mu_p.shape}, expected (T, D) with "
                            f"T, D >= 1")
    T, D = mu_p.shape
    L = sum(sizes)
    expected = {"central_mu_p": ((T, D), "(T, D)"), "central_C_p": ((T, D, D), "(T, D, D)"),
                "central_mu_y": ((T, L), "(T, L)"), "central_C_y": ((T, L, L), "(T, L, L)"),
                "central_C_xy": ((T, D, L), "(T, D, L)")}
    optional = {"y": ((T, L), "(T, L)"), "k": ((T,), "(T,)")}
    for m, l in enumerate(sizes):
        expected.update({f"local{m}_mu_p": ((T, D), "(T, D)"), f"local{m}_mu_y": ((T, l), f"(T, l_{m})"),
                         f"local{m}_C_y": ((T, l, l), f"(T, l_{m}, l_{m})"),
                         f"local{m}_C_xy": ((T, D, l), f"(T, D, l_{m})"), f"local{m}_mu_e": ((T, D), "(T, D)")})
        optional[f"local{m}_C_e"] = ((T, D, D), "(T, D, D)")
    known = set(expected) | set(optional) | {"sizes", "rank_tol", "central_circular"} \
        | {f"circular{m}" for m in range(len(sizes))}
    unknown = sorted(set(arrays) - known)
    if unknown:
        raise CaseFileError(f"{path}: unknown array(s) {', '.join(unknown)} (N = {len(sizes)} sensors from "
                            f"sizes; layout in docs/run-file-format.md)")
    for name, (shape, what) in expected.items():
        if name not in arrays:
            raise CaseFileError(f"{path}: missing array {name} {what} (layout in docs/run-file-format.md)")
        _shaped(path, name, arrays[name], shape, what)
    for name, (shape, what) in optional.items():
        if name in arrays:
            _shaped(path, name, arrays[name], shape, what)
    ks, explicit = list(range(T)), "k" in arrays
    if explicit:
        k = _numeric(path, "k", arrays["k"], integer=True)
        if np.any(k < 0):
            raise CaseFileError(f"{path}: array k must hold step indices >= 0, got {int(k.min())}")
        ks = [int(v) for v in k]
        _check_ks(ks, lambda i: f"{path}: array k entry {i}")
    rank_tol: list[float | None] = [None] * T
    if "rank_tol" in arrays:
        tol = _numeric(path, "rank_tol", arrays["rank_tol"]).astype(float)
        if tol.shape not in ((), (T,)):
            raise CaseFileError(f"{path}: array rank_tol has shape {tol.shape}, expected () or (T,) = ({T},)")
        rank_tol = [None if np.isnan(v) else float(v) for v in np.broadcast_to(tol, (T,))]
    circular = {}
    for name in ["central_circular"] + [f"circular{m}" for m in range(len(sizes))]:
        if name in arrays:
            arr = _numeric(path, name, arrays[name], integer=True)
            if arr.ndim != 1:
                raise CaseFileError(f"{path}: array {name} must be one-dimensional, got shape {arr.shape}")
            circular[name] = [int(i) for i in arr]
    steps = []
    for t in range(T):
        central = {key: arrays[f"central_{key}"][t] for key in ("mu_p", "C_p", "mu_y", "C_y", "C_xy")}
        data: dict[str, Any] = {"central": central, "locals": [], "rank_tol": rank_tol[t]}
        data["central"]["sizes"] = list(sizes)
        if "central_circular" in circular:
            data["central"]["circular"] = circular["central_circular"]
        for m in range(len(sizes)):
            local = {key: arrays[f"local{m}_{key}"][t] for key in _LOCAL_KEYS if f"local{m}_{key}" in arrays}
            if f"circular{m}" in circular:
                local["circular"] = circular[f"circular{m}"]
            data["locals"].append(local)
        if "y" in arrays:
            row = arrays["y"][t]
            if not np.all(np.isnan(row)):
                data["y"] = row
        try:
            case = case_from_dict(data)
        except InputError as exc:
            raise CaseFileError(f"{path} step {t} (k = {ks[t]}): {_npz_name(_one_line(exc))}") from None
        steps.append((ks[t], case))
    return RunFile(str(path), "npz", tuple(steps), explicit)


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


def _npz_arrays(cases: list[FusionCase], ks) -> dict[str, np.ndarray]:
    first = _shape_signature(cases[0])
    for t, case in enumerate(cases):
        if _shape_signature(case) != first:
            raise InputError(f"case {t} has other dimensions or angle outputs than case 0: "
                             f"{_shape_signature(case)} vs {first}")
    sizes = cases[0].central.sizes
    out = {"sizes": np.array(sizes, dtype=np.int64)}
    for key in ("mu_p", "C_p", "mu_y", "C_y", "C_xy"):
        out[f"central_{key}"] = np.stack([getattr(c.central, key) for c in cases])
    for m in range(len(sizes)):
        for key in _LOCAL_KEYS[:-1]:
            out[f"local{m}_{key}"] = np.stack([getattr(c.locals[m], key) for c in cases])
        c_e = [c.locals[m].C_e for c in cases]
        given = [v for v in c_e if v is not None]
        if len(given) == len(c_e):
            out[f"local{m}_C_e"] = np.stack(given)
        elif given:
            raise InputError(f"locals[{m}].C_e must be given at every step or at none for an npz run file")
        if cases[0].locals[m].circular:
            out[f"circular{m}"] = np.array(cases[0].locals[m].circular, dtype=np.int64)
    if any(c.y is not None for c in cases):
        nan = np.full(sum(sizes), np.nan)
        out["y"] = np.stack([nan if c.y is None else c.y for c in cases])
    tols = [c.rank_tol for c in cases]
    if any(v is not None for v in tols):
        out["rank_tol"] = (np.array(tols[0]) if len(set(tols)) == 1
                           else np.array([np.nan if v is None else v for v in tols]))
    if ks is not None:
        out["k"] = np.array(ks, dtype=np.int64)
    return out
