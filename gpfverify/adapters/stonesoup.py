"""Stone Soup trackers as gpfverify systems, and gpfverify's fusion as Stone Soup tracks
(extra ``gpfverify[stonesoup]``, Stone Soup ≥ 1.9).

* :func:`state_space_model`: a Stone Soup transition model, one measurement model per sensor, a
  ``GaussianState`` prior and the time between two steps → a
  :class:`~gpfverify.models.StateSpaceModel`. A linear model (``LinearModel``: ``LinearGaussian``,
  ``CombinedLinearGaussianTransitionModel``, ...) becomes its matrix, so the Kalman filter takes
  it; any other model becomes a function evaluated by Stone Soup itself (``model.function``, all
  sigma points in one call, noise-free) with Stone Soup's own Jacobian (``model.jacobian``, for
  the EKF). Each model's ``mapping``, offsets and rotation are therefore the model's own.
* **Angles as Stone Soup types mark them.** A measurement model's output whose value is a Stone
  Soup ``Angle`` (``Bearing``, ``Azimuth``, ``Elevation``, ...: what the model's ``function``
  returns at the prior mean) is a circular output; a prior state component held as an ``Angle``
  is a circular state component. gpfverify wraps every difference of them to (−π, π]. For a
  ``Bearing`` or ``Azimuth`` that is Stone Soup's own wrap (``mod_bearing``, to [−π, π)); an
  ``Elevation`` lies in [−π/2, π/2], so a difference of two never reaches ±π and the wrap never
  acts (Stone Soup folds an elevation *difference* beyond ±π/2 back into [−π/2, π/2], which only
  matters for differences no Gaussian filter on such a sensor produces).
* :func:`system_from_objects`: the same from the objects a Stone Soup script already has — a
  mapping or sequence of them, recognised by type (what ``gpfverify check SYSTEM.py:NAME`` accepts).
* :func:`measurements` / :func:`write_measurements`: ``Detection`` s over time (one per sensor and
  time step; a Stone Soup detector's ``(time, detections)`` pairs are accepted as they come) and
  optionally the ground truth → the measurements file of ``gpfverify check --measurements``.
* :func:`tracks`: a :func:`~gpfverify.model_fusion.run_fusion` result → one Stone Soup ``Track`` of
  ``GaussianState`` s per fusion rule and per sensor's local filter, timestamped, for Stone Soup's
  metrics and plotters.

One difference from Stone Soup's own unscented filters: a weighted mean of angles (the sigma
points' bearing) is gpfverify's — relative to the central sigma point,
wrap(r + Σ w_i wrap(a_i − r)) (:mod:`gpfverify.angles`) — where Stone Soup's ``Angle.average``
takes atan2(Σ w sin a_i, Σ w cos a_i). The two agree to second order in the sigma points' spread
in angle (docs/ecosystem.md gives the measured difference); with the mean made the same, the
filters agree to rounding (tests/test_adapters_stonesoup.py).
"""

from __future__ import annotations

import datetime
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from stonesoup.base import Base
from stonesoup.models.base import LinearModel
from stonesoup.models.measurement.base import MeasurementModel
from stonesoup.models.transition.base import TransitionModel
from stonesoup.types.angle import Angle
from stonesoup.types.array import StateVector, StateVectors
from stonesoup.types.detection import Detection
from stonesoup.types.state import GaussianState, State
from stonesoup.types.track import Track

from gpfverify.adapters.objects import user_call, user_floats
from gpfverify.errors import InputError
from gpfverify.models.system import Sensor, StateSpaceModel


def _floats(values) -> np.ndarray:
    """A Stone Soup vector or matrix (possibly of ``Angle`` objects) as floats."""
    return np.asarray(values, dtype=float)


def _angle_rows(vector) -> tuple[int, ...]:
    """Indices of the entries of a Stone Soup vector (l, 1) or (l, N) held as ``Angle`` s."""
    rows = np.asarray(vector, dtype=object).reshape(len(vector), -1)[:, 0]
    return tuple(i for i, value in enumerate(rows) if isinstance(value, Angle))


