"""The rules: what a certificate may use, and the check of every step.

A **proof** (JSON object) is ``{"bases": {e: size, ...}, "steps": [step, ...]}``. Each step
proves one claim from the statement's hypotheses and earlier steps; every conclusion of the
statement must be, term for term, the claim of some step.

**Equation step** ``{"id", "claim": ["=", L, R], "index": {i: J, ...}, "by": [entry, ...]}``:
accepted iff the normal form of L − R − Σ_k entry_k is zero, where an entry
``{"over": [[i, J], ...], "left": a, "gen": g, "right": b}`` stands for Σ_{i∈J} a·g·b and g is one
of the generators below (each an expression that is 0 under the statement's hypotheses, so
L − R is 0 too: ideal membership). ``index`` names generic indices: the step holds for every value.

Generators (G1–G6), each issued for what the statement declares and nothing else:

* G1 ``{"hyp": k[, "index": i][, "at": {x: t}]}`` — L − R of the statement's equation hypothesis
  k, at index i when it holds for every member of a family, at x := t when it holds for every x;
* G2 ``{"lemma": id[, "index": {i: j}]}`` — L − R of an earlier equation step, its generic
  indices renamed;
* G3 ``{"penrose": 1..4, "of": A}`` — AXA − A, XAX − X, (AX)ᵀ − AX, (XA)ᵀ − XA for X = A⁺ (the
  Moore–Penrose inverse satisfies them for every A);
* G4 ``{"inverse": "right" | "left", "of": E}`` — EE⁺ − I or E⁺E − I, only for E invertible (R1);
* G5 ``{"fcr": A, "hyp": k[, "index": i]}`` — A⁺A − I, A of full column rank by hypothesis k;
* G6 ``{"complete": S}`` — Σ_i S_i S_iᵀ − I for the selectors of a partition (or a basis);
* G7 ``{"def": D[, "index": i]}`` — D − (its body) for an opaque definition D (a fresh letter);
* G8 ``{"congruence": f, "by": id[, "index": {...}]}`` — f(L) − f(R) for an earlier equation step
  L = R and f one of pinv, det, exp, tr (a function takes equal arguments to equal values).

**Side steps** ``{"id", "claim": ["invertible" | "positive", E], "factors": [F, ...], "by": id}``:
the equation step ``id`` proves E = F₁⋯F_k, and each F is invertible (R1), resp. each det(F) > 0
(R2), so E is invertible, resp. det(E) = Π det(F) > 0.

**Size steps** ``{"id", "claim": ["<=", a, b], "squares": [[c, W], ...], "slack": [[k, μ], ...],
"const": c₀, "by": [entry, ...]}``: b − a − Σ c·tr(WᵀW) − Σ μ·(size hypothesis k: rhs − lhs) − c₀
equals Σ tr(entry_k) in normal form, with every c > 0, μ ≥ 0, c₀ ≥ 0: tr(WᵀW) is a sum of squares.

Derived facts (R1–R3): R1 E is invertible if it is SPD (R3), an invertible hypothesis, c times
the inverse of an invertible matrix (c a nonzero coefficient, as a divisor is), or an earlier side
step; R2 det(E) > 0 if E is SPD or an earlier side step; R3 E is SPD if it is a sum, with positive
rational coefficients, of I, letters with an SPD hypothesis and inverses of SPD matrices. A divisor
is nonzero when each of its irreducible factors is one of a nonzero or positive hypothesis (or a
size constrained to be ≥ 1).
"""

from __future__ import annotations

from fractions import Fraction

import sympy as sp

from gpfverify.kernel.normal import EMPTY, INTEGRATION, NF, Context, c_add, c_mul, key, refs
from gpfverify.kernel.terms import (KernelError, Size, Statement, canonical_json, fail, number, parse_size, rename_size,
                                    substitute)

#: each generator and the fields it takes (the first field present names it)
GENERATORS = {"fcr": {"fcr", "hyp", "index"}, "penrose": {"penrose", "of"}, "inverse": {"inverse", "of"},
              "complete": {"complete"}, "def": {"def", "index"}, "gauss": {"gauss", "A", "b", "c"},
              "congruence": {"congruence", "by", "index"},
              "lemma": {"lemma", "index"}, "hyp": {"hyp", "index", "at"}}
#: G8's functions: each maps equal arguments to equal values
CONGRUENT = ("pinv", "det", "exp", "tr")


