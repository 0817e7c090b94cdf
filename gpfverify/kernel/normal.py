"""Normal forms: a term as a polynomial in non-commuting matrix atoms, with every operation
type-checked as it is built (an ill-typed product is refused even if it would cancel).

A normal form (:class:`NF`) maps monomials to coefficients. A monomial is ``(scalars, binders,
word)``: a product of scalar atoms (``tr``, ``det``, ``2π`` with exponents, and one ``exp``
argument), the index sets of the sums it is summed over, and a word of matrix atoms — a variable
or selector (possibly transposed) or ``pinv`` of a normal form. Coefficients are exact rationals,
or rational functions of the sizes and parameters (sympy's field over ℚ) when they involve them.

What the normal form identifies, each valid for all real matrices of the right shapes:

* N1 ring axioms: associativity, distributivity, I·X = X, scalars commute with matrices;
* N2 transpose: (XY)ᵀ = YᵀXᵀ, (Xᵀ)ᵀ = X, (A⁺)ᵀ = (Aᵀ)⁺, Xᵀ = X for a letter the statement
  declares symmetric or SPD (for every member of a family: the hypothesis is in force);
* N3 a 1×1 word equals its transpose (it is a number);
* N4 inv(X) is pinv(X) (equal whenever X is invertible, which the kernel requires of every inv);
* N5 sums: Σ_i is linear, factors free of i move in and out, Σ_i c = |J|·c for c free of i,
  bound indices are renamed canonically, and for the selectors of a partition
  S_iᵀS_i = I and Σ_i u(i) S_iᵀS_t w(i) = u(t) w(t) (S_iᵀS_t = δ_it I);
* N6 scalars: tr is linear, tr(XY) = tr(YX), tr(Xᵀ) = tr(X), tr(I_n) = n; det(I) = 1,
  det(Xᵀ) = det(X); a^p a^q = a^{p+q} for an atom a that is positive (or nonzero for integer
  exponents: every negative or fractional power records that side condition); exp(a)exp(b) = exp(a+b).

Definitions are expanded where they are used (a letter's meaning is fixed once, by the
statement). The side conditions met while normalising (every inv(X) needs X invertible, a
fractional power of det(X) needs det(X) > 0, a division needs a nonzero divisor) are collected
in :attr:`Context.needs` for :mod:`gpfverify.kernel.rules` to discharge.
"""

from __future__ import annotations

import itertools
from fractions import Fraction
from functools import cache
from typing import Any

from sympy import QQ
from sympy.polys.fields import field

from gpfverify.kernel.terms import HEAD, Size, Statement, _expand, fail, number, parse_size

REFS = ("@f", "@b", "@x")  # a free index, a bound position, the index of a sum under construction
EMPTY = ((), None)  # no scalar atoms, no exp
INTEGRATION = "@∫"  # the canonical name of an integration variable inside its integral
MAX_POWER = 64  # an integer power is taken up to this exponent (a power of a sum is expanded)


# ---- coefficients -----------------------------------------------------------------------------------

def _lower(c):
    """A rational function that is a constant, as a Fraction."""
    if isinstance(c, Fraction):
        return c
    if c.numer.is_ground and c.denom.is_ground:
        n, d = c.numer.LC, c.denom.LC
        return Fraction(int(n.numerator), int(n.denominator)) / Fraction(int(d.numerator), int(d.denominator))
    return c


def _lift(c, like):
    return like.field.field_new(QQ(c.numerator, c.denominator)) if isinstance(c, Fraction) else c


def c_add(a, b):
    if isinstance(a, Fraction) and isinstance(b, Fraction):
        return a + b
    return _lower(_lift(a, b if isinstance(a, Fraction) else a) + _lift(b, a if isinstance(b, Fraction) else b))


def c_mul(a, b):
    if isinstance(a, Fraction) and isinstance(b, Fraction):
        return a * b
    return _lower(_lift(a, b if isinstance(a, Fraction) else a) * _lift(b, a if isinstance(b, Fraction) else b))


def is_zero(c) -> bool:
    return c == 0