def _evaluated(model, **kwargs):
    """``model``'s noise-free function as a gpfverify model function: (N, D) → (N, E), every row
    one Stone Soup state (all rows in one call, as Stone Soup's own filters call it)."""
    def function(x: np.ndarray) -> np.ndarray:
        out = model.function(State(StateVectors(np.asarray(x, dtype=float).T)), noise=False, **kwargs)
        return _floats(out).T

    return function


def _jacobian(model, **kwargs):
    """``model``'s Jacobian (Stone Soup's, analytic or its finite differences) at one state (D,)."""
    def jacobian(x: np.ndarray) -> np.ndarray:
        return _floats(model.jacobian(State(StateVector(np.asarray(x, dtype=float))), **kwargs))

    return jacobian


def _state_dim(model, what: str) -> int:
    dim = getattr(model, "ndim_state", None)
    if not isinstance(dim, (int, np.integer)):
        raise InputError(f"{what} ({type(model).__name__}) has no ndim_state")
    return int(dim)


def sensor(measurement_model: MeasurementModel, prior: GaussianState, name: str = "") -> Sensor:
    """One gpfverify :class:`~gpfverify.models.Sensor` from a Stone Soup measurement model: its
    matrix when it is linear, else its function and Jacobian; its noise covariance; its angle
    outputs as its function marks them at the prior mean (module docstring)."""
    if not isinstance(measurement_model, MeasurementModel):
        raise InputError(f"a measurement model must be a Stone Soup MeasurementModel, got "
                         f"{type(measurement_model).__name__}")
    name = name or type(measurement_model).__name__
    what = f"measurement model {name}"
    typed = user_call(f"{what}: function", measurement_model.function, State(prior.state_vector), noise=False)
    circular = _angle_rows(typed)
    noise = user_floats(user_call(f"{what}: covar", measurement_model.covar), f"{what}'s covar")
    if isinstance(measurement_model, LinearModel):
        matrix = user_floats(user_call(f"{what}: matrix", measurement_model.matrix), f"{what}'s matrix")
        return Sensor(matrix, noise, circular=circular, name=name)
    return Sensor(_evaluated(measurement_model), noise, circular=circular, jacobian=_jacobian(measurement_model),
                  name=name)


def _checked_interval(time_interval) -> datetime.timedelta:
    if not isinstance(time_interval, datetime.timedelta) or time_interval <= datetime.timedelta(0):
        raise InputError(f"time_interval must be a positive datetime.timedelta (the time between two "
                         f"steps), got {time_interval!r}")
    return time_interval


def state_space_model(transition_model: TransitionModel, measurement_models: Sequence[MeasurementModel],
                      prior: GaussianState, time_interval: datetime.timedelta, name: str = "") -> StateSpaceModel:
    """The :class:`~gpfverify.models.StateSpaceModel` of a Stone Soup system (module docstring):
    x_k = f(x_{k−1}) + w_k with f and Q = ``transition_model``'s at ``time_interval``, one sensor
    per measurement model (in the order given), x_0 ~ ``prior``."""
    if not isinstance(transition_model, TransitionModel):
        raise InputError(f"transition_model must be a Stone Soup TransitionModel, got "
                         f"{type(transition_model).__name__}")
    if not isinstance(prior, GaussianState):
        raise InputError(f"prior must be a Stone Soup GaussianState, got {type(prior).__name__}")
    if isinstance(measurement_models, MeasurementModel) or not len(measurement_models):
        raise InputError("measurement_models must be a non-empty sequence of Stone Soup measurement models, "
                         "one per sensor")
    interval = _checked_interval(time_interval)
    dim = len(prior.state_vector)
    for what, model in [("transition_model", transition_model)] + [
            (f"measurement model {m}", mm) for m, mm in enumerate(measurement_models)]:
        if _state_dim(model, what) != dim:
            raise InputError(f"{what} ({type(model).__name__}) has ndim_state {model.ndim_state}, but the "
                             f"prior's state has {dim} components")
    names = [type(mm).__name__ for mm in measurement_models]
    sensors = [sensor(mm, prior, f"{n} {m}" if names.count(n) > 1 else n)
               for m, (mm, n) in enumerate(zip(measurement_models, names))]
    what = f"transition model {type(transition_model).__name__}"
    q = user_floats(user_call(f"{what}: covar", transition_model.covar, time_interval=interval), f"{what}'s covar")
    if isinstance(transition_model, LinearModel):
        transition: object = user_floats(user_call(f"{what}: matrix", transition_model.matrix, time_interval=interval),
                                         f"{what}'s matrix")
        jacobian = None
    else:
        transition = _evaluated(transition_model, time_interval=interval)
        jacobian = _jacobian(transition_model, time_interval=interval)
    return StateSpaceModel(transition, q, sensors, user_floats(prior.state_vector, "the prior's state_vector").ravel(),
                           user_floats(prior.covar, "the prior's covar"),
                           circular_state=_angle_rows(prior.state_vector), transition_jacobian=jacobian,
                           name=name or f"Stone Soup {type(transition_model).__name__}, {len(sensors)} sensors")


