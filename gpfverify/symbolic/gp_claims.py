"""The uncertain-input SE-kernel integrals of seed 000 eq. 8–11 and 20 (Deisenroth et al. 2009)
in D dimensions with a full input covariance Σ, by two routes.

With x ~ N(μ, Σ), k_a(x, x') = α_a² exp(−½ (x − x')ᵀΛ_a⁻¹(x − x')), ν_i = x_i − μ:

* q_i  = E[k_a(x, x_i)] = α_a² |ΣΛ_a⁻¹ + I|^{-1/2} exp(−½ ν_iᵀ(Σ + Λ_a)⁻¹ν_i)                 (eq. 8–9)
* Cov[x, k_a(x, x_i)] = E[(x − μ) k_a(x, x_i)] = Σ(Σ + Λ_a)⁻¹ ν_i q_i                          (eq. 20)
* Q_ij = E[k_a(x, x_i) k_b(x, x_j)] = k_a(x_i, μ) k_b(x_j, μ) |R|^{-1/2} exp(½ zᵀR⁻¹Σz),
  R = Σ(Λ_a⁻¹ + Λ_b⁻¹) + I, z = Λ_a⁻¹ν_i + Λ_b⁻¹ν_j                                           (eq. 11)

**Route 1, symbolic D** (:mod:`gpfverify.symbolic.word_algebra`, supporting): the Gaussian
product identity and the matrix identities behind each closed form, proved from the declarations
of a :class:`~gpfverify.symbolic.theory.Theory` (Λ_a, Λ_b, Σ symmetric positive definite — not
only diagonal Λ —, their inverses, C = (Λ⁻¹ + Σ⁻¹)⁻¹, S = (Λ + Σ)⁻¹, Ξ = Λ_a⁻¹ + Λ_b⁻¹,
M⁻¹ = (Ξ + Σ⁻¹)⁻¹, R⁻¹ = (ΣΞ + I)⁻¹). The integrals follow from them only with |XY| = |X||Y| and
the D-dimensional Gaussian integral, which the engine neither proves nor checks: route 1 does not
widen the certificate's scope.

**Route 2, D = 1, 2 (and 3 in the large size) by direct integration**, the certificate's scope:
x = μ + Lz with Σ = LLᵀ (L lower triangular,
every entry a free symbol, positive diagonal) and z ~ N(0, I); the integrand p(z)·exp(E(z)), p
linear, is integrated one coordinate at a time with the 1-D rule
∫(p₀ + p₁u)e^{−au² + bu + c}du = √(π/a) e^{b²/4a + c}(p₀ + p₁ b/2a) (a > 0), itself verified by
``sympy.integrate``. The result has the exact form r·√s·e^{E} with r, s, E rational functions, and
is accepted only if r, s and E each equal the closed form's as rational functions (the difference
cancels to 0) — a sign error changes r and is rejected.

Every route carries negative controls: mutated closed forms (a sign, a wrong inverse, a dropped
determinant, a flipped exponent) that must be rejected.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import sympy as sp

from gpfverify.symbolic import word_algebra as wa
from gpfverify.symbolic.argument import Argument
from gpfverify.symbolic.certificate import Certificate
from gpfverify.symbolic.theory import Theory
from gpfverify.symbolic.word_algebra import identity

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


def direct_route(argument: Argument, size: str) -> None:
    """Route 2: each integral against its closed form, per D (``argument.at_sizes``), and the
    mutated closed forms at D = 2 as negative controls."""
    argument.at_sizes("the 1-D rule ∫(p₀ + p₁u)e^{−au² + bu + c}du = √(π/a)e^{b²/4a + c}(p₀ + p₁b/2a) "
                      "(sympy.integrate)",
                      "D = 1", one_dimensional_rule_residual())
    for d, product in DIRECT_DIMS[size].items():
        s = Setting.of(d)
        got = integrals(s, product)
        closed = closed_forms(s, product)
        for name, form in got.items():
            argument.at_sizes(f"{name} equals its closed form as r·√s·e^E", f"D = {d}", residual(form, closed[name]))
        if d == 2:
            for mutant in DIRECT_MUTANTS:
                wrong = closed_forms(s, product, mutant)
                affected = [key for key in wrong if wrong[key] != closed[key]]
                argument.control_residual(f"direct route, D = 2: {mutant}",
                                          tuple(residual(got[key], wrong[key]) for key in affected))


# ---- route 1: symbolic D ----------------------------------------------------------------------------

n = sp.Symbol("n", integer=True, positive=True)  # D
ONE = sp.Integer(1)
GP = Theory("uncertain-input SE-kernel integrals", 2009)
Lam, LAM = GP.spd("Λ", n, "Λ_a symmetric positive definite")
Lam_b, LAM_B = GP.spd("Λ_b", n, "Λ_b symmetric positive definite")
Sig, SIG = GP.spd("Σ", n, "Σ symmetric positive definite")
Lam_i, LAM_INV = GP.inverse("Λ⁻¹", Lam)
Lam_bi, LAM_B_INV = GP.inverse("Λ_b⁻¹", Lam_b)
Sig_i, SIG_INV = GP.inverse("Σ⁻¹", Sig)
Cc, C_INV = GP.inverse("C", Lam_i + Sig_i, "Λ⁻¹ + Σ⁻¹ invertible")
Sm, S_INV = GP.inverse("S", Lam + Sig, "Λ + Σ invertible")
Xi, XI = GP.define("Ξ", Lam_i + Lam_bi)
Mi, M_INV = GP.inverse("M⁻¹", Xi + Sig_i, "Ξ + Σ⁻¹ invertible")
I_n = identity(n)
Ri, R_INV = GP.inverse("R⁻¹", Sig * Xi + I_n, "ΣΞ + I invertible")
xv, av, bv, uv, zv = (GP.general(name, n, ONE) for name in ("x", "x_i", "μ", "u", "z"))
#: R⁻¹ = (ΣΞ + I)⁻¹ is not symmetric: declared so by hand, for a negative control
PLANTED_R_SYMMETRIC = wa.Rule("R⁻¹ᵀ = R⁻¹", Ri.T, Ri, "axiom")


def _lemma(name: str, chain: list, statement: str) -> tuple[wa.Rule, wa.Proof]:
    proof = wa.prove_by_chain(chain, statement)
    return wa.lemma(name, proof), proof


def _quad(v, m, w=None):
    w = v if w is None else w
    return v.T * m * w


def dimension_free_route(argument: Argument) -> None:
    """Route 1's proofs (supporting the argument) and its negative controls."""
    xi_sym = wa.lemma("Ξᵀ = Ξ", wa.prove_by_normal_form(Xi.T, Xi, [XI, LAM_INV[2], LAM_B_INV[2]], "Ξᵀ = Ξ"))
    symmetries = [LAM, SIG, LAM_INV[2], SIG_INV[2], C_INV[2], S_INV[2], M_INV[2], xi_sym]
    inverses = symmetries + [LAM_INV[0], LAM_INV[1], SIG_INV[0], SIG_INV[1]]
    c_def, c_def_proof = _lemma("Λ⁻¹C = I − Σ⁻¹C", [(Lam_i * Cc, None), (I_n - Sig_i * Cc, C_INV[0])],
                                "Λ⁻¹C = I − Σ⁻¹C (C = (Λ⁻¹ + Σ⁻¹)⁻¹)")
    c_t, c_t_proof = _lemma("CΛ⁻¹ = I − CΣ⁻¹", [(Cc * Lam_i, None), (I_n - Cc * Sig_i, C_INV[1])], "CΛ⁻¹ = I − CΣ⁻¹")
    c_lemma, c_proof = _lemma("CΣ⁻¹Λ = Λ − C", [(Cc * Sig_i * Lam, None), (Lam - Cc * Lam_i * Lam, c_t),
                                                 (Lam - Cc, LAM_INV[1])], "CΣ⁻¹Λ = Λ − C")
    target = Lam_i * Cc * Sig_i
    right_inverse = wa.prove_by_normal_form((Lam + Sig) * target, I_n, inverses + [c_def], "(Λ + Σ)Λ⁻¹CΣ⁻¹ = I")
    ri = wa.lemma("(Λ + Σ)Λ⁻¹CΣ⁻¹ = I", right_inverse)
    s_lemma, s_proof = _lemma("S = Λ⁻¹CΣ⁻¹", [(Sm, None), (Sm * (Lam + Sig) * target, ri), (target, S_INV[1])],
                              "S = Λ⁻¹CΣ⁻¹ (uniqueness of the inverse)")
    m_def, m_def_proof = _lemma("Σ⁻¹M⁻¹ = I − ΞM⁻¹", [(Sig_i * Mi, None), (I_n - Xi * Mi, M_INV[0])],
                                "Σ⁻¹M⁻¹ = I − ΞM⁻¹ (M⁻¹ = (Ξ + Σ⁻¹)⁻¹)")
    m_lemma, m_proof = _lemma("M⁻¹ = R⁻¹Σ", [(Ri * Sig, None), (Ri * Sig * Xi * Mi + Ri * Sig * Sig_i * Mi, M_INV[0]),
                                             (Ri * Sig * Xi * Mi + Ri * Mi, SIG_INV[0]), (Mi, R_INV[1])], "R⁻¹Σ = M⁻¹")
    base = inverses + [c_def, c_t, c_lemma, s_lemma]
    c = Cc * (Lam_i * av + Sig_i * bv)
    product_lhs = _quad(xv - av, Lam_i) + _quad(xv - bv, Sig_i)
    product_rhs = _quad(xv - c, Lam_i + Sig_i) + _quad(av - bv, Sm)
    m = Xi + Sig_i
    square_lhs = _quad(uv, m) - 2 * _quad(uv, I_n, zv)
    square_rhs = _quad(uv - Mi * zv, m) - _quad(zv, Mi)
    argument.support(
        c_def_proof, c_t_proof, c_proof, right_inverse, s_proof, m_def_proof, m_proof,
        wa.prove_by_normal_form(product_lhs, product_rhs, base,
                                "Gaussian product: (x−x_i)ᵀΛ⁻¹(x−x_i) + (x−μ)ᵀΣ⁻¹(x−μ) = (x−c)ᵀ(Λ⁻¹+Σ⁻¹)(x−c) + "
                                "ν_iᵀ(Λ+Σ)⁻¹ν_i, c = C(Λ⁻¹x_i + Σ⁻¹μ)"),
        wa.prove_by_normal_form(Lam * (Lam_i + Sig_i) * Sig, Lam + Sig, inverses,
                                "Λ(Λ⁻¹ + Σ⁻¹)Σ = Λ + Σ (the normalisers' matrices)"),
        wa.prove_by_normal_form((Sig * Lam_i + I_n) * Lam, Sig + Lam, inverses,
                                "(ΣΛ⁻¹ + I)Λ = Σ + Λ (eq. 9's determinant)"),
        wa.prove_by_normal_form(c - bv, Sig * Sm * (av - bv), base, "c − μ = Σ(Σ + Λ)⁻¹ν_i (eq. 20)"),
        wa.prove_by_normal_form(square_lhs, square_rhs, inverses + [m_def],
                                "uᵀMu − 2uᵀz = (u − M⁻¹z)ᵀM(u − M⁻¹z) − zᵀM⁻¹z, M = Ξ + Σ⁻¹ (eq. 11's exponent)"),
        wa.prove_by_normal_form(_quad(zv, Mi), _quad(zv, Ri * Sig), symmetries + [m_lemma],
                                "zᵀM⁻¹z = zᵀR⁻¹Σz, R = ΣΞ + I (eq. 11)"),
        wa.prove_by_normal_form(Sig * (Xi + Sig_i), Sig * Xi + I_n, inverses,
                                "Σ(Ξ + Σ⁻¹) = ΣΞ + I"))
    standing = frozenset({LAM, LAM_B, SIG})
    for mutant, lhs, rhs, rules in (
            ("cross moment sign flipped: c − μ = −Σ(Σ + Λ)⁻¹ν_i", c - bv, -(Sig * Sm * (av - bv)), base),
            ("Σ ignored: c − μ = ν_i", c - bv, av - bv, base),
            ("wrong inverse: (Λ + Σ)⁻¹ replaced by Λ⁻¹ in the product identity", product_lhs,
             _quad(xv - c, Lam_i + Sig_i) + _quad(av - bv, Lam_i), base),
            ("dropped term ν_iᵀ(Λ+Σ)⁻¹ν_i in the product identity", product_lhs, _quad(xv - c, Lam_i + Sig_i), base),
            ("completed square with −M⁻¹z (sign)", square_lhs, _quad(uv + Mi * zv, m) - _quad(zv, Mi),
             inverses + [m_def]),
            ("eq. 11 with ΣR⁻¹ in place of R⁻¹Σ (a transpose, seen in zᵀ·w)", _quad(zv, Mi, uv),
             _quad(zv, Sig * Ri, uv), symmetries + [m_lemma])):
        argument.control(mutant, wa.prove_by_normal_form(lhs, rhs, rules), statement=mutant, false_under=standing)
    argument.control("planted rule R⁻¹ᵀ = R⁻¹, an axiom no declaration issued (proves zᵀR⁻¹u = uᵀR⁻¹z)",
                     wa.prove_by_normal_form(_quad(zv, Ri, uv), _quad(uv, Ri, zv), [PLANTED_R_SYMMETRIC]),
                     statement="zᵀR⁻¹u = uᵀR⁻¹z", false_under=standing)


