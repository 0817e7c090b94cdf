"""The UKF equals the KF on linear models, for any state dimension D and output size l
(seed 000 eq. 21–31; SPEC §2: the reference oracle "UKF = KF on linear models").

Sigma points μ and μ ± ρ S e_i (i = 1..D), with S Sᵀ = P and e_i the standard basis (Σ_i e_i e_iᵀ = I);
weights w₀ = 1 − D/ρ² for the mean, w₀ + γ for the covariances, and 1/(2ρ²) for the other 2D points.
The usual parameters enter only through ρ² = D + λ = α²(D + κ) and γ = 1 − α² + β, so the
statement holds for every choice of them with ρ ≠ 0 (a printed hypothesis). For the affine map
x ↦ Hx + b the unscented mean, covariance (+ R) and cross covariance are Hμ + b, HPHᵀ + R and PHᵀ,
and the UKF update equals the KF update. The prediction is the same statement with (H, b, R) :=
(F, u, Q). Also checked, by another route: the same moments at listed (D, l) with sympy
(every entry of μ, of a lower-triangular S, of H and b a free symbol).
"""

from __future__ import annotations

import time

import sympy as sp

from gpfverify.kernel.rules import Checker
from gpfverify.kernel.terms import frozen, read_statement
from gpfverify.symbolic.certificate import Certificate, Control, ListedCheck, Part
from gpfverify.symbolic.formal import Declare, Sum, eq, invertible, nonzero, num, size
from gpfverify.symbolic.polynomial import generic_matrix
from gpfverify.symbolic.search import Template, prove_equation
from gpfverify.symbolic.witness import Builder, refuting

SIZES = {"small": ((1, 1), (2, 1), (2, 2)), "large": ((1, 1), (2, 1), (2, 2), (3, 1), (3, 2), (3, 3), (4, 2))}
MUTANTS = ("offset b dropped from the mean", "cross covariance with −ρ S e_i for +ρ S e_i",
           "mean weight w₀ = 1 − D/(2ρ²)", "R left out of the unscented covariance")


def statement(mutation: str = "") -> dict:
    d = Declare()
    d.sizes("D", "l")
    d.index_set("coord", "D")
    e = d.partition("e", "coord", "D", 1)
    rho, gamma = d.param("ρ"), d.param("γ")
    mu, S = d.matrix("μ", "D", 1), d.matrix("S", "D", "D")
    H, b, R, y = d.matrix("H", "l", "D"), d.matrix("b", "l", 1), d.matrix("R", "l", "l"), d.matrix("y", "l", 1)
    P = d.define("P", S * S.T)
    f = d.define("h", lambda x: H * x + (b if mutation != MUTANTS[0] else 0 * b), args=(("x", "D", 1),))
    w0 = d.define("w₀", 1 - (size("D") if mutation != MUTANTS[2] else num("1/2") * size("D")) * rho ** -2)
    wc = d.define("w_c", w0 + gamma)
    w = d.define("w", num("1/2") * rho ** -2)
    plus = lambda i: mu + rho * S * e[i]  # noqa: E731
    minus = lambda i: mu - rho * S * e[i]  # noqa: E731
    ybar = d.define("ȳ", w0 * f(mu) + Sum("i", "coord", w * (f(plus("i")) + f(minus("i")))))
    dev = lambda x: f(x) - ybar  # noqa: E731
    noise = R if mutation != MUTANTS[3] else 0 * R
    cy = d.define("C_y", wc * dev(mu) * dev(mu).T + Sum("i", "coord", w * (dev(plus("i")) * dev(plus("i")).T
                                                                          + dev(minus("i")) * dev(minus("i")).T))
                  + noise, opaque=True)
    step = (lambda i: -(rho * S * e[i])) if mutation == MUTANTS[1] else (lambda i: rho * S * e[i])
    cxy = d.define("C_xy", Sum("i", "coord", w * (step("i") * dev(plus("i")).T - step("i") * dev(minus("i")).T)))
    mu_ukf = d.define("μ_UKF", mu + cxy * cy.inv * (y - ybar))
    p_ukf = d.define("P_UKF", P - cxy * cy.inv * cxy.T)
    gain = P * H.T * (H * P * H.T + R).inv
    mu_kf = d.define("μ_KF", mu + gain * (y - H * mu - b))
    p_kf = d.define("P_KF", P - gain * H * P)
    d.assume(nonzero(rho), invertible(H * P * H.T + R))
    d.conclude(eq(ybar, H * mu + b), eq(cy, H * P * H.T + R), eq(cxy, P * H.T), eq(mu_ukf, mu_kf), eq(p_ukf, p_kf))
    return d.json()


