"""casadi model functions: a ``casadi.Function`` as a :class:`ModelFunction`, from which
:meth:`StateSpaceModel.from_casadi` builds a whole state-space model from casadi expressions.

A model function is a casadi Function ``g(x[, k])`` with one input of D entries (the state),
optionally a second scalar input (the step index k), and one output of E entries. It is
normalised once to the column form

    value(x (D, 1), k) = vec(g(x, k))  (E, 1),        jac(x, k) = ∂ vec(g(x, k)) / ∂x  (E, D),

the Jacobian by casadi's automatic differentiation (exact up to rounding). Both are evaluated
for N states at once by ``Function.map(N)``: the states go in column-major as (D, N), k is
broadcast, and the outputs come back as (E, N) and (E, N·D) = [J(x_1) … J(x_N)].
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence

import casadi as ca
import numpy as np

from gpfverify.errors import GpfverifyError, InputError
from gpfverify.models.functions import ModelFunction


def casadi_name(label: str) -> str:
    """A valid casadi Function name for a label ("sensor 1 (range) measure" → "sensor_1_range_measure")."""
    return re.sub(r"[\W_]+", "_", label).strip("_") or "f"


def casadi_message(exc: Exception) -> str:
    """The last line of a casadi error without its source location."""
    last = str(exc).strip().splitlines()[-1]
    return re.sub(r"^.*\.[ch]pp:\d+: ", "", last)


def checked_jacobian(fn: ModelFunction, x, k: int,
                     compute: Callable[[np.ndarray, int], np.ndarray]) -> np.ndarray:
    """``compute(flat (M, D), k) -> (M, E, D)`` at the states x (..., D), reshaped to (..., E, D);
    an exception inside, or a NaN or inf in the result, raises InputError naming ``fn``."""
    x = np.asarray(x, dtype=float)
    flat = x.reshape(-1, fn.in_dim)
    try:
        jac = np.asarray(compute(flat, k), dtype=float)
    except GpfverifyError:
        raise
    except Exception as exc:
        raise InputError(f"{fn.name} jacobian raised {type(exc).__name__}: {exc}") from exc
    if not np.all(np.isfinite(jac)):
        raise InputError(f"{fn.name} jacobian returned NaN or inf at step k={k}")
    return jac.reshape(x.shape[:-1] + (fn.out_dim, fn.in_dim))


def _check_signature(function: ca.Function, name: str, in_dim: int, out_dim: int) -> None:
    """InputError naming ``name`` unless ``function`` is (x: D entries[, k: scalar]) -> E entries."""
    n_in, n_out = function.n_in(), function.n_out()
    if n_in not in (1, 2) or n_out != 1:
        raise InputError(f"{name}: a casadi Function must take the state (and optionally the step k) "
                         f"and return one output; got {n_in} input(s) and {n_out} output(s)")
    expected = [("input 0 (the state)", function.sparsity_in(0), in_dim),
                ("output 0", function.sparsity_out(0), out_dim)]
    if n_in == 2:
        expected.append(("input 1 (the step k)", function.sparsity_in(1), 1))
    for what, sparsity, size in expected:
        if not sparsity.is_vector() or sparsity.numel() != size:
            raise InputError(f"{name}: casadi {what} has shape {sparsity.size()}; "
                             f"expected a vector of {size} entries")


class CasadiFunction(ModelFunction):
    """A casadi Function ``g(x[, k])`` (module docstring): evaluation and AD Jacobian mapped over
    the leading axis, the mapped Functions cached per batch size."""

    def __init__(self, function: ca.Function, name: str, in_dim: int, out_dim: int,
                 circular: Sequence[int] = ()):
        _check_signature(function, name, in_dim, out_dim)
        super().__init__(name, in_dim, out_dim, circular)
        x, k = ca.MX.sym("x", in_dim), ca.MX.sym("k")
        args = [ca.reshape(x, function.size_in(0))] + ([k] if function.n_in() == 2 else [])
        y = ca.vec(ca.densify(function.call(args)[0]))
        self.function = function
        self.value = ca.Function("value", [x, k], [y])
        self.derivative = ca.Function("jacobian", [x, k], [ca.densify(ca.jacobian(y, x))])
        self.mapped: dict[tuple[str, int], ca.Function] = {}

    def _map(self, function: ca.Function, x: np.ndarray, k: int) -> np.ndarray:
        """``function`` at every row of x (N, D) by its cached ``map(N)``: the (rows, N·cols) output."""
        n = x.shape[0]
        key = (function.name(), n)
        if key not in self.mapped:
            self.mapped[key] = function.map(n)
        return self.mapped[key](x.T, float(k)).full()

    def evaluate(self, x, k):
        return self._map(self.value, np.asarray(x, dtype=float), k).T

    def jacobian(self, x, k=1):
        def compute(flat, k):
            jac = self._map(self.derivative, flat, k)                       # (E, M·D)
            return jac.reshape(self.out_dim, flat.shape[0], self.in_dim).transpose(1, 0, 2)
        return checked_jacobian(self, x, k, compute)


def casadi_function(obj, name: str, in_dim: int, out_dim: int, circular: Sequence[int] = ()
                    ) -> CasadiFunction:
    """A casadi Function as a :class:`ModelFunction`; InputError naming ``name`` for anything else
    (a bare casadi expression has no declared state: use :meth:`StateSpaceModel.from_casadi`)."""
    if not isinstance(obj, ca.Function):
        raise InputError(f"{name} is a casadi {type(obj).__name__}, not a casadi.Function: wrap it in "
                         "casadi.Function(name, [x], [expr]) or build the model with "
                         "StateSpaceModel.from_casadi(state, ...)")
    return CasadiFunction(obj, name, in_dim, out_dim, circular)
