"""Symbolic integration of the SE-kernel moment integrals against a Gaussian input, D = 1
(seed 000 eq. 8–11 and 20; Deisenroth et al. 2009).

With x ~ N(μ, Σ), k_a(x, x') = α_a² exp(−(x − x')²/(2ℓ_a²)):

* l_i  = E[k_a(x, x_i)] = α_a² (Σ/ℓ_a² + 1)^{-1/2} exp(−(x_i − μ)²/(2(Σ + ℓ_a²)))           (eq. 8–9)
* L_ij = E[k_a(x, x_i) k_b(x, x_j)] = k_a(x_i, μ) k_b(x_j, μ) R^{-1/2} exp(z² Σ/(2R)),
  R = Σ(1/ℓ_a² + 1/ℓ_b²) + 1, z = (x_i − μ)/ℓ_a² + (x_j − μ)/ℓ_b²                           (eq. 11)
* E[(x − μ) k_a(x, x_i)] = Σ (Σ + ℓ_a²)⁻¹ (x_i − μ) l_i                                       (eq. 20)

sympy integrates each integrand over the real line in the centred variable u = x − μ (a
translation, exact), with ν_i = x_i − μ; the result is compared with the closed form by reducing
the difference of their logarithms to zero.
"""

from __future__ import annotations

import time

import sympy as sp

from gpfverify.symbolic.certificate import Certificate, verdict

u, nu_i, nu_j = sp.symbols("u nu_i nu_j", real=True)  # u = x − μ, ν_i = x_i − μ
var, ell_a, ell_b, alpha_a, alpha_b = sp.symbols("Sigma ell_a ell_b alpha_a alpha_b", positive=True)


def kernel(difference, alpha, ell):
    """k(x, x') as a function of x − x'."""
    return alpha**2 * sp.exp(-difference**2 / (2 * ell**2))


def integrate_against_gaussian(factor, log_integrand) -> sp.Expr:
    """∫ factor · exp(log_integrand) · N(u; 0, Σ) du over ℝ, by sympy (``factor`` polynomial in u)."""
    exponent = sp.expand(log_integrand - u**2 / (2 * var))
    integrand = factor * sp.exp(exponent) / sp.sqrt(2 * sp.pi * var)
    return sp.integrate(integrand, (u, -sp.oo, sp.oo), conds="none")


_a, _b = sp.symbols("a", positive=True), sp.Symbol("b", real=True)


def integrate_completed_square(factor, log_integrand) -> sp.Expr:
    """The same integral with the square completed first: the exponent c₂u² + c₁u + c₀ (c₂ < 0)
    is rewritten exactly as −a(u − b)² + c₀ + ab², and sympy integrates the standard form
    ``factor · exp(−a(u − b)²)`` with fresh symbols a > 0, b real before substituting back."""
    exponent = sp.expand(log_integrand - u**2 / (2 * var))
    c2, c1, c0 = sp.Poly(exponent, u).all_coeffs()
    a_val = sp.cancel(-c2)
    b_val = sp.cancel(c1 / (2 * a_val))
    standard = sp.integrate(factor * sp.exp(-_a * (u - _b) ** 2), (u, -sp.oo, sp.oo), conds="none")
    return (standard.subs({_a: a_val, _b: b_val}) * sp.exp(c0 + a_val * b_val**2)
            / sp.sqrt(2 * sp.pi * var))


def same_positive(a: sp.Expr, b: sp.Expr) -> bool:
    """True iff log a − log b reduces to 0 (a, b positive expressions)."""
    difference = sp.simplify(sp.logcombine(sp.expand_log(sp.log(a) - sp.log(b), force=True), force=True))
    if difference == 0:
        return True
    # a residual sum of logarithms: compare the product of their arguments with 1
    return sp.cancel(sp.expand(sp.exp(2 * difference))) == 1


def mean_integral_closed() -> sp.Expr:
    return alpha_a**2 * (var / ell_a**2 + 1) ** sp.Rational(-1, 2) * sp.exp(-nu_i**2 / (2 * (var + ell_a**2)))


def product_integral_closed() -> sp.Expr:
    r = var * (1 / ell_a**2 + 1 / ell_b**2) + 1
    z = nu_i / ell_a**2 + nu_j / ell_b**2
    return (kernel(nu_i, alpha_a, ell_a) * kernel(nu_j, alpha_b, ell_b) * r ** sp.Rational(-1, 2)
            * sp.exp(z**2 * var / (2 * r)))


def prove_gp_moment_integrals(size: str = "small") -> Certificate:
    start = time.perf_counter()
    log_ka = -(u - nu_i) ** 2 / (2 * ell_a**2)
    log_kb = -(u - nu_j) ** 2 / (2 * ell_b**2)
    integrals = {
        "l_i (eq. 8-9)": (alpha_a**2, log_ka, mean_integral_closed()),
        "L_ij (eq. 11)": (alpha_a**2 * alpha_b**2, log_ka + log_kb, product_integral_closed()),
        "Cov[x, k_a(x, x_i)] (eq. 20)": (alpha_a**2 * u, log_ka,
                                         var / (var + ell_a**2) * nu_i * mean_integral_closed()),
    }
    routes = {"completed square": integrate_completed_square}
    if size == "large":
        routes["direct sympy.integrate"] = integrate_against_gaussian
    results = {f"{name} [{route}]": same_positive(integrate(factor, log_integrand), closed)
               for name, (factor, log_integrand, closed) in integrals.items()
               for route, integrate in routes.items()}
    holds = all(results.values())
    detail = ("D = 1, symbols ν_i = x_i − μ, ν_j = x_j − μ real and Σ, ℓ_a, ℓ_b, α_a, α_b positive (two different "
              "outputs a, b). sympy.integrate of each integrand times N(u; 0, Σ) over ℝ (u = x − μ) — after "
              "completing the square exactly (route 'completed square') and, in the large size, directly — "
              "compared with the closed form by reducing log(integral) − log(closed form) to 0 (for the cross moment, "
              "which changes sign with ν_i, the logarithms are expanded formally): "
              + "; ".join(f"{k}: {'equal' if v else 'NOT equal'}" for k, v in results.items()) + ".")
    return Certificate("gp-moment-integrals",
                       "the closed forms of the uncertain-input kernel integrals l_i, L_ij and the input-output "
                       "cross moment (seed 000 eq. 8–11, 20) for D = 1",
                       "sympy: symbolic integration against the Gaussian", verdict(holds), detail,
                       time.perf_counter() - start)