# -- recognising a Stone Soup system among the objects of a script ---------------------------------

#: attributes through which Stone Soup components hold the models and the prior
_HOLDERS = ("transition_model", "measurement_model", "predictor", "updater", "initiator", "data_associator",
            "hypothesiser", "sensors")


@dataclass
class _Found:
    transitions: list
    measurements: list
    priors: list
    intervals: list

    def add(self, obj, seen: set[int]) -> None:
        if obj is None or id(obj) in seen:
            return
        seen.add(id(obj))
        if isinstance(obj, TransitionModel):
            self.transitions.append(obj)
        elif isinstance(obj, MeasurementModel):
            self.measurements.append(obj)
        elif isinstance(obj, GaussianState):
            self.priors.append(obj)
        elif isinstance(obj, datetime.timedelta):
            self.intervals.append(obj)
        elif isinstance(obj, Mapping):
            for value in obj.values():
                self.add(value, seen)
        elif isinstance(obj, (list, tuple, set, frozenset)):
            for value in obj:
                self.add(value, seen)
        elif isinstance(obj, Base) and hasattr(obj, "prior_state"):  # an initiator: its prior only (its
            self.add(obj.prior_state, seen)  # measurement model converts detections, it is not a sensor)
        elif isinstance(obj, Base):  # a predictor, updater, hypothesiser, tracker or sensor
            for attribute in _HOLDERS:
                self.add(getattr(obj, attribute, None), seen)


def _one(found: list, what: str, hint: str):
    distinct = list({id(x): x for x in found}.values())
    if len(distinct) != 1:
        raise InputError(f"a Stone Soup system needs exactly one {what}, found {len(distinct)}{hint}")
    return distinct[0]


def system_from_objects(objects) -> StateSpaceModel:
    """The system described by Stone Soup objects, found by type in ``objects`` (a mapping, a
    sequence, or one object): exactly one ``TransitionModel`` (or a predictor holding it), one
    ``MeasurementModel`` per sensor in the order met (or updaters and sensors holding them), one
    ``GaussianState`` prior (or an initiator's ``prior_state``) and one ``datetime.timedelta``,
    the time between two steps. Trackers are searched through their predictor, updater and
    initiator. For example ``{"transition_model": cv, "measurement_models": [radar1, radar2],
    "prior": GaussianState(...), "time_interval": timedelta(seconds=1)}``."""
    found = _Found([], [], [], [])
    found.add(objects, set())
    transition = _one(found.transitions, "transition model", "")
    prior = _one(found.priors, "GaussianState prior", " (the belief about the state before the first step)")
    interval = _one(found.intervals, "datetime.timedelta", " (the time between two steps)")
    if not found.measurements:
        raise InputError("a Stone Soup system needs at least one measurement model (one per sensor), found none")
    return state_space_model(transition, found.measurements, prior, interval)


