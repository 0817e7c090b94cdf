"""Proof search: untrusted code that writes the kernel's certificates.

:func:`reduce` proves an equation by noncommutative division: the difference L − R, in the
kernel's normal form, is reduced by the generators it is given (each rewrites its leading word,
the longest, into the rest), and every rewrite is recorded as an entry c·u·g·v of the
certificate. The kernel then re-checks the whole combination; nothing found here is believed.
Completeness (Σ_i S_i S_iᵀ = I) is applied where an index occurs only in S_i S_iᵀ.

:func:`term_of` turns pieces of normal forms back into terms (the certificate's language).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from gpfverify.kernel.normal import EMPTY, NF, c_mul, key, walk
from gpfverify.kernel.rules import Checker
from gpfverify.kernel.terms import KernelError, show_number


# ---- normal forms back to terms --------------------------------------------------------------------

def _index_name(ref, names: dict) -> str:
    if ref[0] == "@f":
        return ref[1].lstrip("@")
    return names[ref]


def coefficient_term(ctx, c):
    """A coefficient (rational, or rational function of sizes and parameters) as a term."""
    if isinstance(c, Fraction):
        return ("num", show_number(c))
    names = {g: name for name, g in ctx.gens.items()}
    symbols = {str(g.numer.as_expr()): names[g] for g in names}

    def poly(p):
        terms = []
        for monom, coeff in p.terms():
            factors = [("num", show_number(Fraction(int(coeff.numerator), int(coeff.denominator))))]
            for gen, power in zip(ctx.field.gens, monom):
                if power:
                    name = symbols[str(gen.numer.as_expr())]
                    leaf = ("param", name) if name in ctx.st.params else ("size", name)
                    factors.append(("^", leaf, power) if power != 1 else leaf)
            terms.append(("*", *factors))
        return ("+", *terms) if len(terms) > 1 else terms[0]

    top = poly(c.numer)
    return top if c.denom == 1 else ("*", top, ("^", poly(c.denom), -1))


def term_of(ctx, nf_or_word, names: dict, shape=None):
    """A normal form (or a word of atoms, of ``shape``) as a term; ``names`` maps index references."""
    if isinstance(nf_or_word, NF):
        parts = [term_of_mono(ctx, mono, c, names, nf_or_word.shape) for mono, c in nf_or_word.terms.items()]
        if not parts:
            shape = nf_or_word.shape
            return ("num", 0) if shape is None else ("0", _size(shape[0], names), _size(shape[1], names))
        return parts[0] if len(parts) == 1 else ("+", *parts)
    word = nf_or_word
    if not word:
        return ("I", _size(shape[0], names))
    factors = [_atom_term(ctx, a, names) for a in word]
    return factors[0] if len(factors) == 1 else ("*", *factors)


def term_of_mono(ctx, mono, c, names: dict, shape):
    (powers, exp), binders, word = mono
    if binders:
        raise KernelError("term_of_mono: a monomial with its own sums")
    factors = _scalar_factors(ctx, powers, exp, c, names)
    if shape is not None:
        factors.append(term_of(ctx, word, names, shape))
    return _product(factors)


def _scalar_atom(ctx, atom, names):
    if atom[0] == "tr":
        w = atom[1]
        return ("tr", term_of(ctx, w, names))
    if atom[0] == "det":
        return ("det", term_of(ctx, NF.thaw(atom[1]), names))
    if atom[0] == "int":
        return _integral(ctx, atom, names)
    return ("2pi",)


def _integral(ctx, atom, names):
    return ("int", "x", _size(atom[1], names), term_of(ctx, NF.thaw(atom[2]), dict(names, **{"@∫": "x"})))


def _atom_term(ctx, atom, names):
    if atom[0] == "v" and atom[1] == "@∫":
        return ("T", ("var", names["@∫"])) if atom[3] else ("var", names["@∫"])
    if atom[0] == "int":
        return _integral(ctx, atom, names)
    if atom[0] in ("v", "s"):
        head = "var" if atom[0] == "v" else "sel"
        t = (head, atom[1]) if atom[2] is None else (head, atom[1], _index_name(atom[2], names))
        return ("T", t) if atom[3] else t
    return ("pinv", term_of(ctx, NF.thaw(atom[1]), names))


def _size(size, names) -> str:
    parts = [(f"{c}*" if c != 1 else "") + n + (f"[{_index_name(i, names)}]" if i is not None else "")
             for n, i, c in size.atoms]
    if size.const or not parts:
        parts.append(str(size.const))
    return " + ".join(parts)


# ---- generators as rewrite rules ----------------------------------------------------------------------

@dataclass(frozen=True)
class Template:
    """A generator spec, or a family of them: ``spec`` is a dict, or a function of an index name."""

    spec: Any
    index_set: str | None = None
    #: which word the generator rewrites: its longest, ("letter") its one-letter word (a definition's
    #: name), or the word of a given term
    orient: Any = "longest"
    #: use the generator transposed (an entry with "T")
    transposed: bool = False

    def instances(self, checker: Checker, scope: dict, names: dict) -> Iterable[tuple[dict, NF]]:
        specs = [self.spec] if self.index_set is None else [
            self.spec(name) for name, binding in scope.items()
            if isinstance(binding, tuple) and binding[0] == "index" and binding[2] == self.index_set]
        for spec in specs:
            try:
                g = checker.generator(spec, scope)
                yield spec, (checker.ctx.transpose(g) if self.transposed else g)
            except KernelError:  # not a generator here (a dropped hypothesis, a matrix not shown invertible)
                continue


def _lead(g: NF, orient="longest", checker=None, scope=None):
    if isinstance(orient, tuple):  # a term: its (one) word is the word rewritten
        word = next(iter(checker.ctx.nf(orient, scope).terms))[2]
        return next(t for t in g.terms.items() if t[0][2] == word)
    if orient == "letter":
        return next(t for t in g.terms.items() if len(t[0][2]) == 1 and t[0][1] == () and t[0][2][0][0] == "v")
    return max(g.terms.items(), key=lambda t: (len(t[0][2]), key(t[0])))


def _scope_for(checker: Checker, scope: dict, binders: tuple):
    """The scope extended with one name per bound index of a monomial, and the reference map."""
    inner, names, mapping = dict(scope), {}, {}
    for k, index_set in enumerate(binders):
        name = f"i{k}"
        while name in inner or name in checker.st.names:
            name += "'"
        ref = ("@x", -1 - k)
        inner[name] = ("index", ref, index_set)
        names[ref] = name
        mapping[("@b", k)] = ref
    for n, binding in scope.items():
        if isinstance(binding, tuple) and binding[0] == "index":
            names[binding[1]] = n
    return inner, names, mapping


def _match(word, pattern) -> int:
    n = len(pattern)
    for p in range(len(word) - n + 1):
        if word[p:p + n] == pattern:
            return p
    return -1


def reduce(checker: Checker, residual: NF, templates: list[Template], scope: dict,
           max_steps: int = 20000) -> tuple[list[dict], NF]:
    """Entries whose sum is ``residual`` minus what is left (zero when the search succeeds)."""
    entries: list[dict] = []
    cache: dict = {}
    for _ in range(max_steps):
        if residual.is_zero:
            break
        found = None
        for mono, c in sorted(residual.terms.items(), key=lambda t: (-len(t[0][2]), key(t[0]))):
            (powers, exp), binders, word = mono
            inner, names, mapping = _scope_for(checker, scope, binders)
            local = walk((powers, exp, word), lambda r, mapping=mapping: mapping.get(r, r))
            over = [[names[mapping[("@b", k)]], s] for k, s in enumerate(binders)]
            found = _rewrite(checker, local, c, inner, names, over, templates, cache) or _complete(
                checker, local, c, over, names)
            if found:
                break
        if not found:
            break
        entries.append(found)
        residual = checker.ctx.add(residual, checker.ctx.scale(_value(checker, [found], scope), Fraction(-1)))
    return entries, residual


def _rewrite(checker, local, c, inner, names, over, templates, cache):
    powers, exp, word = local
    for template in templates:
        for spec, g in template.instances(checker, inner, names):
            lead_key = repr((spec, template.orient, template.transposed))
            if lead_key not in cache:
                cache[lead_key] = _lead(g, template.orient, checker, inner)
            (lead_scalars, lead_binders, lead_word), lead_c = cache[lead_key]
            if lead_scalars != EMPTY or lead_binders or not lead_word:
                continue
            p = _match(word, lead_word)
            if p < 0:
                continue
            factor = c_mul(c, Fraction(1) / lead_c if isinstance(lead_c, Fraction) else 1 / lead_c)
            if template.transposed:  # c u gᵀ v = (c vᵀ g uᵀ)ᵀ
                entry = _entry(checker.ctx, over, (), None, Fraction(1), checker.ctx.tword(word[p + len(lead_word):]),
                               spec, checker.ctx.tword(word[:p]), names)
                entry["T"] = True
                entry["left"] = ("*", _scalars_term(checker.ctx, powers, exp, factor, names), entry["left"])
                return entry
            return _entry(checker.ctx, over, powers, exp, factor, word[:p], spec, word[p + len(lead_word):], names)
    return None


def _scalars_term(ctx, powers, exp, c, names):
    return _product(_scalar_factors(ctx, powers, exp, c, names))


def _scalar_factors(ctx, powers, exp, c, names) -> list:
    """c · Π atom^e · exp(·) as a list of factors (empty for the number 1)."""
    factors = [] if c == 1 else [coefficient_term(ctx, c)]
    for atom, e in powers:
        base = _scalar_atom(ctx, atom, names)
        factors.append(base if e == 1 else ("^", base, _exponent(ctx, e)))
    if exp is not None:
        factors.append(("exp", term_of(ctx, NF.thaw(exp), names)))
    return factors


def _product(factors: list):
    return ("*", *factors) if len(factors) > 1 else factors[0] if factors else ("num", 1)


def _exponent(ctx, e):
    return show_number(e) if isinstance(e, Fraction) else coefficient_term(ctx, e)


def _entry(ctx, over, powers, exp, c, prefix, spec, suffix, names) -> dict:
    """The entry c·(scalar atoms)·prefix·g·suffix, summed over ``over``."""
    factors = _scalar_factors(ctx, powers, exp, c, names)
    if prefix:
        factors.append(term_of(ctx, prefix, names))
    entry = {"over": over, "left": _product(factors), "gen": spec}
    if suffix:
        entry["right"] = term_of(ctx, suffix, names)
    return entry


def _complete(checker, local, c, over, names):
    """An index that occurs only in an adjacent S_i S_iᵀ: Σ_i u S_i S_iᵀ v = u v + u(Σ_i S_i S_iᵀ − I)v."""
    powers, exp, word = local
    for p in range(len(word) - 1):
        a, b = word[p], word[p + 1]
        if a[0] == b[0] == "s" and a[1] == b[1] and a[2] == b[2] and not a[3] and b[3] and a[2][0] == "@x":
            rest = (powers, exp, word[:p] + word[p + 2:])
            if a[2] in _refs_of(rest):
                continue
            k = -1 - a[2][1]
            keep = [o for j, o in enumerate(over) if j != k]
            return _entry(checker.ctx, keep, powers, exp, c, word[:p], {"complete": a[1]}, word[p + 2:], names)
    return None


def _value(checker: Checker, entries: list, scope: dict) -> NF:
    value = checker.entries(entries, scope)
    if value is None:
        raise KernelError("no entries")
    return value


def _refs_of(obj) -> list:
    from gpfverify.kernel.normal import refs

    return refs(obj, [])


def prove_equation(checker: Checker, sid: str, lhs, rhs, templates: list[Template], generic: dict | None = None,
                   extra: list | None = None, subst: list | None = None) -> tuple[dict, NF]:
    """A step ``sid`` claiming lhs = rhs, its entries found by :func:`reduce` after the ``extra``
    entries (given by hand); also returns what is left (zero iff the kernel will accept it)."""
    scope = checker.ctx.scope()
    for name, index_set in (generic or {}).items():
        scope[name] = ("index", ("@f", "@" + name), index_set)
    ctx = checker.ctx
    residual = ctx.add(ctx.nf(lhs, scope), ctx.scale(ctx.nf(rhs, scope), Fraction(-1)))
    entries = list(extra or [])
    if entries:
        residual = ctx.add(residual, ctx.scale(_value(checker, entries, scope), Fraction(-1)))
    step: dict[str, Any] = {"id": sid, "claim": ("=", lhs, rhs)}
    if subst:  # the given entries first, then the substitutions, then the search
        for sub in subst:
            residual = checker.substitute(residual, sub, scope, sid)
        found, residual = reduce(checker, residual, templates, scope)
        step.update(by=entries, subst=list(subst), then=found)
    else:
        found, residual = reduce(checker, residual, templates, scope)
        step["by"] = entries + found
    if generic:
        step["index"] = dict(generic)
    return step, residual
