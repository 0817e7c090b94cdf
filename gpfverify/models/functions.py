"""The functions of a state-space model, normalised to one calling convention.

Whatever form a user gives (a numpy callable, a casadi Function or expression, a sympy expression,
a matrix), the model holds a :class:`ModelFunction`:

* ``fn(x, k)`` with x (N, D) returns (N, E) — vectorised over the leading axis, ``k`` the step
  index (ignored by time-invariant functions);
* ``fn.jacobian(x, k)`` with x (..., D) returns (..., E, D).

A numpy callable may take ``(x)`` or ``(x, k)`` (decided once, when the model is built, from its
signature) and may return (N,) when E = 1. Its Jacobian is the user's ``jacobian(x (D,)[, k]) ->
(E, D)`` when given, else central differences (:func:`central_difference_jacobian`). Every call
checks the output's shape and finiteness and turns an exception raised inside the user's function
into :class:`~gpfverify.errors.InputError` naming the part of the model ("sensor 1 measure");
under a time limit (``check --timeout``) a call of the user's function or Jacobian that does not
return in time is stopped (:func:`gpfverify.usercode.call_limited`), the message naming it.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Sequence

import numpy as np

from gpfverify.angles import difference
from gpfverify.errors import GpfverifyError, InputError
from gpfverify.tolerances import EPS
from gpfverify.usercode import call_limited, describe

#: Relative step of the central-difference Jacobian, h_j = FD_STEP · max(1, |x_j|): the cube root
#: of eps balances truncation (O(h²)) against rounding (O(eps/h)); error ≈ eps^(2/3) ≈ 4e-11 relative
#: for smooth functions of unit scale.
FD_STEP: float = EPS ** (1.0 / 3.0)


def takes_step_index(fn: Callable) -> bool:
    """Whether ``fn`` takes the step index k as its second positional argument: a second positional
    parameter without a default, or one named ``k`` (``f(x, k=0)``); a defaulted parameter with
    another name (``lambda x, a=a: ...``, a captured value) is not the step index."""
    try:
        params = list(inspect.signature(fn).parameters.values())
    except (TypeError, ValueError):  # builtins and ufuncs without a signature
        return getattr(fn, "nin", 1) >= 2
    positional = [p for p in params if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    if len(positional) >= 2:
        second = positional[1]
        return second.default is second.empty or second.name == "k"
    return any(p.kind == p.VAR_POSITIONAL for p in params)


class ModelFunction:
    """Base of every normalised model function: ``name`` (used in errors), ``in_dim``,
    ``out_dim`` and ``circular`` (output indices that are angles, for wrapped differences)."""

    def __init__(self, name: str, in_dim: int, out_dim: int, circular: Sequence[int] = ()):
        self.name, self.in_dim, self.out_dim = name, int(in_dim), int(out_dim)
        self.circular = tuple(circular)

    def renamed(self, name: str, circular: Sequence[int]) -> ModelFunction:
        """A copy that reports errors as ``name`` and wraps the ``circular`` outputs."""
        clone = object.__new__(type(self))
        clone.__dict__.update(self.__dict__)
        clone.name, clone.circular = name, tuple(circular)
        return clone

    def evaluate(self, x: np.ndarray, k: int) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def described(self) -> str:
        """How a message names this function (the user's function behind it, where there is one)."""
        return self.name

    def __call__(self, x: np.ndarray, k: int = 1) -> np.ndarray:
        return self.checked_finite(self.shaped(x, k), k)

    def shaped(self, x: np.ndarray, k: int) -> np.ndarray:
        """The function's real values at x (N, D) as an (N, E) float array — the user's exceptions,
        types and shape checked, not yet finiteness (:meth:`checked_finite`)."""
        try:
            raw = np.asarray(call_limited(self.described, self.evaluate, x, k))
        except GpfverifyError:
            raise
        except Exception as exc:  # the user's code: report which part failed, keep the cause
            hint = (" (functions take a batch of states as rows, x of shape (N, D): index columns, x[:, i], "
                    "not x[i])" if isinstance(exc, IndexError) else "")
            raise InputError(f"{self.name} raised {type(exc).__name__}: {exc}{hint}") from exc
        if raw.dtype.kind not in "iufO":
            what = {"c": "complex numbers", "b": "booleans"}.get(raw.dtype.kind, f"values of type {raw.dtype}")
            raise InputError(f"{self.name} returned {what}; it must return real numbers")
        try:
            out = raw.astype(float, copy=False)
        except (TypeError, ValueError):  # objects that are not real numbers (complex, text)
            raise InputError(f"{self.name} returned values that are not real numbers") from None
        n = x.shape[0]
        if out.shape != (n, self.out_dim):
            if self.out_dim == 1 and out.shape == (n,):
                out = out[:, None]
            else:
                raise InputError(f"{self.name} returned shape {out.shape} for {n} state(s); "
                                 f"expected ({n}, {self.out_dim})")
        return out

    def checked_finite(self, out: np.ndarray, k: int) -> np.ndarray:
        """``out`` unless it holds NaN or inf (InputError naming the function and the step)."""
        if not np.isfinite(out).all():
            raise InputError(f"{self.name} returned NaN or inf at step k={k}")
        return out

    def jacobian(self, x: np.ndarray, k: int = 1) -> np.ndarray:
        """∂fn/∂x at every x (..., D): (..., E, D)."""
        return central_difference_jacobian(self, x, k)


def central_difference_jacobian(fn: ModelFunction, x: np.ndarray, k: int) -> np.ndarray:
    """J[..., :, j] = (f(x + h_j e_j) − f(x − h_j e_j)) / (2 h_j), h_j = FD_STEP · max(1, |x_j|),
    all 2D perturbed points in one vectorised call; differences of circular outputs are wrapped.
    Accuracy O(h²) + O(eps/h) ≈ 1e-10 relative for smooth functions of unit scale."""
    x = np.asarray(x, dtype=float)
    d = x.shape[-1]
    flat = x.reshape(-1, d)
    steps = FD_STEP * np.maximum(1.0, np.abs(flat))                     # (M, D)
    offsets = np.eye(d)[None] * steps[:, None, :]                       # (M, D, D): row j = h_j e_j
    points = np.concatenate([flat[:, None] + offsets, flat[:, None] - offsets], axis=1)
    values = fn(points.reshape(-1, d), k).reshape(flat.shape[0], 2 * d, fn.out_dim)
    diff = difference(values[:, :d], values[:, d:], fn.circular)        # (M, D, E)
    jac = np.swapaxes(diff / (2.0 * steps[:, :, None]), -1, -2)          # (M, E, D)
    return jac.reshape(x.shape[:-1] + (fn.out_dim, d))


class NumpyFunction(ModelFunction):
    """A user's numpy callable ``fn(x (N, D)[, k]) -> (N, E)`` with an optional per-state Jacobian
    ``jacobian(x (D,)[, k]) -> (E, D)`` (else central differences)."""

    def __init__(self, fn: Callable, name: str, in_dim: int, out_dim: int,
                 jacobian: Callable | None = None, circular: Sequence[int] = ()):
        if not callable(fn):
            raise InputError(f"{name} must be callable, got {type(fn).__name__}")
        if jacobian is not None and not callable(jacobian):
            raise InputError(f"{name} jacobian must be callable, got {type(jacobian).__name__}")
        super().__init__(name, in_dim, out_dim, circular)
        self.fn, self.takes_k = fn, takes_step_index(fn)
        self.user_jacobian = jacobian
        self.jacobian_takes_k = jacobian is not None and takes_step_index(jacobian)

    def evaluate(self, x, k):
        return self.fn(x, k) if self.takes_k else self.fn(x)

    def described(self) -> str:
        return f"{self.name}, {describe(self.fn)},"

    def jacobian(self, x, k=1):
        if self.user_jacobian is None:
            return central_difference_jacobian(self, x, k)
        x = np.asarray(x, dtype=float)
        if x.ndim == 1:
            return self._user_jacobian_at(x, k)
        flat = x.reshape(-1, self.in_dim)
        out = np.stack([self._user_jacobian_at(xi, k) for xi in flat])
        return out.reshape(x.shape[:-1] + out.shape[1:])

    def _user_jacobian_at(self, xi: np.ndarray, k: int) -> np.ndarray:
        """The user's Jacobian at one state (D,), checked: (E, D), finite."""
        shape = (self.out_dim, self.in_dim)
        user_jacobian = self.user_jacobian
        if user_jacobian is None:  # only called when the user gave one
            raise InputError(f"{self.name} has no user Jacobian")
        try:
            value = call_limited(lambda: f"{self.name} jacobian, {describe(user_jacobian)},",
                                 *((user_jacobian, xi, k) if self.jacobian_takes_k else (user_jacobian, xi)))
            value = np.asarray(value, dtype=float)
        except GpfverifyError:
            raise
        except Exception as exc:
            raise InputError(f"{self.name} jacobian raised {type(exc).__name__}: {exc}") from exc
        if value.shape != shape:
            if value.size != self.out_dim * self.in_dim:
                raise InputError(f"{self.name} jacobian returned shape {value.shape}; expected {shape}")
            value = value.reshape(shape)
        if not np.isfinite(value).all():
            raise InputError(f"{self.name} jacobian returned NaN or inf at step k={k}")
        return value


class LinearFunction(ModelFunction):
    """x ↦ M x with the exact Jacobian M; ``matrix`` (E, D) is what the Kalman filter uses."""

    def __init__(self, matrix: np.ndarray, name: str):
        matrix = np.asarray(matrix, dtype=float)
        super().__init__(name, matrix.shape[1], matrix.shape[0])
        self.matrix = matrix

    def evaluate(self, x, k):
        return x @ self.matrix.T

    def __call__(self, x, k=1):  # no user code to guard, nothing to check
        return x @ self.matrix.T

    def jacobian(self, x, k=1):
        x = np.asarray(x, dtype=float)
        return np.broadcast_to(self.matrix, x.shape[:-1] + self.matrix.shape)


def linear_matrix(fn: ModelFunction) -> np.ndarray | None:
    """The matrix M of a linear function x ↦ M x (also when applied run by run), else None."""
    inner = fn.fn if isinstance(fn, RunwiseFunction) else fn
    return inner.matrix if isinstance(inner, LinearFunction) else None


class RunwiseFunction(ModelFunction):
    """``fn`` applied to the points of B Monte Carlo runs run by run: x (N, D) holds run b's N/B
    points in its b-th block of rows (how a filter step of B runs lays out (B, …, D) points
    flattened), and each block is mapped exactly as one run's filter maps it alone — by a call of
    its own, or for a linear map by one stacked matrix product (one BLAS call per run) — so a run's
    values do not depend on the other runs or on B. A user's function may map a row differently in
    a larger call (a matrix product inside it lets BLAS choose its kernel by the number of rows):
    called per run it cannot. Jacobians: the central differences of the wrapped function (each
    run's 2D perturbed points in one call of their own), the user's per state, or the matrix."""

    def __init__(self, fn: ModelFunction, runs: int):
        super().__init__(fn.name, fn.in_dim, fn.out_dim, fn.circular)
        self.fn, self.runs = fn, int(runs)

    def renamed(self, name: str, circular: Sequence[int]) -> ModelFunction:
        return RunwiseFunction(self.fn.renamed(name, circular), self.runs)

    def _blocks(self, x: np.ndarray) -> np.ndarray:
        if x.ndim != 2 or x.shape[0] % self.runs:
            raise InputError(f"{self.name} of {self.runs} runs takes points (B·m, {self.in_dim}) with B = "
                             f"{self.runs}, got {x.shape}")
        return x.reshape(self.runs, -1, x.shape[-1])

    def __call__(self, x: np.ndarray, k: int = 1) -> np.ndarray:
        blocks = self._blocks(np.asarray(x, dtype=float))
        if isinstance(self.fn, LinearFunction):
            return (blocks @ self.fn.matrix.T).reshape(-1, self.out_dim)
        # each run's block by a call of its own; finiteness checked once for the whole batch
        return self.fn.checked_finite(np.concatenate([self.fn.shaped(block, k) for block in blocks]), k)

    def evaluate(self, x, k):
        return self(x, k)

    def jacobian(self, x, k=1):
        if isinstance(self.fn, NumpyFunction) and self.fn.user_jacobian is None:
            return central_difference_jacobian(self, x, k)
        return self.fn.jacobian(x, k)
