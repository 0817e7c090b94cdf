"""A theory: the letters a word-algebra proof may use, every rule known about them, and the exact
instances on which the engine checks those rules.

A letter is *declared*, and the declaration issues the rules that hold by what it declares:

* :meth:`Theory.general` — a matrix about which nothing is known;
* :meth:`Theory.symmetric`, :meth:`Theory.spd` — issue the hypothesis Xᵀ = X;
* :meth:`Theory.inverse` — M = X⁻¹ issues the axioms XM = MX = I resting on the hypothesis
  "X invertible" (for a symmetric positive definite letter X, on that hypothesis), and (X⁻¹)ᵀ = X⁻¹
  when X is symmetric;
* :meth:`Theory.pinv` — A⁺ issues the four Penrose equations (their unique solution is A⁺, for
  every A);
* :meth:`Theory.left_inverse` — L issues L A = I, the hypothesis "A has full column rank";
* :meth:`Theory.partition` — the column blocks of a size L = l₁ + … + l_N: selectors S_i (L × l_i,
  [0; I; 0]) with S_iᵀS_j = δ_ij I and Σ S_i S_iᵀ = I, so a block row is Σ P_i S_iᵀ and a block
  column Σ S_i V_i (definitions);
* :meth:`Theory.define` — a fresh letter := an expression (a conservative extension);
* :meth:`Theory.hypothesis` — any equation, assumed: every statement resting on it carries its
  phrase;
* :meth:`Theory.fact` — a stated fact: checked on the engine's general instances, never proved,
  so a statement resting on it is at most "checked".

A library axiom is a theorem of matrix algebra about the declared objects; a definition introduces
a fresh letter; everything else assumed is a hypothesis. Nothing else is issued, and a rule that a
theory did not issue (nor a proof derive) is refused by :mod:`gpfverify.symbolic.argument`.

**Instances** (:meth:`Theory.instances`) are drawn by the engine, never by a proof's author: for
every assignment of the free sizes in :data:`SIZE_VALUES` (at most :data:`MAX_ASSIGNMENTS` of them,
the smallest and largest always included) and two rank patterns — every general matrix drawn with
random integer entries (non-diagonal, non-symmetric, generically of full rank) and every general
matrix drawn rank-deficient (a product of random factors of rank min(rows, cols) − 1) — with exact
rational values: X⁻¹ the exact inverse, A⁺ sympy's exact pseudo-inverse, L = A⁺ + Z(I − AA⁺) for a
random Z. Only the hypotheses in force shape an instance: a symmetric or SPD letter is drawn so
only when its hypothesis is in force, a full-column-rank hypothesis draws that matrix of full column
rank (and drops the sizes where it cannot be), a hypothesis may name a realisation (a letter drawn
as an expression of others, e.g. G = W A C⁻¹), and every other hypothesis filters the draws. So a
restricted instance set is always the set of a hypothesis, and that hypothesis is in the statement.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any
import numpy as np
import sympy as sp

from gpfverify.errors import InputError
from gpfverify.symbolic.word_algebra import Expr, Rule, Scalar, ShapeError, identity, same_size, size_at, symbol, zero

#: the values each free size takes on the instances
SIZE_VALUES = (1, 2, 3)
#: a stated fact is checked on sizes up to this (one more than the rules' instances)
FACT_SIZE_VALUES = (1, 2, 3, 4)
#: at most this many size assignments per instance set (a seeded choice beyond it)
MAX_ASSIGNMENTS = 12
#: general matrices have integer entries in [−ENTRY, ENTRY]
ENTRY = 3
PATTERNS = ("generic", "deficient")


@dataclass(frozen=True)
class Declaration:
    name: str
    kind: str  # general | symmetric | spd | inverse | pinv | left_inverse | defined | selector
    letter: Expr
    #: inverse / pinv / left_inverse: the matrix; defined: the definition; selector: (index, parts)
    of: Any = None
    #: the hypothesis that shapes the draw (symmetric, spd) or that the value needs (inverse)
    hypothesis: Rule | None = None


@dataclass(frozen=True)
class Instance:
    """Exact values of the letters (name -> sympy Matrix, None where undefined) at integer sizes."""

    values: dict
    sizes: dict
    pattern: str


@dataclass
class RuleCheck:
    """The engine's check of one rule (or conclusion) on exact instances."""

    rule: str
    kind: str
    instances: int
    holds: bool
    #: what the instances were: "sizes 1..3, 2 rank patterns, under: ..."
    over: str = ""

    @property
    def passed(self) -> bool:
        """Held on every instance, and there was at least one (an empty check is a failure)."""
        return self.holds and self.instances > 0

    def to_json(self) -> dict:
        return {"rule": self.rule, "kind": self.kind, "instances": self.instances, "holds": self.passed}

    def __str__(self) -> str:
        if self.instances == 0:
            return f"{self.rule}: NO instance ({self.over}) — not checked"
        return f"{self.rule}: {'holds' if self.holds else 'FAILS'} on {self.instances} instances ({self.over})"


