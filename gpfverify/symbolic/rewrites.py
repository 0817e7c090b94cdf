"""Dimension-free arguments as chains of matrix-expression rewrites, each step checked by sympy.

Matrices are ``sympy.MatrixSymbol`` objects of symbolic size (n states, l outputs), so a checked
chain holds for every dimension. A step says ``before = after`` because of a stated reason; the
reason's content enters as substitutions (a definition or hypothesis, e.g. A⁺ = (AᵀA)⁻¹Aᵀ) and
as rewrite rules (e.g. P² = P) applied to both sides. sympy then expands ``before − after`` and
the step is accepted only if the result is the zero matrix. sympy's own simplification uses
M⁻¹M = I for a square M, which is valid exactly when M is invertible: every step that relies on
it names the invertibility in its reason.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import sympy as sp


@dataclass(frozen=True)
class Rewrite:
    """One step ``before = after``; ``substitutions`` (symbol -> expression) and ``rules``
    (pattern -> replacement, applied after expansion) carry what ``reason`` asserts."""

    before: sp.MatrixExpr
    after: sp.MatrixExpr
    reason: str
    substitutions: dict = field(default_factory=dict)
    rules: tuple = ()


def _normal_form(expr, rules) -> sp.Basic:
    out = sp.expand(expr).doit()
    for pattern, replacement in rules:
        out = sp.expand(out.subs(pattern, replacement)).doit()
    return out


def _is_zero(expr) -> bool:
    return expr == 0 or bool(getattr(expr, "is_ZeroMatrix", False))


def step_holds(step: Rewrite) -> bool:
    """sympy's verdict on one step (True only if the difference reduces to zero)."""
    ordered = list(step.substitutions.items())  # applied in the order written
    before = step.before.subs(ordered)
    after = step.after.subs(ordered)
    return _is_zero(_normal_form(before - after, step.rules))


@dataclass(frozen=True)
class ChainResult:
    steps: tuple[Rewrite, ...]
    verdicts: tuple[bool, ...]

    @property
    def holds(self) -> bool:
        return all(self.verdicts)

    def describe(self) -> str:
        lines = []
        for k, (step, ok) in enumerate(zip(self.steps, self.verdicts), 1):
            mark = "checked" if ok else "FAILED"
            lines.append(f"({k}) {sp.sstr(step.before)} = {sp.sstr(step.after)} [{step.reason}; {mark}]")
        return "; ".join(lines)


def check_chain(steps: list[Rewrite]) -> ChainResult:
    """Check every step and that consecutive steps connect (each ``before`` is the previous
    ``after``); a broken link counts as a failed step."""
    verdicts = []
    for k, step in enumerate(steps):
        linked = k == 0 or steps[k - 1].after == step.before
        verdicts.append(linked and step_holds(step))
    return ChainResult(tuple(steps), tuple(verdicts))


# ---- the symbols of one sensor's fusion step, of symbolic size ----------------------------------

n_states, n_outputs = sp.symbols("n l", integer=True, positive=True)
G = sp.MatrixSymbol("G_m", n_states, n_outputs)  # column block of C_xy C_y⁻¹
C = sp.MatrixSymbol("C_ym", n_outputs, n_outputs)  # local innovation covariance (SPD)
A = sp.MatrixSymbol("C_xym", n_states, n_outputs)  # local cross covariance
A_pinv = sp.MatrixSymbol("C_xym_pinv", n_outputs, n_states)
P = sp.MatrixSymbol("P_m", n_outputs, n_outputs)  # A⁺A
X = sp.MatrixSymbol("X_m", n_states, n_outputs)  # G_m C_y^m (I − P_m)
y = sp.MatrixSymbol("y_m", n_outputs, 1)
mu_y = sp.MatrixSymbol("mu_ym", n_outputs, 1)  # local predicted measurement
mu_c = sp.MatrixSymbol("mu_y_m_central", n_outputs, 1)  # central block μ_y(m)
mu_p = sp.MatrixSymbol("mu_pm", n_states, 1)
mu_e = sp.MatrixSymbol("mu_em", n_states, 1)
v = sp.MatrixSymbol("v", n_outputs, 1)
I_l = sp.Identity(n_outputs)

