"""A user's state-space model: one type for every filter and fusion rule (SPEC §6).

    x_k = f(x_{k−1}, k) + w_k,          w_k ~ N(0, Q)              (transition, process_cov)
    y_k^m = h_m(x_k, k) + v_k^m,        v_k^m ~ N(0, R_m)           (sensors[m]: measure, noise_cov)
    x_0 ~ N(prior_mean, prior_cov)

Q and R_m are full covariances (symmetric positive semidefinite; R_m positive definite). The
stacked measurement y_k = [y_k¹; …; y_k^N] has h = [h_1; …; h_N] and R = blkdiag(R_1, …, R_N).
``Sensor.circular`` lists the outputs of a sensor that are angles in radians and
``circular_state`` the state components that are: every difference of such a value is wrapped to
(−π, π] (:mod:`gpfverify.angles`).

Functions can be given as numpy callables ``fn(x (N, D)[, k]) -> (N, E)`` (with optional
Jacobians, else central differences), as 2-D arrays (linear maps, exact Jacobians), as casadi
Functions or expressions (:meth:`StateSpaceModel.from_casadi`, exact Jacobians by AD) or as sympy
expressions (:meth:`StateSpaceModel.from_sympy`); all end in the same :class:`ModelFunction`
calling convention (:mod:`gpfverify.models.functions`).

The model is validated once, when it is built — covariances, prior, circular indices, and one
probe call of every function at the prior mean (step k = 1) for shape and finiteness — so that
the filters' step functions can trust it. Problems raise :class:`~gpfverify.errors.InputError`
naming the part ("sensor 1 (range-bearing) noise_cov", "transition").

Particle filters may also use ``transition_sampler(x_prev (N, D), k, rng) -> (N, D)`` and
``transition_logpdf(x_new (N, D), x_prev (N, D), k) -> (N,)`` for non-Gaussian process noise;
then ``transition`` and ``process_cov`` are the Gaussian approximation a Gaussian filter uses.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import TYPE_CHECKING
from collections.abc import Callable, Sequence

import numpy as np
import scipy.linalg as sla

from gpfverify.angles import difference
from gpfverify.errors import InputError
from gpfverify.linalg import sampling_factor
from gpfverify.models.functions import LinearFunction, ModelFunction, NumpyFunction, RunwiseFunction, linear_matrix
from gpfverify.tolerances import algebra_rtol
from gpfverify.validate import as_covariance, as_indices, as_vector, real_floats


def as_model_function(obj, name: str, in_dim: int, out_dim: int, jacobian=None,
                      circular: Sequence[int] = ()) -> ModelFunction:
    """Normalise a numpy callable, a matrix, a casadi Function or an existing ModelFunction."""
    if isinstance(obj, ModelFunction):
        fn = obj.renamed(name, circular)
    elif isinstance(obj, np.ndarray) or (isinstance(obj, (list, tuple)) and not callable(obj)):
        matrix = real_floats(obj, name)
        if matrix.shape != (out_dim, in_dim):
            raise InputError(f"{name} as a matrix must have shape ({out_dim}, {in_dim}), got {matrix.shape}")
        fn = LinearFunction(matrix, name).renamed(name, circular)
    elif type(obj).__module__.startswith("casadi"):
        from gpfverify.models.casadi_input import casadi_function
        fn = casadi_function(obj, name, in_dim, out_dim, circular)
    else:
        fn = NumpyFunction(obj, name, in_dim, out_dim, jacobian, circular)
    if (fn.in_dim, fn.out_dim) != (in_dim, out_dim):
        raise InputError(f"{name} maps {fn.in_dim} -> {fn.out_dim} values, expected {in_dim} -> {out_dim}")
    return fn


def _sensor_label(name: str, measure: object) -> str:
    """How messages name a sensor: its ``name``, else its measurement function's own name (a
    lambda has none worth showing)."""
    if name:
        return f"sensor {name!r}"
    function_name = getattr(measure, "__name__", "")
    return f"sensor (measure {function_name})" if function_name and function_name != "<lambda>" else "sensor"


@dataclass(frozen=True, eq=False)
class Sensor:
    """y^m = measure(x, k) + v, v ~ N(0, noise_cov): ``noise_cov`` (l, l) positive definite,
    ``circular`` the 0-based outputs that are angles (radians), ``jacobian`` optional for numpy
    callables (``jacobian(x (D,)[, k]) -> (l, D)``), ``name`` used in messages."""

    measure: object  # as given; a StateSpaceModel binds it to a ModelFunction (StateSpaceModel.measures)
    noise_cov: np.ndarray
    circular: tuple[int, ...] = ()
    jacobian: Callable | None = None
    name: str = ""

    if TYPE_CHECKING:
        # the arguments as given; __post_init__ stores noise_cov and circular validated
        def __init__(self, measure: object, noise_cov: object, circular: Sequence[int] = (),
                     jacobian: Callable | None = None, name: str = "") -> None: ...

    def __post_init__(self):
        label = _sensor_label(self.name, self.measure)
        cov = as_covariance(_floats(self.noise_cov, f"{label} noise_cov", 2), f"{label} noise_cov",
                            definite=True)
        object.__setattr__(self, "noise_cov", cov)
        object.__setattr__(self, "circular", as_indices(self.circular, cov.shape[0], f"{label} circular"))

    @property
    def size(self) -> int:
        return self.noise_cov.shape[0]


def _floats(value, what: str, ndim: int) -> np.ndarray:
    """``value`` as a float array of at least ``ndim`` dimensions (a scalar variance is 1 x 1);
    booleans, complex numbers and text refused, not converted."""
    arr = real_floats(value, what)
    return np.atleast_2d(arr) if ndim == 2 else np.atleast_1d(arr)


class StackedMeasurement:
    """The stacked measurement y = [y¹; …; y^N] of a model's sensors, shared by the model types:
    they define ``sizes`` (l_1, …, l_N) and ``sensor_circular`` (each sensor's angle outputs)."""

    if TYPE_CHECKING:
        @property
        def sizes(self) -> tuple[int, ...]: ...

        @property
        def sensor_circular(self) -> Sequence[Sequence[int]]: ...

    @property
    def measurement_dim(self) -> int:
        return int(sum(self.sizes))

    @cached_property
    def blocks(self) -> tuple[slice, ...]:
        """Slice of sensor m's outputs in the stacked measurement."""
        ends = np.cumsum((0,) + tuple(self.sizes))
        return tuple(slice(int(a), int(b)) for a, b in zip(ends[:-1], ends[1:]))

    @cached_property
    def circular(self) -> tuple[int, ...]:
        """Indices of the angle outputs in the stacked measurement."""
        return tuple(b.start + i for b, c in zip(self.blocks, self.sensor_circular) for i in c)


@dataclass(frozen=True, eq=False)
class StateSpaceModel(StackedMeasurement):
    """The model of the module docstring. After construction ``transition`` and every sensor's
    ``measure`` are :class:`ModelFunction`\\ s, ``process_cov``, ``prior_mean``, ``prior_cov`` and
    every ``noise_cov`` validated float arrays, ``sensors`` a tuple."""

    transition: ModelFunction
    process_cov: np.ndarray
    sensors: tuple[Sensor, ...]
    prior_mean: np.ndarray
    prior_cov: np.ndarray
    circular_state: tuple[int, ...] = ()
    transition_jacobian: Callable | None = None
    transition_sampler: Callable | None = None
    transition_logpdf: Callable | None = None
    name: str = ""
    probe: bool = field(default=True, repr=False)

    if TYPE_CHECKING:
        # the arguments as given (module docstring); __post_init__ stores them validated and bound
        def __init__(self, transition: object, process_cov: object, sensors: Sensor | Sequence[Sensor],
                     prior_mean: object, prior_cov: object, circular_state: Sequence[int] = (),
                     transition_jacobian: Callable | None = None, transition_sampler: Callable | None = None,
                     transition_logpdf: Callable | None = None, name: str = "", probe: bool = True) -> None: ...

    @classmethod
    def from_casadi(cls, *args, **kwargs) -> StateSpaceModel:
        """See :func:`model_from_casadi`."""
        return model_from_casadi(*args, **kwargs)

    @classmethod
    def from_sympy(cls, *args, **kwargs) -> StateSpaceModel:
        """See :func:`model_from_sympy`."""
        return model_from_sympy(*args, **kwargs)

    def __post_init__(self):
        set_ = lambda key, value: object.__setattr__(self, key, value)  # noqa: E731
        Q = as_covariance(_floats(self.process_cov, "process_cov", 2), "process_cov")
        d = Q.shape[0]
        if d == 0:
            raise InputError("process_cov must be at least 1 x 1")
        set_("process_cov", Q)
        set_("prior_mean", as_vector(_floats(self.prior_mean, "prior_mean", 1), "prior_mean", d))
        set_("prior_cov", as_covariance(_floats(self.prior_cov, "prior_cov", 2), "prior_cov", d))
        set_("circular_state", as_indices(self.circular_state, d, "circular_state"))
        sensors = tuple(self.sensors) if isinstance(self.sensors, (list, tuple)) else (self.sensors,)
        if not sensors:
            raise InputError("a model needs at least one sensor")
        bound = []
        for m, s in enumerate(sensors):
            if not isinstance(s, Sensor):
                raise InputError(f"sensors[{m}] must be a gpfverify.models.Sensor, got {type(s).__name__}")
            label = f"sensor {m}" + (f" ({s.name})" if s.name else "")
            if not self.probe and isinstance(s.measure, ModelFunction) and s.measure.circular == s.circular:
                fn = s.measure  # a model derived from a built one (with_sensors): each keeps its name, "sensor 2"
            else:
                fn = as_model_function(s.measure, f"{label} measure", d, s.size, s.jacobian, s.circular)
            bound.append(replace(s, measure=fn) if fn is not s.measure else s)
        set_("sensors", tuple(bound))
        set_("transition", as_model_function(self.transition, "transition", d, d,
                                             self.transition_jacobian, self.circular_state))
        for what, fn in (("transition_sampler", self.transition_sampler),
                         ("transition_logpdf", self.transition_logpdf)):
            if fn is not None and not callable(fn):
                raise InputError(f"{what} must be callable")
        if self.probe:
            self.check_functions(self.prior_mean)

    def check_functions(self, x, k: int = 1) -> None:
        """Call every function (and Jacobian) at the state ``x`` (D,) and at the batch
        (x, x + δ, x − 2δ), δ the prior standard deviations (1 where zero): InputError naming the
        part when one raises, returns the wrong shape or NaN, or maps a row of the batch
        differently from the same state alone (not vectorised over the leading axis)."""
        x = as_vector(x, "probe state", self.state_dim)
        spread = np.sqrt(np.diag(self.prior_cov))
        spread = np.where(spread > 0.0, spread, 1.0)
        batch = np.stack([x, x + spread, x - 2.0 * spread])
        for fn in (self.transition,) + self.measures:
            alone = np.concatenate([fn(row[None], k) for row in batch])
            together = fn(batch, k)
            tol = algebra_rtol() * max(float(np.abs(alone).max()), 1.0)
            if np.abs(difference(together, alone, fn.circular)).max() > tol:
                raise InputError(f"{fn.name} is not vectorised over the leading axis: rows of a "
                                 f"batch (N, {self.state_dim}) must be mapped independently")
            fn.jacobian(x, k)

    # -- the stacked model -------------------------------------------------------------------

    @property
    def state_dim(self) -> int:
        return self.process_cov.shape[0]

    @property
    def sizes(self) -> tuple[int, ...]:
        """Measurement dimension of every sensor."""
        return tuple(s.size for s in self.sensors)

    @property
    def sensor_circular(self) -> tuple[tuple[int, ...], ...]:
        """Each sensor's angle outputs."""
        return tuple(s.circular for s in self.sensors)

    @cached_property
    def measures(self) -> tuple[ModelFunction, ...]:
        """Every sensor's ``measure`` as the :class:`ModelFunction` ``__post_init__`` bound it to."""
        out = []
        for s in self.sensors:
            assert isinstance(s.measure, ModelFunction)  # bound in __post_init__
            out.append(s.measure)
        return tuple(out)

    @property
    def Q(self) -> np.ndarray:
        return self.process_cov

    @cached_property
    def R(self) -> np.ndarray:
        """blkdiag(R_1, …, R_N) (L, L)."""
        return sla.block_diag(*(s.noise_cov for s in self.sensors))

    def f(self, x: np.ndarray, k: int = 1) -> np.ndarray:
        """f(x, k) for states x (N, D): (N, D)."""
        return self.transition(x, k)

    def h(self, x: np.ndarray, k: int = 1) -> np.ndarray:
        """Stacked h(x, k) for states x (N, D): (N, L)."""
        if len(self.sensors) == 1:
            return self.measures[0](x, k)
        return np.concatenate([h(x, k) for h in self.measures], axis=-1)

    def f_jacobian(self, x: np.ndarray, k: int = 1) -> np.ndarray:
        """∂f/∂x at states x (..., D): (..., D, D)."""
        return self.transition.jacobian(x, k)

    def h_jacobian(self, x: np.ndarray, k: int = 1) -> np.ndarray:
        """∂h/∂x of the stacked measurement at states x (..., D): (..., L, D)."""
        if len(self.sensors) == 1:
            return self.measures[0].jacobian(x, k)
        return np.concatenate([h.jacobian(x, k) for h in self.measures], axis=-2)

    def residual(self, y: np.ndarray, y_pred: np.ndarray) -> np.ndarray:
        """y − y_pred with the angle outputs wrapped to (−π, π]."""
        return difference(y, y_pred, self.circular)

    def linear_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """(F, H) of a linear model; InputError when a function is not linear."""
        if self._linear is None:
            raise InputError("the Kalman filter needs a linear model (matrices for the transition "
                             "and every sensor, e.g. gpfverify.models.linear_model)")
        return self._linear

    @cached_property
    def _linear(self) -> tuple[np.ndarray, np.ndarray] | None:
        matrices = [m for m in (linear_matrix(fn) for fn in (self.transition, *self.measures)) if m is not None]
        if len(matrices) != 1 + len(self.measures):
            return None
        return matrices[0], np.concatenate(matrices[1:])

    # -- derived models ---------------------------------------------------------------------------

    def sensor_model(self, m: int) -> StateSpaceModel:
        """The same system seen by sensor ``m`` alone (its local filter's model)."""
        return self.with_sensors([m])

    def with_sensors(self, indices: Sequence[int]) -> StateSpaceModel:
        """The same system with the sensors ``indices`` (in that order)."""
        if not as_indices(indices, len(self.sensors), "sensor indices"):
            raise InputError("a model needs at least one sensor")
        return replace(self, sensors=tuple(self.sensors[i] for i in indices), probe=False)

    def for_runs(self, runs: int) -> StateSpaceModel:
        """The same system for filter steps of ``runs`` Monte Carlo runs at once (beliefs (B, D),
        measurements (B, L), B = ``runs``): every function maps each run's points as that run's
        own step would, by a call of its own (:class:`~gpfverify.models.functions.RunwiseFunction`),
        so that a run's numbers do not depend on the other runs or on B."""
        if isinstance(runs, bool) or not isinstance(runs, int) or runs < 1:
            raise InputError(f"runs must be an integer >= 1, got {runs!r}")
        def runwise(fn: ModelFunction) -> RunwiseFunction:
            return RunwiseFunction(fn.fn if isinstance(fn, RunwiseFunction) else fn, runs)
        return replace(self, transition=runwise(self.transition),
                       sensors=tuple(replace(s, measure=runwise(m)) for s, m in zip(self.sensors, self.measures)),
                       probe=False)

    def with_noise(self, process_cov=None, noise_covs: Sequence | None = None) -> StateSpaceModel:
        """The same functions with new noise covariances (validated; the functions are not probed
        again): a time-varying Q_k or R_k without rebuilding the model."""
        sensors = self.sensors if noise_covs is None else tuple(
            replace(s, noise_cov=c) for s, c in zip(self.sensors, noise_covs, strict=True))
        return replace(self, process_cov=self.process_cov if process_cov is None else process_cov,
                       sensors=sensors, probe=False)

    # -- simulation -----------------------------------------------------------------------------

    def sample_transition(self, x_prev: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
        """Draws x_k ~ p(x_k | x_{k−1}) for states x_prev (N, D)."""
        if self.transition_sampler is not None:
            return np.asarray(self.transition_sampler(x_prev, k, rng), dtype=float)
        # for a positive definite Q, the draws of rng.multivariate_normal(0, Q, N, method="cholesky"),
        # bit for bit, without factorising Q at every call
        noise = rng.standard_normal((x_prev.shape[0], self.state_dim)) @ self._process_factor.T
        return self.f(x_prev, k) + noise

    @cached_property
    def _process_factor(self) -> np.ndarray:
        """A factor of Q (:func:`~gpfverify.linalg.sampling_factor`: numpy's lower Cholesky factor,
        as rng.multivariate_normal uses, or an eigen-factor for a singular Q)."""
        return sampling_factor(self.Q)

    def simulate(self, steps: int, rng: np.random.Generator, x0=None) -> tuple[np.ndarray, np.ndarray]:
        """States x_1..x_T (T, D) and stacked measurements y_1..y_T (T, L), from x_0 = ``x0`` or a
        draw from the prior. Angle components are wrapped to (−π, π]."""
        if steps < 1:
            raise InputError(f"steps must be at least 1, got {steps}")
        if x0 is None:  # numpy's multivariate_normal(prior_mean, prior_cov, method="cholesky"), step by step
            x = np.dot(rng.standard_normal(self.state_dim).reshape(1, -1), sampling_factor(self.prior_cov).T)
            x += self.prior_mean
        else:
            x = as_vector(x0, "x0", self.state_dim)[None, :]
        noise = rng.multivariate_normal(np.zeros(self.measurement_dim), self.R, size=steps, method="cholesky")
        states, measurements = np.empty((steps, self.state_dim)), np.empty((steps, self.measurement_dim))
        for k in range(1, steps + 1):
            x = self.sample_transition(x, k, rng)
            if self.circular_state:
                x = difference(x, 0.0 * x, self.circular_state)
            states[k - 1] = x[0]
            measurements[k - 1] = difference(self.h(x, k)[0] + noise[k - 1], 0.0, self.circular)
        return states, measurements


def linear_model(F, H, Q, R, prior_mean=None, prior_cov=None, sizes: Sequence[int] | None = None
                 ) -> StateSpaceModel:
    """x_k = F x_{k−1} + w, y_k = H x_k + v as a :class:`StateSpaceModel` (prior N(0, I) unless
    given); ``sizes`` splits H and R into sensors (default one sensor). R must be block diagonal
    for that split."""
    F, H, R = (np.atleast_2d(real_floats(a, name)) for a, name in ((F, "F"), (H, "H"), (R, "R")))
    d = F.shape[0]
    sizes = (H.shape[0],) if sizes is None else tuple(sizes)
    ends = np.cumsum((0,) + sizes)
    blocks = [slice(int(a), int(b)) for a, b in zip(ends[:-1], ends[1:])]
    if ends[-1] != H.shape[0]:
        raise InputError(f"sizes {sizes} do not add up to the {H.shape[0]} rows of H")
    off = R.copy()
    for b in blocks:
        off[b, b] = 0.0
    if np.any(off != 0.0):
        raise InputError("R must be block diagonal over the sensors' sizes")
    sensors = [Sensor(H[b], R[b, b]) for b in blocks]
    return StateSpaceModel(F, Q, sensors, np.zeros(d) if prior_mean is None else prior_mean,
                           np.eye(d) if prior_cov is None else prior_cov)



def require_model(model, kind: type, who: str) -> None:
    """InputError unless ``model`` is a ``kind`` (the filters' one check on the model they get)."""
    if not isinstance(model, kind):
        hint = (" (learn one with gpfverify.models.learn_gp_model or fit_gp_model)"
                if kind.__name__ == "GPModel" else " (gpfverify.models.StateSpaceModel)")
        raise InputError(f"{who} needs a {kind.__name__}{hint}, got {type(model).__name__}")


def _measure_label(m: int, sensor: Sensor) -> str:
    """How :class:`StateSpaceModel` names sensor ``m``'s function in messages."""
    return f"sensor {m}" + (f" ({sensor.name})" if sensor.name else "") + " measure"


def model_from_casadi(state, transition, process_cov, sensors: Sequence[Sensor], prior_mean,
                      prior_cov, *, step=None, circular_state: Sequence[int] = (), name: str = "",
                      **kwargs) -> StateSpaceModel:
    """The model x_k = f(x_{k−1}, k) + w_k, y_k^m = h_m(x_k, k) + v_k^m with f = ``transition``
    and h_m = ``sensors[m].measure`` casadi expressions in the column symbol ``state`` (D x 1) and
    the optional scalar symbol ``step`` (k). Each expression becomes casadi.Function(label,
    [state(, step)], [expr]); casadi Functions, matrices and numpy callables are passed on
    unchanged. Other keyword arguments go to :class:`StateSpaceModel`."""
    import casadi as ca

    from gpfverify.models.casadi_input import casadi_message, casadi_name

    inputs = [state] if step is None else [state, step]
    sensors = [sensors] if isinstance(sensors, Sensor) else sensors

    def function(expr, label: str):
        if not isinstance(expr, (ca.SX, ca.MX)):
            return expr
        try:
            # SX or MX: casadi's overloads take one kind per call, a mix is casadi's error below
            return ca.Function(casadi_name(label), inputs, [expr])  # type: ignore[list-item]
        except Exception as exc:  # free symbols, a state that is not a symbol, mixed SX and MX
            raise InputError(f"{label} is not a casadi expression in the state"
                             f"{'' if step is None else ' and the step k'}: {casadi_message(exc)}") from exc

    bound = [replace(s, measure=function(s.measure, _measure_label(m, s))) if isinstance(s, Sensor) else s
             for m, s in enumerate(sensors)]
    return StateSpaceModel(function(transition, "transition"), process_cov, bound, prior_mean,
                           prior_cov, circular_state=circular_state, name=name, **kwargs)


def model_from_sympy(states: Sequence, transition, process_cov, sensors: Sequence[Sensor],
                     prior_mean, prior_cov, *, step=None,
                     circular_state: Sequence[int] = (), name: str = "", **kwargs) -> StateSpaceModel:
    """The model x_k = f(x_{k−1}, k) + w_k, y_k^m = h_m(x_k, k) + v_k^m with f = ``transition``
    and h_m = ``sensors[m].measure`` sympy expressions (sequences or Matrices, one entry per
    output) in the symbols ``states`` (x_1, …, x_D) and the optional ``step`` symbol k; each
    becomes a :class:`~gpfverify.models.sympy_input.SympyFunction`. Other keyword arguments go to
    :class:`StateSpaceModel`."""
    from gpfverify.models.sympy_input import SympyFunction

    states = tuple(states)
    sensors = [sensors] if isinstance(sensors, Sensor) else sensors
    bound = [replace(s, measure=SympyFunction(s.measure, states, step, _measure_label(m, s)))
             if isinstance(s, Sensor) else s for m, s in enumerate(sensors)]
    return StateSpaceModel(SympyFunction(transition, states, step, "transition"), process_cov, bound,
                           prior_mean, prior_cov, circular_state=circular_state, name=name, **kwargs)
