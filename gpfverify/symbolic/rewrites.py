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

That is enforced. sympy cancels M·M⁻¹ as soon as the product is formed (``B*F.T*(B*F.T).I`` *is*
``B*F.T``), so an inverse is made only by :func:`inverse`, never by ``.I``: it refuses a matrix that
is not square for every size (its row and column sizes equal symbolically) and returns an opaque
symbol that nothing cancels. A step replaces it by sympy's ``M⁻¹`` only for an M listed in the
step's ``invertible`` hypotheses (any other inverse in a step refuses the step), and every
hypothesis is checked on exact integer instances of every size assignment in 1..3 (the matrices
listed as ``full_column_rank`` drawn with full column rank): each M listed as invertible must be
nonsingular there, and the step itself must hold there.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import product

import numpy as np
import sympy as sp

from gpfverify.errors import InputError


@dataclass(frozen=True)
class Rewrite:
    """One step ``before = after``; ``substitutions`` (symbol -> expression) and ``rules``
    (pattern -> replacement, applied after expansion) carry what ``reason`` asserts."""

    before: sp.MatrixExpr
    after: sp.MatrixExpr
    reason: str
    substitutions: dict = field(default_factory=dict)
    rules: tuple = ()
    #: hypotheses: the matrices assumed invertible (the only ones a step may invert)
    invertible: tuple = ()
    #: hypotheses: matrix symbols of full column rank (how instances are drawn)
    full_column_rank: tuple = ()


def _normal_form(expr, rules) -> sp.Basic:
    out = sp.expand(expr).doit()
    for pattern, replacement in rules:
        out = sp.expand(out.subs(pattern, replacement)).doit()
    return out


def _is_zero(expr) -> bool:
    return expr == 0 or bool(getattr(expr, "is_ZeroMatrix", False))


#: the values each size symbol takes on the instances that check a step's hypotheses
INSTANCE_SIZES = (1, 2, 3)
INSTANCE_SEED = 20240229


#: opaque inverse symbols made by :func:`inverse` -> the matrix they invert
_INVERTED: dict[sp.MatrixSymbol, sp.MatrixExpr] = {}


def inverse(m: sp.MatrixExpr) -> sp.MatrixSymbol:
    """M⁻¹ of a matrix that is square for every size, as an opaque symbol; a step that lists M among
    its ``invertible`` hypotheses (checked on instances) may use M⁻¹M = MM⁻¹ = I, no other may."""
    if sp.expand(m.shape[0] - m.shape[1]) != 0:
        raise InputError(f"{m} is {m.shape[0]}×{m.shape[1]}, not square for every size: it has no inverse")
    symbol = sp.MatrixSymbol(f"({sp.sstr(m)})⁻¹", m.shape[0], m.shape[1])
    _INVERTED[symbol] = m
    return symbol


def _with_stated_inverses(expr, invertible):
    """``expr`` with every inverse symbol of a listed matrix made sympy's inverse; None when it
    contains an inverse (opaque or sympy's) of a matrix that is not listed."""
    used = {s for s in expr.free_symbols if s in _INVERTED}
    if any(not any(_INVERTED[s] == m for m in invertible) for s in used):
        return None
    if any(not any(inv.arg == m for m in invertible) for inv in expr.atoms(sp.Inverse)):
        return None
    return expr.xreplace({s: sp.Inverse(_INVERTED[s]) for s in used})


def _instances(step: Rewrite, before, after):
    """Integer values of every matrix symbol at every assignment of the size symbols in
    :data:`INSTANCE_SIZES` where the full-column-rank premises can hold (rows ≥ columns)."""
    difference = before - after
    symbols = difference.free_symbols | set().union(*(m.free_symbols for m in step.invertible))
    matrices = sorted((m for m in symbols if isinstance(m, sp.MatrixSymbol)), key=str)
    sizes = sorted({s for m in matrices for s in m.shape[0].free_symbols | m.shape[1].free_symbols}
                   | difference.shape[0].free_symbols | difference.shape[1].free_symbols, key=str)
    rng = np.random.default_rng(INSTANCE_SEED)
    for assignment in product(INSTANCE_SIZES, repeat=len(sizes)):
        at = dict(zip(sizes, assignment))
        shapes = {m: (int(m.shape[0].subs(at)), int(m.shape[1].subs(at))) for m in matrices}
        if any(shapes[m][0] < shapes[m][1] for m in step.full_column_rank):
            continue
        values = {}
        for m in matrices:
            concrete = sp.MatrixSymbol(m.name, *shapes[m])
            rows, cols = shapes[m]
            while True:
                value = sp.ImmutableMatrix(rows, cols, lambda i, j: int(rng.integers(-3, 4)))
                if m not in step.full_column_rank or value.rank() == cols:
                    break
            values[concrete] = value
        yield at, values


def hypotheses_hold(step: Rewrite, before, after) -> bool:
    """On every instance: each listed invertible matrix is nonsingular and ``before = after``."""
    for at, values in _instances(step, before, after):
        def explicit(expr, at=at, values=values):
            return sp.Matrix(expr.subs(at).xreplace(values).doit())
        for m in step.invertible:
            value = explicit(m)
            if not value.is_square or value.det() == 0:
                return False
        if not explicit(before - after).is_zero_matrix:
            return False
    return True


def step_holds(step: Rewrite) -> bool:
    """sympy's verdict on one step (True only if the difference reduces to zero), given that it
    inverts only matrices whose invertibility is a hypothesis and the hypotheses hold on instances."""
    ordered = list(step.substitutions.items())  # applied in the order written
    before = _with_stated_inverses(step.before.subs(ordered), step.invertible)
    after = _with_stated_inverses(step.after.subs(ordered), step.invertible)
    if before is None or after is None:
        return False
    return _is_zero(_normal_form(before - after, step.rules)) and hypotheses_hold(step, before, after)


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
    a, x = b * f.T, f * inverse(f.T * f) * inverse(b.T * b) * b.T
    reason = "BᵀB and FᵀF invertible (B, F full column rank)"
    conditions = [(a * x * a, a, "AXA = A"), (x * a * x, x, "XAX = X"), ((a * x).T, a * x, "(AX)ᵀ = AX"),
                  ((x * a).T, x * a, "(XA)ᵀ = XA")]
    return [Rewrite(before, after, f"Penrose {name}: {reason}", invertible=(f.T * f, b.T * b),
                    full_column_rank=(b, f)) for before, after, name in conditions]


def check_independent(steps: list[Rewrite]) -> ChainResult:
    """Check steps that are separate facts (not a chain)."""
    return ChainResult(tuple(steps), tuple(step_holds(s) for s in steps))
