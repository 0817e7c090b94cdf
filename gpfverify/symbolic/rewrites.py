"""Matrix-expression identities checked by sympy's own simplification (used for the Penrose
conditions of the factored pseudo-inverse). The dimension-free proofs of the fusion claims are in
:mod:`gpfverify.symbolic.dimension_free` (explicit rules, no conclusion substituted).

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