def generator_kind(spec) -> str | None:
    """The generator a spec names (its first field among :data:`GENERATORS`)."""
    return next((k for k in GENERATORS if isinstance(spec, dict) and k in spec), None)


def _neg(t):
    return ("*", ("num", -1), t)


class Checker:
    """The check of one proof of one statement."""

    def __init__(self, st: Statement, proof: dict):
        if not isinstance(proof, dict) or not set(proof) <= {"bases", "steps"}:
            fail("a proof is {'bases': {...}, 'steps': [...]}")
        bases = proof.get("bases", {})
        if not isinstance(bases, dict):
            fail("proof: 'bases' must be an object")
        index_sets, partitions = {}, {}
        for name, size in bases.items():
            if not isinstance(name, str) or name in st.names or name in index_sets:
                fail(f"proof: the basis name {name!r} is already in use")
            index_sets[name] = parse_size(size)
            partitions[name] = (name, parse_size(size), Size(1, ()))  # e_i: the standard basis, Σ e_i e_iᵀ = I
        self.st = st
        self.ctx = Context(st, index_sets, partitions)
        self.steps: dict = {}  # id -> (claim, generic indices)
        self.invertible: list = []  # frozen NFs proved invertible by side steps
        self.positive: list = []
        self.sizes: list = [(k, h) for k, h in enumerate(st.hypotheses) if h[0] == "<="]

    # ---- derived facts ----------------------------------------------------------------------------
    def _hyp_nfs(self, kind: str, around: NF):
        """Normal forms of the matrices of the hypotheses ``kind`` (at every index reference met in ``around``).
        "For every m ∈ J: P(m)" is used only when P(m) depends on m, and then P(r) matches ``around`` only
        where ``around`` uses r as a member of J; a P free of m says nothing (J may be empty)."""
        for k, h in enumerate(self.st.hypotheses):
            if h[0] == kind and len(h) == 2:
                yield k, None, self.ctx.nf(h[1], self.ctx.scope())
            elif h[0] == "every" and len(h) == 4 and isinstance(h[3], tuple) and h[3][0] == kind:
                fresh = ("@x", next(self.ctx._fresh))
                probe = self.ctx.nf(h[3][1], dict(self.ctx.scope(), **{h[1]: ("index", fresh, h[2])}))
                if fresh not in refs(probe.frozen(), []):
                    continue
                for ref in refs(around.frozen(), []):
                    scope = dict(self.ctx.scope(), **{h[1]: ("index", ref, h[2])})
                    try:
                        yield k, ref, self.ctx.nf(h[3][1], scope)
                    except KernelError:  # a reference of another index set
                        continue

    def spd(self, a: NF) -> bool:
        """R3."""
        if a.shape is None or not a.terms:
            return False
        for ((scalars, binders, word)), c in a.terms.items():
            if scalars != EMPTY or binders or not isinstance(c, Fraction) or c <= 0 or len(word) > 1:
                return False
            if word and not ((word[0][0] == "v" and word[0][1] in self.ctx.spd)
                             or (word[0][0] == "p" and self.spd(NF.thaw(word[0][1])))
                             or any(a_ == NF(a.shape, {(EMPTY, (), word): Fraction(1)})
                                    for _, _, a_ in self._hyp_nfs("spd", a))):
                return False
        return True

    def is_invertible(self, a: NF) -> bool:
        """R1."""
        if self.spd(a) or a.frozen() in self.invertible:
            return True
        if any(a == h for _, _, h in self._hyp_nfs("invertible", a)):
            return True
        if len(a.terms) == 1:
            ((scalars, binders, word)), c = next(iter(a.terms.items()))
            if scalars == EMPTY and not binders and len(word) == 1 and word[0][0] == "p":  # c·E⁻¹, c ≠ 0
                return self.is_invertible(NF.thaw(word[0][1])) and self.nonzero(c)
        return False

    def is_positive(self, a: NF) -> bool:
        """R2: det(a) > 0."""
        return self.spd(a) or a.frozen() in self.positive

    def nonzero(self, c) -> bool:
        """A coefficient is nonzero: a rational ≠ 0, or every irreducible factor of a rational function
        (numerator and denominator) is one of a nonzero or positive hypothesis, or a size s with 1 ≤ s."""
        if isinstance(c, Fraction):
            return c != 0
        factors = {}
        scope = self.ctx.scope()
        for h in self.st.hypotheses:
            if h[0] in ("nonzero", "positive"):
                value = self.ctx.nf(h[1], scope)
                if value.shape is None and len(value.terms) == 1 and next(iter(value.terms)) == (EMPTY, (), ()):
                    for f in _irreducible(next(iter(value.terms.values()))):
                        factors[f] = True
            elif h[0] == "<=" and parse_size(h[1]).is_one and not parse_size(h[2]).const:
                atoms = parse_size(h[2]).atoms
                if len(atoms) == 1 and atoms[0][1] is None and atoms[0][2] == 1:  # 1 ≤ s: s ≠ 0
                    factors[sp.Symbol(_gen_name(self.ctx, atoms[0][0]))] = True
        return all(f in factors or -f in factors for f in _irreducible(c))

    def discharge(self, needs: list, where: str) -> None:
        for kind, value in needs:
            if kind == "nonzero":
                ok = self.nonzero(value)
            elif kind == "invertible":
                ok = self.is_invertible(NF.thaw(value))
            else:
                ok = self.is_positive(NF.thaw(value))
            if not ok:
                what = value if kind == "nonzero" else _short(value)
                fail(f"{where}: the side condition '{kind} {what}' does not follow from the hypotheses or earlier "
                     "steps")

    # ---- generators --------------------------------------------------------------------------------
    def generator(self, spec, scope: dict) -> NF:
        kind = generator_kind(spec)
        if kind is None or not set(spec) <= GENERATORS[kind]:
            fail(f"unknown generator {str(spec)[:80]}: the generators are {sorted(GENERATORS)}")
        nf = lambda t: self.ctx.nf(t, scope)  # noqa: E731
        if kind in ("hyp", "lemma"):
            lhs, rhs = self._equation(spec, scope)
            return self.ctx.add(nf(lhs), self.ctx.scale(nf(rhs), Fraction(-1)))
        if kind == "penrose":
            a = spec.get("of")
            x = ("pinv", a)
            forms = {1: (("*", a, x, a), a), 2: (("*", x, a, x), x), 3: (("T", ("*", a, x)), ("*", a, x)),
                     4: (("T", ("*", x, a)), ("*", x, a))}
            if spec["penrose"] not in forms:
                fail("penrose: the equations are numbered 1..4")
            lhs, rhs = forms[spec["penrose"]]
            return nf(("+", lhs, _neg(rhs)))
        if kind == "inverse":
            e = nf(spec.get("of"))
            if e.shape is None or e.shape[0] != e.shape[1] or not self.is_invertible(e):
                fail(f"inverse: {_short(e.frozen())} is not shown invertible (R1)")
            side = {"right": ("*", spec["of"], ("pinv", spec["of"])), "left": ("*", ("pinv", spec["of"]), spec["of"])}
            if spec["inverse"] not in side:
                fail("inverse: 'right' or 'left'")
            return self.ctx.add(nf(side[spec["inverse"]]), self.ctx.scale(self.ctx.identity(e.shape[0]), Fraction(-1)))
        if kind == "fcr":
            a = nf(spec["fcr"])
            matrix = self._hypothesis(spec, scope, "fcr")
            if a != nf(matrix):
                fail("fcr: the matrix is not the one the hypothesis says has full column rank")
            return self.ctx.add(nf(("*", ("pinv", spec["fcr"]), spec["fcr"])),
                                self.ctx.scale(self.ctx.identity(a.shape[1]), Fraction(-1)))
        if kind == "def":
            index = spec.get("index")
            letter = ("var", spec["def"]) if index is None else ("var", spec["def"], index)
            if not self.st.definitions.get(spec["def"], None) or not self.st.definitions[spec["def"]].opaque:
                fail(f"def: {spec['def']!r} is not an opaque definition")
            return self.ctx.add(nf(letter), self.ctx.scale(self.ctx.body(spec["def"], index, scope), Fraction(-1)))
        if kind == "congruence":
            if spec["congruence"] not in CONGRUENT:
                fail(f"congruence: the functions are {CONGRUENT}")
            cited = {"lemma": spec.get("by"), **({"index": spec["index"]} if "index" in spec else {})}
            lhs, rhs = self._equation(cited, scope)
            f = spec["congruence"]
            return self.ctx.add(nf((f, lhs)), self.ctx.scale(nf((f, rhs)), Fraction(-1)))
        if kind == "gauss":
            return self._gauss(spec, scope)
        family = spec["complete"]
        if family not in self.ctx.partitions:
            fail(f"complete: unknown partition {family!r}")
        over, total, _ = self.ctx.partitions[family]
        i = "@i"
        whole = ("sum", i, over, ("*", ("sel", family, i), ("T", ("sel", family, i))))
        return self.ctx.add(nf(whole), self.ctx.scale(self.ctx.identity(self.ctx.resolve(total, self.ctx.scope())),
                                                      Fraction(-1)))

    def _gauss(self, spec: dict, scope: dict) -> NF:
        """G9: ∫ p(x) e^{−½xᵀAx + bᵀx + c} dx = p(A⁻¹b) (2π)^{n/2} det(A)^{−1/2} e^{½bᵀA⁻¹b + c} for A SPD and
        p of degree ≤ 1 in x (each monomial holds x or xᵀ at most once): the Gaussian integral and its mean."""
        ctx, integral = self.ctx, spec["gauss"]
        if not (isinstance(integral, tuple) and len(integral) == 4 and integral[0] == "int"):
            fail("gauss: the first field is an integral ['int', x, n, body]")
        _, name, size, body = integral
        whole = ctx.nf(integral, scope)
        n = ctx.size(size, scope)
        vector = (n, parse_size(1))
        a, b, c = (ctx.nf(spec[k], scope) for k in ("A", "b", "c"))
        if a.shape != (n, n) or not self.spd(a) or b.shape != vector:
            fail("gauss: A must be n × n and SPD (R3), b n × 1")
        if c.shape is None:
            c = ctx.mul(c, ctx.identity(parse_size(1)))
        inner = dict(scope, **{name: ("matrix", vector, INTEGRATION)})
        x = ctx.nf(("var", name), inner)
        quadratic = ctx.add(ctx.add(ctx.scale(ctx.mul(ctx.mul(ctx.transpose(x), a), x), Fraction(-1, 2)),
                                    ctx.mul(ctx.transpose(b), x)), c)
        atom = ("int", n, ctx.nf(body, inner).frozen())
        integrand = NF.thaw(atom[2])
        mean = ctx.mul(ctx.nf(("pinv", spec["A"]), scope), b)
        factor = ctx.mul(ctx.power(ctx.scalar(Fraction(1), ((("2pi",), Fraction(1)),)),
                                   c_mul(Fraction(1, 2), ctx.number(n))),
                         ctx.power(ctx.scalar(Fraction(1), ((ctx.det_atom(a), Fraction(1)),)), Fraction(-1, 2))
                         if ctx.det_atom(a) else ctx.scalar(Fraction(1)))
        exponent = ctx.add(ctx.scale(ctx.mul(ctx.transpose(b), mean), Fraction(1, 2)), c)
        factor = ctx.mul(factor, ctx.scalar(Fraction(1), (), exponent.frozen()))
        value = NF(integrand.shape, {})
        for ((powers, exp), _, word), coeff in integrand.terms.items():
            if exp is None or NF.thaw(exp) != quadratic:
                fail("gauss: the integrand's exponent is not −½xᵀAx + bᵀx + c")
            if any(INTEGRATION in str(p) for p in powers):
                fail("gauss: a trace or determinant of the integration variable")
            at = [k for k, w in enumerate(word) if w[0] == "v" and w[1] == INTEGRATION]
            if len(at) > 1 or INTEGRATION in str([w for k, w in enumerate(word) if k not in at]):
                fail("gauss: the integrand is not of degree ≤ 1 in the integration variable")
            piece = ctx.scalar(coeff, powers)
            if at:
                k = at[0]
                point = mean if not word[k][3] else ctx.transpose(mean)
                rows = integrand.shape[0] if integrand.shape else parse_size(1)
                left = NF((rows, point.shape[0]), {(EMPTY, (), word[:k]): Fraction(1)})
                cols = integrand.shape[1] if integrand.shape else parse_size(1)
                right = NF((point.shape[1], cols), {(EMPTY, (), word[k + 1:]): Fraction(1)})
                term = ctx.mul(ctx.mul(left, point), right)
                piece = ctx.mul(piece, term if integrand.shape else _as_scalar(ctx, term))
            elif word:
                piece = ctx.mul(piece, NF(integrand.shape, {(EMPTY, (), word): Fraction(1)}))
            elif integrand.shape is not None:
                piece = ctx.mul(piece, ctx.identity(integrand.shape[0]))
            value = ctx.add(value, ctx.mul(piece, factor))
        return ctx.add(whole, ctx.scale(value, Fraction(-1)))

    def _hypothesis(self, spec: dict, scope: dict, kind: str):
        """The body of hypothesis ``spec['hyp']`` (of the given kind) at its index and bound variables."""
        k = spec.get("hyp")
        if not isinstance(k, int) or isinstance(k, bool) or not 0 <= k < len(self.st.hypotheses):
            fail(f"no hypothesis {k!r}")
        h = self.st.hypotheses[k]
        if h[0] == "every":
            if "index" not in spec:
                fail(f"hypothesis {k} holds for every member of {h[2]}: name the index")
            self.ctx.index(spec["index"], h[2], scope)
            h = substitute_pred(h[3], index=(h[1], spec["index"]))
        elif "index" in spec:
            fail(f"hypothesis {k} is not about every member of a family")
        if h[0] == "forall":
            at = spec.get("at")
            if not isinstance(at, dict) or set(at) != {v[0] for v in h[1]}:
                fail(f"hypothesis {k} holds for every {[v[0] for v in h[1]]}: give each a value ('at')")
            for name, rows, cols in h[1]:
                value = self.ctx.nf(at[name], scope)
                if value.shape != (self.ctx.size(rows, scope), self.ctx.size(cols, scope)):
                    fail(f"hypothesis {k}: the value of {name} has the wrong shape")
            h = substitute_pred(h[2], variables=dict(at))
        elif "at" in spec:
            fail(f"hypothesis {k} is not about every value of a variable")
        if h[0] != kind:
            fail(f"hypothesis {k} is not of the form '{kind}'")
        return h[1] if kind != "=" else (h[1], h[2])

    def _equation(self, spec: dict, scope: dict):
        if "lemma" not in spec:
            return self._hypothesis(spec, scope, "=")
        if spec["lemma"] not in self.steps:
            fail(f"lemma {spec['lemma']!r}: no earlier step with that id")
        claim, generic = self.steps[spec["lemma"]]
        if claim[0] != "=":
            fail(f"lemma {spec['lemma']!r} is not an equation")
        renaming = spec.get("index", {})
        if not isinstance(renaming, dict) or set(renaming) != set(generic):
            fail(f"lemma {spec['lemma']!r}: give a value to each of its generic indices {sorted(generic)}")
        lhs, rhs = claim[1], claim[2]
        temporary = {name: f"@t{k}" for k, name in enumerate(renaming)}  # simultaneous renaming
        for name, tmp in temporary.items():
            lhs, rhs = substitute(lhs, index=(name, tmp)), substitute(rhs, index=(name, tmp))
        for name, tmp in temporary.items():
            self.ctx.index(renaming[name], generic[name], scope)
            lhs, rhs = substitute(lhs, index=(tmp, renaming[name])), substitute(rhs, index=(tmp, renaming[name]))
        return lhs, rhs

    def entries(self, entries, scope: dict, trace: bool = False) -> NF | None:
        total = None
        if not isinstance(entries, list | tuple):
            fail("'by' must be a list of entries")
        for entry in entries:
            if not isinstance(entry, dict) or not {"gen"} <= set(entry) <= {"over", "left", "gen", "right", "T"}:
                fail("an entry is {'over', 'left', 'gen', 'right'[, 'T']}")
            inner = dict(scope)
            for item in entry.get("over", ()):
                if not isinstance(item, list | tuple) or len(item) != 2:
                    fail("'over' lists [index, index set] pairs")
                name, index_set = item
                if name in self.st.names or name in inner or index_set not in self.ctx.index_sets:
                    fail(f"entry: the index {name!r} is in use or its set {index_set!r} unknown")
                inner[name] = ("index", ("@x", next(self.ctx._fresh)), index_set)
            g = self.generator(entry["gen"], inner)
            value = g
            if "left" in entry:
                value = self.ctx.mul(self.ctx.nf(entry["left"], inner), value)
            if "right" in entry:
                value = self.ctx.mul(value, self.ctx.nf(entry["right"], inner))
            if entry.get("T") is True:  # (a·g·b)ᵀ: 0 too
                value = self.ctx.transpose(value)
            if trace:
                value = self.ctx.trace(value)
            for item in reversed(entry.get("over", ())):
                value = self.ctx.close(value, inner[item[0]][1], item[1])
            total = value if total is None else self.ctx.add(total, value)
        return total

    # ---- steps ----------------------------------------------------------------------------------------
    def step(self, step) -> None:
        if not isinstance(step, dict) or "id" not in step or "claim" not in step:
            fail("a step is an object with 'id' and 'claim'")
        sid, claim = step["id"], step["claim"]
        if not isinstance(sid, str) or sid in self.steps:
            fail(f"step id {sid!r} is not a new name")
        if not isinstance(claim, tuple) or not claim:
            fail(f"step {sid}: a claim is a predicate")
        generic = step.get("index", {})
        if not isinstance(generic, dict):
            fail(f"step {sid}: 'index' maps generic index names to index sets")
        scope = self.ctx.scope()
        for name, index_set in generic.items():
            if name in self.st.names or index_set not in self.ctx.index_sets:
                fail(f"step {sid}: the generic index {name!r} is in use or its set unknown")
            scope[name] = ("index", ("@f", "@" + name), index_set)
        self.ctx.needs = []
        if claim[0] == "=" and len(claim) == 3:
            lhs, rhs = self.ctx.nf(claim[1], scope), self.ctx.nf(claim[2], scope)
            difference = self.ctx.add(lhs, self.ctx.scale(rhs, Fraction(-1)))
            combination = self.entries(step.get("by", []), scope)
            if combination is not None:
                difference = self.ctx.add(difference, self.ctx.scale(combination, Fraction(-1)))
            for sub in step.get("subst", ()):
                difference = self.substitute(difference, sub, scope, sid)
            combination = self.entries(step.get("then", []), scope)
            if combination is not None:
                difference = self.ctx.add(difference, self.ctx.scale(combination, Fraction(-1)))
            if not difference.is_zero:
                fail(f"step {sid}: L − R minus the combination of generators is not zero ({len(difference.terms)} "
                     "terms remain)")
        elif claim[0] in ("invertible", "positive") and len(claim) == 2:
            factors = step.get("factors")
            by = self.steps.get(step.get("by"))
            if not isinstance(factors, list | tuple) or not factors or by is None:
                fail(f"step {sid}: give 'factors' and the equation step 'by' that proves the factorisation")
            product = factors[0] if len(factors) == 1 else ("*", *factors)
            if canonical_json(by[0]) != canonical_json(("=", claim[1], product)) or by[1]:
                fail(f"step {sid}: step {step.get('by')!r} does not prove {claim[1]} = the product of the factors")
            test = self.is_invertible if claim[0] == "invertible" else self.is_positive
            for f in factors:
                value = self.ctx.nf(f, scope)
                if value.shape is None or value.shape[0] != value.shape[1] or not test(value):
                    fail(f"step {sid}: a factor is not shown {'invertible' if claim[0] == 'invertible' else 'SPD'}")
            target = self.ctx.nf(claim[1], scope)  # and its transpose: det(Eᵀ) = det(E)
            (self.invertible if claim[0] == "invertible" else self.positive).extend(
                [target.frozen(), self.ctx.transpose(target).frozen()])
        elif claim[0] == "<=" and len(claim) == 3:
            self._size_step(sid, step, claim, scope)
        else:
            fail(f"step {sid}: no rule proves a claim of the form {claim[0]!r}")
        self.discharge(self.ctx.needs, f"step {sid}")
        self.steps[sid] = (claim, dict(generic))

    def substitute(self, a: NF, sub, scope: dict, sid: str) -> NF:
        """S1 det(E) ↦ Π det(F_k)^{±1} (E = F₁⋯F_k by an earlier step, every det positive: R2), or
        S2 exp(W) ↦ exp(W − L + R) (L = R by an earlier step), in every monomial of ``a``."""
        ctx = self.ctx
        if not isinstance(sub, dict) or not ({"det", "factors", "by"} == set(sub) or {"exp", "by"} == set(sub)):
            fail(f"step {sid}: a substitution is {{'det', 'factors', 'by'}} or {{'exp', 'by'}}")
        if sub["by"] not in self.steps or self.steps[sub["by"]][0][0] != "=" or self.steps[sub["by"]][1]:
            fail(f"step {sid}: substitution by {sub['by']!r}, which is not an earlier equation step")
        lhs, rhs = self.steps[sub["by"]][0][1:]
        replace: dict = {}
        if "det" in sub:
            factors = sub["factors"]
            product = factors[0] if len(factors) == 1 else ("*", *factors)
            if canonical_json((lhs, rhs)) != canonical_json((sub["det"], product)):
                fail(f"step {sid}: step {sub['by']!r} does not prove det's matrix = the product of the factors")
            target = ctx.nf(sub["det"], scope)
            old = ctx.det_atom(target)
            if old is None or not self.is_positive(target):
                fail(f"step {sid}: det of the substituted matrix is not shown positive (R2)")
            for f in factors:
                sign, f = (-1, f[1]) if isinstance(f, tuple) and f[0] == "inv" else (1, f)
                value = ctx.nf(f, scope)
                if value.shape != target.shape:
                    fail(f"step {sid}: a factor is not square of the size of the substituted matrix")
                if not self.is_positive(value):
                    fail(f"step {sid}: det of a factor is not shown positive (R2)")
                if ctx.det_atom(value) is not None:
                    accumulate_atom(replace, ctx.det_atom(value), sign)
            out: dict = {}
            for ((powers, exp), binders, word), c in a.terms.items():
                atoms = dict(powers)
                e = atoms.pop(old, None)
                if e is not None:
                    for atom, k in replace.items():
                        atoms[atom] = c_add(atoms.get(atom, Fraction(0)), c_mul(e, Fraction(k)))
                    atoms = {k: v for k, v in atoms.items() if v != 0}
                mono = ((tuple(sorted(atoms.items(), key=lambda t: key(t[0]))), exp), binders, word)
                out[mono] = c_add(out.get(mono, Fraction(0)), c)
            return NF(a.shape, {m: c for m, c in out.items() if c != 0})
        where = ctx.nf(sub["exp"], scope)
        if where.shape is None:
            where = ctx.mul(where, ctx.identity(parse_size(1)))
        shift = ctx.add(ctx.nf(rhs, scope), ctx.scale(ctx.nf(lhs, scope), Fraction(-1)))
        if shift.shape is None:
            shift = ctx.mul(shift, ctx.identity(parse_size(1)))
        if shift.shape != where.shape:
            fail(f"step {sid}: an exponent substitution needs a 1 × 1 equation")
        out = {}
        for ((powers, exp), binders, word), c in a.terms.items():
            if exp is not None and NF.thaw(exp) == where:
                moved = ctx.add(where, shift)
                exp = None if moved.is_zero else moved.frozen()
            mono = ((powers, exp), binders, word)
            out[mono] = c_add(out.get(mono, Fraction(0)), c)
        return NF(a.shape, {m: c for m, c in out.items() if c != 0})

    def _size_step(self, sid, step, claim, scope) -> None:
        ctx = self.ctx
        total = ctx.add(ctx.nf(("size", claim[2]), scope), ctx.scale(ctx.nf(("size", claim[1]), scope), Fraction(-1)))
        for c, w in step.get("squares", ()):
            c = number(c)
            if c <= 0:
                fail(f"step {sid}: a square's weight must be positive")
            total = ctx.add(total, ctx.scale(ctx.nf(("tr", ("*", ("T", w), w)), scope), -c))
        for k, mult in step.get("slack", ()):
            mult = number(mult)
            hyp = self.st.hypotheses[k] if isinstance(k, int) and 0 <= k < len(self.st.hypotheses) else None
            if mult < 0 or hyp is None or hyp[0] != "<=":
                fail(f"step {sid}: slack needs a size hypothesis and a non-negative multiplier")
            gap = ctx.add(ctx.nf(("size", hyp[2]), scope), ctx.scale(ctx.nf(("size", hyp[1]), scope), Fraction(-1)))
            total = ctx.add(total, ctx.scale(gap, -mult))
        c0 = number(step.get("const", 0))
        if c0 < 0:
            fail(f"step {sid}: the constant must be non-negative")
        total = ctx.add(total, ctx.scalar(-c0))
        combination = self.entries(step.get("by", []), scope, trace=True)
        if combination is not None:
            total = ctx.add(total, ctx.scale(combination, Fraction(-1)))
        if not total.is_zero:
            fail(f"step {sid}: b − a is not the stated sum of squares and slacks")


