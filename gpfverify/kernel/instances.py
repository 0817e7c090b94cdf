"""Exact instances: a statement evaluated at integer sizes and rational matrices.

An instance (JSON object) gives ``sizes`` {n: int}, ``indexed_sizes`` {l: [int per member]},
``params`` {a: number}, ``free_indices`` {j: 1-based int} and ``values`` {X: matrix, or a list
of matrices for a family}, a matrix being a list of rows of numbers (``[]`` for one with no rows).
Selectors are not given: S_i is the block [0; I; 0] of the partition, whose total must equal the sum
of its parts.

Every term is evaluated exactly (sympy rationals; A⁺ from sympy's rank decomposition); an
inverse of a singular matrix, a division by zero or a fractional power of a negative number is
outside the statement's domain (:class:`Undefined`). A hypothesis "for every x" is evaluated
with the entries of x as symbols and holds when the difference cancels to 0 identically. A
predicate is evaluated only where that is exact: otherwise :class:`NotEvaluable`.

* a **witness** satisfies every hypothesis, with every size ≥ 2 (a proved statement with none is
  reported vacuous);
* a **counterexample** satisfies every hypothesis and falsifies a conclusion.
"""

from __future__ import annotations

from fractions import Fraction

import sympy as sp

from gpfverify.kernel.terms import HEAD, Size, Statement, fail, number, parse_size


#: an instance is evaluated exactly: its sizes stay small (a witness needs no large ones), and so
#: does every size it evaluates (a constant such as I of size 10⁸ in a statement is refused)
MAX_SIZE = 64
MAX_EVALUATED = 4 * MAX_SIZE


class Undefined(Exception):
    """A term outside its domain at this instance (a singular inverse, a division by zero)."""


class NotEvaluable(Exception):
    """A predicate the kernel cannot decide exactly at this instance (an integral, a transcendental number)."""


def _count(v) -> bool:
    """An integer (JSON true is not 1 here)."""
    return isinstance(v, int) and not isinstance(v, bool)


def _matrix(rows, what: str, width: int) -> sp.Matrix:
    """A list of rows as an exact matrix; ``[]`` has no rows, and the declared ``width``."""
    if not isinstance(rows, list | tuple) or not all(isinstance(r, list | tuple) for r in rows):
        fail(f"instance: {what} is not a list of rows")
    widths = {len(r) for r in rows}
    if len(widths) > 1:
        fail(f"instance: the rows of {what} differ in length")
    return sp.Matrix(len(rows), widths.pop() if widths else width,
                     [sp.Rational(number(x).numerator, number(x).denominator) for r in rows for x in r])


