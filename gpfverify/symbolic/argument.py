"""What a certificate rests on, walked and checked by the engine, and the status that follows.

An :class:`Argument` collects what establishes one claim:

* ``conclude(...)`` — word-algebra results (proofs, lemmas, inductions, instantiations): the claim
  in any dimension;
* ``at_sizes(...)`` — identities at listed sizes by exact polynomial or rational arithmetic (the
  engine tests the residual for zero itself);
* ``support(...)`` — word-algebra results a route relies on that are not the claim (validated and
  checked like conclusions, shown in the detail, their hypotheses kept out of the statement);
* ``refute(...)`` — an exact counterexample: residuals that must vanish and one that must not;
* ``control(...)``, ``control_residual(...)`` — negative controls: a mutated claim that the same
  checks must refuse.

:meth:`Argument.verdict` then walks every proof down to the rules it *applied* (not the rules its
author listed) and computes the status:

* every applied rule must be issued by the argument's :class:`~gpfverify.symbolic.theory.Theory`
  (axiom, definition, hypothesis, stated fact) or derived by the engine (a lemma with its proof, an
  induction or instantiation the theory made); anything else is "not issued" and refuses the proof;
* every issued rule a proof applies is checked on the engine's instances of that proof's own
  hypotheses, and so is the proof's conclusion; a check that ran on no instance fails;
* the hypotheses the conclusions rest on are the certificate's: each is written into its statement,
  and the statement may not claim "any <noun>" (e.g. "any rank") for a noun a hypothesis restricts;
* a stated fact is only checked (on general instances), so a claim resting on one is "checked";
* scope: "any dimension" only from word-algebra conclusions; from identities at listed sizes, the
  listed sizes, and then neither the statement nor the notes may speak of any dimension or size.

Status: "proved" when every requirement holds; "refuted" when an identity fails exactly (a nonzero
residual, a conclusion false on an instance of its hypotheses, or a verified counterexample);
otherwise "checked", with every reason it is not a proof in the detail.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np
import sympy as sp
from sympy.polys.matrices import DomainMatrix

from gpfverify.errors import InputError
from gpfverify.symbolic.certificate import Certificate
from gpfverify.symbolic.polynomial import Fraction
from gpfverify.symbolic.theory import (FACT_SIZE_VALUES, SIZE_VALUES, Induction, Instantiation, RuleCheck,
                                       Theory, size_counterexample)
from gpfverify.symbolic import word_algebra as wa
from gpfverify.symbolic.word_algebra import ControlResult, Expr, Proof, Rule, Scalar

ANY_DIMENSION = "any dimension"
#: words that claim every size; a statement or note with a narrower scope may not use them
_EVERY_SIZE = re.compile(r"\b(any|every|all|arbitrary|each)\s+(dimensions?|sizes?|D|N|l_m|n)\b|\bany dimension\b"
                         r"|\bdimension-free\b", re.IGNORECASE)


def _any_of(noun: str) -> re.Pattern:
    return re.compile(rf"\b(any|every|all|each|arbitrary|whatever(\s+the)?)\s+(\w+\s+)?{re.escape(noun)}s?\b",
                      re.IGNORECASE)


def _zero_expression(e: sp.Basic) -> bool:
    """0 as a rational function: by expansion when every denominator is a monomial (a polynomial
    in the symbols and their inverses, where expanding cancels everything), else by cancel after
    together. Both are exact, so "not zero" means the expression is not identically zero."""
    sums_below = any(p.exp.is_negative and isinstance(p.base, sp.Add) for p in e.atoms(sp.Pow))
    if not sums_below and sp.expand(e) == 0:
        return True
    return sp.cancel(sp.together(e)) == 0


def is_identically_zero(residual) -> bool:
    """The engine's zero test for an identity's residual: a polynomial :class:`Fraction` or
    DomainMatrix (every numerator coefficient), a sympy matrix or expression (each entry cancels to
    0 as a rational function), or a tuple of these."""
    if isinstance(residual, (tuple, list)):
        return bool(residual) and all(is_identically_zero(r) for r in residual)
    if isinstance(residual, Fraction):
        return residual.is_zero()
    if isinstance(residual, DomainMatrix):
        return residual.is_zero_matrix
    if isinstance(residual, sp.MatrixBase):
        return all(_zero_expression(e) for e in residual)
    if isinstance(residual, sp.Basic):
        return _zero_expression(residual)
    raise InputError(f"no zero test for a residual of type {type(residual).__name__}")


def nonzero_at_a_point(residual, seed: int = 20191126) -> bool:
    """The residual is nonzero at a point of seeded rationals in [1, 4] (positive, so every
    positivity assumption on a symbol holds): evidence that a mutated identity is false."""
    if isinstance(residual, (tuple, list)):
        return any(nonzero_at_a_point(r, seed) for r in residual)
    if isinstance(residual, Fraction):
        residual = residual.num.to_Matrix() / residual.num.domain.to_sympy(residual.den)
    if isinstance(residual, DomainMatrix):
        residual = residual.to_Matrix()
    symbols = sorted(residual.free_symbols, key=str)
    rng = np.random.default_rng(seed)
    point = {x: sp.Rational(int(rng.integers(4, 17)), 4) for x in symbols}
    value = residual.xreplace(point)
    entries = list(value) if isinstance(value, sp.MatrixBase) else [value]
    return any(sp.nsimplify(sp.simplify(e)) != 0 for e in entries)


def _scope_of(labels) -> str:
    """Listed sizes as one phrase: "D = 1", "D = 2" → "D ∈ {1, 2}"; labels of other forms are listed."""
    groups: dict = {}
    for label in dict.fromkeys(labels):
        name, _, value = label.partition(" = ")
        groups.setdefault(name if value else label, []).append(value)
    return "; ".join(f"{name} ∈ {{{', '.join(values)}}}" if all(values) else name for name, values in groups.items())


def _derived(rule: Rule) -> str:
    rests = (f" (rests on: {'; '.join(sorted(h.phrase or h.name for h in rule.premises))})" if rule.premises else "")
    if isinstance(rule.derivation, Induction):
        d = rule.derivation
        return (f"[proved by induction] {rule.name}: {rule.lhs} = {rule.rhs} for every N ≥ 1 — base N = 1 at "
                f"{d.base_map}; step N → N + 1 at {d.step_map}{rests}")
    if isinstance(rule.derivation, Instantiation):
        parent = rule.derivation.parent.name
        return f"[proved by instantiation] {rule.name}: {rule.lhs} = {rule.rhs} — from {parent}{rests}"
    return rule.name


@dataclass
class AtSizes:
    statement: str
    sizes: str
    residual: object
    #: hypotheses of the theory the route needs (e.g. every inverse it formed exists)
    hypotheses: tuple = ()
    #: the engine's zero test of the residual, made once when the identity is added
    zero: bool = field(init=False)

    def __post_init__(self):
        self.zero = is_identically_zero(self.residual)


@dataclass
class Refutation:
    statement: str
    zero: tuple
    nonzero: tuple


@dataclass
class _Control:
    mutant: str
    statement: str
    results: tuple
    false_under: frozenset | None
    residual: object = None


@dataclass
class Verdict:
    """The engine's verdict on an argument (see the module docstring)."""

    claim: str
    status: str
    scope: str
    hypotheses: tuple
    checks: list
    facts: list
    reasons: list
    shown: list

    @property
    def proved(self) -> bool:
        return self.status == "proved"