def substitute_pred(pred, variables=None, index=None):
    """A predicate with variables replaced / an index renamed (terms via :func:`substitute`; an
    index also in every size: a "for every x" declaration's and a size comparison's)."""
    head = pred[0]
    size = (lambda s: rename_size(s, *index)) if index else (lambda s: s)
    if head == "every":
        return (head, pred[1], pred[2], substitute_pred(pred[3], variables, index))
    if head == "forall":
        return (head, tuple((x, size(r), size(c)) for x, r, c in pred[1]), substitute_pred(pred[2], variables, index))
    if head == "<=":
        return (head, size(pred[1]), size(pred[2]))
    return (head, *(substitute(t, variables, index) for t in pred[1:]))


def check_proof(st: Statement, proof: dict) -> Checker:
    """Check every step, every side condition of the statement, and that each conclusion is a
    step's claim; raises :class:`~gpfverify.kernel.terms.KernelError` at the first failure."""
    checker = Checker(st, proof)
    needs = statement_needs(st, checker.ctx)
    steps = proof.get("steps")
    if not isinstance(steps, list | tuple):
        fail("proof: 'steps' must be a list")
    for step in steps:
        checker.step(step)
    checker.discharge(needs, "the statement")
    claims = {canonical_json(claim) for claim, generic in checker.steps.values() if not generic}
    for conclusion in st.conclusion:
        if canonical_json(conclusion) not in claims:
            fail(f"the conclusion {str(conclusion)[:120]} is not the claim of any step")
    return checker


