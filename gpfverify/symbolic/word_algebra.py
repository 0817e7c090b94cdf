"""A small, explicit rewriting system for dimension-free matrix identities.

An expression is a noncommutative polynomial: a sum of rational multiples of *words*, a word being
a product of letters. A letter is a real matrix symbol of symbolic size (sympy ``Symbol`` rows and
columns, e.g. n states × l outputs), possibly transposed. The only built-in algebra is what holds
in every ring of real matrices:

* associativity and distributivity (words are flat tuples; sums are expanded);
* transposition: (XY)ᵀ = YᵀXᵀ, (Xᵀ)ᵀ = X, pushed down to the letters (no letter is its own
  transpose: symmetry is a rule);
* a 1×1 word equals its transpose (it is a scalar); such words are stored in a canonical order;
* the empty word is the identity of the right size, I·X = X;
* the trace (:func:`trace`): linear, tr(XY) = tr(YX), tr(Xᵀ) = tr(X), tr(I_k) = k, and
  tr(WᵀW) = Σ_ij W_ij² ≥ 0 (:func:`prove_size_bound`).

There is no inverse and no power: ``X.I`` and ``X ** -1`` raise :class:`InputError`. An inverse,
a pseudo-inverse or a left inverse is a letter of its own that nothing relates to X except the
rules of the :class:`~gpfverify.symbolic.theory.Theory` that declared it, so nothing cancels when
an expression is built.

Everything else is a :class:`Rule` issued by a theory (library axioms of its declarations,
definitions of fresh letters, hypotheses) or derived here:

* :func:`prove_by_normal_form` rewrites ``lhs − rhs`` with the oriented rules (left side a single
  word) until no rule applies and accepts iff the result is the zero polynomial;
* :func:`prove_by_chain` accepts e₀ = lhs, …, e_k = rhs iff every e_{j+1} − e_j equals
  c·u(L − R)w for the named rule L = R (or its transpose), words u, w and a rational c;
* :func:`prove_trace_identity` and :func:`prove_size_bound` do the same for traces.

Each proof records the rule *objects* it applied (:attr:`Proof.used`), not the rules an author
listed: the certificate (:mod:`gpfverify.symbolic.argument`) checks exactly those. All provers are
sound — each accepted step replaces equals by equals — and none is complete, so a rejected
statement is not thereby false: negative controls also evaluate each mutant on exact instances.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from fractions import Fraction as Q
from typing import Any

import sympy as sp

from gpfverify.errors import InputError

NO_INVERSE = ("the word algebra has no inverse and no power: an inverse is a letter of its own, declared with "
              "Theory.inverse and related to its matrix only by the rules that declaration issues")


# ---- letters, words, expressions ------------------------------------------------------------------

@dataclass(frozen=True, order=True)
class Letter:
    """A matrix symbol ``name`` of size rows × cols, or its transpose."""

    name: str
    rows: sp.Expr = field(compare=False)
    cols: sp.Expr = field(compare=False)
    transposed: bool = False

    @property
    def shape(self):
        return (self.cols, self.rows) if self.transposed else (self.rows, self.cols)

    @property
    def T(self) -> Letter:
        return Letter(self.name, self.rows, self.cols, not self.transposed)

    def __str__(self) -> str:
        return self.name + ("ᵀ" if self.transposed else "")

    def key(self):
        return (self.name, self.transposed)


Word = tuple  # tuple[Letter, ...]


def _word_key(word: Word):
    return tuple(letter.key() for letter in word)


def _transpose_word(word: Word) -> Word:
    return tuple(letter.T for letter in reversed(word))


class ShapeError(InputError):
    """A product or sum of matrices whose sizes do not match."""


def same_size(a, b) -> bool:
    return sp.expand(sp.sympify(a) - sp.sympify(b)) == 0


@dataclass(frozen=True)
class Expr:
    """Σ coefficient · word, of the given shape (rows, cols). The empty word is the identity."""

    shape: tuple
    terms: tuple  # ((word, Fraction), ...) sorted by word key, no zero coefficients

    # -- construction ----------------------------------------------------------------------------
    @staticmethod
    def of(terms: dict, shape) -> Expr:
        merged: dict = {}
        words: dict = {}
        for word, coeff in terms.items():
            if shape[0] == 1 and shape[1] == 1:  # a scalar equals its transpose: canonical order
                other = _transpose_word(word)
                if _word_key(other) < _word_key(word):
                    word = other
            k = _word_key(word)
            merged[k] = merged.get(k, Q(0)) + Q(coeff)
            words[k] = word
        items = tuple(sorted(((words[k], c) for k, c in merged.items() if c != 0), key=lambda t: _word_key(t[0])))
        return Expr(tuple(shape), items)

    @property
    def is_zero(self) -> bool:
        return not self.terms

    @property
    def letters(self) -> frozenset:
        """The names of the letters it contains."""
        return frozenset(letter.name for word, _ in self.terms for letter in word)

    # -- algebra ---------------------------------------------------------------------------------
    def __add__(self, other: Expr) -> Expr:
        if not (same_size(self.shape[0], other.shape[0]) and same_size(self.shape[1], other.shape[1])):
            raise ShapeError(f"sum of {self.shape} and {other.shape}")
        total: dict = {}
        for w, c in self.terms + other.terms:
            total[w] = total.get(w, Q(0)) + c
        return Expr.of(total, self.shape)

    def __neg__(self) -> Expr:
        return Expr.of({w: -c for w, c in self.terms}, self.shape)

    def __sub__(self, other: Expr) -> Expr:
        return self + (-other)

    def __mul__(self, other) -> Expr:
        if not isinstance(other, Expr):
            return Expr.of({w: c * Q(other) for w, c in self.terms}, self.shape)
        if not same_size(self.shape[1], other.shape[0]):
            raise ShapeError(f"product of {self.shape} and {other.shape}")
        out: dict = {}
        for w1, c1 in self.terms:
            for w2, c2 in other.terms:
                w = w1 + w2
                out[w] = out.get(w, Q(0)) + c1 * c2
        return Expr.of(out, (self.shape[0], other.shape[1]))

    def __rmul__(self, scalar) -> Expr:
        return self * scalar

    def __pow__(self, exponent):
        raise InputError(NO_INVERSE)

    @property
    def I(self):  # noqa: E743 - sympy's spelling of the inverse, refused on purpose
        raise InputError(NO_INVERSE)

    def inverse(self):
        raise InputError(NO_INVERSE)

    @property
    def T(self) -> Expr:
        return Expr.of({_transpose_word(w): c for w, c in self.terms}, (self.shape[1], self.shape[0]))

    def __eq__(self, other) -> bool:
        if not isinstance(other, Expr):
            return False
        try:
            return (self - other).is_zero
        except ShapeError:
            return False

    def __hash__(self):
        return hash(self.terms)

    def __str__(self) -> str:
        if not self.terms:
            return "0"
        parts = []
        for word, coeff in self.terms:
            body = "·".join(map(str, word)) if word else "I"
            sign = "−" if coeff < 0 else "+"
            mag = abs(coeff)
            parts.append(f"{sign} {'' if mag == 1 else str(mag) + '·'}{body}")
        text = " ".join(parts)
        return text[2:] if text.startswith("+ ") else text

    # -- substitution ----------------------------------------------------------------------------
    def substitute(self, letters: dict, sizes: dict | None = None) -> Expr:
        """Every letter named in ``letters`` (name -> Expr of the letter's shape after ``sizes``)
        replaced by its expression (Xᵀ by its transpose), every size symbol in ``sizes`` by its
        value. Sound for an identity that holds for every value of the replaced letters."""
        sizes = sizes or {}
        shape = tuple(sp.sympify(s).subs(sizes) for s in self.shape)
        total = zero(*shape)
        for word, coeff in self.terms:
            piece = identity(shape[0])
            for letter in word:
                rows, cols = (sp.sympify(s).subs(sizes) for s in (letter.rows, letter.cols))
                if letter.name in letters:
                    value = letters[letter.name]
                    if not (same_size(value.shape[0], rows) and same_size(value.shape[1], cols)):
                        raise ShapeError(f"{letter.name} ({rows}×{cols}) replaced by an expression of shape "
                                         f"{value.shape}")
                else:
                    value = symbol(letter.name, rows, cols)
                piece = piece * (value.T if letter.transposed else value)
            total = total + piece * coeff
        return total

    # -- evaluation on an exact instance ---------------------------------------------------------
    def evaluate(self, values: dict, sizes: dict) -> sp.Matrix:
        """The exact sympy Matrix for letter values ``values`` (name -> Matrix) and sizes
        ``sizes`` (size symbol -> int). A letter without a value raises KeyError, a value of the
        wrong shape ShapeError."""
        rows, cols = (size_at(s, sizes) for s in self.shape)
        total = sp.zeros(rows, cols)
        for word, coeff in self.terms:
            m = sp.eye(rows)
            for letter in word:
                v = values[letter.name]
                if v is None:
                    raise KeyError(letter.name)
                expected = (size_at(letter.rows, sizes), size_at(letter.cols, sizes))
                if v.shape != expected:
                    raise ShapeError(f"{letter.name} has a value of shape {v.shape}, not {expected}")
                m = m * (v.T if letter.transposed else v)
            total += sp.Rational(coeff.numerator, coeff.denominator) * m
        return total


_SIZES: dict = {}


def size_at(size, sizes: dict) -> int:
    """The integer value of a size expression at integer values of its symbols (memoised: shapes
    are evaluated for every letter of every word on every instance)."""
    key = (size, frozenset(sizes.items()))
    if key not in _SIZES:
        _SIZES[key] = int(sp.sympify(size).xreplace(sizes))
    return _SIZES[key]


def symbol(name: str, rows, cols) -> Expr:
    """The matrix symbol ``name`` (rows × cols) as an expression, with nothing known about it. A
    proof uses letters declared by a :class:`~gpfverify.symbolic.theory.Theory`."""
    return Expr.of({(Letter(name, sp.sympify(rows), sp.sympify(cols)),): 1}, (sp.sympify(rows), sp.sympify(cols)))


def identity(size) -> Expr:
    size = sp.sympify(size)
    return Expr.of({(): 1}, (size, size))


def zero(rows, cols) -> Expr:
    return Expr.of({}, (sp.sympify(rows), sp.sympify(cols)))


# ---- rules ----------------------------------------------------------------------------------------

#: axiom: issued by a theory's declaration (a theorem of matrix algebra about what it declares);
#: definition: a fresh letter := expression; hypothesis: assumed, carried into the statement;
#: fact: stated, checked on instances, never proved;
#: lemma / induction / instance: derived by this module or by the theory (each carries how)
KINDS = ("axiom", "definition", "hypothesis", "fact", "lemma", "induction", "instance")


@dataclass(frozen=True, eq=False)
class Rule:
    """``lhs = rhs`` with a name and a kind (:data:`KINDS`). Rules compare by identity: only the
    objects a theory issued (or a derivation made) count, never a look-alike built by hand."""

    name: str
    lhs: Any  # Expr; a Scalar for a stated fact about traces
    rhs: Any
    kind: str
    #: the hypotheses (Rule objects) it rests on; a hypothesis also rests on itself
    premises: frozenset = frozenset()
    #: lemma: its Proof; induction / instance: the derivation record
    derivation: object = None
    #: hypothesis: the words a statement resting on it must carry, and what it restricts
    phrase: str = ""
    restricts: tuple = ()
    #: hypothesis: the letters it is universally quantified over ("for every measurement y")
    for_all: tuple = ()

    def __post_init__(self):
        if self.kind not in KINDS:
            raise InputError(f"rule kind must be one of {KINDS}, got {self.kind!r}")

    @property
    def rests_on(self) -> frozenset:
        return self.premises | {self} if self.kind == "hypothesis" else self.premises

    @property
    def difference(self) -> Expr:
        return self.lhs - self.rhs

    @property
    def oriented(self) -> bool:
        """Usable by normal-form rewriting: the left side is a single word with coefficient 1."""
        return len(self.lhs.terms) == 1 and self.lhs.terms[0][1] == 1 and len(self.lhs.terms[0][0]) > 0

    def __str__(self) -> str:
        return f"{self.name}: {self.lhs} = {self.rhs}"


@dataclass(frozen=True)
class _Oriented:
    """A rule or its transpose, as normal-form rewriting uses it (``origin`` is what it records)."""

    lhs: Expr
    rhs: Expr
    origin: Rule


def _versions(rule: Rule) -> list[_Oriented]:
    if not isinstance(rule.lhs, Expr):  # a rule about traces rewrites traces only (trace_normal_form)
        return []
    # a rule whose transpose is its own reverse (Cᵀ = C, (AA⁺)ᵀ = AA⁺) is used one way only
    both = [_Oriented(rule.lhs, rule.rhs, rule)]
    if not rule.lhs.T == rule.rhs:
        both.append(_Oriented(rule.lhs.T, rule.rhs.T, rule))
    return [v for v in both if len(v.lhs.terms) == 1 and v.lhs.terms[0][1] == 1 and v.lhs.terms[0][0]]


def _find(word: Word, pattern: Word) -> Iterable[int]:
    keys, pkeys = _word_key(word), _word_key(pattern)
    n = len(pkeys)
    for i in range(len(keys) - n + 1):
        if keys[i:i + n] == pkeys:
            yield i


class NotTerminating(RuntimeError):
    pass


def _outer_rows(prefix: Word, default):
    return prefix[0].shape[0] if prefix else default


def _outer_cols(suffix: Word, default):
    return suffix[-1].shape[1] if suffix else default


def _reshape(expr: Expr, shape) -> Expr:
    return Expr.of({w: c for w, c in expr.terms}, shape)


def _splice(prefix: Word, middle: Expr, suffix: Word, rows, cols) -> Expr:
    """prefix · middle · suffix as an expression of shape (rows, cols)."""
    left = Expr.of({prefix: 1}, (_outer_rows(prefix, rows), middle.shape[0]))
    right = Expr.of({suffix: 1}, (middle.shape[1], _outer_cols(suffix, cols)))
    return _reshape(left * middle * right, (rows, cols))


def normal_form(expr: Expr, rules: list[Rule], max_steps: int = 5000) -> tuple[Expr, dict]:
    """Rewrite with the oriented rules (and their transposes), leftmost-first, to a fixed point.
    Returns the result and {rule object: applications}."""
    oriented = [v for rule in rules for v in _versions(rule)]
    used: dict = {}
    current = expr
    for _ in range(max_steps):
        step = None
        for word, coeff in current.terms:
            for rule in oriented:
                hit = next(iter(_find(word, rule.lhs.terms[0][0])), None)
                if hit is not None:
                    step = (word, coeff, rule, hit)
                    break
            if step:
                break
        if step is None:
            return current, used
        word, coeff, rule, hit = step
        pattern = rule.lhs.terms[0][0]
        replacement = _splice(word[:hit], rule.rhs, word[hit + len(pattern):], *current.shape) * coeff
        current = current - Expr.of({word: coeff}, current.shape) + replacement
        used[rule.origin] = used.get(rule.origin, 0) + 1
    raise NotTerminating(f"no normal form within {max_steps} rewrites")


def one_application(diff: Expr, rule: Rule) -> bool:
    """diff == c·u(L − R)w for words u, w and a rational c (L = R the rule or its transpose)."""
    if diff.is_zero:
        return True
    for delta in (rule.difference, rule.difference.T):
        if delta.is_zero:
            continue
        anchor_word, anchor_coeff = max(delta.terms, key=lambda t: len(t[0]))
        for word, coeff in diff.terms:
            candidates = [word]
            if diff.shape[0] == 1 and diff.shape[1] == 1:
                candidates.append(_transpose_word(word))
            for cand in candidates:
                for i in _find(cand, anchor_word) if anchor_word else range(len(cand) + 1):
                    try:
                        candidate = _splice(cand[:i], delta, cand[i + len(anchor_word):], *diff.shape)
                    except ShapeError:
                        continue
                    if candidate * (coeff / anchor_coeff) == diff:
                        return True
    return False


# ---- proofs ---------------------------------------------------------------------------------------

@dataclass(eq=False)
class Proof:
    """One proof attempt: the formal statement ``lhs relation rhs``, accepted or not, the rule
    objects it applied and a readable trace."""

    statement: str
    lhs: Any  # Expr, or Scalar for a trace proof, or a size for a bound
    rhs: Any
    proved: bool
    used: tuple
    trace: str
    relation: str = "="
    #: how it was made ("normal form", "chain", "trace", "bound") and what replaying it needs
    method: str = ""
    data: tuple = ()

    @property
    def premises(self) -> frozenset:
        """The hypotheses the rules it applied rest on."""
        return frozenset().union(*(r.rests_on for r in self.used))

    @property
    def formal(self) -> str:
        return f"{self.lhs} {self.relation} {self.rhs}"


def _failed(statement: str, lhs, rhs, reason: str, relation: str = "=") -> Proof:
    return Proof(statement, lhs, rhs, False, (), f"no proof: {reason}", relation)


def _by_rewriting(lhs, rhs, rules: list[Rule], statement: str, rewrite, method: str) -> Proof:
    """lhs = rhs iff ``rewrite`` takes lhs − rhs to zero with ``rules``."""
    statement = statement or f"{lhs} = {rhs}"
    try:
        result, used = rewrite(lhs - rhs, rules)
    except (NotTerminating, ShapeError) as err:
        return _failed(statement, lhs, rhs, str(err))
    trace = f"lhs − rhs rewrites to {result} using " + ", ".join(f"{r.name}×{k}" for r, k in used.items())
    return Proof(statement, lhs, rhs, result.is_zero, tuple(used), trace, method=method)


def prove_by_normal_form(lhs: Expr, rhs: Expr, rules: list[Rule], statement: str = "") -> Proof:
    return _by_rewriting(lhs, rhs, rules, statement, normal_form, "normal form")


def prove_by_chain(chain: list[tuple[Expr, Rule | None]], statement: str = "") -> Proof:
    """``chain`` = [(e₀, None), (e₁, rule), …]: each e_j follows from e_{j−1} by one application
    of ``rule`` (a Rule object), in either direction."""
    lhs, rhs = chain[0][0], chain[-1][0]
    statement = statement or f"{lhs} = {rhs}"
    ok, lines, used = len(chain) > 1, [str(lhs)], []
    for (prev, _), (cur, rule) in zip(chain, chain[1:]):
        try:
            step_ok = isinstance(rule, Rule) and one_application(cur - prev, rule)
        except ShapeError:
            step_ok = False
        ok &= step_ok
        if isinstance(rule, Rule):
            used.append(rule)
        lines.append(f"= {cur} [{getattr(rule, 'name', rule)}{'' if step_ok else ': FAILED'}]")
    return Proof(statement, lhs, rhs, ok, tuple(dict.fromkeys(used)), " ".join(lines), method="chain",
                 data=tuple(chain))


def lemma(name: str, proof: Proof) -> Rule:
    """The rule ``proof.lhs = proof.rhs`` derived by ``proof``, resting on the hypotheses its proof
    rests on; refuses an unproved proof or one that is not an equation of matrices."""
    if not proof.proved:
        raise InputError(f"lemma {name} is not proved: {proof.trace}")
    if proof.relation != "=" or not isinstance(proof.lhs, Expr):
        raise InputError(f"lemma {name}: only a proved matrix equation is a rule")
    return Rule(name, proof.lhs, proof.rhs, "lemma", proof.premises, proof)


# ---- traces ----------------------------------------------------------------------------------------

def _rotations(word: Word) -> list[Word]:
    return [word[i:] + word[:i] for i in range(len(word))]


def _cyclic_forms(word: Word) -> list[Word]:
    """Every word with the same trace by cyclicity and tr(Xᵀ) = tr(X)."""
    return _rotations(word) + _rotations(_transpose_word(word))


def _canonical_cycle(word: Word) -> Word:
    return min(_cyclic_forms(word), key=_word_key) if word else word


@dataclass(frozen=True)
class Scalar:
    """Σ c · tr(word): a real number built from traces, c a polynomial in the size symbols (the
    empty word stands for the number 1). Words are stored in a canonical cyclic form."""

    terms: tuple  # ((word, sympy coefficient), ...), canonical, sorted, no zero coefficients

    @staticmethod
    def of(terms: dict) -> Scalar:
        merged: dict = {}
        words: dict = {}
        for word, coeff in terms.items():
            word = _canonical_cycle(word)
            k = _word_key(word)
            merged[k] = sp.expand(merged.get(k, sp.Integer(0)) + sp.sympify(coeff))
            words[k] = word
        return Scalar(tuple(sorted(((words[k], c) for k, c in merged.items() if c != 0),
                                   key=lambda t: _word_key(t[0]))))

    @staticmethod
    def number(value) -> Scalar:
        return Scalar.of({(): value})

    @property
    def is_zero(self) -> bool:
        return not self.terms

    def __add__(self, other: Scalar) -> Scalar:
        total: dict = {}
        for w, c in self.terms + other.terms:
            total[w] = total.get(w, 0) + c
        return Scalar.of(total)

    def __neg__(self) -> Scalar:
        return Scalar.of({w: -c for w, c in self.terms})

    def __sub__(self, other: Scalar) -> Scalar:
        return self + (-other)

    def __mul__(self, number) -> Scalar:
        return Scalar.of({w: c * sp.sympify(number) for w, c in self.terms})

    __rmul__ = __mul__

    def __str__(self) -> str:
        if not self.terms:
            return "0"
        return " + ".join(f"({c})·tr({'·'.join(map(str, w))})" if w else f"({c})" for w, c in self.terms)


def trace(expr: Expr) -> Scalar:
    """tr of a square expression: linear, tr(I_k) = k."""
    if not same_size(*expr.shape):
        raise ShapeError(f"trace of a {expr.shape[0]}×{expr.shape[1]} expression")
    return Scalar.of({w: (c * expr.shape[0] if not w else c) for w, c in
                      ((w, sp.Rational(c.numerator, c.denominator)) for w, c in expr.terms)})


def trace_normal_form(scalar: Scalar, rules: list[Rule], max_steps: int = 5000) -> tuple[Scalar, dict]:
    """Rewrite inside every trace, at every cyclic position, with the oriented rules; a rule about
    traces whose left side is one trace tr(w) replaces that trace."""
    oriented = [v for rule in rules for v in _versions(rule)]
    whole = [r for r in rules if isinstance(r.lhs, Scalar) and len(r.lhs.terms) == 1 and r.lhs.terms[0][0]
             and r.lhs.terms[0][1] == 1]
    used: dict = {}
    current = scalar
    for _ in range(max_steps):
        swap = next(((word, coeff, r) for word, coeff in current.terms for r in whole
                     if _word_key(word) == _word_key(r.lhs.terms[0][0])), None)
        if swap is not None:
            word, coeff, r = swap
            current = current - Scalar.of({word: coeff}) + r.rhs * coeff
            used[r] = used.get(r, 0) + 1
            continue
        step = None
        for word, coeff in current.terms:
            for form in _cyclic_forms(word) if word else ():
                for rule in oriented:
                    hit = next(iter(_find(form, rule.lhs.terms[0][0])), None)
                    if hit is not None:
                        step = (word, coeff, form, rule, hit)
                        break
                if step:
                    break
            if step:
                break
        if step is None:
            return current, used
        word, coeff, form, rule, hit = step
        size = form[0].shape[0]
        replaced = _splice(form[:hit], rule.rhs, form[hit + len(rule.lhs.terms[0][0]):], size, size)
        current = current - Scalar.of({word: coeff}) + trace(replaced) * coeff
        used[rule.origin] = used.get(rule.origin, 0) + 1
    raise NotTerminating(f"no normal form within {max_steps} rewrites")


def prove_trace_identity(lhs: Scalar, rhs: Scalar, rules: list[Rule], statement: str = "") -> Proof:
    return _by_rewriting(lhs, rhs, rules, statement, trace_normal_form, "trace")


def prove_size_bound(smaller, larger, squares: list[tuple], rules: list[Rule], statement: str = "") -> Proof:
    """``smaller ≤ larger`` for size expressions, from larger − smaller = Σ c_k tr(W_kᵀW_k) with
    every c_k > 0 (``squares`` = [(c_k, W_k)]): each tr(WᵀW) = Σ_ij W_ij² ≥ 0 for real W. The
    identity is proved by :func:`trace_normal_form`."""
    statement = statement or f"{smaller} ≤ {larger}"
    if not squares or any(Q(c) <= 0 for c, _ in squares):
        return _failed(statement, smaller, larger, "a bound needs a sum of squares with positive weights", "≤")
    try:
        certificate = sum((trace(w.T * w) * sp.Rational(Q(c).numerator, Q(c).denominator) for c, w in squares),
                          Scalar.number(0))
    except ShapeError as err:
        return _failed(statement, smaller, larger, str(err), "≤")
    identity_proof = prove_trace_identity(Scalar.number(larger) - Scalar.number(smaller), certificate, rules)
    squares_text = " + ".join(f"{c}·tr(WᵀW), W = {w}" for c, w in squares)
    return Proof(statement, sp.sympify(smaller), sp.sympify(larger), identity_proof.proved, identity_proof.used,
                 f"({larger}) − ({smaller}) = {squares_text} ≥ 0: {identity_proof.trace}", "≤", "bound",
                 tuple(squares))


def replays(proof: Proof) -> bool:
    """The proof, made again from its statement and the rules it records, is accepted using only
    those rules: a Proof object is never taken on its word."""
    if not isinstance(proof, Proof) or not proof.proved:
        return False
    rules = list(proof.used)
    if proof.method == "normal form":
        again = prove_by_normal_form(proof.lhs, proof.rhs, rules)
    elif proof.method == "trace":
        again = prove_trace_identity(proof.lhs, proof.rhs, rules)
    elif proof.method == "chain":
        if not proof.data or not (proof.data[0][0] == proof.lhs and proof.data[-1][0] == proof.rhs):
            return False
        again = prove_by_chain(list(proof.data))
    elif proof.method == "bound":
        again = prove_size_bound(proof.lhs, proof.rhs, list(proof.data), rules)
    else:
        return False
    return again.proved and set(map(id, again.used)) <= set(map(id, proof.used))


# ---- negative controls ----------------------------------------------------------------------------

@dataclass
class ControlResult:
    """A mutated statement: whether the prover rejected it, and whether an exact instance shows
    it false (None when the mutant is not an equation the instances can evaluate)."""

    mutant: str
    rejected: bool
    false_on_instance: bool | None

    def to_json(self) -> dict:
        out = {"mutant": self.mutant, "rejected": self.rejected}
        if self.false_on_instance is not None:
            out["false_on_instance"] = self.false_on_instance
        return out
