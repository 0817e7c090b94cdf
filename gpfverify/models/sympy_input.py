"""sympy model functions, from which :meth:`StateSpaceModel.from_sympy` builds a state-space model
from sympy expressions.

A model function is a column of expressions g(x, k) = [g_1, …, g_E] in the state symbols
x = (x_1, …, x_D) and an optional step symbol k. It is evaluated by ``sympy.lambdify(...,
"numpy")`` with one argument per state component, so N states (N, D) go in as D arrays of N
values; its Jacobian is the exact symbolic one,

    J_ij(x, k) = ∂g_i/∂x_j                                   (Matrix.jacobian, lambdified alike),

evaluated the same way at states (..., D) into (..., E, D). Entries that do not depend on x (a
constant, or k alone) come back as scalars and are broadcast to every state.

:meth:`SympyFunction.casadi_function` turns the same expressions into a casadi Function
(x (D, 1)[, k]) -> (E, 1), so one symbolic model also feeds casadi code. Only +, −, ×, /, powers,
numbers, π, e and the functions of :data:`CASADI_FUNCTIONS` translate; anything else raises
InputError naming the part of the model.
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import numpy as np
import sympy as sp

from gpfverify.errors import InputError
from gpfverify.models.casadi_input import casadi_message, casadi_name, checked_jacobian
from gpfverify.models.functions import ModelFunction

#: The sympy functions (by class name) that :meth:`SympyFunction.casadi_function` translates.
CASADI_FUNCTIONS: dict[str, object] = {
    "sin": ca.sin, "cos": ca.cos, "tan": ca.tan, "asin": ca.asin, "acos": ca.acos,
    "atan": ca.atan, "atan2": ca.atan2, "sinh": ca.sinh, "cosh": ca.cosh, "tanh": ca.tanh,
    "asinh": ca.asinh, "acosh": ca.acosh, "atanh": ca.atanh, "exp": ca.exp, "log": ca.log,
    "sqrt": ca.sqrt, "Abs": ca.fabs, "floor": ca.floor, "ceiling": ca.ceil,
}
#: Expression nodes every translation handles: arithmetic, numbers, π, e and symbols.
_ARITHMETIC = (sp.Symbol, sp.Number, sp.Add, sp.Mul, sp.Pow)


def _expressions(value, name: str) -> sp.Matrix:
    """A sequence, Matrix or single expression as a column Matrix (E, 1); InputError naming ``name``."""
    items = list(value) if isinstance(value, (sp.MatrixBase, list, tuple, np.ndarray)) else [value]
    try:
        return sp.Matrix([sp.sympify(item, strict=True) for item in items])
    except (sp.SympifyError, TypeError, ValueError) as exc:
        raise InputError(f"{name} must be sympy expressions, one per output: {exc}") from exc


def _symbol(value, what: str) -> sp.Symbol:
    if not isinstance(value, sp.Symbol):
        raise InputError(f"{what} must be a sympy Symbol, got {value!r}")
    return value


def _stack(values, shape: tuple[int, ...]) -> np.ndarray:
    """Entries (each an array of ``shape`` or a scalar) stacked on a new last axis: shape + (E,)."""
    return np.stack([np.broadcast_to(np.asarray(v, dtype=float), shape) for v in values], axis=-1)


class SympyFunction(ModelFunction):
    """g(x, k) given as sympy ``expressions`` (E, 1) in ``symbols`` (x_1, …, x_D) and the optional
    ``step_symbol`` k (module docstring)."""

    def __init__(self, expressions, symbols: Sequence[sp.Symbol], step_symbol: sp.Symbol | None = None,
                 name: str = "", circular: Sequence[int] = ()):
        self.symbols = tuple(_symbol(s, f"{name}: state symbol") for s in symbols)
        self.step_symbol = None if step_symbol is None else _symbol(step_symbol, f"{name}: step")
        self.expressions = _expressions(expressions, name)
        if len(set(self.arguments)) != len(self.arguments):
            raise InputError(f"{name}: the state and step symbols must be distinct, got {self.arguments}")
        stray = self.expressions.free_symbols - set(self.arguments)
        if stray:
            raise InputError(f"{name} uses {sorted(map(str, stray))}, which "
                             f"{'is' if len(stray) == 1 else 'are'} neither a state nor the step symbol")
        super().__init__(name, len(self.symbols), len(self.expressions), circular)
        jacobian = self.expressions.jacobian(self.symbols)
        self.numeric_value = self._lambdify(list(self.expressions), "")
        self.numeric_jacobian = self._lambdify(jacobian.tolist(), " jacobian")

    @property
    def arguments(self) -> tuple[sp.Symbol, ...]:
        """The lambdified functions' arguments: x_1, …, x_D[, k]."""
        return self.symbols + (() if self.step_symbol is None else (self.step_symbol,))

    def _lambdify(self, expressions, what: str):
        try:
            return sp.lambdify(self.arguments, expressions, "numpy")
        except Exception as exc:
            raise InputError(f"{self.name}{what} cannot be translated to numpy: {exc}") from exc

    def _numeric(self, fn, x: np.ndarray, k: int):
        columns = list(np.moveaxis(np.asarray(x, dtype=float), -1, 0))
        return fn(*columns, *(() if self.step_symbol is None else (float(k),)))

    def evaluate(self, x, k):
        return _stack(self._numeric(self.numeric_value, x, k), x.shape[:-1])

    def jacobian(self, x, k=1):
        def compute(flat, k):
            rows = self._numeric(self.numeric_jacobian, flat, k)             # E lists of D entries
            return np.stack([_stack(row, flat.shape[:-1]) for row in rows], axis=-2)
        return checked_jacobian(self, x, k, compute)

    def casadi_function(self) -> ca.Function:
        """The same expressions as casadi.Function(x (D, 1)[, k]) -> (E, 1) (SX); InputError
        naming this part for a node outside arithmetic, numbers and :data:`CASADI_FUNCTIONS`."""
        nodes = (node for expr in self.expressions for node in sp.preorder_traversal(expr))
        unsupported = {type(node).__name__ for node in nodes
                       if not isinstance(node, _ARITHMETIC) and node not in (sp.pi, sp.E)
                       and type(node).__name__ not in CASADI_FUNCTIONS}
        if unsupported:
            raise InputError(f"{self.name} uses {sorted(unsupported)}, which casadi_function cannot "
                             f"translate (supported: arithmetic, numbers, pi, E, {sorted(CASADI_FUNCTIONS)})")
        x, k = ca.SX.sym("x", self.in_dim), ca.SX.sym("k")
        fn = sp.lambdify(self.arguments, list(self.expressions), modules=[CASADI_FUNCTIONS])
        entries = fn(*ca.vertsplit(x), *(() if self.step_symbol is None else (k,)))
        inputs = [x] if self.step_symbol is None else [x, k]
        try:
            return ca.Function(casadi_name(self.name), inputs, [ca.vertcat(*(ca.SX(e) for e in entries))])
        except Exception as exc:
            raise InputError(f"{self.name} could not be built as a casadi Function: "
                             f"{casadi_message(exc)}") from exc