class Instance:
    """The values of a statement's sizes, parameters, indices and matrices."""

    def __init__(self, st: Statement, data: dict, bases: dict | None = None):
        if not isinstance(data, dict) or not set(data) <= {"sizes", "indexed_sizes", "params", "free_indices",
                                                           "values"}:
            fail("an instance is {'sizes', 'indexed_sizes', 'params', 'free_indices', 'values'}")
        self.st = st
        self.sizes = {k: v for k, v in data.get("sizes", {}).items()}
        if set(self.sizes) != set(st.sizes) or not all(_count(v) and 0 <= v <= MAX_SIZE
                                                       for v in self.sizes.values()):
            fail(f"instance: every size symbol needs a value in 0..{MAX_SIZE} (and nothing else)")
        self.counts = {k: self.size(v, {}) for k, v in st.index_sets.items()}
        self.indexed = {k: list(v) for k, v in data.get("indexed_sizes", {}).items()}
        for name, index_set in st.indexed_sizes.items():
            values = self.indexed.get(name)
            if not isinstance(values, list | tuple) or len(values) != self.counts[index_set] or not all(
                    _count(v) and 0 <= v <= MAX_SIZE for v in values):
                fail(f"instance: the sizes {name} need one value ≥ 0 per member of {index_set}")
        self.params = {k: sp.Rational(number(v).numerator, number(v).denominator)
                       for k, v in data.get("params", {}).items()}
        if set(self.params) != set(st.params):
            fail("instance: every parameter needs a value")
        self.free = dict(data.get("free_indices", {}))
        if set(self.free) != set(st.free_indices) or not all(
                _count(v) and 1 <= v <= self.counts[st.free_indices[k]] for k, v in self.free.items()):
            fail("instance: every free index needs a value in its index set")
        self.partitions = dict(st.partitions)
        for name, size in (bases or {}).items():
            self.counts[name] = self.size(parse_size(size), self.free)
            self.partitions[name] = (name, parse_size(size), Size(1, ()))
        for name, (over, total, part) in self.partitions.items():
            if sum(self.size(part, {HEAD: i}) for i in range(1, self.counts[over] + 1)) != self.size(total, self.free):
                fail(f"instance: the parts of the partition {name} do not add up to its total")
        values = data.get("values", {})
        if set(values) != set(st.variables):
            fail(f"instance: values are needed for exactly {sorted(st.variables)}")
        self.values: dict = {}
        for name, decl in st.variables.items():
            members = range(1, self.counts[decl.over] + 1) if decl.over else [None]
            given = values[name] if decl.over else [values[name]]
            if not isinstance(given, list | tuple) or len(given) != len(members):
                fail(f"instance: {name} needs one matrix per member of {decl.over}")
            for i, rows in zip(members, given):
                env = {HEAD: i} if i is not None else {}
                m = _matrix(rows, name, self.size(decl.cols, env))
                if m.shape != (self.size(decl.rows, env), self.size(decl.cols, env)):
                    fail(f"instance: {name}{'' if i is None else f'[{i}]'} has the wrong shape {m.shape}")
                self.values[(name, i)] = m

    # ---- evaluation -------------------------------------------------------------------------------
    def size(self, size, env: dict) -> int:
        size = parse_size(size) if not isinstance(size, Size) else size
        total = size.const
        for name, index, c in size.atoms:
            if index is None:
                total += c * self.sizes[name]
            else:
                total += c * self.indexed[name][self._index(index, env) - 1]
        if total > MAX_EVALUATED:
            fail(f"instance: a size evaluates to {total}, above {MAX_EVALUATED}")
        return total

    def _index(self, name, env):
        value = env.get(name, self.free.get(name))
        if not isinstance(value, int):
            fail(f"instance: the index {name!r} has no value")
        return value

    def value(self, term, env: dict):
        head, args = term[0], term[1:]
        if head == "var":
            bound = env.get(args[0])
            if isinstance(bound, tuple):
                return bound[1]
            if args[0] in self.st.variables:
                return self.values[(args[0], self._index(args[1], env) if len(args) > 1 else None)]
            decl = self.st.definitions[args[0]]
            return self.value(decl.body, {HEAD: self._index(args[1], env)} if len(args) > 1 else {})
        if head == "call":
            decl = self.st.definitions[args[0]]
            inner = {HEAD: self._index(args[2], env)} if len(args) > 2 else {}
            for (name, _, _), t in zip(decl.args, args[1]):
                inner[name] = ("value", self.value(t, env))
            return self.value(decl.body, inner)
        if head == "sel":
            over, total, part = self.partitions[args[0]]
            i = self._index(args[1], env)
            start = sum(self.size(part, {HEAD: k}) for k in range(1, i))
            width = self.size(part, {HEAD: i})
            out = sp.zeros(self.size(total, self.free), width)
            for k in range(width):
                out[start + k, k] = 1
            return out
        if head == "I":
            return sp.eye(self.size(args[0], env))
        if head == "0":
            return sp.zeros(self.size(args[0], env), self.size(args[1], env))
        if head in ("+", "*"):
            values = [self.value(t, env) for t in args]
            out = values[0]
            for v in values[1:]:
                out = out + v if head == "+" else _product(out, v)
            return out
        if head == "T":
            return self.value(args[0], env).T
        if head in ("pinv", "inv"):
            m = self.value(args[0], env)
            if m.free_symbols:
                raise NotEvaluable("a pseudo-inverse of a symbolic matrix")
            if head == "inv":
                if m.det() == 0:
                    raise Undefined("the inverse of a singular matrix")
                return m.inv()
            return m.pinv() if m.shape[0] and m.shape[1] else m.T
        if head == "sum":
            name, index_set, body = args
            total = None
            for i in range(1, self._count(index_set) + 1):
                v = self.value(body, dict(env, **{name: i}))
                total = v if total is None else total + v
            if total is None:
                raise NotEvaluable("an empty sum (its shape is not known)")
            return total
        if head == "num":
            x = number(args[0])
            return sp.Rational(x.numerator, x.denominator)
        if head == "param":
            return self.params[args[0]]
        if head == "size":
            return sp.Integer(self.size(args[0], env))
        if head == "^":
            base = self.value(args[0], env)
            exponent = number(args[1]) if not isinstance(args[1], tuple) else self.value(args[1], env)
            if not isinstance(exponent, Fraction):
                if not exponent.is_Rational:
                    raise NotEvaluable("an exponent that is not rational")
                exponent = Fraction(int(exponent.p), int(exponent.q))
            if base == 0 and exponent < 0:
                raise Undefined("a division by zero")
            if exponent.denominator != 1 and base.is_negative:
                raise Undefined("a fractional power of a negative number")
            return base ** sp.Rational(exponent.numerator, exponent.denominator)
        if head == "tr":
            return self.value(args[0], env).trace()
        if head == "det":
            return self.value(args[0], env).det()
        if head == "exp":
            v = self.value(args[0], env)
            return sp.exp(v[0, 0] if isinstance(v, sp.MatrixBase) else v)
        if head == "2pi":
            return 2 * sp.pi
        raise NotEvaluable(f"the kernel does not evaluate '{head}'")

    def _count(self, index_set: str) -> int:
        return self.counts[index_set]

    # ---- predicates ---------------------------------------------------------------------------------
    def holds(self, pred, env: dict | None = None) -> bool:
        env = dict(env or {})
        head = pred[0]
        if head == "every":
            return all(self.holds(pred[3], dict(env, **{pred[1]: i})) for i in range(1, self._count(pred[2]) + 1))
        if head == "forall":
            inner = dict(env)
            for name, rows, cols in pred[1]:
                r, c = self.size(rows, env), self.size(cols, env)
                inner[name] = ("value", sp.Matrix(r, c, lambda i, j, name=name: sp.Symbol(f"{name}_{i}_{j}")))
            return self.holds(pred[2], inner)
        if head == "<=":
            return self.size(pred[1], env) <= self.size(pred[2], env)
        values = [self.value(t, env) for t in pred[1:]]
        if head == "=":
            a, b = values
            if isinstance(a, sp.MatrixBase) != isinstance(b, sp.MatrixBase) or getattr(a, "shape", 0) != getattr(
                    b, "shape", 0):
                raise NotEvaluable("the two sides differ in kind or shape")
            entries = list(a - b) if isinstance(a, sp.MatrixBase) else [a - b]
            return all(_exactly_zero(e) for e in entries)
        m = values[0]
        if head == "sym":
            return m == m.T
        if head == "spd":
            if m != m.T:
                return False
            return all(m[:k, :k].det() > 0 for k in range(1, m.shape[0] + 1))  # Sylvester's criterion
        if head == "fcr":
            return m.rank() == m.shape[1]
        if head == "invertible":
            return m.shape[0] == m.shape[1] and m.det() != 0
        if head in ("nonzero", "positive"):
            if not m.is_Rational:
                raise NotEvaluable("a number that is not rational")
            return m != 0 if head == "nonzero" else m > 0
        fail(f"not a predicate: {head!r}")