@dataclass
class _Walk:
    reasons: list = field(default_factory=list)
    proofs: list = field(default_factory=list)
    facts: list = field(default_factory=list)
    seen: set = field(default_factory=set)


class Argument:
    """One claim's argument; :meth:`certificate` turns it into its certificate."""

    def __init__(self, claim: str, statement: str, method: str, theory: Theory | None = None,
                 also: tuple[Theory, ...] = ()):
        self.claim, self.statement, self.method, self.theory = claim, statement, method, theory
        self.theories = ((theory,) if theory is not None else ()) + tuple(also)
        self.results: list = []
        self.supports: list = []
        self.sizes: list[AtSizes] = []
        self.refutations: list[Refutation] = []
        self.notes: list[str] = []
        self._controls: list[_Control] = []
        self._check_cache: dict = {}

    # ---- what the author adds ------------------------------------------------------------------
    def conclude(self, *results) -> None:
        for r in results:
            if not isinstance(r, (Proof, Rule)):
                raise InputError(f"a conclusion is a Proof or a derived Rule, not {type(r).__name__}")
        self.results.extend(results)

    def support(self, *results) -> None:
        for r in results:
            if not isinstance(r, (Proof, Rule)):
                raise InputError(f"a supporting result is a Proof or a derived Rule, not {type(r).__name__}")
        self.supports.extend(results)

    def at_sizes(self, statement: str, sizes: str, residual, hypotheses: tuple = ()) -> bool:
        self.sizes.append(AtSizes(statement, sizes, residual, tuple(hypotheses)))
        return self.sizes[-1].zero

    def refute(self, statement: str, zero: tuple = (), nonzero: tuple = ()) -> None:
        self.refutations.append(Refutation(statement, tuple(zero), tuple(nonzero)))

    def note(self, text: str) -> None:
        self.notes.append(text)

    def control(self, mutant: str, *results, statement: str | None = None,
                false_under: frozenset | None = None) -> None:
        """A mutated claim that must be refused: ``results`` as a conclusion would be given, the
        statement (default: the argument's). ``false_under``: the hypotheses of the instances on
        which the mutant must be false (default: the claim's and the mutant's own)."""
        self._controls.append(_Control(mutant, self.statement if statement is None else statement, results,
                                       false_under))

    def control_residual(self, mutant: str, residual) -> None:
        """A mutated identity at listed sizes: rejected iff its residual is not identically zero;
        false iff the residual is nonzero at an exact point (the engine's seeded rationals)."""
        self._controls.append(_Control(mutant, self.statement, (), None, residual))

    # ---- the engine's side ---------------------------------------------------------------------
    def _owner(self, rule: Rule) -> Theory | None:
        return next((t for t in self.theories if t.owns(rule)), None)

    def _issued(self, rule: Rule) -> bool:
        return self._owner(rule) is not None

    def _theory_of(self, proof: Proof) -> Theory | None:
        owners = {id(t): t for t in (self._owner(r) for r in proof.used) if t is not None}
        return next(iter(owners.values())) if len(owners) == 1 else (self.theory if not owners else None)

    def _walk(self, item, walk: _Walk) -> None:
        if id(item) in walk.seen:
            return
        walk.seen.add(id(item))
        if isinstance(item, Proof):
            walk.proofs.append(item)
            if not item.proved:
                walk.reasons.append(f"not proved: {item.statement} ({item.trace})")
            elif not wa.replays(item):
                walk.reasons.append(f"{item.statement}: the proof does not replay from the rules it records")
            for rule in item.used:
                self._walk(rule, walk)
            return
        rule = item
        if rule.kind in ("axiom", "definition", "hypothesis", "fact"):
            if not self._issued(rule):
                walk.reasons.append(f"the {rule.kind} {rule.name!r} was not issued by the theory: a rule a proof "
                                    "applies must be a theory's declaration, definition or hypothesis")
            elif rule.kind == "fact":
                walk.facts.append(rule)
            return
        if rule.kind == "lemma":
            proof = rule.derivation
            if not isinstance(proof, Proof) or not (proof.lhs == rule.lhs and proof.rhs == rule.rhs):
                walk.reasons.append(f"the lemma {rule.name!r} is not the conclusion of its proof")
                return
            if rule.premises != proof.premises:
                walk.reasons.append(f"the lemma {rule.name!r} does not rest on what its proof rests on")
            self._walk(proof, walk)
            return
        if not self._issued(rule):
            walk.reasons.append(f"the {rule.kind} {rule.name!r} was not derived by the theory")
            return
        if isinstance(rule.derivation, Induction):
            self._walk(rule.derivation.base, walk)
            self._walk(rule.derivation.step, walk)
        elif isinstance(rule.derivation, Instantiation):
            self._walk(rule.derivation.parent, walk)
        else:
            walk.reasons.append(f"the {rule.kind} {rule.name!r} has no derivation")

    def _check(self, theory: Theory, rule: Rule, in_force: frozenset, values=None, label="") -> RuleCheck:
        key = (id(rule), in_force, values)
        if key not in self._check_cache:
            self._check_cache[key] = (theory.check(rule, in_force, values, label) if values
                                      else theory.check(rule, in_force, label=label))
        return self._check_cache[key]

    def _hypotheses_of(self, results) -> frozenset:
        out: frozenset = frozenset()
        for r in results:
            out |= r.premises
        for theory in self.theories:
            out -= theory.induction_hypotheses
        return out

    def _judge(self, statement: str, results: tuple, sizes: list[AtSizes], notes: list[str],
               supports: tuple = ()) -> Verdict:
        walk = _Walk()
        for r in results + supports:
            self._walk(r, walk)
        checks: list[RuleCheck] = []
        refuted: list[str] = []
        for proof in walk.proofs:
            theory = self._theory_of(proof)
            if theory is None:
                walk.reasons.append(f"{proof.statement}: no single theory issued the rules it applies")
                continue
            in_force = proof.premises
            for rule in proof.used:
                if rule.kind in ("axiom", "definition", "hypothesis") and self._issued(rule):
                    checks.append(self._check(theory, rule, in_force))
            if isinstance(proof.lhs, (Expr, Scalar)):
                conclusion = Rule(f"conclusion: {proof.statement}", proof.lhs, proof.rhs, "lemma")
                check = self._check(theory, conclusion, in_force)
                checks.append(check)
                if proof.proved and check.instances and not check.holds:
                    refuted.append(f"{proof.statement} is false on an exact instance of its hypotheses")
        fact_checks = [self._check(owner, f, frozenset(), FACT_SIZE_VALUES, f"stated fact {f.name}")
                       for f in walk.facts if (owner := self._owner(f)) is not None]
        reasons = list(walk.reasons)
        reasons += [f"check failed: {c}" for c in checks if not c.passed]
        reasons += [f"rests on the stated fact {c.rule.removeprefix('stated fact ')}, checked on {c.instances} "
                    f"general instances (sizes ≤ {FACT_SIZE_VALUES[-1]}), not proved" for c in fact_checks]
        hypotheses = self._hypotheses_of(results) | frozenset(h for s in sizes for h in s.hypotheses)
        text = " ".join([statement] + notes)
        for h in sorted(hypotheses, key=lambda h: h.name):
            for noun in h.restricts:
                if _any_of(noun).search(text):
                    reasons.append(f"the statement speaks of any {noun} but rests on the hypothesis "
                                   f"'{h.phrase or h.name}'")
        zero = [s.zero for s in sizes]
        refuted += [f"{s.statement} at {s.sizes}: the residual is not zero" for s, z in zip(sizes, zero) if not z]
        if results:
            scope = ANY_DIMENSION
        elif sizes:
            scope = _scope_of(s.sizes for s in sizes)
        else:
            scope = ""
            reasons.append("nothing establishes the claim")
        if scope != ANY_DIMENSION and _EVERY_SIZE.search(text):
            reasons.append(f"the statement or a note speaks of every size, but the scope is {scope or 'empty'}")
        shown = [f"[{'proved' if p.proved else 'NOT PROVED'}] {p.statement}: {p.formal} — {p.trace}"
                 + (f" (rests on: {'; '.join(sorted(h.phrase or h.name for h in p.premises))})" if p.premises else "")
                 for p in walk.proofs]
        shown += [_derived(r) for r in results + supports
                  if isinstance(r, Rule) and r.kind in ("induction", "instance")]
        shown += [f"[{'zero' if z else 'NOT ZERO'}] {s.statement} at {s.sizes}" for s, z in zip(sizes, zero)]
        if refuted:
            status = "refuted"
            reasons = refuted + reasons
        elif reasons:
            status = "checked"
        else:
            status = "proved"
        if status != "proved" and scope == ANY_DIMENSION:  # what was shown, not what was aimed at
            scope = ("false on an exact instance" if refuted else
                     f"checked on exact instances, sizes {SIZE_VALUES[0]}..{SIZE_VALUES[-1]} (not proved)")
        return Verdict(self.claim, status, scope, tuple(sorted(hypotheses, key=lambda h: h.name)), checks,
                       fact_checks, reasons, shown)

    def _refutation_verdict(self) -> Verdict:
        lines, ok = [], bool(self.refutations)
        for r in self.refutations:
            holds = all(is_identically_zero(z) for z in r.zero) if r.zero else True
            fails = bool(r.nonzero) and all(not is_identically_zero(x) for x in r.nonzero)
            ok &= holds and fails
            lines.append(f"{r.statement}: premises hold exactly ({'yes' if holds else 'NO'}), the claimed identity "
                         f"fails exactly ({'yes' if fails else 'NO'})")
        return Verdict(self.claim, "refuted" if ok else "checked", "the counterexample", (), [], [],
                       [] if ok else ["the counterexample does not verify"], lines)

    def verdict(self) -> Verdict:
        if self.refutations:
            return self._refutation_verdict()
        return self._judge(self.statement, tuple(self.results), self.sizes, self.notes, tuple(self.supports))

    def controls(self, hypotheses: frozenset) -> list[ControlResult]:
        out = []
        for c in self._controls:
            if c.residual is not None:
                out.append(ControlResult(c.mutant, not is_identically_zero(c.residual), nonzero_at_a_point(c.residual)))
                continue
            verdict = self._judge(c.statement, c.results, [], [])
            false = None
            if self.theory is not None:
                found = []
                for r in c.results:
                    under = c.false_under if c.false_under is not None else hypotheses | r.premises
                    if isinstance(r.lhs, (Expr, Scalar)):
                        found.append(self.theory.counterexample(r.lhs, r.rhs, under))
                    elif getattr(r, "relation", "=") == "≤":
                        found.append(size_counterexample(self.theory, r.lhs, r.rhs, under))
                false = any(found) if found else None
            out.append(ControlResult(c.mutant, not verdict.proved, false))
        return out

    def _assumptions(self, verdict: Verdict) -> str:
        """The hypotheses for the statement: those every conclusion rests on, then those only some
        conclusions (one direction of an iff) rest on."""
        if not verdict.hypotheses:
            return ""
        premises = ([self._hypotheses_of((r,)) for r in self.results] if self.results
                    else [frozenset(s.hypotheses) for s in self.sizes])
        common = frozenset.intersection(*premises) if premises else frozenset()
        text = [h.phrase or h.name for h in verdict.hypotheses if h in common]
        extra = [h.phrase or h.name for h in verdict.hypotheses if h not in common]
        out = " — assuming: " + "; ".join(text) if text else " —"
        if extra:
            out += (("; and, " if text else " ") + "where a direction or part rests on it (see the detail): "
                    + "; ".join(extra))
        return out

    def certificate(self, seconds: float = 0.0) -> Certificate:
        verdict = self.verdict()
        phrases = [h.phrase or h.name for h in verdict.hypotheses]
        statement = self.statement + self._assumptions(verdict)
        parts = list(self.notes)
        if verdict.reasons:
            parts.append("NOT PROVED: " + "; ".join(verdict.reasons))
        parts.append("Shown: " + "; ".join(verdict.shown))
        if verdict.checks:
            parts.append("Checked by the engine on exact instances: " + "; ".join(map(str, verdict.checks)))
        if verdict.facts:
            parts.append("Stated facts: " + "; ".join(map(str, verdict.facts)))
        controls = self.controls(frozenset(verdict.hypotheses))
        return Certificate(self.claim, statement, self.method, verdict.status, " ".join(parts), seconds,
                           scope=verdict.scope, negative_controls=tuple(c.to_json() for c in controls),
                           stated_facts=tuple(str(c) for c in verdict.facts), hypotheses=tuple(phrases),
                           checks=tuple(c.to_json() for c in verdict.checks + verdict.facts), evidence=verdict)
