"""The JSON form of a fusion case and of a run-file line: typed records decoded by msgspec, and
the JSON Schemas generated from the same types (docs/schemas/; a test compares the files with
:func:`case_schema` and :func:`run_line_schema`, so reader and schema cannot drift).

Decoding is strict (docs/fusion-case-format.md, "Numbers" and "Keys"):

* numbers are JSON numbers: strings, booleans, ``null`` in place of a number (except in the
  block of ``y`` of a sensor that did not report, whose ``locals`` entry is ``null``), ``NaN`` and
  ``Infinity`` are refused, and so is any magnitude above :data:`MAX_MAGNITUDE` (an integer
  literal of any length included; ``1e999`` is out of the float range);
* integers (``sizes``, ``circular``, ``k``) are written without a fraction;
* unknown keys are refused (a misspelt optional key such as ``"Y"`` would otherwise be lost
  silently), and so are duplicate keys (JSON parsers disagree on which one wins);
* nesting is fixed by the types, so deeply nested input is refused at its first wrong level.

Every refusal is a :class:`~gpfverify.errors.CaseFileError` naming the entry
(``locals[1].C_xy[0][2] must be a number, got a string``). The shapes implied by D and
``sizes``, symmetry, definiteness and the agreement of the angle outputs are checked afterwards,
on arrays stacked over steps (:mod:`gpfverify.fusion.caseblock`).
"""

from __future__ import annotations

import json
import re
from typing import Annotated

import msgspec
from msgspec import UNSET, Meta, Struct, UnsetType

from gpfverify.errors import CaseFileError

#: largest magnitude accepted for a number in a case file: squares and quadratic forms of such
#: entries stay inside the float range (tests/test_error_boundary.py)
MAX_MAGNITUDE = 1e100
#: largest step index (it must fit the int64 ``k`` array of an npz run file)
MAX_K = 2**63 - 1

Number = Annotated[float, Meta(ge=-MAX_MAGNITUDE, le=MAX_MAGNITUDE,
                               description="a finite number of magnitude at most 1e100")]
Vector = Annotated[list[Number], Meta(min_length=1)]
Matrix = Annotated[list[Vector], Meta(min_length=1)]
Index = Annotated[int, Meta(ge=0)]
StackedIndices = Annotated[list[Index], Meta(description="0-based indices of angle outputs (radians) into the "
                                                         "stacked measurement; distinct")]
SensorIndices = Annotated[list[Index], Meta(description="0-based indices of angle outputs (radians) into the "
                                                        "sensor's own outputs; distinct")]
StateIndices = Annotated[list[Index], Meta(description="0-based indices of angle components (radians) of the "
                                                       "state; distinct")]
OptionalCovariance = Annotated[Matrix, Meta(description="(D, D), optional posterior covariance, a list of rows")]


class Central(Struct, forbid_unknown_fields=True):
    """The fusion centre's prediction, measurement moments stacked in sensor order."""

    mu_p: Annotated[Vector, Meta(description="(D,)")]
    C_p: Annotated[Matrix, Meta(description="(D, D), positive semidefinite, a list of rows")]
    mu_y: Annotated[Vector, Meta(description="(L,), stacked in sensor order")]
    C_y: Annotated[Matrix, Meta(description="(L, L), positive definite, a list of rows")]
    C_xy: Annotated[Matrix, Meta(description="(D, L), a list of rows")]
    sizes: Annotated[list[Annotated[int, Meta(ge=1)]],
                     Meta(min_length=1, description="l_1, ..., l_N (sum L)")]
    circular: StackedIndices | None | UnsetType = UNSET


class Local(Struct, forbid_unknown_fields=True):
    """What sensor m sends."""

    mu_p: Annotated[Vector, Meta(description="(D,), the sensor's prediction")]
    mu_y: Annotated[Vector, Meta(description="(l_m,)")]
    C_y: Annotated[Matrix, Meta(description="(l_m, l_m), positive definite, a list of rows")]
    C_xy: Annotated[Matrix, Meta(description="(D, l_m), a list of rows")]
    mu_e: Annotated[Vector, Meta(description="(D,), the sensor's posterior mean")]
    C_e: OptionalCovariance | None | UnsetType = UNSET
    circular: SensorIndices | None | UnsetType = UNSET