@cache
def key(obj):
    """A total order on atoms and monomials (for canonical choices and sorting)."""
    if isinstance(obj, tuple):
        return (0, tuple(key(o) for o in obj))
    if isinstance(obj, str):
        return (1, obj)
    if isinstance(obj, bool | int):
        return (2, int(obj))
    if obj is None:
        return (3,)
    if isinstance(obj, Fraction):
        return (4, obj)
    if isinstance(obj, Size):
        return (5, obj.const, key(obj.atoms))
    return (6, str(obj))


# ---- references to indices --------------------------------------------------------------------------

def walk(obj, f):
    """``obj`` with every index reference r replaced by f(r) (inside atoms, sizes, nested forms)."""
    if isinstance(obj, tuple):
        if len(obj) == 2 and obj[0] in REFS:
            return f(obj)
        return tuple(walk(o, f) for o in obj)
    if isinstance(obj, Size):
        return Size.of(obj.const, {(n, walk(i, f) if i is not None else None): c for n, i, c in obj.atoms})
    return obj


def refs(obj, out: list) -> list:
    """The index references in ``obj``, in order of first occurrence."""
    if isinstance(obj, tuple):
        if len(obj) == 2 and obj[0] in REFS:
            if obj not in out:
                out.append(obj)
        else:
            for o in obj:
                refs(o, out)
    elif isinstance(obj, Size):
        for _, i, _ in obj.atoms:
            if i is not None:
                refs(i, out)
    return out


def _replace(obj, old, new):
    return walk(obj, lambda r: new if r == old else r)


# ---- normal forms -----------------------------------------------------------------------------------

class NF:
    """Σ coefficient · monomial, of a shape (rows, cols) or a scalar (shape None)."""

    __slots__ = ("shape", "terms")

    def __init__(self, shape, terms: dict):
        self.shape = shape
        self.terms = terms

    @property
    def is_zero(self) -> bool:
        return not self.terms

    def frozen(self):
        return ("nf", self.shape, tuple(sorted(self.terms.items(), key=lambda t: key(t[0]))))

    @staticmethod
    def thaw(f) -> NF:
        return NF(f[1], dict(f[2]))

    def __eq__(self, other):
        return isinstance(other, NF) and self.shape == other.shape and self.terms == other.terms

    __hash__ = None  # type: ignore[assignment]


def _shape_text(shape) -> str:
    return "a scalar" if shape is None else f"{shape[0].text()} × {shape[1].text()}"


def accumulate(out: dict, mono, c) -> None:
    total = c_add(out[mono], c) if mono in out else c
    if is_zero(total):
        out.pop(mono, None)
    else:
        out[mono] = total