def prove_gp_moment_integrals(size: str = "small") -> Certificate:
    start = time.perf_counter()
    dims = ", ".join(str(d) for d in DIRECT_DIMS[size])
    argument = Argument("gp-moment-integrals",
                        "the closed forms of the uncertain-input kernel integrals q_i, Q_ij and the input-output cross "
                        f"moment (seed 000 eq. 8–11, 20) with a full input covariance Σ, for D = {dims}",
                        "iterated exact Gaussian integration (listed D) + word-algebra rewriting of the matrix "
                        "identities behind the closed forms (supporting, symbolic D)", GP)
    direct_route(argument, size)
    dimension_free_route(argument)
    argument.note(f"Route 2 (the scope: D = {dims}): Σ = LLᵀ with every entry of the lower-triangular L free, diagonal "
                  "Λ_a, Λ_b, ν_i, ν_j free; each integral, integrated coordinate by coordinate with the 1-D rule, has "
                  "the exact form r·√s·e^E and equals its closed form iff r, s and E are equal rational functions. "
                  "Route 1 (supporting, symbolic D, Λ any SPD matrix): the matrix identities below. With "
                  "|XY| = |X||Y| and ∫N(x; m, P)dx = 1 they would give the integrals for larger D; the engine neither "
                  "proves nor checks those two facts here, so larger D is not claimed.")
    return argument.certificate(time.perf_counter() - start)