@dataclass(frozen=True)
class Induction:
    """How an induction rule was derived: IH(N) for every N ≥ 1 from the base IH(1) and the step
    IH(N) ⇒ IH(N + 1) (the maps say what the letters of N = 1 and of N + 1 sensors are)."""

    hypothesis: Rule
    base: object  # Proof or Rule
    step: object  # Proof
    base_map: str
    step_map: str


@dataclass(frozen=True)
class Instantiation:
    parent: Rule
    letters: dict
    sizes: dict


def _int_matrix(rng, rows, cols):
    return sp.Matrix(rows, cols, lambda i, j: int(rng.integers(-ENTRY, ENTRY + 1)))


def _of_rank(rng, rows, cols, rank):
    if rank <= 0:
        return sp.zeros(rows, cols)
    while True:
        value = _int_matrix(rng, rows, rank) * _int_matrix(rng, cols, rank).T
        if value.rank() == rank:
            return value


class Theory:
    """Letters, the rules their declarations issue, and the engine's instances of them."""

    def __init__(self, name: str, seed: int = 20191126):
        self.name = name
        self.seed = seed
        self.declarations: dict[str, Declaration] = {}
        self.issued: list[Rule] = []
        #: inductions and instantiations this theory derived
        self.derived: list[Rule] = []
        #: letters that stand for a function of others not written out: never instantiated
        self.opaque: set[str] = set()
        #: an opaque letter -> the letters it is declared a function of; trusted only once an
        #: induction that builds it has verified it (:meth:`induction`)
        self.claimed: dict[str, frozenset] = {}
        self.verified: dict[str, frozenset] = {}
        #: hypothesis -> how it shapes the draw: [("full column rank", letter), ("realise", {name: Expr}),
        #: ("needs", letter)]
        self.effects: dict[Rule, list] = {}
        #: hypotheses of induction steps (discharged by :meth:`induction`, never a statement's)
        self.induction_hypotheses: set[Rule] = set()
        self._cache: dict = {}

    # ---- declarations ------------------------------------------------------------------------
    def _declare(self, name, kind, letter, of=None, hypothesis=None) -> Expr:
        if name in self.declarations:
            raise InputError(f"{self.name}: the letter {name!r} is already declared")
        self.declarations[name] = Declaration(name, kind, letter, of, hypothesis)
        self._cache.clear()
        return letter

    def _issue(self, rule: Rule) -> Rule:
        self.issued.append(rule)
        self._cache.clear()
        return rule

    def general(self, name: str, rows, cols, opaque: bool = False, depends_on: tuple = ()) -> Expr:
        """A matrix about which nothing is known. ``opaque``: it stands for a function of other
        letters that is not written out (a sum over sensors); it is never instantiated, and it is
        taken to depend on every letter until an induction that builds it verifies ``depends_on``
        (the letters it is a function of)."""
        letter = self._declare(name, "general", symbol(name, rows, cols))
        if opaque:
            self.opaque.add(name)
            self.claimed[name] = frozenset(self._names(depends_on))
        return letter

    def symmetric(self, name: str, size, phrase: str = "") -> tuple[Expr, Rule]:
        return self._structured(name, size, "symmetric", phrase or f"{name} symmetric")

    def spd(self, name: str, size, phrase: str = "") -> tuple[Expr, Rule]:
        return self._structured(name, size, "spd", phrase or f"{name} symmetric positive definite")

    def _structured(self, name, size, kind, phrase):
        letter = symbol(name, size, size)
        rule = self._issue(Rule(f"{name}ᵀ = {name}", letter.T, letter, "hypothesis", phrase=phrase))
        self._declare(name, kind, letter, hypothesis=rule)
        return letter, rule

    def inverse(self, name: str, of: Expr, phrase: str = "", full_column_rank: Expr | None = None
                ) -> tuple[Expr, tuple[Rule, ...]]:
        """M = X⁻¹ for a square X (a letter or an expression): XM = I and MX = I, resting on "X
        invertible" (issued here, or X's SPD hypothesis); (X⁻¹)ᵀ = X⁻¹ when X is symmetric (equal
        to its transpose in the algebra, or a combination of symmetric letters). For X = FᵀF,
        ``full_column_rank=F`` draws F of full column rank where the hypothesis is in force (FᵀF is
        invertible exactly then)."""
        if not same_size(*of.shape):
            raise InputError(f"{of} is {of.shape[0]}×{of.shape[1]}, not square for every size: it has no inverse")
        size = of.shape[0]
        base = self._single_letter(of)
        decl = self.declarations[base] if base is not None else None
        if decl is not None and decl.kind == "spd" and decl.hypothesis is not None:
            invertible = decl.hypothesis
        else:
            self._check_declared(of)
            invertible = self._issue(Rule(f"{of} invertible", of, of, "hypothesis", phrase=phrase or f"{of} invertible",
                                          restricts=("rank",)))
            self.effects[invertible] = [("needs", name)]
            if full_column_rank is not None:
                base_letter = self._single_letter(full_column_rank)
                if base_letter is None:
                    raise InputError(f"inverse: {full_column_rank} is not a declared letter")
                self.effects[invertible].append(("full column rank", base_letter))
        letter = self._declare(name, "inverse", symbol(name, size, size), of=of, hypothesis=invertible)
        premises = frozenset({invertible})
        rules = [self._issue(Rule(f"({of})·{name} = I", of * letter, identity(size), "axiom", premises)),
                 self._issue(Rule(f"{name}·({of}) = I", letter * of, identity(size), "axiom", premises))]
        symmetric = self._symmetry_of(of)
        if symmetric is not None:
            rules.append(self._issue(Rule(f"{name}ᵀ = {name}", letter.T, letter, "axiom", premises | symmetric)))
        return letter, tuple(rules)

    def _symmetry_of(self, expr: Expr) -> frozenset | None:
        """The symmetry hypotheses that make ``expr`` symmetric when it is a rational combination
        of the identity, symmetric (or SPD) letters, inverses of symmetric matrices and letters
        defined as such combinations; None otherwise."""
        if expr.T == expr:
            return frozenset()
        needed: set = set()
        for word, _ in expr.terms:
            if len(word) > 1:
                return None
            if not word:
                continue
            decl = self.declarations.get(word[0].name)
            if decl is None:
                return None
            if decl.kind in ("symmetric", "spd"):
                needed.add(decl.hypothesis)
            elif decl.kind == "defined":
                inner = self._symmetry_of(decl.of)
                if inner is None:
                    return None
                needed |= inner
            elif decl.kind == "inverse":
                axiom = [r for r in self.issued
                         if r.kind == "axiom" and r.lhs == decl.letter.T and r.rhs == decl.letter]
                if not axiom:
                    return None
                needed |= axiom[0].premises
            else:
                return None
        return frozenset(needed)

    def pinv(self, name: str, of: Expr) -> tuple[Expr, tuple[Rule, ...]]:
        """A⁺, the Moore–Penrose inverse: the four Penrose equations, for every A."""
        if self._single_letter(of) is None:
            raise InputError(f"pinv: {of} is not a declared letter")
        rows, cols = of.shape
        x = self._declare(name, "pinv", symbol(name, cols, rows), of=of)
        return x, tuple(self._issue(Rule(label, lhs, rhs, "axiom")) for label, lhs, rhs in (
            (f"Penrose {of}{name}{of} = {of}", of * x * of, of),
            (f"Penrose {name}{of}{name} = {name}", x * of * x, x),
            (f"Penrose ({of}{name})ᵀ = {of}{name}", (of * x).T, of * x),
            (f"Penrose ({name}{of})ᵀ = {name}{of}", (x * of).T, x * of)))

    def left_inverse(self, name: str, of: Expr, phrase: str = "") -> tuple[Expr, Rule]:
        """L with L A = I: the hypothesis "A has full column rank" in algebraic form."""
        base = self._single_letter(of)
        if base is None or self.declarations[base].kind != "general":
            raise InputError(f"left_inverse: {of} is not a general letter")
        rows, cols = of.shape
        letter = symbol(name, cols, rows)
        rule = self._issue(Rule(f"{name}{of} = I", letter * of, identity(cols), "hypothesis",
                                phrase=phrase or f"{of} has full column rank", restricts=("rank",)))
        self.effects[rule] = [("full column rank", base)]
        self._declare(name, "left_inverse", letter, of=of, hypothesis=rule)
        return letter, rule

    def partition(self, prefix: str, parts: tuple) -> tuple[tuple[Expr, ...], tuple[Rule, ...]]:
        """Selectors of the column blocks of a size Σ parts: S_i (Σ × part_i) with S_iᵀS_j = δ_ij I
        and Σ_i S_i S_iᵀ = I."""
        total = sp.Add(*parts)
        selectors = tuple(self._declare(f"{prefix}{i + 1}", "selector", symbol(f"{prefix}{i + 1}", total, p),
                                        of=(i, parts)) for i, p in enumerate(parts))
        rules = [self._issue(Rule(f"{a}ᵀ{b} = {'I' if i == j else '0'}", selectors[i].T * selectors[j],
                                  identity(parts[i]) if i == j else zero(parts[i], parts[j]), "axiom"))
                 for i, a in enumerate(selectors) for j, b in enumerate(selectors)]
        rules.append(self._issue(Rule(f"Σ {prefix}_i {prefix}_iᵀ = I",
                                      sum((s * s.T for s in selectors[1:]), selectors[0] * selectors[0].T),
                                      identity(total), "axiom")))
        return selectors, tuple(rules)

    def define(self, name: str, expr: Expr) -> tuple[Expr, Rule]:
        """A fresh letter ``name`` := ``expr``."""
        letter = symbol(name, *expr.shape)
        self._check_declared(expr)
        rule = self._issue(Rule(f"{name} := {expr}", letter, expr, "definition"))
        self._declare(name, "defined", letter, of=expr)
        return letter, rule

    def hypothesis(self, name: str, lhs: Expr, rhs: Expr, phrase: str, restricts: tuple = (),
                   realise: dict | None = None, for_all: tuple = (), induction: bool = False) -> Rule:
        """``lhs = rhs`` assumed. ``phrase``: how a statement resting on it says it; ``restricts``:
        nouns it restricts (a statement saying "any rank" cannot rest on a rank hypothesis);
        ``realise``: general letters drawn as expressions of others so that it holds on instances;
        ``for_all``: letters it quantifies over (it may be instantiated at any value of those);
        ``induction``: an induction hypothesis, discharged by :meth:`induction`."""
        self._check_declared(lhs)
        self._check_declared(rhs)
        rule = self._issue(Rule(name, lhs, rhs, "hypothesis", phrase=phrase, restricts=tuple(restricts),
                                for_all=tuple(self._names(for_all))))
        if realise:
            for letter in realise:
                if self.declarations[letter].kind != "general":
                    raise InputError(f"hypothesis {name}: only a general letter can be realised, not {letter!r}")
            self.effects[rule] = [("realise", dict(realise))]
        if induction:
            self.induction_hypotheses.add(rule)
        return rule

    def fact(self, name: str, lhs, rhs) -> Rule:
        """A stated fact ``lhs = rhs`` (matrices or traces): checked on general instances at sizes
        :data:`FACT_SIZE_VALUES`, never proved."""
        for side in (lhs, rhs):
            self._check_declared(side)
        return self._issue(Rule(name, lhs, rhs, "fact"))

    # ---- helpers -----------------------------------------------------------------------------
    @staticmethod
    def _names(letters) -> list[str]:
        out = []
        for item in letters:
            if isinstance(item, Expr):
                out.extend(sorted(item.letters))
            else:
                out.append(item)
        return out

    def _single_letter(self, expr: Expr) -> str | None:
        if len(expr.terms) == 1 and expr.terms[0][1] == 1 and len(expr.terms[0][0]) == 1:
            letter = expr.terms[0][0][0]
            if not letter.transposed and letter.name in self.declarations:
                return letter.name
        return None

    def _check_declared(self, item) -> None:
        names = _letters_of(item)
        unknown = sorted(names - set(self.declarations))
        if unknown:
            raise InputError(f"{self.name}: undeclared letters {unknown}")

    def owns(self, rule: Rule) -> bool:
        return any(rule is r for r in self.issued) or any(rule is r for r in self.derived)

    def _derive(self, rule: Rule) -> Rule:
        self.derived.append(rule)
        return rule

    def depends_on(self, name: str) -> frozenset:
        """The letters ``name``'s value is a function of (through every declaration); an opaque
        letter, of every letter."""
        if name in self.opaque:
            return self.verified.get(name, frozenset(self.declarations))
        decl = self.declarations[name]
        direct = set(decl.of.letters) if decl.kind in ("inverse", "pinv", "left_inverse", "defined") else set()
        out = set(direct)
        for other in direct:
            if other != name:
                out |= self.depends_on(other)
        return frozenset(out)

    # ---- instantiation and induction ----------------------------------------------------------
    def instantiate(self, rule: Rule, letters: dict, sizes: dict | None = None, name: str = "") -> Rule:
        """``rule`` with the general letters in ``letters`` (name -> Expr) replaced and the size
        symbols in ``sizes`` given values. Sound when the rule holds for every value of those
        letters: each must be a general letter, no premise may pin it (a premise mentioning it must
        quantify over it), and a letter that is a function of it is expanded by its definition or,
        if it has none, refused."""
        sizes = dict(sizes or {})
        for letter in letters:
            decl = self.declarations.get(letter)
            if decl is None or decl.kind != "general" or letter in self.opaque:
                raise InputError(f"instantiate: {letter!r} is not a general (non-opaque) letter of {self.name}")
        moved = set(letters)
        for premise in rule.rests_on:  # a hypothesis instantiated rests on itself, so it is checked too
            pinned = {x for x in _letters_of(premise.lhs) | _letters_of(premise.rhs)
                      if x in moved or self.depends_on(x) & moved} - set(premise.for_all)
            if pinned and not (premise.kind == "hypothesis" and moved <= set(premise.for_all)):
                raise InputError(f"instantiate: the premise {premise.name!r} holds at one value of {sorted(pinned)}")
        expanded: dict[str, Expr | None] = {}
        for name_, decl in self.declarations.items():
            if name_ not in moved and self.depends_on(name_) & moved:
                if decl.kind != "defined":
                    expanded[name_] = None
                else:
                    expanded[name_] = decl.of
        sides = []
        for side in (rule.lhs, rule.rhs):
            for _ in range(len(expanded) + 1):  # definitions may refer to defined letters
                hit = {k: v for k, v in expanded.items() if k in side.letters}
                if not hit:
                    break
                missing = sorted(k for k, v in hit.items() if v is None)
                if missing:
                    raise InputError(f"instantiate: {missing} depend on {sorted(moved)} and have no definition to "
                                     "expand")
                side = side.substitute({k: v for k, v in hit.items() if v is not None})
            sides.append(side.substitute(letters, sizes))
        lhs, rhs = sides
        derivation = Instantiation(rule, dict(letters), sizes)
        return self._derive(Rule(name or f"{rule.name} at {_show_map(letters, sizes)}", lhs, rhs, "instance",
                                 rule.rests_on, derivation))

    def induction(self, name: str, hypothesis: Rule, base, step, base_map: dict, step_map: dict,
                  base_sizes: dict | None = None, step_sizes: dict | None = None) -> Rule:
        """IH(N) for every N ≥ 1: ``base`` proves IH with ``base_map`` (the letters of N = 1), ``step``
        proves IH with ``step_map`` (the letters of N + 1) from IH itself. Refused unless
        ``hypothesis`` is an induction hypothesis of this theory, both proofs are accepted, each
        proves exactly the mapped IH, and no other premise mentions an induction letter."""
        if hypothesis not in self.induction_hypotheses or not self.owns(hypothesis):
            raise InputError(f"induction {name}: {hypothesis.name!r} is not an induction hypothesis of {self.name}")
        for label, proof, mapping, sizes in (("base", base, base_map, base_sizes),
                                             ("step", step, step_map, step_sizes)):
            if not getattr(proof, "proved", False):
                raise InputError(f"induction {name}: the {label} is not proved")
            expected = hypothesis.difference.substitute(mapping, sizes)
            if not (proof.lhs - proof.rhs) == expected:
                raise InputError(f"induction {name}: the {label} proves {proof.lhs} = {proof.rhs}, not the "
                                 f"hypothesis at {_show_map(mapping, sizes)}")
        moved = set(base_map) | set(step_map)
        others = (base.premises | step.premises) - {hypothesis}
        for premise in others:
            if (_letters_of(premise.lhs) | _letters_of(premise.rhs)) & moved:
                raise InputError(f"induction {name}: the premise {premise.name!r} constrains an induction letter")
        if hypothesis in base.premises:
            raise InputError(f"induction {name}: the base uses the induction hypothesis")
        self._verify_dependencies(name, base_map, step_map)
        derivation = Induction(hypothesis, base, step, _show_map(base_map, base_sizes), _show_map(step_map, step_sizes))
        return self._derive(Rule(name, hypothesis.lhs, hypothesis.rhs, "induction", frozenset(others), derivation))

    def _closure(self, letters) -> set:
        """``letters`` and everything their declarations are built from, opaque letters as leaves."""
        out, todo = set(), list(letters)
        while todo:
            x = todo.pop()
            if x in out:
                continue
            out.add(x)
            decl = self.declarations[x]
            if x not in self.opaque and decl.kind in ("inverse", "pinv", "left_inverse", "defined"):
                todo.extend(decl.of.letters)
        return out

    def _verify_dependencies(self, name: str, base_map: dict, step_map: dict) -> None:
        """An opaque induction letter X declared a function of ``depends_on`` only: no other
        (non-opaque) induction letter f may enter X's images — at N = 1, X's letters share none
        with f's; at N + 1, X's image contains neither f nor what f's image adds (selectors
        aside). By induction X is then a function of its declared letters and the sensors' own."""
        selectors = {k for k, d in self.declarations.items() if d.kind == "selector"}
        for x in self.opaque & set(base_map) & set(step_map):
            others = [f for f in base_map if f not in self.opaque and f not in self.claimed[x] and f in step_map]
            base_x, step_x = self._closure(base_map[x].letters), self._closure(step_map[x].letters)
            for f in others:
                added = self._closure(step_map[f].letters) - selectors - {f}
                if base_x & self._closure(base_map[f].letters) or step_x & (added | {f}):
                    raise InputError(f"induction {name}: {x} is built from {f}, which it is declared not to depend on")
            self.verified[x] = self.claimed[x]

    # ---- instances ---------------------------------------------------------------------------
    def free_sizes(self) -> list[sp.Symbol]:
        found = set()
        for decl in self.declarations.values():
            for s in decl.letter.shape:
                found |= sp.sympify(s).free_symbols
        return sorted(found, key=str)

    def _assignments(self, values: tuple, in_force: frozenset) -> list[dict]:
        sizes = self.free_sizes()
        full_rank = [self.declarations[e[1]].letter for r, effects in self.effects.items() if r in in_force
                     for e in effects if e[0] == "full column rank"]
        every = [dict(zip(sizes, combo)) for combo in itertools.product(values, repeat=len(sizes))]
        every = [a for a in every if all(size_at(m.shape[0], a) >= size_at(m.shape[1], a) for m in full_rank)]
        if len(every) <= MAX_ASSIGNMENTS:
            return every
        rng = np.random.default_rng(self.seed)
        keep = {0, len(every) - 1} | set(rng.choice(len(every), MAX_ASSIGNMENTS, replace=False).tolist())
        return [every[i] for i in sorted(keep)][:MAX_ASSIGNMENTS]

    def instances(self, in_force: frozenset = frozenset(), values: tuple = SIZE_VALUES) -> list[Instance]:
        """Exact instances on which every hypothesis in ``in_force`` holds (see the module
        docstring); cached."""
        key = (frozenset(in_force), values)
        if key not in self._cache:
            self._cache[key] = self._draw(frozenset(in_force), values)
        return self._cache[key]

    def _draw(self, in_force: frozenset, values: tuple) -> list[Instance]:
        rng = np.random.default_rng(self.seed)
        realised: dict = {}
        full_rank: set = set()
        for rule in in_force:
            for effect in self.effects.get(rule, ()):
                if effect[0] == "realise":
                    realised.update(effect[1])
                elif effect[0] == "full column rank":
                    full_rank.add(effect[1])
        out = []
        for sizes in self._assignments(values, in_force):
            for pattern in PATTERNS:
                inst = self._draw_one(rng, sizes, pattern, in_force, realised, full_rank)
                if inst is not None:
                    out.append(inst)
        return out

    def _draw_one(self, rng, sizes, pattern, in_force, realised, full_rank) -> Instance | None:
        vals: dict = {}

        def shape(decl):
            return tuple(size_at(s, sizes) for s in decl.letter.shape)

        pending = list(self.declarations.values())
        for _ in range(len(pending) + 1):
            left = []
            for decl in pending:
                try:
                    vals[decl.name] = self._value(decl, shape(decl), vals, sizes, rng, pattern, in_force,
                                                  realised, full_rank)
                except KeyError:  # a letter it needs has no value yet
                    left.append(decl)
            if len(left) == len(pending):
                break
            pending = left
        for decl in pending:
            vals[decl.name] = None
        inst = Instance(vals, dict(sizes), pattern)
        for rule in in_force:
            if rule.kind != "hypothesis":
                continue
            if any(e[0] == "needs" and vals.get(e[1]) is None for e in self.effects.get(rule, ())):
                return None
            try:
                if not _holds(rule, inst):
                    return None
            except (KeyError, ShapeError):
                return None
        return inst

    def _value(self, decl, shape, vals, sizes, rng, pattern, in_force, realised, full_rank):
        rows, cols = shape
        if decl.name in realised:
            return realised[decl.name].evaluate(vals, sizes)
        if decl.kind == "general":
            if decl.name in full_rank:
                while True:
                    value = _int_matrix(rng, rows, cols)
                    if value.rank() == cols:
                        return value
            if pattern == "deficient":
                return _of_rank(rng, rows, cols, min(rows, cols) - 1)
            return _int_matrix(rng, rows, cols)
        if decl.kind in ("symmetric", "spd"):
            m = _int_matrix(rng, rows, cols)
            if decl.hypothesis not in in_force:
                return m
            return m + m.T if decl.kind == "symmetric" else m * m.T + sp.eye(rows)
        if decl.kind == "selector":
            index, parts = decl.of
            widths = [size_at(p, sizes) for p in parts]
            start = sum(widths[:index])
            out = sp.zeros(rows, cols)
            for j in range(cols):
                out[start + j, j] = 1
            return out
        base = decl.of.evaluate(vals, sizes)
        if decl.kind == "defined":
            return base
        if decl.kind == "inverse":
            return None if base.det() == 0 else base.inv()
        if decl.kind == "pinv":
            return base.pinv()
        if decl.kind == "left_inverse":
            if base.rank() != base.shape[1]:
                return None
            pinv = base.pinv()
            return pinv + _int_matrix(rng, rows, cols) * (sp.eye(cols) - base * pinv)
        raise InputError(f"unknown declaration kind {decl.kind!r}")

    def check(self, rule: Rule, in_force: frozenset, values: tuple = SIZE_VALUES, label: str = "") -> RuleCheck:
        """``rule`` on the instances of ``in_force``: held on every instance where all its letters
        have values, and how many those were."""
        count, holds = 0, True
        for inst in self.instances(in_force, values):
            try:
                ok = _holds(rule, inst)
            except KeyError:
                continue
            except ShapeError:
                ok = False
            count += 1
            holds &= ok
        over = f"sizes {values[0]}..{values[-1]}, {len(PATTERNS)} rank patterns"
        if in_force:
            over += ", under: " + "; ".join(sorted(r.phrase or r.name for r in in_force))
        return RuleCheck(label or rule.name, rule.kind, count, holds, over)

    def counterexample(self, lhs, rhs, in_force: frozenset) -> bool:
        """Some instance of ``in_force`` makes ``lhs ≠ rhs`` (or their shapes differ)."""
        for inst in self.instances(in_force):
            try:
                if not _equal(lhs, rhs, inst):
                    return True
            except KeyError:
                continue
            except ShapeError:
                return True
        return False


