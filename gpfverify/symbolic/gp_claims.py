"""The uncertain-input SE-kernel integrals of seed 000 eq. 8–11 and 20 (Deisenroth et al. 2009)
in D dimensions with a full input covariance Σ, by two routes.

With x ~ N(μ, Σ), k_a(x, x') = α_a² exp(−½ (x − x')ᵀΛ_a⁻¹(x − x')), ν_i = x_i − μ:

* q_i  = E[k_a(x, x_i)] = α_a² |ΣΛ_a⁻¹ + I|^{-1/2} exp(−½ ν_iᵀ(Σ + Λ_a)⁻¹ν_i)                 (eq. 8–9)
* Cov[x, k_a(x, x_i)] = E[(x − μ) k_a(x, x_i)] = Σ(Σ + Λ_a)⁻¹ ν_i q_i                          (eq. 20)
* Q_ij = E[k_a(x, x_i) k_b(x, x_j)] = k_a(x_i, μ) k_b(x_j, μ) |R|^{-1/2} exp(½ zᵀR⁻¹Σz),
  R = Σ(Λ_a⁻¹ + Λ_b⁻¹) + I, z = Λ_a⁻¹ν_i + Λ_b⁻¹ν_j                                           (eq. 11)

**Route 1, any D, through the kernel** (the certificate): Σ, Λ_a, Λ_b any SPD matrices (not
only diagonal Λ). Each integral ∫ N(x; μ, Σ) … dx is rewritten by the kernel's Gaussian-integral
rule G9 (completing the square: A = Σ⁻¹ + Λ_a⁻¹ [+ Λ_b⁻¹], b, c given here, the exponent checked
by the normal form); the determinant lemma det(ΣΛ_a⁻¹ + I) = det(Σ) det(Σ⁻¹ + Λ_a⁻¹), resp.
det(R) = det(Σ) det(Σ⁻¹ + Ξ), enters by substitution S1; and the exponents ½bᵀA⁻¹b + c equal the
closed forms' by the matrix identities Λ_a⁻¹(Σ⁻¹ + Λ_a⁻¹)⁻¹Σ⁻¹ = (Σ + Λ_a)⁻¹ and
(Σ⁻¹ + Ξ)⁻¹ = R⁻¹Σ, each proved from the inverse rules.

**Route 2, D = 1, 2 (and 3 in the large size) by direct integration** ("also checked"):
x = μ + Lz with Σ = LLᵀ (L lower triangular,
every entry a free symbol, positive diagonal) and z ~ N(0, I); the integrand p(z)·exp(E(z)), p
linear, is integrated one coordinate at a time with the 1-D rule
∫(p₀ + p₁u)e^{−au² + bu + c}du = √(π/a) e^{b²/4a + c}(p₀ + p₁ b/2a) (a > 0), itself verified by
``sympy.integrate``. The result has the exact form r·√s·e^{E} with r, s, E rational functions, and
is accepted only if r, s and E each equal the closed form's as rational functions (the difference
cancels to 0) — a sign error changes r and is rejected.

Negative controls: mutated forms of the identities route 1 rests on (refused by the kernel and
refuted on exact instances), and mutated closed forms that route 2 must reject.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import sympy as sp

from fractions import Fraction

from gpfverify.kernel.rules import Checker
from gpfverify.kernel.terms import frozen, read_statement
from gpfverify.symbolic.certificate import Certificate, Control, ListedCheck, Part
from gpfverify.symbolic.formal import TWO_PI, Declare, I, Term, as_term, det, eq, exp, num, size, spd
from gpfverify.symbolic.search import Template, prove_equation
from gpfverify.symbolic.witness import Builder, refuting

# ---- route 2: direct integration ------------------------------------------------------------------

_a = sp.Symbol("a", positive=True)
_b, _c, _p0, _p1, _u = sp.symbols("b c p0 p1 u", real=True)


def one_dimensional_rule_residual() -> sp.Expr:
    """sympy.integrate of the 1-D rule the iterated integration uses, minus the rule (simplified)."""
    integral = sp.integrate((_p0 + _p1 * _u) * sp.exp(-_a * _u**2 + _b * _u + _c), (_u, -sp.oo, sp.oo), conds="none")
    rule = sp.sqrt(sp.pi / _a) * sp.exp(_b**2 / (4 * _a) + _c) * (_p0 + _p1 * _b / (2 * _a))
    return sp.simplify(integral - rule)


@dataclass(frozen=True)
class ExpForm:
    """r · √s · exp(E) with r, s, E rational functions (s > 0)."""

    r: sp.Expr
    s: sp.Expr
    e: sp.Expr

    def value(self) -> sp.Expr:
        return self.r * sp.sqrt(self.s) * sp.exp(self.e)


def residual(f: ExpForm, g: ExpForm) -> tuple:
    """(E_f − E_g, s_f − s_g, r_f − r_g): r√s e^E = r'√s' e^E' when all three vanish as rational
    functions (a sound, exact test: a sign error changes r)."""
    return (f.e - g.e, f.s - g.s, f.r - g.r)


def exactly_equal(f: ExpForm, g: ExpForm) -> bool:
    return all(sp.cancel(sp.together(x)) == 0 for x in residual(f, g))


def gaussian_expectation(prefactor: sp.Expr, exponent: sp.Expr, zs: list[sp.Symbol]) -> ExpForm:
    """E_{z ~ N(0, I)}[prefactor(z) · exp(exponent(z))], prefactor linear and exponent quadratic in
    z, integrated coordinate by coordinate with the 1-D rule.

    The exponent (with the density's −½zᵀz) is held as −½zᵀAz + bᵀz + c. Integrating the first
    remaining coordinate u with the 1-D rule (a = A_uu/2, linear coefficient b_u − A_u,rest·z)
    gives c + (b_u − A_u,rest·z)²/(2A_uu), i.e. A ← A_rest − A_rest,u A_u,rest/A_uu,
    b ← b_rest − A_rest,u b_u/A_uu, c ← c + b_u²/(2A_uu), a factor √(π/a)/√(2π) = 1/√A_uu, and the
    linear prefactor p₀ + p_u u + p·z ← p₀ + p·z + p_u (b_u − A_u,rest·z)/A_uu."""
    total = sp.expand(exponent - sum(z**2 for z in zs) / 2)
    at_zero = {z: 0 for z in zs}
    k = len(zs)
    a = sp.Matrix(k, k, lambda i, j: -sp.diff(total, zs[i], zs[j]))
    b = [sp.diff(total, z).subs(at_zero) for z in zs]
    c = total.subs(at_zero)
    pre = sp.expand(prefactor)
    p0, p = pre.subs(at_zero), [sp.diff(pre, z) for z in zs]
    s = sp.Integer(1)
    while a.shape[0]:
        pivot = a[0, 0]
        col = [a[i, 0] for i in range(1, a.shape[0])]
        c = sp.cancel(c + b[0] ** 2 / (2 * pivot))
        p0 = sp.cancel(p0 + p[0] * b[0] / pivot)
        p = [sp.cancel(p[i + 1] - p[0] * col[i] / pivot) for i in range(len(col))]
        b = [sp.cancel(b[i + 1] - col[i] * b[0] / pivot) for i in range(len(col))]
        a = sp.Matrix(len(col), len(col),
                      lambda i, j, a=a, col=col, pivot=pivot: sp.cancel(a[i + 1, j + 1] - col[i] * col[j] / pivot))
        s = sp.cancel(s / pivot)
    return ExpForm(sp.cancel(p0), s, sp.cancel(c))


@dataclass(frozen=True)
class Setting:
    """Symbols of one D-dimensional case: L (Σ = LLᵀ), two outputs' lengthscales and amplitudes,
    ν_i, ν_j, the standard-normal coordinates z."""

    d: int
    chol: sp.Matrix
    ell_a: sp.Matrix
    ell_b: sp.Matrix
    alpha_a: sp.Symbol
    alpha_b: sp.Symbol
    nu_i: sp.Matrix
    nu_j: sp.Matrix
    zs: list

    @classmethod
    def of(cls, d: int) -> Setting:
        chol = sp.Matrix(d, d, lambda i, j: (sp.Symbol(f"L{i}{j}", positive=True) if i == j
                                             else sp.Symbol(f"L{i}{j}", real=True) if i > j else 0))
        pos = lambda name: sp.Matrix([sp.Symbol(f"{name}{k}", positive=True) for k in range(d)])  # noqa: E731
        real = lambda name: sp.Matrix([sp.Symbol(f"{name}{k}", real=True) for k in range(d)])  # noqa: E731
        return cls(d, chol, pos("la"), pos("lb"), sp.Symbol("alpha_a", positive=True),
                   sp.Symbol("alpha_b", positive=True), real("nui"), real("nuj"),
                   [sp.Symbol(f"z{k}", real=True) for k in range(d)])

    @property
    def sigma(self) -> sp.Matrix:
        return self.chol * self.chol.T

    def lam(self, which: str) -> sp.Matrix:
        return sp.diag(*[e**2 for e in (self.ell_a if which == "a" else self.ell_b)])

    def lam_inv(self, which: str) -> sp.Matrix:
        return sp.diag(*[1 / e**2 for e in (self.ell_a if which == "a" else self.ell_b)])

    @property
    def x_minus_mu(self) -> sp.Matrix:
        return self.chol * sp.Matrix(self.zs)

    def log_kernel(self, nu: sp.Matrix, which: str) -> sp.Expr:
        diff = self.x_minus_mu - nu
        return -(diff.T * self.lam_inv(which) * diff)[0] / 2


def _inv(m: sp.Matrix) -> sp.Matrix:
    return m.adjugate() / m.det()


def integrals(s: Setting, product: bool) -> dict:
    """The integrals by iterated integration: {name: ExpForm} (the cross moment per component)."""
    out = {"q_i (eq. 8-9)": gaussian_expectation(s.alpha_a**2, s.log_kernel(s.nu_i, "a"), s.zs)}
    for k in range(s.d):
        out[f"Cov[x, k_a]_{k} (eq. 20)"] = gaussian_expectation(s.alpha_a**2 * s.x_minus_mu[k],
                                                                s.log_kernel(s.nu_i, "a"), s.zs)
    if product:
        out["Q_ij (eq. 11)"] = gaussian_expectation(s.alpha_a**2 * s.alpha_b**2,
                                                    s.log_kernel(s.nu_i, "a") + s.log_kernel(s.nu_j, "b"), s.zs)
    return out


def closed_forms(s: Setting, product: bool, mutate: str = "") -> dict:
    """The paper's closed forms as ExpForms; ``mutate`` names one deliberate error."""
    sigma, eye = s.sigma, sp.eye(s.d)
    lam, lam_inv = s.lam("a"), s.lam_inv("a")
    inner = sigma + lam if mutate != "wrong inverse" else lam
    inner_inv = _inv(inner)
    e = -(s.nu_i.T * inner_inv * s.nu_i)[0] / 2
    det = (sigma * lam_inv + eye).det()
    q = ExpForm(s.alpha_a**2, 1 / det if mutate != "determinant dropped" else sp.Integer(1),
                e if mutate != "exponent sign flipped" else -e)
    out = {"q_i (eq. 8-9)": q}
    shift = sigma * _inv(sigma + lam) * s.nu_i
    if mutate == "cross moment sign flipped":
        shift = -shift
    if mutate == "Σ ignored in the cross moment":
        shift = s.nu_i
    for k in range(s.d):
        out[f"Cov[x, k_a]_{k} (eq. 20)"] = ExpForm(q.r * shift[k], q.s, q.e)
    if product:
        xi = lam_inv + s.lam_inv("b")
        r = sigma * xi + eye
        lam_a_for_z = lam_inv if mutate != "Λ_a in place of Λ_a⁻¹ in z" else lam
        z = lam_a_for_z * s.nu_i + s.lam_inv("b") * s.nu_j
        log_k = (-(s.nu_i.T * lam_inv * s.nu_i)[0] - (s.nu_j.T * s.lam_inv("b") * s.nu_j)[0]) / 2
        out["Q_ij (eq. 11)"] = ExpForm(s.alpha_a**2 * s.alpha_b**2, 1 / r.det(),
                                       log_k + (z.T * _inv(r) * sigma * z)[0] / 2)
    return out


DIRECT_MUTANTS = ("cross moment sign flipped", "wrong inverse", "determinant dropped", "exponent sign flipped",
                  "Σ ignored in the cross moment", "Λ_a in place of Λ_a⁻¹ in z")
DIRECT_DIMS = {"small": {1: True, 2: True}, "large": {1: True, 2: True, 3: True}}


def _nonzero_somewhere(residuals) -> bool:
    """Some residual is nonzero at a point of seeded positive rationals (a mutant is false)."""
    rng = np.random.default_rng(20191126)
    for r in residuals:
        point = {x: sp.Rational(int(rng.integers(4, 17)), 4) for x in sorted(sp.sympify(r).free_symbols, key=str)}
        if sp.nsimplify(sp.simplify(sp.sympify(r).xreplace(point))) != 0:
            return True
    return False


def direct_check(size: str) -> ListedCheck:
    """Route 2: each integral against its closed form per D, and every mutated closed form refused."""
    holds = sp.simplify(one_dimensional_rule_residual()) == 0
    for d, product in DIRECT_DIMS[size].items():
        s = Setting.of(d)
        got, closed = integrals(s, product), closed_forms(s, product)
        holds &= all(exactly_equal(form, closed[name]) for name, form in got.items())
        if d == 2:
            for mutant in DIRECT_MUTANTS:
                wrong = closed_forms(s, product, mutant)
                affected = [k for k in wrong if wrong[k] != closed[k]]
                holds &= _nonzero_somewhere([x for k in affected for x in residual(got[k], wrong[k])])
    return ListedCheck("q_i, Q_ij and the cross moment E[(x − μ) k_a(x, x_i)] of seed 000 eq. 8–11, 20 equal their "
                       "closed forms, by exact iterated Gaussian integration (x = μ + Lz, every entry of the "
                       "lower-triangular L free, diagonal Λ_a, Λ_b); the mutated closed forms ("
                       + ", ".join(DIRECT_MUTANTS) + ") are refused", tuple(f"D = {d}" for d in DIRECT_DIMS[size]),
                       ("Σ = LLᵀ with every diagonal entry of L > 0", "every lengthscale ℓ > 0", "α_a, α_b > 0"), holds)


# ---- route 1: any D, through the kernel ----------------------------------------------------------------

def declare() -> tuple[Declare, dict]:
    """The GP quantities: x ~ N(μ, Σ), SE kernels k_a, k_b with SPD Λ_a, Λ_b (diagonal in SE-ARD;
    any SPD here), training inputs x_i, x_j, and the closed forms of seed 000 eq. 8–11, 20."""
    d = Declare()
    d.sizes("D")
    aa, ab = d.param("α_a"), d.param("α_b")
    mu, sig = d.matrix("μ", "D", 1), d.matrix("Σ", "D", "D")
    la, lb = d.matrix("Λ_a", "D", "D"), d.matrix("Λ_b", "D", "D")
    xi, xj = d.matrix("x_i", "D", 1), d.matrix("x_j", "D", 1)
    vec = (("u", "D", 1), ("v", "D", 1))
    ka = d.define("k_a", lambda u, v: aa ** 2 * exp(num("-1/2") * (u - v).T * la.inv * (u - v)), args=vec)
    kb = d.define("k_b", lambda u, v: ab ** 2 * exp(num("-1/2") * (u - v).T * lb.inv * (u - v)), args=vec)
    normal = d.define("N", lambda u: TWO_PI ** (num("-1/2") * size("D")) * det(sig) ** Fraction(-1, 2)
                      * exp(num("-1/2") * (u - mu).T * sig.inv * (u - mu)), args=(("u", "D", 1),))
    nu_i, nu_j = d.define("ν_i", xi - mu), d.define("ν_j", xj - mu)
    q = d.define("q", aa ** 2 * det(sig * la.inv + I("D")) ** Fraction(-1, 2)
                 * exp(num("-1/2") * nu_i.T * (sig + la).inv * nu_i))
    r = d.define("R", sig * (la.inv + lb.inv) + I("D"))
    z = d.define("z", la.inv * nu_i + lb.inv * nu_j)
    big_q = d.define("Q", ka(xi, mu) * kb(xj, mu) * det(r) ** Fraction(-1, 2) * exp(num("1/2") * z.T * r.inv * sig * z))
    d.assume(spd(sig), spd(la), spd(lb))
    x = Term(("var", "x"))
    terms = {"mu": mu, "sig": sig, "la": la, "lb": lb, "xi": xi, "xj": xj, "x": x, "nu_i": nu_i, "q": q, "R": r,
             "z": z, "Q": big_q,
             "int_q": integral(normal(x) * ka(x, xi)), "int_cross": integral((x - mu) * normal(x) * ka(x, xi)),
             "int_Q": integral(normal(x) * ka(x, xi) * kb(x, xj))}
    return d, terms


def integral(body) -> Term:
    return Term(("int", "x", "D", as_term(body)))


def statement() -> dict:
    d, t = declare()
    d.conclude(eq(t["int_q"], t["q"]), eq(t["int_cross"], t["sig"] * (t["sig"] + t["la"]).inv * t["nu_i"] * t["q"]),
               eq(t["int_Q"], t["Q"]))
    return d.json()


def proof(statement_json: dict) -> dict:
    """Completing the square (G9) with the determinant lemma (S1) and the matrix identities behind
    the closed forms, each proved by the search from the inverse and symmetry rules."""
    st = read_statement(frozen(statement_json))
    checker = Checker(st, {"steps": []})
    _, t = declare()
    g = {k: v.t for k, v in t.items()}
    sig, la, lb, mu, xi, xj = (t[k] for k in ("sig", "la", "lb", "mu", "xi", "xj"))
    a1 = sig.inv + la.inv
    c1 = a1.inv
    a2 = sig.inv + la.inv + lb.inv
    c2 = a2.inv
    k = (sig + la).inv
    b1 = sig.inv * mu + la.inv * xi
    e1 = num("-1/2") * mu.T * sig.inv * mu + num("-1/2") * xi.T * la.inv * xi
    b2 = b1 + lb.inv * xj
    e2 = e1 + num("-1/2") * xj.T * lb.inv * xj
    steps: list = []

    def add(step):
        checker.step(frozen(step))
        steps.append(step)
        return step["id"]

    def inverse(matrix, side="right", lead=None):
        return Template({"inverse": side, "of": as_term(matrix)}, orient=lead.t if lead is not None else "longest")

    def lemma(sid, lead=None, transposed=False):
        return Template({"lemma": sid}, orient=lead.t if lead is not None else "longest", transposed=transposed)

    basics = [inverse(m, side) for m in (sig, la, lb) for side in ("right", "left")]

    def prove(sid, lhs, rhs, templates, extra=None, subst=None):
        step, left = prove_equation(checker, sid, as_term(lhs), as_term(rhs), templates, extra=extra, subst=subst)
        return add(step)

    # determinants and invertibility (the statement's side conditions, and S1)
    prove("ΣΛ_a⁻¹ + I = Σ(Σ⁻¹ + Λ_a⁻¹)", sig * la.inv + I("D"), sig * a1, basics)
    add({"id": "det(ΣΛ_a⁻¹ + I) > 0", "claim": ("positive", as_term(sig * la.inv + I("D"))),
         "factors": [sig.t, a1.t], "by": "ΣΛ_a⁻¹ + I = Σ(Σ⁻¹ + Λ_a⁻¹)"})
    prove("R = Σ(Σ⁻¹ + Ξ)", t["R"], sig * a2, basics)
    for kind in ("positive", "invertible"):
        add({"id": f"R {kind}", "claim": (kind, g["R"]), "factors": [sig.t, a2.t], "by": "R = Σ(Σ⁻¹ + Ξ)"})
    # q and the cross moment: A = Σ⁻¹ + Λ_a⁻¹, C = A⁻¹, K = (Σ + Λ_a)⁻¹
    prove("(Σ + Λ_a)Λ_a⁻¹CΣ⁻¹ = I", (sig + la) * la.inv * c1 * sig.inv, I("D"),
          [inverse(la), inverse(a1, lead=la.inv * c1)] + basics)
    prove("Λ_a⁻¹CΣ⁻¹ = (Σ + Λ_a)⁻¹", la.inv * c1 * sig.inv, k, [],
          extra=[{"left": k.t, "gen": {"lemma": "(Σ + Λ_a)Λ_a⁻¹CΣ⁻¹ = I"}},
                 {"left": num(-1).t, "gen": {"inverse": "left", "of": as_term(sig + la)},
                  "right": as_term(la.inv * c1 * sig.inv)}])
    cs = "Λ_a⁻¹CΣ⁻¹ = (Σ + Λ_a)⁻¹"
    prove("completing the square (q)", num("1/2") * b1.T * c1 * b1 + e1, num("-1/2") * t["nu_i"].T * k * t["nu_i"],
          [lemma(cs), lemma(cs, transposed=True), inverse(a1, lead=sig.inv * c1),
           inverse(a1, "left", lead=c1 * la.inv)] + basics)
    prove("the mean: Cb − μ = Σ(Σ + Λ_a)⁻¹ν_i", c1 * b1 - mu, sig * k * t["nu_i"],
          [lemma(cs, lead=k, transposed=True), inverse(a1, "left", lead=c1 * sig.inv)] + basics)
    det_q = {"det": as_term(sig * la.inv + I("D")), "factors": [sig.t, a1.t], "by": "ΣΛ_a⁻¹ + I = Σ(Σ⁻¹ + Λ_a⁻¹)"}
    exp_q = {"exp": as_term(num("1/2") * b1.T * a1.pinv * b1 + e1), "by": "completing the square (q)"}
    gauss_q = {"A": a1.t, "b": b1.t, "c": e1.t}
    prove("eq. 8–9", t["int_q"], t["q"], [], extra=[{"gen": {"gauss": g["int_q"], **gauss_q}}], subst=[det_q, exp_q])
    prove("eq. 20", t["int_cross"], t["sig"] * k * t["nu_i"] * t["q"], [lemma("the mean: Cb − μ = Σ(Σ + Λ_a)⁻¹ν_i")],
          extra=[{"gen": {"gauss": g["int_cross"], **gauss_q}}], subst=[det_q, exp_q])
    # Q_ij: A₂ = Σ⁻¹ + Λ_a⁻¹ + Λ_b⁻¹, C₂ = A₂⁻¹, R = ΣA₂
    r = t["R"]
    prove("C₂ = R⁻¹Σ", c2, r.inv * sig, [],
          extra=[{"left": num(-1).t, "gen": {"inverse": "left", "of": g["R"]}, "right": c2.t},
                 {"left": r.inv.t, "gen": {"lemma": "R = Σ(Σ⁻¹ + Ξ)"}, "right": c2.t},
                 {"left": (r.inv * sig).t, "gen": {"inverse": "right", "of": a2.t}}])
    half = num("-1/2") * t["nu_i"].T * la.inv * t["nu_i"] + num("-1/2") * (xj - mu).T * lb.inv * (xj - mu)
    prove("completing the square (Q), in C₂", num("1/2") * b2.T * c2 * b2 + e2,
          num("1/2") * t["z"].T * c2 * t["z"] + half,
          [inverse(a2, lead=sig.inv * c2), inverse(a2, "left", lead=c2 * sig.inv)] + basics)
    prove("completing the square (Q)", num("1/2") * b2.T * c2 * b2 + e2,
          num("1/2") * t["z"].T * r.inv * sig * t["z"] + half,
          [lemma("C₂ = R⁻¹Σ", lead=r.inv * sig), lemma("C₂ = R⁻¹Σ", lead=(r.inv * sig).T, transposed=True)],
          extra=[{"gen": {"lemma": "completing the square (Q), in C₂"}}])
    prove("eq. 11", t["int_Q"], t["Q"], [], extra=[{"gen": {"gauss": g["int_Q"], "A": a2.t, "b": b2.t, "c": e2.t}}],
          subst=[{"det": g["R"], "factors": [sig.t, a2.t], "by": "R = Σ(Σ⁻¹ + Ξ)"},
                 {"exp": as_term(num("1/2") * b2.T * a2.pinv * b2 + e2), "by": "completing the square (Q)"}])
    return {"steps": steps}


def witness(seed: int = 1) -> dict:
    b = Builder(seed, {"D": 2}, params={"α_a": 2, "α_b": "3/2"})
    for name in ("Σ", "Λ_a", "Λ_b"):
        b.draw(name, 2, 2, "spd")
    for name in ("μ", "x_i", "x_j"):
        b.draw(name, 2, 1)
    return b.json()


#: mutated forms of the identities the proof rests on (integral-free, so the kernel refutes them exactly)
MUTANTS = ("the cross moment's mean without Σ: Cb − μ = ν_i", "(Σ + Λ_a)⁻¹ replaced by Λ_a⁻¹ in q's exponent",
           "the determinant lemma with the factors swapped: ΣΛ_a⁻¹ + I = (Σ⁻¹ + Λ_a⁻¹)Σ",
           "Q's exponent with ΣR⁻¹ in place of R⁻¹Σ")


def mutant(which: str) -> dict:
    d, t = declare()
    sig, la, lb, mu, xi, xj = (t[k] for k in ("sig", "la", "lb", "mu", "xi", "xj"))
    a1, a2 = sig.inv + la.inv, sig.inv + la.inv + lb.inv
    b1 = sig.inv * mu + la.inv * xi
    e1 = num("-1/2") * mu.T * sig.inv * mu + num("-1/2") * xi.T * la.inv * xi
    b2, e2 = b1 + lb.inv * xj, e1 + num("-1/2") * xj.T * lb.inv * xj
    half = num("-1/2") * t["nu_i"].T * la.inv * t["nu_i"] + num("-1/2") * (xj - mu).T * lb.inv * (xj - mu)
    if which == MUTANTS[0]:
        d.conclude(eq(a1.inv * b1 - mu, t["nu_i"]))
    elif which == MUTANTS[1]:
        d.conclude(eq(num("1/2") * b1.T * a1.inv * b1 + e1, num("-1/2") * t["nu_i"].T * la.inv * t["nu_i"]))
    elif which == MUTANTS[2]:
        d.conclude(eq(sig * la.inv + I("D"), a1 * sig))
    else:
        d.conclude(eq(num("1/2") * b2.T * a2.inv * b2 + e2, num("1/2") * t["z"].T * sig * t["R"].inv * t["z"] + half))
    return d.json()


def _attempt(statement_json: dict) -> dict:
    st = read_statement(frozen(statement_json))
    checker = Checker(st, {"steps": []})
    templates = [Template({"inverse": side, "of": ("var", m)}) for m in ("Σ", "Λ_a", "Λ_b")
                 for side in ("right", "left")]
    c = st.conclusion[0]
    return {"steps": [prove_equation(checker, "s1", c[1], c[2], templates)[0]]}


def prove_gp_moment_integrals(size: str = "small") -> Certificate:
    start = time.perf_counter()
    main = statement()
    controls = [Control(m, mutant(m), _attempt(mutant(m)), refuting(mutant(m), witness, range(2, 22)))
                for m in MUTANTS]
    return Certificate("gp-moment-integrals",
                       "The uncertain-input SE-kernel integrals q_i, Q_ij and the input-output cross moment (seed 000 "
                       "eq. 8–11, 20) with a full input covariance Σ", [Part(main, proof(main), witness())], controls,
                       [direct_check(size)], time.perf_counter() - start)