class Case(Struct, forbid_unknown_fields=True):
    """One fusion step (docs/fusion-case-format.md)."""

    central: Central
    locals: Annotated[list[Local | None], Meta(min_length=1, description="one entry per sensor, in the order of "
                                                                         "central.sizes; null for a sensor that "
                                                                         "did not report at this step")]
    y: Annotated[list[Number | None], Meta(min_length=1, description="(L,), optional stacked raw measurement; "
                                                                     "null in the block of a sensor that did "
                                                                     "not report")] | None | UnsetType = UNSET
    rank_tol: Annotated[float, Meta(ge=0, le=MAX_MAGNITUDE, description="optional absolute singular-value "
                                                                        "tolerance for rank(C_xy^m)")] \
        | None | UnsetType = UNSET
    circular_state: StateIndices | None | UnsetType = UNSET


class RunLine(Case, forbid_unknown_fields=True):
    """One line of a JSON Lines run file: a fusion case plus an optional step index."""

    k: Annotated[int, Meta(ge=0, le=MAX_K, description="step index; given on every line or on none, "
                                                       "strictly increasing")] | UnsetType = UNSET


def given(value):
    """``value`` with msgspec's UNSET (key absent) read as None (absent or null: the same)."""
    return None if value is UNSET else value


# --------------------------------------------------------------------------------------------
# Schemas
# --------------------------------------------------------------------------------------------

_SCHEMA_URI = "https://json-schema.org/draft/2020-12/schema"
_SHAPES_NOTE = ("Structure only: the shapes implied by D and central.sizes, symmetry and positive "
                "(semi)definiteness and the agreement of central/locals circular are checked by "
                "gpfverify's reader, which also refuses duplicate keys.")


def _schema(tp, title: str, description: str) -> dict:
    generated = msgspec.json.schema(tp)
    return {"$schema": _SCHEMA_URI, "title": title, "description": f"{description} {_SHAPES_NOTE}",
            **generated}


def case_schema() -> dict:
    """JSON Schema of one fusion case (docs/schemas/fusion-case.schema.json)."""
    return _schema(Case, "gpfverify fusion case", "One fusion step (docs/fusion-case-format.md).")


def run_line_schema() -> dict:
    """JSON Schema of one line of a .jsonl run file (docs/schemas/run-line.schema.json)."""
    return _schema(RunLine, "gpfverify run-file line", "One line of a JSON Lines run file "
                   "(docs/run-file-format.md): a fusion case plus an optional step index k.")


# --------------------------------------------------------------------------------------------
# Decoding
# --------------------------------------------------------------------------------------------

CASE_DECODER = msgspec.json.Decoder(Case)
RUN_LINE_DECODER = msgspec.json.Decoder(RunLine)

_TYPES = {"float": "a number", "int": "an integer", "str": "a string", "bool": "a boolean", "null": "null",
          "array": "a list", "object": "an object", "int | null": "an integer", "array | null": "a list",
          "float | null": "a number"}
_AT = re.compile(r"^(?P<msg>.*?)(?: - at `(?P<path>\$[^`]*)`)?$", re.S)


def _entry(path: str | None) -> str:
    if not path or path == "$":
        return "the case"
    return path[2:] if path.startswith("$.") else path


def _expected(kind: str) -> str:
    return _TYPES.get(kind, kind.replace("`", ""))


def explain(error: msgspec.ValidationError) -> str:
    """msgspec's validation message in the case format's words: ``ENTRY must be ...``."""
    match = _AT.match(str(error))
    msg, entry = (match["msg"], _entry(match["path"])) if match else (str(error), "the case")
    if m := re.fullmatch(r"Expected `([^`]*)`, got `([^`]*)`", msg):
        if entry == "the case":
            return f"a fusion case must be a JSON object, got {_expected(m[2])}"
        return f"{entry} must be {_expected(m[1])}, got {_expected(m[2])}"
    if m := re.fullmatch(r"Expected `(float|int)[^`]*` ([<>]=) (\S+)", msg):
        if m[1] == "float" and m[3].lstrip("-") == f"{MAX_MAGNITUDE:g}":
            return (f"{entry} is outside the accepted range: magnitudes up to {MAX_MAGNITUDE:g} (and NaN "
                    f"or infinity are not numbers)")
        return f"{entry} must be {'an integer' if m[1] == 'int' else 'a number'} {m[2]} {m[3]}"
    if msg == "Number out of range":
        return f"{entry} is outside the float range (numbers must be finite)"
    if m := re.fullmatch(r"Expected `array` of length >= (\d+)", msg):
        return f"{entry} must have at least {m[1]} entr{'y' if m[1] == '1' else 'ies'}, got fewer"
    if m := re.fullmatch(r"Object missing required field `([^`]*)`", msg):
        return f"{entry} lacks the key '{m[1]}'"
    if m := re.fullmatch(r"Object contains unknown field `([^`]*)`", msg):
        return f"{entry} has an unknown key '{m[1]}' ({_known_keys(entry)})"
    return f"{entry}: {msg}"