# -- detections in, tracks out ---------------------------------------------------------------------

@dataclass(frozen=True)
class Measurements:
    """Measurements in the layout of ``gpfverify check --measurements`` (docs/check-format.md):
    ``y`` (T, L) stacked in sensor order, ``x`` (T, D) the truth or None, and the ``timestamps``
    of the T steps."""

    y: np.ndarray
    x: np.ndarray | None
    timestamps: tuple[datetime.datetime, ...]


def _detections(items) -> list[Detection]:
    """Detections from a flat iterable, sets of them, or a detector's (time, detections) pairs."""
    out: list[Detection] = []
    for item in items:
        if isinstance(item, Detection):
            out.append(item)
        elif (isinstance(item, tuple) and len(item) == 2 and isinstance(item[0], datetime.datetime)):
            out.extend(_detections(item[1]))
        elif isinstance(item, Iterable) and not isinstance(item, (str, bytes, State)):
            out.extend(_detections(item))
        else:
            raise InputError(f"expected Stone Soup Detections (or a detector's (time, detections) pairs), "
                             f"got a {type(item).__name__}")
    return out


def _spacing(timestamps: Sequence[datetime.datetime], time_interval) -> None:
    steps = {b - a for a, b in zip(timestamps, timestamps[1:])}
    expected = {time_interval} if time_interval is not None else steps
    if len(steps) > 1 or steps - expected:
        raise InputError(f"the detections' time steps are {sorted(str(s) for s in steps)}; a measurements "
                         f"file has one row per step of {time_interval or 'one fixed interval'}")


def _sensor_index(measurement_models: Sequence[MeasurementModel]):
    """Which of ``measurement_models`` a detection's model is: the same object, or else the one
    model with the same type and properties (Stone Soup's sensors make a new measurement model
    object for every scan; ``repr`` lists a model's properties)."""
    by_id = {id(mm): m for m, mm in enumerate(measurement_models)}
    reprs = [repr(mm) for mm in measurement_models]
    by_repr = {r: m for m, r in enumerate(reprs) if reprs.count(r) == 1}

    def index(model) -> int | None:
        found = by_id.get(id(model))
        return by_repr.get(repr(model)) if found is None and model is not None else found

    return index


def _measurement_size(model, m: int) -> int:
    """How many values sensor ``m``'s measurement model measures (its ``ndim_meas``)."""
    size = user_call(f"measurement model {m} ({type(model).__name__}): ndim_meas", getattr, model, "ndim_meas")
    if not isinstance(size, (int, np.integer)) or size < 1:
        raise InputError(f"measurement model {m} ({type(model).__name__}) has ndim_meas {size!r}, not a count")
    return int(size)


def _detection_values(detection: Detection, m: int, size: int) -> np.ndarray:
    """A detection of sensor ``m`` as its ``size`` real values; refused when it holds another number
    of values (stacked, they would be split across the sensors at the wrong places)."""
    what = f"the detection of sensor {m} at {detection.timestamp}"
    values = user_floats(detection.state_vector, what).ravel()
    if values.size != size:
        raise InputError(f"{what} holds {values.size} value(s), but its measurement model "
                         f"({type(detection.measurement_model).__name__}) measures {size}")
    return values


