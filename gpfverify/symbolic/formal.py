"""Building formal statements in Python: terms with operators, declarations, predicates.

Everything here only writes the kernel's JSON (:mod:`gpfverify.kernel.terms`); nothing is
trusted. ``A * B`` is a product, ``A.T``, ``A.pinv``, ``A.inv`` transpose and inverses, numbers
(ints, Fractions) are scalars, and a family's member is ``C[i]``.
"""

from __future__ import annotations

from fractions import Fraction

from gpfverify.kernel.terms import HEAD, show_number


def as_term(x):
    if isinstance(x, Term):
        return x.t
    if isinstance(x, bool) or not isinstance(x, int | Fraction):
        raise TypeError(f"not a term: {x!r}")
    return ("num", show_number(Fraction(x)))


class Term:
    """A kernel term with arithmetic."""

    __slots__ = ("t",)

    def __init__(self, t):
        self.t = t

    def _join(self, head, other, swap=False):
        a, b = (as_term(other), self.t) if swap else (self.t, as_term(other))
        parts = []
        for x in (a, b):
            parts.extend(x[1:] if x[0] == head else (x,))
        return Term((head, *parts))

    def __add__(self, other):
        return self._join("+", other)

    def __radd__(self, other):
        return self._join("+", other, swap=True)

    def __sub__(self, other):
        return self + (-as_term_obj(other))

    def __rsub__(self, other):
        return as_term_obj(other) + (-self)

    def __neg__(self):
        return Term(("*", ("num", -1), self.t))

    def __mul__(self, other):
        return self._join("*", other)

    def __rmul__(self, other):
        return self._join("*", other, swap=True)

    def __pow__(self, exponent):
        if isinstance(exponent, Term):  # a rational function of sizes and parameters
            return Term(("^", self.t, exponent.t))
        return Term(("^", self.t, show_number(Fraction(exponent))))

    @property
    def T(self):
        return Term(("T", self.t))

    @property
    def pinv(self):
        return Term(("pinv", self.t))

    @property
    def inv(self):
        return Term(("inv", self.t))

    def __repr__(self):
        return f"Term({self.t!r})"


def as_term_obj(x) -> Term:
    return x if isinstance(x, Term) else Term(as_term(x))


class Family:
    """A family of matrices (or selectors, or a definition) indexed by an index set."""

    def __init__(self, make):
        self.make = make

    def __getitem__(self, index: str):
        return self.make(index)


def I(size) -> Term:  # noqa: E743 - the identity's usual name
    return Term(("I", str(size)))


def zero(rows, cols) -> Term:
    return Term(("0", str(rows), str(cols)))


def num(x) -> Term:
    return Term(as_term(Fraction(x)))


def Sum(index: str, index_set: str, body) -> Term:  # noqa: N802 - the operator's symbol
    return Term(("sum", index, index_set, as_term(body)))


def tr(x) -> Term:
    return Term(("tr", as_term(x)))


def det(x) -> Term:
    return Term(("det", as_term(x)))


def exp(x) -> Term:
    return Term(("exp", as_term(x)))


def size(s) -> Term:
    return Term(("size", str(s)))


TWO_PI = Term(("2pi",))


# ---- predicates ---------------------------------------------------------------------------------------

def eq(a, b):
    return ("=", as_term(a), as_term(b))


def spd(a):
    return ("spd", as_term(a))


def sym(a):
    return ("sym", as_term(a))


def fcr(a):
    return ("fcr", as_term(a))


def invertible(a):
    return ("invertible", as_term(a))


def nonzero(a):
    return ("nonzero", as_term(a))


def positive(a):
    return ("positive", as_term(a))


def le(a, b):
    return ("<=", str(a), str(b))


def every(index: str, index_set: str, pred):
    return ("every", index, index_set, pred)


def forall(variables, pred):
    return ("forall", tuple((x, str(r), str(c)) for x, r, c in variables), pred)


# ---- statements --------------------------------------------------------------------------------------

class Declare:
    """A statement under construction; :meth:`json` is what the kernel reads."""

    def __init__(self):
        self.data: dict = {"sizes": [], "params": [], "index_sets": {}, "indexed_sizes": {}, "partitions": {},
                           "variables": {}, "definitions": {}, "free_indices": {}, "hypotheses": [],
                           "conclusion": []}

    def sizes(self, *names: str) -> tuple[str, ...]:
        self.data["sizes"].extend(names)
        return names

    def index_set(self, name: str, count) -> str:
        self.data["index_sets"][name] = str(count)
        return name

    def family_size(self, name: str, over: str) -> str:
        self.data["indexed_sizes"][name] = over
        return name

    def partition(self, name: str, over: str, total, part) -> Family:
        self.data["partitions"][name] = {"over": over, "total": str(total), "part": str(part)}
        return Family(lambda i: Term(("sel", name, i)))

    def param(self, name: str) -> Term:
        self.data["params"].append(name)
        return Term(("param", name))

    def matrix(self, name: str, rows, cols, over: str | None = None):
        self.data["variables"][name] = {"rows": str(rows), "cols": str(cols), **({"over": over} if over else {})}
        return Family(lambda i: Term(("var", name, i))) if over else Term(("var", name))

    def define(self, name: str, body, over: str | None = None, args: tuple = (), opaque: bool = False):
        """``body`` a Term, or a function of (index if ``over``, then one Term per argument)."""
        values = [Term(("var", a[0])) for a in args]
        if callable(body):
            body = body(HEAD, *values) if over else body(*values)
        entry = {"body": as_term(body)}
        if over:
            entry["over"] = over
        if args:
            entry["args"] = [[a, str(r), str(c)] for a, r, c in args]
        if opaque:
            entry["opaque"] = True
        self.data["definitions"][name] = entry
        if args:
            call = lambda *xs, index=None: Term(("call", name, tuple(as_term(x) for x in xs),  # noqa: E731
                                                 *((index,) if index else ())))
            return call
        return Family(lambda i: Term(("var", name, i))) if over else Term(("var", name))

    def free_index(self, name: str, over: str) -> str:
        self.data["free_indices"][name] = over
        return name

    def assume(self, *preds) -> None:
        self.data["hypotheses"].extend(preds)

    def conclude(self, *preds) -> None:
        self.data["conclusion"].extend(preds)

    def json(self) -> dict:
        return {k: v for k, v in self.data.items() if v}
