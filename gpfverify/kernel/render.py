"""The words a reader sees, rendered from the formal statement alone.

The statement text is the conclusion, its definitions ("where …") and every hypothesis
("assuming: …"); the scope is "any dimension" when no dimension is fixed to a number ≥ 2
(every size is a symbol, each ≥ 0), else the fixed sizes. Nothing here decides a status.
"""

from __future__ import annotations

from gpfverify.kernel.terms import HEAD, Statement, _expand, number, parse_size

ANY_DIMENSION = "any dimension"
_SUP = str.maketrans("0123456789-", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻")


def member(name: str, index) -> str:
    """X with index i: X_i, or X^i when the name already has a subscript."""
    if index is None:
        return name
    return f"{name}^{index}" if "_" in name else f"{name}_{index}"


def size_text(size) -> str:
    s = parse_size(size) if not hasattr(size, "atoms") else size
    parts = [(f"{c}·" if c != 1 else "") + member(n, i) for n, i, c in s.atoms]
    if s.const or not parts:
        parts.append(str(s.const))
    return " + ".join(parts)


class Renderer:
    def __init__(self, st: Statement):
        self.st = st

    def term(self, t, level: int = 0) -> str:
        """``level``: 0 inside a sum, 1 a factor of a product, 2 an operand of ᵀ, ⁺, ⁻¹, ^."""
        head, args = t[0], t[1:]
        if head == "var":
            return member(args[0], args[1] if len(args) > 1 else None)
        if head == "call":
            return member(args[0], args[2] if len(args) > 2 else None) + "(" + ", ".join(
                self.term(a) for a in args[1]) + ")"
        if head == "sel":
            return member(args[0], args[1])
        if head == "I":
            return "I"
        if head == "0":
            return "0"
        if head == "+":
            text = ""
            for k, a in enumerate(args):
                piece = self.term(a, 0)
                text += piece if k == 0 else (" − " + piece[1:] if piece.startswith("−") else " + " + piece)
            return f"({text})" if level >= 1 else text
        if head == "*":
            sign, factors = "", list(args)
            if factors and factors[0][0] == "num" and number(factors[0][1]) == -1 and len(factors) > 1:
                sign, factors = "−", factors[1:]
            text = sign + " ".join(self.term(a, 1) for a in factors)
            return f"({text})" if level >= 2 or (sign and level >= 1) else text
        if head in ("T", "pinv", "inv"):
            base = self.term(args[0], 2)
            if "^" in base and not base.startswith("("):  # C_y^m⁻¹ would read as a power of m
                base = f"({base})"
            return base + {"T": "ᵀ", "pinv": "⁺", "inv": "⁻¹"}[head]
        if head == "sum":
            count = size_text(self.st.index_sets.get(args[1], parse_size(0)))
            text = f"Σ_{{{args[0]}=1}}^{{{count}}} {self.term(args[2], 1)}"
            return f"({text})" if level >= 1 else text
        if head == "num":
            x = number(args[0])
            text = str(x) if x >= 0 else f"−{-x}"
            return f"({text})" if (x.denominator != 1 or x < 0) and level >= 1 else text
        if head == "param":
            return args[0]
        if head == "size":
            text = size_text(args[0])
            return f"({text})" if "+" in text and level >= 1 else text
        if head == "^":
            if isinstance(args[1], tuple):
                return self.term(args[0], 2) + "^(" + self.term(args[1]) + ")"
            x = number(args[1])
            if x == 1 / 2:
                return "√" + self.term(args[0], 2)
            exponent = str(x.numerator).translate(_SUP) + ("ᐟ" + str(x.denominator).translate(_SUP)
                                                           if x.denominator != 1 else "")
            return self.term(args[0], 2) + exponent
        if head in ("tr", "det", "exp"):
            return f"{head}({self.term(args[0])})"
        if head == "2pi":
            return "(2π)" if level >= 2 else "2π"
        if head == "int":
            return f"∫_{{{args[0]} ∈ ℝ^{size_text(args[1])}}} {self.term(args[2], 1)} d{args[0]}"
        return str(t)

    def predicate(self, p) -> str:
        head = p[0]
        if head == "every":
            count = size_text(self.st.index_sets[p[2]])
            return f"{self.predicate(p[3])} for every {p[1]} = 1..{count}"
        if head == "forall":
            names = ", ".join(f"{x} ({size_text(r)} × {size_text(c)})" for x, r, c in p[1])
            return f"for every {names}: {self.predicate(p[2])}"
        if head == "=":
            return f"{self.term(p[1])} = {self.term(p[2])}"
        if head == "<=":
            return f"{size_text(p[1])} ≤ {size_text(p[2])}"
        words = {"sym": "is symmetric", "spd": "is symmetric positive definite", "fcr": "has full column rank",
                 "invertible": "is invertible", "nonzero": "≠ 0", "positive": "> 0"}
        return f"{self.term(p[1], 1)} {words[head]}"

    @property
    def member_index(self) -> str:
        """The letter that names a family's member in the text (one no declaration uses)."""
        return next(i for i in ("m", "k", "i", "r", "s", "t", "m′") if i not in self.st.names)

    def shapes(self, entries) -> str:
        """'A, B ∈ ℝ^{n × l}; C_m ∈ ℝ^{l_m × l_m} (m = 1..N)' for (name, rows, cols[, members]) entries."""
        groups: dict = {}
        for name, rows, cols, *members in entries:
            key = f"ℝ^{{{size_text(rows)} × {size_text(cols)}}}" + (f" ({members[0]})" if members else "")
            groups.setdefault(key, []).append(name)
        return "; ".join(f"{', '.join(names)} ∈ {shape}" for shape, names in groups.items())

    def definitions(self) -> list[str]:
        out = []
        m = self.member_index
        for name, d in self.st.definitions.items():
            index = None if d.over is None else m
            head = member(name, index) + ("(" + ", ".join(a[0] for a in d.args) + ")" if d.args else "")
            body = self.term(_rename_head(d.body, index)) if index else self.term(d.body)
            shapes = self.shapes((a, _renamed(r, index), _renamed(c, index)) for a, r, c in d.args)
            out.append(f"{head} := {body}" + (f" for {shapes}" if d.args else ""))
        return out

    def quantifiers(self) -> str:
        m = self.member_index
        sizes = [member(s, None) for s in self.st.sizes]
        families = [f"{member(n, m)} ({m} = 1..{size_text(self.st.index_sets[s])})"
                    for n, s in self.st.indexed_sizes.items()]
        text = "for all sizes " + ", ".join(sizes + families) + " ≥ 0" if sizes or families else ""
        if self.st.params:
            text += ("; " if text else "for ") + "all real " + ", ".join(self.st.params)
        if self.st.variables:
            text += ("; " if text else "for ") + "all " + self.shapes(
                (name, d.rows, d.cols) if d.over is None else
                (member(name, m), _renamed(d.rows, m), _renamed(d.cols, m),
                 f"{m} = 1..{size_text(self.st.index_sets[d.over])}") for name, d in self.st.variables.items())
        for name, (over, total, part) in self.st.partitions.items():
            count = size_text(self.st.index_sets[over])
            text += (f"; {member(name, m)} ({m} = 1..{count}) the column blocks of I of size {size_text(total)} "
                     f"= Σ_{m} {size_text(_renamed(part, m))}")
        for name, s in self.st.free_indices.items():
            text += f"; every {name} = 1..{size_text(self.st.index_sets[s])}"
        return text


def _renamed(size, index):
    """A declared size with its member's own index ``#`` written ``index``."""
    return size if index is None else size.renamed(HEAD, index)


def _rename_head(term, index: str):
    from gpfverify.kernel.terms import substitute

    return substitute(term, index=(HEAD, index))


def hypotheses(st: Statement) -> list[str]:
    r = Renderer(st)
    return [r.predicate(h) for h in st.hypotheses]


def statement_text(st: Statement) -> str:
    r = Renderer(st)
    text = " and ".join(r.predicate(c) for c in st.conclusion)
    defs = r.definitions()
    if defs:
        text += ", where " + "; ".join(defs)
    text += f" ({r.quantifiers()})" if r.quantifiers() else ""
    hyps = hypotheses(st)
    return text + (" — assuming: " + "; ".join(hyps) if hyps else " — with no hypothesis")


def scope(st: Statement) -> str:
    """"any dimension" unless a dimension is fixed: a number other than 1 as a size anywhere (a shape,
    a count of members, a block, an identity's or an integral's size), or no size symbol at all."""
    dims = list(st.index_sets.values())
    dims += [s for d in st.variables.values() for s in (d.rows, d.cols)]
    dims += [s for d in st.definitions.values() for _, r, c in d.args for s in (r, c)]
    dims += [s for _, total, part in st.partitions.values() for s in (total, part)]
    for d in st.definitions.values():
        _term_sizes(d.body, dims)
    for pred in (*st.hypotheses, *st.conclusion):
        _predicate_sizes(pred, dims)
    numbers = {s.const for s in dims if not s.atoms}
    fixed = numbers - {1} if any(s.atoms for s in dims) else numbers
    return ANY_DIMENSION if not fixed else "dimensions fixed at " + ", ".join(map(str, sorted(fixed)))


def _predicate_sizes(pred, out: list) -> None:
    head = pred[0]
    if head == "every":
        _predicate_sizes(pred[3], out)
    elif head == "forall":
        out.extend(parse_size(s) for _, r, c in pred[1] for s in (r, c))
        _predicate_sizes(pred[2], out)
    elif head == "<=":
        out.extend(parse_size(s) for s in pred[1:])
    else:
        for t in pred[1:]:
            _term_sizes(t, out)


def _term_sizes(term, out: list) -> None:
    """The sizes written in a term (an identity's, a zero's, an integral's; a size used as a number is not one)."""
    head, args = term[0], term[1:]
    for kind, value in zip(_expand(head, len(args)), args):
        if kind == "size" and head != "size":
            out.append(parse_size(value))
        elif kind == "term" or (kind == "exponent" and isinstance(value, tuple)):
            _term_sizes(value, out)
        elif kind == "terms":
            for t in value:
                _term_sizes(t, out)


def instance_text(data: dict) -> str:
    """The sizes of an instance, e.g. "n = 2, N = 1, l = (2)"."""
    parts = [f"{k} = {v}" for k, v in data.get("sizes", {}).items()]
    parts += [f"{k} = ({', '.join(map(str, v))})" for k, v in data.get("indexed_sizes", {}).items()]
    parts += [f"{k} = {v}" for k, v in data.get("params", {}).items()]
    parts += [f"{k} = {v}" for k, v in data.get("free_indices", {}).items()]
    return ", ".join(parts)


__all__ = ["ANY_DIMENSION", "Renderer", "hypotheses", "instance_text", "scope", "statement_text"]