def measurements(detections, measurement_models: Sequence[MeasurementModel], *, truth=None,
                 time_interval: datetime.timedelta | None = None) -> Measurements:
    """Stone Soup detections → the stacked measurements of each time step, in the order of
    ``measurement_models`` (each detection's ``measurement_model`` says which sensor it came from;
    every sensor must report exactly one detection at every time step, the steps ``time_interval``
    apart when it is given; each detection holds as many values as its model measures, its
    ``ndim_meas``). ``truth``: a ``GroundTruthPath`` or states with the same timestamps
    (their state vectors become ``x``). Step 1 of a check is the first timestamp; the prior
    describes the state one interval before it."""
    found = _detections(detections)
    if not found:
        raise InputError("no detections given")
    sensor_of = _sensor_index(measurement_models)
    by_time: dict[datetime.datetime, list] = {}
    for detection in found:
        m = sensor_of(detection.measurement_model)
        if m is None:
            raise InputError(f"a detection at {detection.timestamp} has a measurement model "
                             f"({type(detection.measurement_model).__name__}) that is not one of the "
                             f"{len(measurement_models)} given (clutter, or a sensor left out?)")
        by_time.setdefault(detection.timestamp, [None] * len(measurement_models))
        if by_time[detection.timestamp][m] is not None:
            raise InputError(f"sensor {m} has more than one detection at {detection.timestamp}")
        by_time[detection.timestamp][m] = detection
    timestamps = sorted(by_time)
    for time in timestamps:
        missing = [m for m, d in enumerate(by_time[time]) if d is None]
        if missing:
            raise InputError(f"no detection from sensor(s) {missing} at {time}: every sensor reports once "
                             "per step in a measurements file")
    _spacing(timestamps, None if time_interval is None else _checked_interval(time_interval))
    sizes = [_measurement_size(mm, m) for m, mm in enumerate(measurement_models)]
    y = np.array([np.concatenate([_detection_values(d, m, sizes[m]) for m, d in enumerate(by_time[time])])
                  for time in timestamps])
    x = None
    if truth is not None:
        states = {s.timestamp: s for s in truth}
        absent = [str(t) for t in timestamps if t not in states]
        if absent:
            raise InputError(f"the truth has no state at {absent[0]} ({len(absent)} detection time(s) missing)")
        x = np.array([_floats(states[t].state_vector).ravel() for t in timestamps])
    return Measurements(y, x, tuple(timestamps))


def write_measurements(path, detections, measurement_models: Sequence[MeasurementModel], *, truth=None,
                       time_interval: datetime.timedelta | None = None) -> Path:
    """:func:`measurements` written as the ``.npz`` file ``gpfverify check --measurements`` reads
    (arrays ``y`` and, with the truth, ``x``), atomically; returns the path."""
    from gpfverify.audit.runfile import _atomic_write

    path = Path(path)
    if path.suffix.lower() != ".npz":
        raise InputError(f"a measurements file is an .npz archive, not {path.name}")
    found = measurements(detections, measurement_models, truth=truth, time_interval=time_interval)
    arrays: dict[str, Any] = {"y": found.y} if found.x is None else {"y": found.y, "x": found.x}
    _atomic_write(path, lambda fh: np.savez(fh, **arrays))
    return path


def tracks(fused, start_time: datetime.datetime, time_interval: datetime.timedelta,
           methods: Sequence[str] | None = None, local: bool = True) -> dict[str, Track]:
    """A :func:`~gpfverify.model_fusion.run_fusion` result as Stone Soup tracks: one ``Track`` of
    ``GaussianState`` s per fusion rule (``methods``, default every rule run, keyed by its name)
    and, with ``local``, per sensor's local filter (keys ``"sensor 0"``, ...). Step k is at
    ``start_time + k * time_interval`` (``start_time`` is the prior's time). A rule that failed
    at a step has no state there."""
    interval = _checked_interval(time_interval)
    chosen = tuple(fused.methods if methods is None else methods)
    out: dict[str, Track] = {}
    for method in chosen:
        states = []
        for step in fused.steps:
            if method in step.failed:
                continue
            estimate = step.estimate(method)
            states.append(GaussianState(StateVector(estimate.mean), estimate.cov,
                                        timestamp=start_time + step.k * interval))
        out[method] = Track(states, id=method)
    if local:
        for m in range(len(fused.steps[0].local)):
            out[f"sensor {m}"] = Track([GaussianState(StateVector(s.local[m].mu_e), s.local[m].C_e,
                                                      timestamp=start_time + s.k * interval)
                                        for s in fused.steps], id=f"sensor {m}")
    return out
