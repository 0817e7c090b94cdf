"""The kernel's language: names, sizes, numbers, terms and statements, read from plain JSON values.

A **term** is a JSON array whose first element names its form (the whole table is :data:`FORMS`):

    ["var", X]  ["var", X, i]          a declared matrix X (of family member i), a definition, or a
                                       bound variable
    ["call", f, [t, ...]]  (+ index)   a definition with arguments, expanded by the kernel
    ["sel", S, i]                      block selector i of the partition S (Σ_i S_i S_iᵀ = I)
    ["I", n]  ["0", r, c]              identity and zero
    ["+", t, ...]  ["*", t, ...]       sum; product (scalar factors commute out)
    ["T", t]  ["pinv", t]  ["inv", t]  transpose, Moore–Penrose inverse, inverse
    ["sum", i, J, t]                   Σ over i in the index set J
    ["num", "p/q"]  ["param", a]  ["size", n]    numbers, real parameters, sizes as numbers
    ["^", t, e]  ["tr", t]  ["det", t]  ["exp", t]  ["2pi"]  ["int", x, n, t]
                                       power (e a number, or a term: a rational function of sizes),
                                       trace, determinant, exponential, 2π, ∫ over x ∈ ℝⁿ

A **size** is a string, a sum of size symbols (``n``, or ``l[i]`` for a family of sizes) with
non-negative integer coefficients, e.g. ``"K + 2*l[i] + 1"``: every size is ≥ 0 by construction,
and a negative coefficient is refused when read. A **number** is an integer or ``"p/q"``.

A **statement** is a JSON object (:class:`Statement`); every name it declares lives in one
namespace, so no letter is declared twice and no bound variable captures a declared one.
The kernel creates its own symbols from these names: nothing a caller passes in carries meaning
beyond its text.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, NoReturn

from gpfverify.errors import InputError


class KernelError(InputError):
    """A statement, term or certificate the kernel refuses (malformed, ill-typed, or not a proof)."""


NAME = re.compile(r"^[^\W\d][\w'′,₀-₉]*$")
#: term forms: what each argument is (name, index, size, number, term, terms)
FORMS: dict[str, tuple[str, ...]] = {
    "var": ("name", "index?"), "call": ("name", "terms", "index?"), "sel": ("name", "index"),
    "I": ("size",), "0": ("size", "size"), "+": ("terms*",), "*": ("terms*",), "T": ("term",),
    "pinv": ("term",), "inv": ("term",), "sum": ("name", "name", "term"), "num": ("number",),
    "param": ("name",), "size": ("size",), "^": ("term", "exponent"), "tr": ("term",), "det": ("term",),
    "exp": ("term",), "2pi": (), "int": ("name", "size", "term"),
}
PREDICATES = ("=", "sym", "spd", "fcr", "invertible", "nonzero", "positive", "<=", "every", "forall")
HEAD = "#"  # a family declaration's own index


def fail(message: str) -> NoReturn:
    raise KernelError(message)


_NUMBER = re.compile(r"^-?[0-9]{1,300}(?:/[0-9]{1,300})?$")


def number(value) -> Fraction:
    """An integer or a "p/q" string as an exact rational (no decimal point, no exponent: "1e9999999999"
    would be computed digit by digit)."""
    if isinstance(value, bool) or not isinstance(value, int | str) or (isinstance(value, str)
                                                                       and not _NUMBER.match(value)):
        fail(f"a number is an integer or a 'p/q' string, not {str(value)[:40]!r}")
    try:
        return Fraction(value)
    except (ValueError, ZeroDivisionError):
        fail(f"not a rational number: {str(value)[:40]!r}")


def show_number(value: Fraction) -> str | int:
    return int(value) if value.denominator == 1 else f"{value.numerator}/{value.denominator}"


# ---- sizes ----------------------------------------------------------------------------------------

_SIZE_TERM = re.compile(r"^\s*(?:(\d+)\s*\*\s*)?([^\W\d][\w']*)(?:\[\s*([^\]\s]+)\s*\])?\s*$|^\s*(\d+)\s*$")


@dataclass(frozen=True)
class Size:
    """const + Σ coef·atom, an atom being (name, index) with index None, an index name, or (in a
    normal form) a reference; coefficients and const are non-negative integers."""

    const: int
    atoms: tuple  # ((name, index, coef), ...) sorted, coef > 0

    @staticmethod
    def of(const: int, atoms: dict) -> Size:
        return Size(const, tuple(sorted(((n, i, c) for (n, i), c in atoms.items() if c), key=repr)))

    def __add__(self, other: Size) -> Size:
        return Size.of(self.const + other.const, _merged(self.atoms + other.atoms))

    @property
    def is_one(self) -> bool:
        return self.const == 1 and not self.atoms

    def text(self, times: str = "·") -> str:
        parts = [(f"{c}{times}" if c != 1 else "") + n + (f"[{i}]" if i is not None else "") for n, i, c in self.atoms]
        if self.const or not parts:
            parts.append(str(self.const))
        return " + ".join(parts)

    def renamed(self, old: str, new: str) -> Size:
        """The size with every member index ``old`` renamed ``new``."""
        return Size.of(self.const, _merged((n, new if i == old else i, c) for n, i, c in self.atoms))


def _merged(atoms) -> dict:
    total: dict = {}
    for n, i, c in atoms:
        total[(n, i)] = total.get((n, i), 0) + c
    return total


def rename_size(text, old: str, new: str):
    """A size as written (a string or an integer) with the member index ``old`` renamed ``new``:
    read, renamed atom by atom and written back, so that ``l[ m ]`` is renamed like ``l[m]``."""
    size = parse_size(text)
    return size.renamed(old, new).text(times="*") if any(i == old for _, i, _ in size.atoms) else text


def parse_size(text) -> Size:
    """``"K + 2*l[i] + 1"`` → Size; refuses anything but non-negative integer combinations."""
    if isinstance(text, bool) or not isinstance(text, str | int):
        fail(f"a size is a string such as 'n + l', not {text!r}")
    if isinstance(text, int):
        if text < 0:
            fail(f"the size {text} is negative: every size is a sum of size symbols with non-negative coefficients")
        return Size(text, ())
    if "-" in text:
        fail(f"the size {text!r} has a negative part: every size is a sum of size symbols with non-negative "
             "coefficients, so that it is ≥ 0 by construction")
    const, atoms = 0, {}  # type: tuple[int, dict]
    for piece in text.split("+"):
        match = _SIZE_TERM.match(piece)
        if not match:
            fail(f"not a size: {text!r}")
        coef, name, index, alone = match.groups()
        if alone is not None:
            const += int(alone)
        else:
            atoms[(name, index)] = atoms.get((name, index), 0) + int(coef or 1)
    return Size.of(const, atoms)


# ---- statements -----------------------------------------------------------------------------------

_KEYS = ("sizes", "params", "index_sets", "indexed_sizes", "partitions", "variables", "definitions",
         "free_indices", "hypotheses", "conclusion")


def frozen(value):
    """JSON lists as tuples (terms are compared and hashed by content)."""
    if isinstance(value, list | tuple):
        return tuple(frozen(v) for v in value)
    if isinstance(value, dict):
        return {k: frozen(v) for k, v in value.items()}
    return value


def thawed(value):
    """Tuples back to JSON lists."""
    if isinstance(value, tuple | list):
        return [thawed(v) for v in value]
    if isinstance(value, dict):
        return {k: thawed(v) for k, v in value.items()}
    return value


def canonical_json(value) -> str:
    """The content key of a JSON value (sorted keys, no whitespace)."""
    return json.dumps(thawed(value), sort_keys=True, separators=(",", ":"), ensure_ascii=False)


def _mapping(data: dict, key: str) -> dict:
    value = data.get(key, {})
    if not isinstance(value, dict):
        fail(f"statement: '{key}' must be an object")
    return value


def _list(data: dict, key: str) -> tuple:
    value = data.get(key, [])
    if not isinstance(value, list | tuple):
        fail(f"statement: '{key}' must be a list")
    return frozen(value)


@dataclass(frozen=True)
class Declaration:
    """A variable or definition: its family (index set or None), shape or arguments, body."""

    over: str | None
    rows: Size | None = None
    cols: Size | None = None
    args: tuple = ()  # ((name, rows Size, cols Size), ...)
    body: Any = None  # definitions only
    #: a definition kept as a letter of its own, related to its body only by its defining equation
    opaque: bool = False


@dataclass(frozen=True, eq=False)
class Statement:
    """A claim as a formal object: for all sizes (every size symbol ≥ 0), index values, real
    parameters and real matrices of the declared shapes, the hypotheses imply every conclusion.
    ``data`` is the JSON object it was read from; ``key`` its content key."""

    data: dict
    key: str
    sizes: tuple
    params: tuple
    index_sets: dict  # name -> count Size
    indexed_sizes: dict  # name -> index set
    partitions: dict  # name -> (index set, total Size, part Size with index HEAD)
    variables: dict  # name -> Declaration
    definitions: dict  # name -> Declaration
    free_indices: dict  # name -> index set
    hypotheses: tuple
    conclusion: tuple

    @property
    def names(self) -> set:
        return (set(self.sizes) | set(self.params) | set(self.index_sets) | set(self.indexed_sizes)
                | set(self.partitions) | set(self.variables) | set(self.definitions) | set(self.free_indices))


def _name(value, what: str) -> str:
    if not isinstance(value, str) or not NAME.match(value):
        fail(f"{what}: {value!r} is not a name")
    return value


def read_statement(data) -> Statement:
    """Validate the shape of a statement object (types are checked when its terms are normalised)."""
    if not isinstance(data, dict):
        fail("a statement is a JSON object")
    unknown = set(data) - set(_KEYS)
    if unknown:
        fail(f"statement: unknown fields {sorted(unknown)}")
    seen: set = set()

    def declare(name, what):
        _name(name, what)
        if name in seen or name == HEAD:
            fail(f"statement: the name {name!r} is declared twice (a letter's meaning is fixed once)")
        seen.add(name)
        return name

    sizes = tuple(declare(s, "size") for s in _list(data, "sizes"))
    params = tuple(declare(p, "parameter") for p in _list(data, "params"))
    index_sets = {declare(k, "index set"): parse_size(v) for k, v in _mapping(data, "index_sets").items()}
    indexed = {declare(k, "indexed size"): v for k, v in _mapping(data, "indexed_sizes").items()}
    for k, v in indexed.items():
        if v not in index_sets:
            fail(f"indexed size {k}: no index set {v!r}")
    partitions = {}
    for k, v in _mapping(data, "partitions").items():
        declare(k, "partition")
        if not isinstance(v, dict) or set(v) != {"over", "total", "part"} or v["over"] not in index_sets:
            fail(f"partition {k}: expected {{'over': index set, 'total': size, 'part': size}}")
        partitions[k] = (v["over"], parse_size(v["total"]), parse_size(v["part"]))
    variables, definitions = {}, {}
    for k, v in _mapping(data, "variables").items():
        declare(k, "variable")
        if not isinstance(v, dict) or not {"rows", "cols"} <= set(v) <= {"rows", "cols", "over"}:
            fail(f"variable {k}: expected {{'rows', 'cols'[, 'over']}}")
        variables[k] = Declaration(_over(v, index_sets, k), parse_size(v["rows"]), parse_size(v["cols"]))
    for k, v in _mapping(data, "definitions").items():
        declare(k, "definition")
        if not isinstance(v, dict) or "body" not in v or not set(v) <= {"body", "args", "over", "opaque"}:
            fail(f"definition {k}: expected {{'body'[, 'args', 'over', 'opaque']}}")
        if v.get("opaque", False) not in (True, False) or (v.get("opaque") and v.get("args")):
            fail(f"definition {k}: 'opaque' is true or false, and only for a definition without arguments")
        args: list = []
        for a in v.get("args", []):  # local to the body (lexical scope): they may shadow a declared name
            if not isinstance(a, list | tuple) or len(a) != 3 or a[0] in [b[0] for b in args]:
                fail(f"definition {k}: an argument is [name, rows, cols], each name once")
            args.append((_name(a[0], "argument"), parse_size(a[1]), parse_size(a[2])))
        definitions[k] = Declaration(_over(v, index_sets, k), args=tuple(args), body=frozen(v["body"]),
                                     opaque=bool(v.get("opaque")))
    free = {declare(k, "free index"): v for k, v in _mapping(data, "free_indices").items()}
    for k, v in free.items():
        if v not in index_sets:
            fail(f"free index {k}: no index set {v!r}")
    conclusion = _list(data, "conclusion")
    if not conclusion:
        fail("statement: no conclusion")
    return Statement(frozen(data), canonical_json(data), sizes, params, index_sets, indexed, partitions,
                     variables, definitions, free, _list(data, "hypotheses"), conclusion)


def _over(v: dict, index_sets: dict, name: str):
    over = v.get("over")
    if over is not None and over not in index_sets:
        fail(f"{name}: no index set {over!r}")
    return over


# ---- substitution on terms --------------------------------------------------------------------------

def substitute(term, variables: dict | None = None, index: tuple | None = None):
    """``term`` with the variables in ``variables`` (name -> term) replaced and the index name
    ``index[0]`` renamed ``index[1]`` (in index positions and inside sizes)."""
    if not isinstance(term, tuple) or not term or term[0] not in FORMS:
        fail(f"not a term: {str(term)[:80]}")
    head, args = term[0], term[1:]
    if head == "var" and variables and args[0] in variables:
        if len(args) != 1:
            fail(f"the argument {args[0]} is not a family")
        return variables[args[0]]
    out = [head]
    for kind, value in zip(_expand(head, len(args)), args):
        if kind.startswith("term") or (kind == "exponent" and isinstance(value, tuple)):
            out.append(tuple(substitute(t, variables, index) for t in value) if kind == "terms"
                       else substitute(value, variables, index))
        elif kind.startswith("index") and index and value == index[0]:
            out.append(index[1])
        elif kind == "size" and index:
            out.append(rename_size(value, *index))
        else:
            out.append(value)
    return tuple(out)


def _expand(head: str, count: int) -> tuple:
    """The argument kinds of a form with ``count`` arguments (optional and repeated ones resolved)."""
    kinds = FORMS[head]
    if kinds == ("terms*",):
        return ("term",) * count
    required = [k for k in kinds if not k.endswith("?")]
    if not len(required) <= count <= len(kinds):
        fail(f"'{head}' takes {len(required)}..{len(kinds)} arguments, got {count}")
    return tuple(k.rstrip("?") for k in kinds[:count])
