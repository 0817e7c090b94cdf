"""Systems whose functions are Gaussian processes learned from samples (seed 000 §2.2): the model
the GP-ADF and GP-UKF families filter with.

    x_k = GP_f(x_{k−1}) + w_k,   y_k^m = GP_{g,m}(x_k) + v_k^m

with the transition GP (D → D), one measurement GP per sensor (D → l_m), and the noise learned by
each GP (its ``noise_var``). The stacked measurement is the :class:`~gpfverify.gp.GaussianProcessStack`
of the sensors' GPs (one shared uncertain input, hence cross-sensor blocks in C_y).

Angles. Angle outputs (``sensor_circular``) and angle state components (``circular_state``) are
wrapped by the filters (y − μ_y, μ_p, μ_e) and differenced on the circle by the fusion rules. A
squared-exponential GP knows no period, so an angle is learned and used on one unwrapped branch:

* :func:`fit_gp_model` unwraps the training trajectory (samples in time order): every angle state
  and angle output is moved by whole turns so that consecutive samples differ by at most π
  (numpy's ``unwrap``), a transition target's angle is put within π of its input's, and the
  measurement inputs are put on the transition inputs' branch. A heading that passes ±π is then
  learned as the continuous function it is, not as a jump of 2π through 0;
* the filters evaluate the GPs with the belief's angle states on that branch,
  θ ↦ r + wrap(θ − r), r the mean of the transition GP's training angles
  (:meth:`GPModel.on_training_branch`), and wrap what the GPs return.

:func:`fit_gp_model` learns the GPs from samples (evidence maximisation on at most ``fit_points``
evenly spaced samples, then conditioning on all of them); :func:`learn_gp_model` draws the samples
from a :class:`~gpfverify.models.StateSpaceModel` first.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from typing import Protocol
from collections.abc import Sequence

import numpy as np

from gpfverify.angles import wrap
from gpfverify.errors import InputError
from gpfverify.gp import GaussianProcess, GaussianProcessStack
from gpfverify.models.system import StackedMeasurement, StateSpaceModel
from gpfverify.validate import as_indices
from gpfverify.runtime import one_blas_thread


def _check_gp(gp, what: str, in_dim: int | None = None, out_dim: int | None = None):
    needed = ("input_dim", "output_dim", "noise_var", "predict", "predict_mean", "predict_uncertain")
    missing = [a for a in needed if not hasattr(gp, a)]
    if missing:
        raise InputError(f"{what} must be a GaussianProcess (it lacks {', '.join(missing)})")
    if in_dim is not None and gp.input_dim != in_dim:
        raise InputError(f"{what} takes {gp.input_dim} inputs, expected the state's {in_dim}")
    if out_dim is not None and gp.output_dim != out_dim:
        raise InputError(f"{what} gives {gp.output_dim} outputs, expected {out_dim}")


class GaussianProcessLike(Protocol):
    """What :class:`GPModel` reads from its transition GP itself (:func:`_check_gp` checks the
    rest of the GaussianProcess interface the filters use)."""

    @property
    def input_dim(self) -> int: ...


@dataclass(frozen=True, eq=False)
class GPModel(StackedMeasurement):
    """``transition`` GP (D → D), ``sensors`` measurement GPs (D → l_m), ``sensor_circular`` the
    angle outputs of each sensor (0-based; empty tuple or omitted: none), ``circular_state`` the
    angle state components."""

    transition: GaussianProcessLike
    sensors: Sequence
    sensor_circular: Sequence[Sequence[int]] = ()
    circular_state: tuple[int, ...] = ()

    def __post_init__(self):
        _check_gp(self.transition, "the transition GP")
        d = self.transition.input_dim
        _check_gp(self.transition, "the transition GP", d, d)
        sensors = tuple(self.sensors) if isinstance(self.sensors, (list, tuple)) else (self.sensors,)
        if not sensors:
            raise InputError("a GP model needs at least one sensor GP")
        for m, gp in enumerate(sensors):
            _check_gp(gp, f"sensor {m}'s GP", d)
        circular = tuple(self.sensor_circular) or ((),) * len(sensors)
        if len(circular) != len(sensors):
            raise InputError(f"sensor_circular has {len(circular)} entries for {len(sensors)} sensors")
        object.__setattr__(self, "sensors", sensors)
        object.__setattr__(self, "sensor_circular", tuple(
            as_indices(c, gp.output_dim, f"sensor {m} circular") for m, (c, gp) in enumerate(zip(circular, sensors))))
        object.__setattr__(self, "circular_state", as_indices(self.circular_state, d, "circular_state"))

    @property
    def state_dim(self) -> int:
        return self.transition.input_dim

    @property
    def sizes(self) -> tuple[int, ...]:
        return tuple(gp.output_dim for gp in self.sensors)

    @cached_property
    def measurement(self):
        """The sensors' GP, or their stack when there are several."""
        return self.sensors[0] if len(self.sensors) == 1 else GaussianProcessStack(self.sensors)

    @property
    def runs(self) -> int | None:
        """B for a model of B Monte Carlo runs' GPs (:func:`batch_gp_models`), else None."""
        return getattr(self.transition, "runs", None)

    @cached_property
    def angle_reference(self) -> np.ndarray | None:
        """r: the mean of the transition GP's training inputs' angle state components, on the
        branch they were learned on (None without angle states, or for a GP that does not expose
        its inputs ``X``); (B, k) for a batch of runs' GPs, one per run."""
        inputs = getattr(self.transition, "X", None)
        if not self.circular_state or inputs is None:
            return None
        return np.asarray(inputs, dtype=float)[..., list(self.circular_state)].mean(axis=-2)

    def on_training_branch(self, states: np.ndarray) -> np.ndarray:
        """``states`` (..., D) with the angle components θ moved to r + wrap(θ − r), the branch of
        the GPs' training data (module docstring); unchanged without angle states. For a batch of
        runs, ``states`` holds run b's states in its b-th block of rows ((B, D), or (B·m, D) as the
        GPs take points)."""
        reference = self.angle_reference
        if reference is None:
            return states
        out = np.array(states, dtype=float)
        idx = list(self.circular_state)
        if reference.ndim == 2:  # one reference per run
            runs = out.reshape(reference.shape[0], -1, out.shape[-1])
            runs[..., idx] = reference[:, None, :] + wrap(runs[..., idx] - reference[:, None, :])
            return out
        out[..., idx] = reference + wrap(out[..., idx] - reference)
        return out

    def sensor_model(self, m: int) -> GPModel:
        """Sensor ``m`` alone (its local filter's model)."""
        return self.with_sensors([m])

    def with_sensors(self, indices: Sequence[int]) -> GPModel:
        if not as_indices(indices, len(self.sensors), "sensor indices"):
            raise InputError("a GP model needs at least one sensor")
        return replace(self, sensors=tuple(self.sensors[i] for i in indices),
                       sensor_circular=tuple(self.sensor_circular[i] for i in indices))