def statement_needs(st: Statement, like: Context | None = None) -> list:
    """Normalise every term of the statement on its own (type-checking it, without any basis a
    proof adds) and return its side conditions."""
    ctx = Context(st, field_of=like)
    for pred in (*st.hypotheses, *st.conclusion):
        for head, term, scope in predicate_terms(pred, ctx.scope(), ctx):
            value = ctx.nf(term, scope)
            if head in ("sym", "spd", "invertible", "fcr") and value.shape is None:
                fail(f"'{head}' of a number")
            if head in ("sym", "spd", "invertible") and value.shape[0] != value.shape[1]:
                fail(f"'{head}' of a matrix that is not square for every size")
            if head in ("nonzero", "positive") and value.shape is not None:
                fail(f"'{head}' of a matrix")
    return ctx.needs


def predicate_terms(pred, scope: dict, ctx: Context):
    """(term, scope) for every term of a predicate (validating its form)."""
    if not isinstance(pred, tuple) or not pred or pred[0] not in ("=", "sym", "spd", "fcr", "invertible", "nonzero",
                                                                    "positive", "<=", "every", "forall"):
        fail(f"not a predicate: {str(pred)[:80]}")
    head = pred[0]
    if head == "every":
        if len(pred) != 4 or pred[2] not in ctx.index_sets or pred[1] in scope or pred[1] in ctx.st.names:
            fail("every: ['every', index, index set, predicate] with a fresh index name")
        yield from predicate_terms(pred[3], dict(scope, **{pred[1]: ("index", ("@x", -1 - len(scope)), pred[2])}), ctx)
    elif head == "forall":
        if len(pred) != 3 or pred[2][0] != "=":
            fail("forall: ['forall', [[x, rows, cols], ...], ['=', L, R]]")
        inner = dict(scope)
        for item in pred[1]:
            name, rows, cols = item
            if name in ctx.st.names or name in inner:
                fail(f"forall: the name {name!r} is in use")
            inner[name] = ("matrix", (ctx.size(rows, scope), ctx.size(cols, scope)), name)
        yield from predicate_terms(pred[2], inner, ctx)
    elif head == "<=":
        if len(pred) != 3:
            fail("'<=' compares two sizes")
        ctx.size(pred[1], scope), ctx.size(pred[2], scope)
    else:
        arity = 3 if head == "=" else 2
        if len(pred) != arity:
            fail(f"'{head}' takes {arity - 1} terms")
        for term in pred[1:]:
            yield head, term, scope


def _gen_name(ctx: Context, size: str) -> str:
    return str(ctx.gens[size].numer.as_expr())


def _irreducible(c) -> list:
    """The irreducible non-constant factors of a coefficient's numerator and denominator."""
    if isinstance(c, Fraction):
        return []
    out = []
    for poly in (c.numer, c.denom):
        for f, _ in sp.factor_list(poly.as_expr())[1]:
            out.append(f)
    return out


def _short(frozen_nf) -> str:
    return str(frozen_nf)[:100]


def accumulate_atom(out: dict, atom, k: int) -> None:
    out[atom] = out.get(atom, 0) + k


def _as_scalar(ctx: Context, a: NF) -> NF:
    """A 1 × 1 product used as a number (a scalar integrand with xᵀv or vᵀx)."""
    out: dict = {}
    for (scalars, binders, word), c in a.terms.items():
        if word:
            fail("gauss: a scalar integrand whose x-term is a matrix product: write it as a 1 × 1 matrix")
        out[(scalars, binders, ())] = c
    return NF(None, out)