def size_counterexample(theory: Theory, smaller, larger, in_force: frozenset) -> bool:
    """Some instance of ``in_force`` has ``smaller > larger`` (size expressions)."""
    return any(size_at(smaller, i.sizes) > size_at(larger, i.sizes) for i in theory.instances(in_force))


def _letters_of(item) -> frozenset:
    if isinstance(item, Expr):
        return item.letters
    if isinstance(item, Scalar):
        return frozenset(letter.name for word, _ in item.terms for letter in word)
    return frozenset()


def _value_of(side, inst: Instance):
    if isinstance(side, Scalar):
        total = sp.Integer(0)
        for word, coeff in side.terms:
            c = sp.sympify(coeff).xreplace(inst.sizes)
            if not word:
                total += c
                continue
            size = word[0].shape[0]
            term = Expr.of({word: 1}, (size, size)).evaluate(inst.values, inst.sizes)
            total += c * term.trace()
        return total
    return side.evaluate(inst.values, inst.sizes)


def _equal(lhs, rhs, inst: Instance) -> bool:
    a, b = _value_of(lhs, inst), _value_of(rhs, inst)
    if isinstance(a, sp.MatrixBase) or isinstance(b, sp.MatrixBase):
        return isinstance(a, sp.MatrixBase) and isinstance(b, sp.MatrixBase) and a.shape == b.shape and a == b
    return sp.nsimplify(a - b) == 0


def _holds(rule: Rule, inst: Instance) -> bool:
    return _equal(rule.lhs, rule.rhs, inst)


def _show_map(letters: dict, sizes: dict | None) -> str:
    parts = [f"{k} := {v}" for k, v in letters.items()] + [f"{k} := {v}" for k, v in (sizes or {}).items()]
    return ", ".join(parts)