def batch_gp_models(models: Sequence[GPModel]) -> GPModel:
    """The GP models of B Monte Carlo runs as one model whose GPs are
    :class:`~gpfverify.gp.batch.GaussianProcessBatch`\\ es (run b's GPs at b): the GP filters step
    beliefs with a leading run axis (B, D) through it, run b against run b's GPs. The runs must
    share the GPs' shapes and the angle indices (InputError otherwise)."""
    from gpfverify.gp.batch import GaussianProcessBatch

    models = list(models)
    if not models:
        raise InputError("batch_gp_models needs at least one model")
    first = models[0]
    if any((m.sizes, m.sensor_circular, m.circular_state) != (first.sizes, first.sensor_circular,
                                                               first.circular_state) for m in models):
        raise InputError("the runs' GP models must share their sensors' sizes and angle indices")
    return GPModel(GaussianProcessBatch([m.transition for m in models]),
                   tuple(GaussianProcessBatch([m.sensors[s] for m in models]) for s in range(len(first.sensors))),
                   first.sensor_circular, first.circular_state)


def fit_capped(X: np.ndarray, Y: np.ndarray, restarts: int, fit_points: int | None, seed: int) -> GaussianProcess:
    """Hyperparameters by evidence maximisation on at most ``fit_points`` evenly spaced samples,
    then the GP conditioned on all of (X, Y) with them (all samples when ``fit_points`` is None)."""
    n = X.shape[0]
    if fit_points is None or n <= fit_points:
        return GaussianProcess.fit(X, Y, restarts, seed)
    subset = np.unique(np.linspace(0, n - 1, fit_points).round().astype(int))
    fitted = GaussianProcess.fit(X[subset], Y[subset], restarts, seed)
    return GaussianProcess(X, Y, fitted.lengthscales, fitted.signal_var, fitted.noise_var)