def _known_keys(entry: str) -> str:
    struct = Central if entry == "central" else Local if entry.startswith("locals[") else Case
    keys = ", ".join(struct.__struct_fields__) + (" (and k in a run file)" if struct is Case else "")
    return f"the keys there are {keys}; see docs/fusion-case-format.md"


def _explain_decode(error: msgspec.DecodeError, raw: bytes) -> str:
    """A malformed-JSON message with its column (byte offsets are turned into 1-based columns)."""
    text = str(error)
    if m := re.search(r"\(byte (\d+)\)", text):
        offset = int(m[1])
        line = raw.count(b"\n", 0, offset) + 1
        column = offset - (raw.rfind(b"\n", 0, offset) + 1) + 1
        where = f"line {line} column {column}" if b"\n" in raw[:offset] else f"column {column}"
        text = text[:m.start()].rstrip() + f" at {where}"
    text = text.replace("JSON is malformed: ", "")
    if "invalid character" in text and re.search(rb"\b(NaN|-?Infinity)\b", raw):
        text += " (NaN and Infinity are not JSON numbers)"
    return f"not valid JSON: {text}"


def _present(record: Struct) -> int:
    return sum(v is not UNSET for v in msgspec.structs.astuple(record))


def _key_count(record: Case) -> int:
    """How many keys the decoded record had in its text (every field given, null included)."""
    return _present(record) + _present(record.central) + sum(_present(r) for r in record.locals if r is not None)


def _duplicate_key(raw: bytes) -> str:
    """The first duplicated key of ``raw`` and where it is (slow path: only for a refused text)."""
    found: list[str] = []

    def pairs(items):
        keys = [k for k, _ in items]
        for k in keys:
            if keys.count(k) > 1 and not found:
                found.append(k)
        return dict(items)

    json.loads(raw, object_pairs_hook=pairs)
    return found[0] if found else "?"


def decode(raw: bytes, decoder: msgspec.json.Decoder = CASE_DECODER):
    """``raw`` (UTF-8 JSON text) as a :class:`Case` (or the decoder's type); CaseFileError with
    the entry (or the column) otherwise. Duplicate keys are found by counting: in a text that
    decoded to these types every string is a key (no value is a string), so the text holds
    exactly as many quoted strings as the record has fields unless a key repeats."""
    try:
        value = decoder.decode(raw)
    except msgspec.ValidationError as exc:
        raise CaseFileError(explain(exc)) from None
    except msgspec.DecodeError as exc:
        if "UTF-8" in str(exc):
            try:
                raw.decode("utf-8")
            except UnicodeDecodeError as bad:
                column = bad.start - (raw.rfind(b"\n", 0, bad.start) + 1) + 1
                raise CaseFileError(f"not valid UTF-8 (byte 0x{raw[bad.start]:02x} at column {column})") from None
        raise CaseFileError(_explain_decode(exc, raw)) from None
    if raw.count(b'"') != 2 * _key_count(value):
        raise CaseFileError(f"the key '{_duplicate_key(raw)}' appears twice in one object (duplicate keys are "
                            f"refused: JSON readers disagree on which one counts)")
    return value


def from_python(data, tp=Case):
    """Already-decoded JSON data (dicts and lists) as ``tp``, by the same rules as :func:`decode`."""
    if not isinstance(data, dict):
        raise CaseFileError(f"a fusion case must be a JSON object, got {type(data).__name__}")
    try:
        return msgspec.convert(data, tp, strict=True)
    except msgspec.ValidationError as exc:
        raise CaseFileError(explain(exc)) from None
