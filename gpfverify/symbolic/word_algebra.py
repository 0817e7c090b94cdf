"""A small, explicit rewriting system for dimension-free matrix identities.

An expression is a noncommutative polynomial: a sum of rational multiples of *words*, a word being
a product of letters. A letter is a matrix symbol of symbolic size (sympy ``Symbol`` rows and
columns, e.g. n states × l outputs), possibly transposed; an inverse or a pseudo-inverse is a
letter of its own (``C⁻¹``, ``A⁺``) that nothing relates to ``C`` or ``A`` except the rules a proof
states. The only built-in algebra is what holds in every ring of matrices:

* associativity and distributivity (words are flat tuples; sums are expanded);
* transposition: (XY)ᵀ = YᵀXᵀ, (Xᵀ)ᵀ = X, pushed down to the letters (no letter is its own
  transpose: symmetry is a rule, :func:`symmetry`);
* a 1×1 word equals its transpose (it is a scalar); such words are stored in a canonical order;
* the empty word is the identity of the right size, I·X = X.

Everything else — C C⁻¹ = I, the Penrose equations, symmetry Cᵀ = C, a hypothesis such as
L A = I — is a :class:`Rule` that a proof must name. Rules come in three kinds:

* ``axiom``/``hypothesis``/``definition``: assumed; each is **checked** on exact rational
  instances (sympy ``Matrix``, several sizes) in which its premises hold, so a mistyped axiom
  fails before it is used;
* ``lemma``: derived from earlier rules by :func:`prove_by_normal_form` or :func:`prove_by_chain`.

A proof by normal form rewrites ``lhs − rhs`` with oriented rules (left side a single word) until
no rule applies and accepts iff the result is the zero polynomial. A proof by chain lists
expressions e₀ = lhs, …, e_k = rhs and accepts iff every e_{j+1} − e_j equals c·u(L − R)w for one
rule L = R (or its transpose), words u, w and a rational c — one rule application in either
direction. Both are sound: each accepted step replaces equals by equals. Neither is complete, so
a rejected statement is not thereby false: negative controls therefore also evaluate each mutant
on an exact instance (:func:`counterexample`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction as Q
from collections.abc import Callable, Iterable

import sympy as sp


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


class ShapeError(ValueError):
    """A product or sum of matrices whose sizes do not match."""


def _same(a, b) -> bool:
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

    def as_dict(self) -> dict:
        return {_word_key(w): (w, c) for w, c in self.terms}

    # -- algebra ---------------------------------------------------------------------------------
    def __add__(self, other: Expr) -> Expr:
        if not (_same(self.shape[0], other.shape[0]) and _same(self.shape[1], other.shape[1])):
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
        if not _same(self.shape[1], other.shape[0]):
            raise ShapeError(f"product of {self.shape} and {other.shape}")
        out: dict = {}
        for w1, c1 in self.terms:
            for w2, c2 in other.terms:
                w = w1 + w2
                out[w] = out.get(w, Q(0)) + c1 * c2
        return Expr.of(out, (self.shape[0], other.shape[1]))

    def __rmul__(self, scalar) -> Expr:
        return self * scalar

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

    # -- evaluation on an exact instance ---------------------------------------------------------
    def evaluate(self, values: dict, sizes: dict) -> sp.Matrix:
        """The exact sympy Matrix for letter values ``values`` (name -> Matrix) and sizes
        ``sizes`` (size symbol -> int)."""
        rows, cols = (int(sp.sympify(s).subs(sizes)) for s in self.shape)
        total = sp.zeros(rows, cols)
        for word, coeff in self.terms:
            m = sp.eye(rows)
            for letter in word:
                v = values[letter.name]
                m = m * (v.T if letter.transposed else v)
            total += sp.Rational(coeff.numerator, coeff.denominator) * m
        return total


def symbol(name: str, rows, cols) -> Expr:
    """The matrix symbol ``name`` (rows × cols) as an expression. Nothing is known about it: even
    symmetry is a rule (:func:`symmetry`) that a proof names and that is checked on instances."""
    return Expr.of({(Letter(name, rows, cols),): 1}, (rows, cols))


def identity(size) -> Expr:
    return Expr.of({(): 1}, (size, size))


def zero(rows, cols) -> Expr:
    return Expr.of({}, (rows, cols))


# ---- rules ----------------------------------------------------------------------------------------

KINDS = ("axiom", "hypothesis", "definition", "lemma")


@dataclass(frozen=True)
class Rule:
    """``lhs = rhs`` with a name, a kind (:data:`KINDS`) and, for a lemma, how it was derived."""

    name: str
    lhs: Expr
    rhs: Expr
    kind: str
    derivation: str = ""
    #: the hypotheses (by name) a lemma rests on; a hypothesis rests on itself
    premises: frozenset = frozenset()

    @property
    def rests_on(self) -> frozenset:
        return frozenset({self.name}) if self.kind == "hypothesis" else self.premises

    @property
    def difference(self) -> Expr:
        return self.lhs - self.rhs

    @property
    def oriented(self) -> bool:
        """Usable by normal-form rewriting: the left side is a single word with coefficient 1."""
        return len(self.lhs.terms) == 1 and self.lhs.terms[0][1] == 1 and len(self.lhs.terms[0][0]) > 0

    def transposed(self) -> Rule:
        return Rule(self.name + "ᵀ", self.lhs.T, self.rhs.T, self.kind, self.derivation, self.premises)

    def __str__(self) -> str:
        return f"{self.name}: {self.lhs} = {self.rhs}"


def symmetry(x: Expr, kind: str = "hypothesis") -> Rule:
    """The assumption ``Xᵀ = X`` for a square symbol X, as a rule like any other: a proof that
    needs it lists it, and it is checked on the instances like every assumed rule."""
    return Rule(f"{x}ᵀ={x}", x.T, x, kind)


def _find(word: Word, pattern: Word) -> Iterable[int]:
    keys, pkeys = _word_key(word), _word_key(pattern)
    n = len(pkeys)
    for i in range(len(keys) - n + 1):
        if keys[i:i + n] == pkeys:
            yield i


class NotTerminating(RuntimeError):
    pass


@dataclass
class NormalForm:
    result: Expr
    used: dict  # rule name -> applications


def normal_form(expr: Expr, rules: list[Rule], max_steps: int = 5000) -> NormalForm:
    """Rewrite with the oriented rules (and their transposes), leftmost-first, to a fixed point."""
    oriented = []
    for rule in rules:
        # a rule whose transpose is its own reverse (Cᵀ = C, (AA⁺)ᵀ = AA⁺) is used one way only
        versions = (rule,) if rule.lhs.T == rule.rhs else (rule, rule.transposed())
        for r in versions:
            if r.oriented:
                oriented.append(r)
    used: dict = {}
    current = expr
    for _ in range(max_steps):
        changed = False
        for word, coeff in current.terms:
            for rule in oriented:
                pattern = rule.lhs.terms[0][0]
                hit = next(iter(_find(word, pattern)), None)
                if hit is None:
                    continue
                prefix, suffix = word[:hit], word[hit + len(pattern):]
                left = Expr.of({prefix: 1}, (_outer_rows(prefix, current.shape[0]), rule.lhs.shape[0]))
                right = Expr.of({suffix: 1}, (rule.lhs.shape[1], _outer_cols(suffix, current.shape[1])))
                term = Expr.of({word: coeff}, current.shape)
                replacement = (left * rule.rhs * right) * coeff
                current = current - term + _reshape(replacement, current.shape)
                base = rule.name[:-1] if rule.name.endswith("ᵀ") else rule.name
                used[base] = used.get(base, 0) + 1
                changed = True
                break
            if changed:
                break
        if not changed:
            return NormalForm(current, used)
    raise NotTerminating(f"no normal form within {max_steps} rewrites")


def _outer_rows(prefix: Word, default):
    return prefix[0].shape[0] if prefix else default


def _outer_cols(suffix: Word, default):
    return suffix[-1].shape[1] if suffix else default


def _reshape(expr: Expr, shape) -> Expr:
    return Expr.of({w: c for w, c in expr.terms}, shape)


def _one_application(diff: Expr, rule: Rule) -> bool:
    """diff == c·u(L − R)w for words u, w and a rational c (L = R the rule or its transpose)."""
    if diff.is_zero:
        return True
    for r in (rule, rule.transposed()):
        delta = r.difference
        if delta.is_zero:
            continue
        anchor_word, anchor_coeff = max(delta.terms, key=lambda t: len(t[0]))
        for word, coeff in diff.terms:
            candidates = [word]
            if diff.shape[0] == 1 and diff.shape[1] == 1:
                candidates.append(_transpose_word(word))
            for cand in candidates:
                for i in _find(cand, anchor_word) if anchor_word else range(len(cand) + 1):
                    prefix, suffix = cand[:i], cand[i + len(anchor_word):]
                    try:
                        left = Expr.of({prefix: 1}, (_outer_rows(prefix, diff.shape[0]), delta.shape[0]))
                        right = Expr.of({suffix: 1}, (delta.shape[1], _outer_cols(suffix, diff.shape[1])))
                        candidate = _reshape(left * delta * right, diff.shape) * (coeff / anchor_coeff)
                    except ShapeError:
                        continue
                    if candidate == diff:
                        return True
    return False


# ---- proofs ---------------------------------------------------------------------------------------

@dataclass
class Proof:
    """The outcome of one proof attempt: accepted or not, the rules used, a readable trace."""

    statement: str
    proved: bool
    used: tuple
    trace: str
    #: the hypotheses (by name) the rules it used rest on
    premises: frozenset = frozenset()


def _premises(used, rules: list[Rule]) -> frozenset:
    by_name = {r.name: r for r in rules}
    return frozenset().union(*(by_name[name].rests_on for name in used if name in by_name))


def prove_by_normal_form(lhs: Expr, rhs: Expr, rules: list[Rule], statement: str = "") -> Proof:
    try:
        nf = normal_form(lhs - rhs, rules)
    except (NotTerminating, ShapeError) as err:
        return Proof(statement or f"{lhs} = {rhs}", False, (), f"no proof: {err}")
    trace = f"lhs − rhs rewrites to {nf.result} using " + ", ".join(f"{k}×{v}" for k, v in nf.used.items())
    return Proof(statement or f"{lhs} = {rhs}", nf.result.is_zero, tuple(nf.used), trace, _premises(nf.used, rules))


def prove_by_chain(chain: list[tuple[Expr, str | None]], rules: list[Rule], statement: str = "") -> Proof:
    """``chain`` = [(e₀, None), (e₁, rule name), …]: each e_j follows from e_{j−1} by one
    application of the named rule, in either direction."""
    by_name = {r.name: r for r in rules}
    ok, lines, used = True, [str(chain[0][0])], []
    for (prev, _), (cur, name) in zip(chain, chain[1:]):
        rule = None if name is None else by_name.get(name)
        try:
            step_ok = rule is not None and _one_application(cur - prev, rule)
        except ShapeError:
            step_ok = False
        ok &= step_ok
        used.append(name)
        lines.append(f"= {cur} [{name}{'' if step_ok else ': FAILED'}]")
    return Proof(statement or f"{chain[0][0]} = {chain[-1][0]}", ok, tuple(dict.fromkeys(used)), " ".join(lines),
                 _premises(used, rules))


def lemma(name: str, proof: Proof, lhs: Expr, rhs: Expr) -> Rule:
    """A derived rule, resting on the hypotheses its proof rests on; refuses an unproved one."""
    if not proof.proved:
        raise ValueError(f"lemma {name} is not proved: {proof.trace}")
    return Rule(name, lhs, rhs, "lemma", proof.trace, proof.premises)


# ---- checking rules on exact instances -----------------------------------------------------------

Instance = tuple  # (values: name -> sympy Matrix, sizes: symbol -> int)


def holds_on(rule_or_pair, instances: list[Instance]) -> bool:
    """``lhs = rhs`` exactly at every instance (a ShapeError or a missing value counts as False)."""
    lhs, rhs = (rule_or_pair.lhs, rule_or_pair.rhs) if isinstance(rule_or_pair, Rule) else rule_or_pair
    try:
        return all(lhs.evaluate(v, s) == rhs.evaluate(v, s) for v, s in instances)
    except (KeyError, TypeError, ShapeError, sp.ShapeError):
        return False


def counterexample(lhs: Expr, rhs: Expr, instances: list[Instance]) -> bool:
    """True when some instance makes ``lhs ≠ rhs`` (or the sizes do not match)."""
    try:
        return any(lhs.evaluate(v, s) != rhs.evaluate(v, s) for v, s in instances)
    except (ShapeError, sp.ShapeError, ValueError):
        return True


# ---- a proved claim with its negative controls ---------------------------------------------------

@dataclass
class Mutant:
    """A mutated statement ``lhs = rhs`` (the same rules) that must not be accepted."""

    name: str
    attempt: Callable[[], Proof]
    lhs: Expr | None = None
    rhs: Expr | None = None


@dataclass
class ControlResult:
    mutant: str
    rejected: bool
    false_on_instance: bool | None

    def to_json(self) -> dict:
        out = {"mutant": self.mutant, "rejected": self.rejected}
        if self.false_on_instance is not None:
            out["false_on_instance"] = self.false_on_instance
        return out


def run_controls(mutants: list[Mutant], instances: list[Instance]) -> list[ControlResult]:
    out = []
    for m in mutants:
        try:
            proved = m.attempt().proved
        except (ShapeError, ValueError):
            proved = False
        false = None
        if m.lhs is not None:
            assert m.rhs is not None, f"mutant {m.name} has lhs but no rhs"
            false = counterexample(m.lhs, m.rhs, instances)
        out.append(ControlResult(m.name, not proved, false))
    return out