def proof(statement_json: dict) -> dict:
    st = read_statement(frozen(statement_json))
    checker = Checker(st, {"steps": []})
    (ybar, _), (cy, cy_rhs), (cxy, _), (mu_ukf, mu_kf), (p_ukf, p_kf) = (c[1:3] for c in st.conclusion)
    steps = []

    def add(step):
        checker.step(frozen(step))
        steps.append(step)

    add(prove_equation(checker, "mean", ybar, st.conclusion[0][2], [])[0])
    add(prove_equation(checker, "covariance", cy, cy_rhs, [Template({"def": "C_y"}, orient="letter")])[0])
    add(prove_equation(checker, "cross covariance", cxy, st.conclusion[2][2], [])[0])
    add({"id": "C_y invertible", "claim": ("invertible", cy), "factors": [cy_rhs], "by": "covariance"})
    inverse = [Template({"congruence": "pinv", "by": "covariance"})]
    add(prove_equation(checker, "update mean", mu_ukf, mu_kf, inverse)[0])
    add(prove_equation(checker, "update covariance", p_ukf, p_kf, inverse)[0])
    return {"steps": steps}


def witness(seed: int, n: int = 2, l: int = 2) -> dict:
    b = Builder(seed, {"D": n, "l": l}, params={"ρ": 2, "γ": 2})
    for name, shape in (("μ", (n, 1)), ("S", (n, n)), ("H", (l, n)), ("b", (l, 1)), ("y", (l, 1))):
        b.draw(name, *shape)
    b.draw("R", l, l, "spd")
    return b.json()


def prove_ukf_equals_kf(size_: str = "small") -> Certificate:
    start = time.perf_counter()
    main = statement()
    controls = []
    for m in MUTANTS:
        wrong = statement(m)
        try:
            attempt = proof(wrong)
        except Exception:  # noqa: BLE001 - the search failing on a false statement is expected
            attempt = None
        controls.append(Control(m, wrong, attempt, refuting(wrong, lambda seed: witness(300 + seed))))
    return Certificate("ukf-equals-kf-linear",
                       "The unscented transform is exact for affine maps, so the UKF equals the KF on linear models, "
                       "for every choice of sigma-point parameters", [Part(main, proof(main), witness(1))], controls,
                       [listed_check(size_)], time.perf_counter() - start)


# ---- the second route at listed sizes ---------------------------------------------------------------------

def unscented_moments(mean: sp.Matrix, factor: sp.Matrix, transform, s, gamma):
    """(ȳ, C_y, C_xy) of the scaled unscented transform of ``transform`` at N(mean, factor factorᵀ),
    with s = ρ² = D + λ and γ = 1 − α² + β, the only ways the parameters enter."""
    d = mean.shape[0]
    root = sp.sqrt(s)
    points = [mean] + [mean + root * factor[:, i] for i in range(d)] + [mean - root * factor[:, i] for i in range(d)]
    w_mean = [(s - d) / s] + [1 / (2 * s)] * (2 * d)
    w_cov = [(s - d) / s + gamma] + [1 / (2 * s)] * (2 * d)
    images = [transform(p) for p in points]
    y_bar = sum((w * y for w, y in zip(w_mean, images)), sp.zeros(*images[0].shape))
    c_y = sum((w * (y - y_bar) * (y - y_bar).T for w, y in zip(w_cov, images)), sp.zeros(y_bar.shape[0]))
    c_xy = sum((w * (p - mean) * (y - y_bar).T for w, p, y in zip(w_cov, points, images)),
               sp.zeros(d, y_bar.shape[0]))
    return y_bar, c_y, c_xy


def listed_check(size_: str) -> ListedCheck:
    s, gamma = sp.Symbol("s", positive=True), sp.Symbol("gamma")
    holds = True
    for d, l in SIZES[size_]:
        mean = generic_matrix("mu", d, 1)
        factor = sp.Matrix(d, d, lambda i, j: sp.Symbol(f"L_{i}_{j}") if j <= i else 0)
        h, b = generic_matrix("H", l, d), generic_matrix("b", l, 1)
        y_bar, c_y, c_xy = unscented_moments(mean, factor, lambda x, h=h, b=b: h * x + b, s, gamma)
        cov = factor * factor.T
        for residual in (y_bar - (h * mean + b), c_y - h * cov * h.T, c_xy - cov * h.T):
            holds &= all(sp.cancel(sp.together(e)) == 0 for e in residual)
    return ListedCheck("the unscented mean, covariance and cross covariance of x ↦ Hx + b are Hμ + b, HPHᵀ and PHᵀ "
                       "(sympy, every entry of μ, of a lower-triangular S, of H and b free, √s symbolic)",
                       tuple(f"(D, l) = ({d}, {l})" for d, l in SIZES[size_]),
                       ("s = ρ² > 0 (a sympy assumption of the listed route)",), holds)