#: sensor m's share of μ_DMF − μ_CMF (eq. 35 minus eq. 15)
SENSOR_DIFFERENCE = G * (mu_y - mu_c) + G * C * A_pinv * (mu_e - mu_p) - G * (y - mu_c)
#: sensor m's term of the closed-form gap
GAP_TERM = G * C * (P - I_l) * C.I * (y - mu_y)


def gap_formula_chain() -> list[Rewrite]:
    """DMF_m − CMF_m = G_m C_y^m (P_m − I)(C_y^m)⁻¹(y^m − μ_y^m) for any C_xy^m."""
    after_local = G * (mu_y - y) + G * C * A_pinv * A * C.I * (y - mu_y)
    return [
        Rewrite(SENSOR_DIFFERENCE, after_local,
                "local update μ_e^m − μ_p^m = C_xy^m (C_y^m)⁻¹(y^m − μ_y^m) (eq. 32)",
                {mu_e: mu_p + A * C.I * (y - mu_y)}),
        Rewrite(after_local, GAP_TERM,
                "C_y^m (C_y^m)⁻¹ = I (C_y^m SPD), with P_m := (C_xy^m)⁺C_xy^m", {P: A_pinv * A}),
    ]


def full_rank_chain() -> list[Rewrite]:
    """Proposition 1: the gap term vanishes when C_xy^m has full column rank."""
    return gap_formula_chain() + [
        Rewrite(GAP_TERM, sp.ZeroMatrix(n_states, 1),
                "full column rank: (C_xy^m)⁺ = (C_xyᵀC_xy)⁻¹C_xyᵀ with C_xyᵀC_xy invertible, so P_m = I",
                {P: A_pinv * A, A_pinv: (A.T * A).I * A.T}),
    ]


def sufficiency_chain() -> list[Rewrite]:
    """G_m C_y^m (I − P_m) = 0 ⇒ the gap term vanishes for every y^m."""
    return [
        Rewrite(GAP_TERM, -X * C.I * (y - mu_y), "definition X_m := G_m C_y^m (I − P_m)",
                {X: G * C * (I_l - P)}),
        Rewrite(-X * C.I * (y - mu_y), sp.ZeroMatrix(n_states, 1), "hypothesis X_m = 0",
                {X: sp.ZeroMatrix(n_states, n_outputs)}),
    ]


def necessity_chain() -> list[Rewrite]:
    """With y^m − μ_y^m = C_y^m (I − P_m) v the gap term is −X_m v: nonzero for some v unless X_m = 0."""
    chosen = G * C * (P - I_l) * C.I * C * (I_l - P) * v
    return [
        Rewrite(GAP_TERM, chosen, "choose the measurement y^m = μ_y^m + C_y^m (I − P_m) v",
                {y: mu_y + C * (I_l - P) * v}),
        Rewrite(chosen, -X * v, "P_m² = P_m (Penrose: A⁺AA⁺ = A⁺) and X_m := G_m C_y^m (I − P_m)",
                {X: G * C * (I_l - P)}, ((P**2, P),)),
    ]


def factored_pinv_penrose() -> list[Rewrite]:
    """X = F(FᵀF)⁻¹(BᵀB)⁻¹Bᵀ is the Moore–Penrose inverse of A = BFᵀ when B (n×r) and F (l×r)
    have full column rank r (BᵀB, FᵀF invertible): the four Penrose conditions, each one step."""
    rank = sp.Symbol("r", integer=True, positive=True)
    b = sp.MatrixSymbol("B", n_states, rank)
    f = sp.MatrixSymbol("F", n_outputs, rank)
    a, x = b * f.T, f * (f.T * f).I * (b.T * b).I * b.T
    reason = "BᵀB and FᵀF invertible (B, F full column rank)"
    return [Rewrite(a * x * a, a, f"Penrose AXA = A: {reason}"),
            Rewrite(x * a * x, x, f"Penrose XAX = X: {reason}"),
            Rewrite((a * x).T, a * x, f"Penrose (AX)ᵀ = AX: {reason}"),
            Rewrite((x * a).T, x * a, f"Penrose (XA)ᵀ = XA: {reason}")]


def check_independent(steps: list[Rewrite]) -> ChainResult:
    """Check steps that are separate facts (not a chain)."""
    return ChainResult(tuple(steps), tuple(step_holds(s) for s in steps))