def unwrapped_along_time(values, circular: Sequence[int]) -> np.ndarray:
    """``values`` (n, E) with the ``circular`` columns moved by whole turns so that consecutive rows
    differ by at most π (``numpy.unwrap`` along the rows)."""
    out = np.array(values, dtype=float).reshape(len(values), -1)
    if len(circular) and len(out):
        idx = list(circular)
        out[:, idx] = np.unwrap(out[:, idx], axis=0)
    return out


@one_blas_thread
def fit_gp_model(transition_inputs, transition_targets, measurement_inputs, measurement_targets: Sequence,
                 rng: np.random.Generator, *, restarts: int = 3, fit_points: int | None = None,
                 sensor_circular: Sequence[Sequence[int]] = (), circular_state: Sequence[int] = ()) -> GPModel:
    """Learn a :class:`GPModel`: the transition GP on pairs x_{τ} ↦ x_{τ+1} (n_f, D) → (n_f, D),
    each sensor's GP on x_τ ↦ y_τ^m (n, D) → (n, l_m), the samples in time order. One optimiser
    seed per GP is drawn from ``rng`` (transition first, then the sensors in order). Angles are
    learned on the unwrapped trajectory (module docstring)."""
    angles = list(as_indices(circular_state, np.shape(transition_inputs)[-1], "circular_state"))
    x_in = unwrapped_along_time(transition_inputs, angles)
    x_out = np.array(transition_targets, dtype=float)
    states = unwrapped_along_time(measurement_inputs, angles)
    if angles:
        x_out[:, angles] = x_in[:, angles] + wrap(x_out[:, angles] - x_in[:, angles])
        turns = np.round((x_in[:, angles].mean(axis=0) - states[:, angles].mean(axis=0)) / (2 * np.pi))
        states[:, angles] += 2 * np.pi * turns
    circular = tuple(sensor_circular) or ((),) * len(measurement_targets)
    targets = [unwrapped_along_time(y, c) for y, c in zip(measurement_targets, circular)]
    seeds = [int(s) for s in rng.integers(1 << 31, size=1 + len(measurement_targets))]
    transition = fit_capped(x_in, x_out, restarts, fit_points, seeds[0])
    sensors = tuple(fit_capped(states, y, restarts, fit_points, s) for y, s in zip(targets, seeds[1:]))
    return GPModel(transition, sensors, tuple(sensor_circular), tuple(circular_state))


@one_blas_thread
def learn_gp_model(model: StateSpaceModel, samples: int, rng: np.random.Generator, *, restarts: int = 3,
                   fit_points: int | None = None) -> GPModel:
    """Draw one trajectory of ``samples`` states from ``model`` (started from its prior) with its
    measurements, and :func:`fit_gp_model` on it; angle outputs keep the model's ``circular``."""
    if samples < 2:
        raise InputError(f"learning a GP model needs at least 2 samples, got {samples}")
    states, ys = model.simulate(samples, rng)
    per_sensor = [ys[:, b] for b in model.blocks]
    return fit_gp_model(states[:-1], states[1:], states, per_sensor, rng, restarts=restarts,
                        fit_points=fit_points, sensor_circular=[s.circular for s in model.sensors],
                        circular_state=model.circular_state)