class Context:
    """Normalisation for one statement: its declarations, coefficient field and side conditions."""

    def __init__(self, st: Statement, index_sets: dict | None = None, partitions: dict | None = None,
                 field_of: Context | None = None):
        self.st = st
        #: index sets and partitions: the statement's, and bases a certificate adds
        self.index_sets = dict(st.index_sets, **(index_sets or {}))
        self.partitions = dict(st.partitions, **(partitions or {}))
        names = list(st.sizes) + list(st.params)
        self.field: Any
        self.gens: dict
        if field_of is not None:  # the same coefficient field, so that coefficients compare
            self.field, self.gens = field_of.field, field_of.gens
        else:
            self.field, *gens = field([f"g{k}" for k in range(len(names))] or ["g"], QQ)
            self.gens = dict(zip(names, gens))
        self.symmetric, self.spd = set(), set()
        for h in st.hypotheses:
            body = h[3] if isinstance(h, tuple) and h and h[0] == "every" and len(h) == 4 else h
            if isinstance(body, tuple) and len(body) == 2 and body[0] in ("sym", "spd") and _letter(body[1]):
                # Xᵀ = X enters the normal form for an unindexed letter, or a family's letter for every member
                # (not for "every m: X" with X free of m: that says nothing when there is no m)
                if (h is body and len(body[1]) == 2) or (h[0] == "every" and len(body[1]) == 3
                                                         and body[1][2] == h[1]):
                    self.symmetric.add(body[1][1])
                    if body[0] == "spd":
                        self.spd.add(body[1][1])
        #: side conditions met while normalising: ("invertible" | "positive", frozen NF) or ("nonzero", coefficient)
        self.needs: list = []
        self._fresh = itertools.count()
        self._definitions: dict = {}
        self._transposed: dict = {}
        self._expanding: set = set()

    # ---- sizes and indices ----------------------------------------------------------------------
    def size(self, text, scope: dict) -> Size:
        return self.resolve(parse_size(text), scope)

    def resolve(self, s: Size, scope: dict) -> Size:
        """A size read with index names, with each index resolved to its reference in ``scope``."""
        out = {}
        for name, index, c in s.atoms:
            if index is None:
                if name not in self.st.sizes:
                    fail(f"unknown size symbol {name!r}")
                out[(name, None)] = c
            else:
                if name not in self.st.indexed_sizes:
                    fail(f"{name!r} is not a family of sizes")
                out[(name, self.index(index, self.st.indexed_sizes[name], scope))] = c
        return Size.of(s.const, out)

    def index(self, name, index_set: str, scope: dict):
        binding = scope.get(name)
        if not (isinstance(binding, tuple) and binding[0] == "index"):
            fail(f"{name!r} is not an index in scope")
        if binding[2] != index_set:
            fail(f"the index {name!r} ranges over {binding[2]!r}, not {index_set!r}")
        return binding[1]

    def scope(self) -> dict:
        """The statement's top level: its free indices."""
        return {name: ("index", ("@f", name), s) for name, s in self.st.free_indices.items()}

    def number(self, size: Size):
        """A size as a coefficient (only sums of plain size symbols are numbers)."""
        total = Fraction(size.const)
        for name, index, c in size.atoms:
            if index is not None:
                fail(f"the size {size.text()} of a family member cannot be used as a number")
            if name not in self.st.sizes:  # an index set counted by a parameter, say
                fail(f"unknown size symbol {name!r}")
            total = c_add(total, c_mul(Fraction(c), _lower(self.gens[name])))
        return total

    # ---- monomials ----------------------------------------------------------------------------
    def mono_mul(self, m1, m2):
        (p1, e1), b1, w1 = m1
        shift = len(b1)
        (p2, e2), b2, w2 = walk(m2, lambda r: ("@b", r[1] + shift) if r[0] == "@b" else r)
        powers = dict(p1)
        for atom, exponent in p2:
            accumulate(powers, atom, exponent)
        if e1 is None or e2 is None:
            exp = e1 if e2 is None else e2
        else:
            total = self.add(NF.thaw(e1), NF.thaw(e2))
            exp = None if total.is_zero else total.frozen()
        return ((tuple(sorted(powers.items(), key=lambda t: key(t[0]))), exp), b1 + b2, w1 + w2)

    def canon(self, mono, shape):
        """The canonical monomial (N3, N5) and the count factor of the sums it drops. Only the monomial's
        own bound positions are sifted and renumbered: a normal form nested in an atom (the body of a
        pinv, say) may mention its enclosing monomial's, and Σ_x f(S_xᵀS_y) ≠ f(I) for f nonlinear."""
        scalars, binders, word = mono
        own = lambda r: r[0] == "@b" and r[1] < len(binders)  # noqa: E731
        removed: set = set()
        changed = True
        while changed:
            changed = False
            for p in range(len(word) - 1):
                a, b = word[p], word[p + 1]
                if not (a[0] == b[0] == "s" and a[1] == b[1] and a[3] and not b[3]):
                    continue
                x, y = a[2], b[2]
                rest = word[:p] + word[p + 2:]
                if x == y:  # S_iᵀS_i = I
                    word = rest
                elif own(x):  # Σ_x u(x) S_xᵀS_y w(x) = u(y) w(y)
                    scalars, word = _replace((scalars, rest), x, y)
                    removed.add(x[1])
                elif own(y):
                    scalars, word = _replace((scalars, rest), y, x)
                    removed.add(y[1])
                else:
                    continue
                changed = True
                break
        words = [word]
        if shape is not None and shape[0].is_one and shape[1].is_one and word:
            words.append(self.tword(word))
        best, factor = None, Fraction(1)
        for w in words:
            order = [r[1] for r in refs((w, scalars), []) if own(r)]
            mapping = {old: new for new, old in enumerate(order)}
            renamed = walk((scalars, w), lambda r, mapping=mapping: ("@b", mapping[r[1]]) if own(r) else r)
            candidate = (renamed[0], tuple(binders[k] for k in order), renamed[1])
            if best is None or key(candidate) < key(best):
                best, unused = candidate, [k for k in range(len(binders)) if k not in removed and k not in mapping]
        for k in unused:
            factor = c_mul(factor, self.number(self.index_sets[binders[k]]))
        return best, factor

    # ---- operations ----------------------------------------------------------------------------
    def add(self, a: NF, b: NF) -> NF:
        if a.shape != b.shape:
            fail(f"ill-typed sum: {_shape_text(a.shape)} plus {_shape_text(b.shape)}")
        out = dict(a.terms)
        for m, c in b.terms.items():
            accumulate(out, m, c)
        return NF(a.shape, out)

    def scale(self, a: NF, c) -> NF:
        return NF(a.shape, {m: c_mul(v, c) for m, v in a.terms.items()} if not is_zero(c) else {})

    def mul(self, a: NF, b: NF) -> NF:
        if a.shape is None or b.shape is None:
            shape = b.shape if a.shape is None else a.shape
        elif a.shape[1] != b.shape[0]:
            fail(f"ill-typed product: {_shape_text(a.shape)} times {_shape_text(b.shape)}")
        else:
            shape = (a.shape[0], b.shape[1])
        out: dict = {}
        for m1, c1 in a.terms.items():
            for m2, c2 in b.terms.items():
                mono, factor = self.canon(self.mono_mul(m1, m2), shape)
                accumulate(out, mono, c_mul(c_mul(c1, c2), factor))
        return NF(shape, out)

    def tatom(self, atom):
        if atom[0] == "v" and atom[1] in self.symmetric:
            return atom
        if atom[0] in ("v", "s"):
            return (atom[0], atom[1], atom[2], not atom[3])
        body = atom[-1]  # pinv: (A⁺)ᵀ = (Aᵀ)⁺; int: (∫ f)ᵀ = ∫ fᵀ
        if body not in self._transposed:
            self._transposed[body] = self.transpose(NF.thaw(body)).frozen()
        return (*atom[:-1], self._transposed[body])

    def tword(self, word):
        return tuple(self.tatom(a) for a in reversed(word))

    def transpose(self, a: NF) -> NF:
        if a.shape is None:
            return a
        shape = (a.shape[1], a.shape[0])
        out: dict = {}
        for (scalars, binders, word), c in a.terms.items():
            mono, factor = self.canon((scalars, binders, self.tword(word)), shape)
            accumulate(out, mono, c_mul(c, factor))
        return NF(shape, out)

    def atom(self, atom, shape) -> NF:
        return NF(shape, {(EMPTY, (), (atom,)): Fraction(1)})

    def scalar(self, c, powers=(), exp=None) -> NF:
        return NF(None, {((powers, exp), (), ()): c} if not is_zero(c) else {})

    def identity(self, size: Size) -> NF:
        return NF((size, size), {(EMPTY, (), ()): Fraction(1)})

    def trace(self, a: NF) -> NF:
        if a.shape is None or a.shape[0] != a.shape[1]:
            fail(f"trace of {_shape_text(a.shape)}")
        out: dict = {}
        for ((powers, exp), binders, word), c in a.terms.items():
            if not word:  # tr(I_n) = n
                mono, factor = self.canon(((powers, exp), binders, ()), None)
                accumulate(out, mono, c_mul(c_mul(c, self.number(a.shape[0])), factor))
                continue
            best: Any = None
            for w in (word, self.tword(word)):
                for k in range(len(w)):
                    atoms = dict(powers)
                    accumulate(atoms, ("tr", w[k:] + w[:k]), Fraction(1))
                    cand = self.canon(((tuple(sorted(atoms.items(), key=lambda t: key(t[0]))), exp), binders, ()),
                                      None)
                    if best is None or key(cand[0]) < key(best[0]):
                        best = cand
            accumulate(out, best[0], c_mul(c, best[1]))
        return NF(None, out)

    def power(self, a: NF, exponent) -> NF:
        """a^exponent, the exponent a rational or (for a positive base) a rational function of the sizes."""
        if a.shape is not None:
            fail("a power of a matrix: only numbers have powers")
        integer = isinstance(exponent, Fraction) and exponent.denominator == 1
        if integer and 0 <= exponent <= MAX_POWER:  # a product of copies
            out = self.scalar(Fraction(1))
            for _ in range(int(exponent)):
                out = self.mul(out, a)
            return out
        if integer and abs(exponent) > MAX_POWER:  # c^e would be computed digit by digit
            fail(f"a power beyond ±{MAX_POWER} is not expanded")
        if len(a.terms) != 1:
            fail("a negative or fractional power of a sum")
        ((powers, exp), binders, _), c = next(iter(a.terms.items()))
        if binders:
            fail("a negative or fractional power of a sum over an index")
        if not integer and c != 1:
            fail("a fractional power of a number other than 1")
        if integer:
            if exponent < 0 and not isinstance(c, Fraction):
                self.needs.append(("nonzero", c))
            elif exponent < 0 and c == 0:
                fail("division by zero")
            c = _lower(c ** int(exponent))
        atoms = []
        for atom, e in powers:
            if atom[0] in ("tr", "int"):
                fail(f"a negative or fractional power of {'a trace' if atom[0] == 'tr' else 'an integral'}")
            if atom[0] == "det" and not (integer and exponent > 0):
                self.needs.append(("invertible" if integer else "positive", atom[1]))
            atoms.append((atom, c_mul(e, exponent)))
        scaled = None if exp is None else self.scale(NF.thaw(exp), exponent).frozen()
        return self.scalar(c, tuple(atoms), scaled)

    # ---- terms -------------------------------------------------------------------------------
    def nf(self, term, scope: dict) -> NF:
        """The normal form of ``term`` in ``scope`` (index names, bound variables)."""
        if not isinstance(term, tuple) or not term or not isinstance(term[0], str):
            fail(f"not a term: {str(term)[:80]}")
        head, args = term[0], term[1:]
        handler = getattr(self, "_" + _HANDLERS.get(head, "unknown"))
        if head in _HANDLERS:
            _expand(head, len(args))
        return handler(args, scope, head)

    def _unknown(self, args, scope, head):
        fail(f"unknown term form {head!r}")

    def _var(self, args, scope, head):
        name, index = args[0], (args[1] if len(args) > 1 else None)
        bound = scope.get(name)
        if isinstance(bound, tuple) and bound[0] in ("nf", "matrix"):
            if index is not None:
                fail(f"{name} is not a family")
            return bound[1] if bound[0] == "nf" else self.atom(("v", bound[2], None, False), bound[1])
        decl = self.st.variables.get(name) or self.st.definitions.get(name)
        if decl is None:
            fail(f"unknown name {name!r}")
        if (decl.over is None) != (index is None):
            fail(f"{name} is {'a family: it needs an index' if index is None else 'not a family'}")
        ref = None if index is None else self.index(index, decl.over, scope)
        if name in self.st.definitions:
            if decl.args:
                fail(f"the definition {name} takes arguments: use ['call', {name!r}, [...]]")
            body = self._definition(name, decl, ref, ())
            if decl.opaque:  # a letter of its own (its defining equation is generator G7)
                if body.shape is None:
                    fail(f"the opaque definition {name} is a number: only matrices can be opaque")
                return self.atom(("v", name, ref, False), body.shape)
            return body
        inner = {HEAD: ("index", ref, decl.over)} if ref is not None else {}
        return self.atom(("v", name, ref, False), (self.resolve(decl.rows, inner), self.resolve(decl.cols, inner)))

    def _call(self, args, scope, head):
        name, actual = args[0], args[1]
        index = args[2] if len(args) > 2 else None
        decl = self.st.definitions.get(name)
        if decl is None or not decl.args:
            fail(f"{name!r} is not a definition with arguments")
        if (decl.over is None) != (index is None) or len(actual) != len(decl.args):
            fail(f"{name} called with {len(actual)} arguments{' and no index' if index is None else ''}")
        ref = None if index is None else self.index(index, decl.over, scope)
        values = tuple(self.nf(t, scope) for t in actual)
        return self._definition(name, decl, ref, values)

    def _definition(self, name, decl, ref, values):
        """The body, normalised in its own scope (its index and arguments only): nothing is captured."""
        inner = {HEAD: ("index", ref, decl.over)} if ref is not None else {}
        for (arg, rows, cols), value in zip(decl.args, values):
            shape = (self.resolve(rows, inner), self.resolve(cols, inner))
            if value.shape != shape:
                fail(f"{name}: the argument {arg} is {_shape_text(shape)}, got {_shape_text(value.shape)}")
            inner[arg] = ("nf", value)
        cache = (name, ref, tuple(v.frozen() for v in values))
        if cache not in self._definitions:
            if name in self._expanding:
                fail(f"the definition {name} refers to itself")
            self._expanding.add(name)
            try:
                self._definitions[cache] = self.nf(decl.body, inner)
            finally:
                self._expanding.discard(name)
        return self._definitions[cache]

    def body(self, name: str, index, scope: dict) -> NF:
        """The expansion of a definition without arguments (for an opaque one: its defining equation)."""
        decl = self.st.definitions.get(name)
        if decl is None or decl.args:
            fail(f"{name!r} is not a definition without arguments")
        if (decl.over is None) != (index is None):
            fail(f"{name} needs {'an' if decl.over else 'no'} index")
        return self._definition(name, decl, None if index is None else self.index(index, decl.over, scope), ())

    def _sel(self, args, scope, head):
        family, index = args
        if family not in self.partitions:
            fail(f"unknown partition {family!r}")
        over, total, part = self.partitions[family]
        ref = self.index(index, over, scope)
        inner = {HEAD: ("index", ref, over)}
        return self.atom(("s", family, ref, False), (self.resolve(total, self.scope()), self.resolve(part, inner)))

    def _I(self, args, scope, head):
        return self.identity(self.size(args[0], scope))

    def _0(self, args, scope, head):
        return NF((self.size(args[0], scope), self.size(args[1], scope)), {})

    def _plus(self, args, scope, head):
        if not args:
            fail("an empty sum")
        out = self.nf(args[0], scope)
        for t in args[1:]:
            out = self.add(out, self.nf(t, scope))
        return out

    def _times(self, args, scope, head):
        if not args:
            fail("an empty product")
        out = self.nf(args[0], scope)
        for t in args[1:]:
            out = self.mul(out, self.nf(t, scope))
        return out

    def _T(self, args, scope, head):
        return self.transpose(self.nf(args[0], scope))

    def _pinv(self, args, scope, head):
        a = self.nf(args[0], scope)
        if a.shape is None:
            fail("pinv of a number")
        if any(binders for (_, binders, _) in a.terms):
            fail("pinv of a sum over an index is not supported")
        if head == "inv":
            if a.shape[0] != a.shape[1]:
                fail(f"the inverse of a {_shape_text(a.shape)} matrix")
            self.needs.append(("invertible", a.frozen()))
        return self.atom(("p", a.frozen()), (a.shape[1], a.shape[0]))

    def _sum(self, args, scope, head):
        name, index_set, body = args
        if name in self.st.names or name in scope or name == HEAD:
            fail(f"the index name {name!r} is already in use")
        if index_set not in self.index_sets:
            fail(f"unknown index set {index_set!r}")
        ref = ("@x", next(self._fresh))
        return self.close(self.nf(body, dict(scope, **{name: ("index", ref, index_set)})), ref, index_set)

    def close(self, inner: NF, ref, index_set: str) -> NF:
        """Σ over the index ``ref`` (of ``index_set``) of ``inner``."""
        if ref in refs(inner.shape, []):
            fail("the terms of a sum change size with its index")
        out: dict = {}
        for ((scalars, binders, word)), c in inner.terms.items():
            moved = _replace((scalars, word), ref, ("@b", len(binders)))
            mono, factor = self.canon((moved[0], binders + (index_set,), moved[1]), inner.shape)
            accumulate(out, mono, c_mul(c, factor))
        return NF(inner.shape, out)

    def _num(self, args, scope, head):
        return self.scalar(number(args[0]))

    def _param(self, args, scope, head):
        if args[0] not in self.st.params:
            fail(f"unknown parameter {args[0]!r}")
        return self.scalar(_lower(self.gens[args[0]]))

    def _sizenum(self, args, scope, head):
        return self.scalar(self.number(self.size(args[0], scope)))

    def _pow(self, args, scope, head):
        if isinstance(args[1], tuple):  # an exponent that is a term: a rational function of sizes and parameters
            e = self.nf(args[1], scope)
            if e.shape is not None or len(e.terms) > 1 or (e.terms and next(iter(e.terms)) != (EMPTY, (), ())):
                fail("an exponent must be a number or a rational function of sizes and parameters")
            return self.power(self.nf(args[0], scope), next(iter(e.terms.values())) if e.terms else Fraction(0))
        return self.power(self.nf(args[0], scope), number(args[1]))

    def _int(self, args, scope, head):
        """∫_{x ∈ ℝⁿ} body dx: an atom (its variable renamed canonically); rules apply only through G9."""
        name, size, body = args
        if name in self.st.names or name in scope:
            fail(f"the integration variable {name!r} is in use")
        inner = self.nf(body, dict(scope, **{name: ("matrix", (self.size(size, scope), parse_size(1)), INTEGRATION)}))
        if any(binders for (_, binders, _) in inner.terms):
            fail("an integral of a sum over an index is not supported")
        if _holds_integral(inner.frozen()):  # written inside, or brought in by a definition (whose argument
            fail("an integral inside an integral is not supported")  # could be the outer variable)
        atom = ("int", self.size(size, scope), inner.frozen())
        if inner.shape is None:
            return self.scalar(Fraction(1), ((atom, Fraction(1)),))
        return self.atom(atom, inner.shape)

    def _tr(self, args, scope, head):
        return self.trace(self.nf(args[0], scope))

    def _det(self, args, scope, head):
        a = self.nf(args[0], scope)
        if a.shape is None or a.shape[0] != a.shape[1]:
            fail(f"det of {_shape_text(a.shape)}")
        if any(binders for (_, binders, _) in a.terms):  # its bound positions would mix with the outer monomial's
            fail("det of a sum over an index is not supported")
        atom = self.det_atom(a)
        return self.scalar(Fraction(1)) if atom is None else self.scalar(Fraction(1), ((atom, Fraction(1)),))

    def det_atom(self, a: NF):
        """det(a) as a canonical atom (det(Xᵀ) = det(X)), or None for det(I) = 1."""
        if a == self.identity(a.shape[0]):
            return None
        return ("det", min(a.frozen(), self.transpose(a).frozen(), key=key))

    def _exp(self, args, scope, head):
        a = self.nf(args[0], scope)
        one = parse_size(1)
        if a.shape is None:
            a = self.mul(a, self.identity(one))
        if a.shape != (one, one):
            fail(f"exp of {_shape_text(a.shape)}")
        if any(scalars != EMPTY or binders for (scalars, binders, _) in a.terms):
            fail("exp of a term with traces, determinants, exponentials or sums")
        return self.scalar(Fraction(1), (), a.frozen() if a.terms else None)

    def _twopi(self, args, scope, head):
        return self.scalar(Fraction(1), ((("2pi",), Fraction(1)),))


_HANDLERS = {"var": "var", "call": "call", "sel": "sel", "I": "I", "0": "0", "+": "plus", "*": "times", "T": "T",
             "pinv": "pinv", "inv": "pinv", "sum": "sum", "num": "num", "param": "param", "size": "sizenum",
             "^": "pow", "tr": "tr", "det": "det", "exp": "exp", "2pi": "twopi", "int": "int"}


def _holds_integral(obj) -> bool:
    """Whether a frozen normal form holds an integral atom anywhere."""
    return isinstance(obj, tuple) and bool(obj) and (obj[0] == "int" or any(_holds_integral(o) for o in obj))


def _letter(term) -> bool:
    return isinstance(term, tuple) and len(term) in (2, 3) and term[0] == "var"