def _product(a, b):
    if not isinstance(a, sp.MatrixBase) or not isinstance(b, sp.MatrixBase):
        return a * b
    if a.shape[1] != b.shape[0]:
        fail(f"instance: a product of {a.shape} and {b.shape} matrices")
    return a * b


def _exactly_zero(e) -> bool:
    """Exact zero test of a rational function of the symbols of bound variables."""
    e = sp.cancel(sp.together(sp.expand(e)))
    if e.is_Rational:
        return e == 0
    symbols = sorted(e.free_symbols, key=str)
    if symbols and e.is_rational_function() and all(
            term.as_independent(*symbols)[0].is_Rational for part in sp.fraction(e) for term in sp.Add.make_args(part)):
        return e == 0  # over ℚ cancel decides it (an irrational coefficient could be a zero it does not see)
    raise NotEvaluable("a difference that is not a rational function over the rationals")


#: every size of a witness is at least this: a size symbol stands for every dimension, and hypotheses
#: that hold only with empty or 1 × 1 blocks (where matrices commute) would make a statement vacuous
WITNESS_SIZE = 2


def degenerate(inst: Instance) -> str:
    """'' when every size symbol and every member's size of a witness is ≥ WITNESS_SIZE; otherwise which is not."""
    small = [f"{k} = {v}" for k, v in inst.sizes.items() if v < WITNESS_SIZE]
    small += [f"{k} = {tuple(v)}" for k, v in inst.indexed.items() if any(x < WITNESS_SIZE for x in v)]
    return f"the witness has a size below {WITNESS_SIZE} ({', '.join(small)})" if small else ""


def satisfies(st: Statement, inst: Instance) -> str:
    """'' when every hypothesis holds at ``inst``; otherwise why not."""
    for k, h in enumerate(st.hypotheses):
        try:
            if not inst.holds(h):
                return f"hypothesis {k} does not hold"
        except Undefined as e:
            return f"hypothesis {k} is undefined ({e})"
        except NotEvaluable as e:
            return f"hypothesis {k} cannot be evaluated exactly ({e})"
    return ""


def refutes(st: Statement, inst: Instance) -> str:
    """'' when ``inst`` satisfies every hypothesis and falsifies a conclusion; otherwise why not."""
    why = satisfies(st, inst)
    if why:
        return why
    for k, c in enumerate(st.conclusion):
        try:
            if not inst.holds(c):
                return ""
        except (Undefined, NotEvaluable) as e:
            return f"conclusion {k} cannot be decided at the instance ({e})"
    return "every conclusion holds at the instance"


def conclusion_fails(st: Statement, inst: Instance) -> bool:
    """A proved statement's conclusion evaluated at its witness (where that is exact): False if it
    holds or cannot be evaluated, True if it fails — which only a kernel error could produce."""
    for c in st.conclusion:
        try:
            if not inst.holds(c):
                return True
        except (Undefined, NotEvaluable):
            continue
    return False
