"""filterpy filters as gpfverify systems, and a logged filterpy run as an audit run file
(extra ``gpfverify[filterpy]``).

* :func:`system_from_filters`: one filterpy filter per sensor — all ``KalmanFilter`` (F, H, Q, R,
  x, P) or all ``UnscentedKalmanFilter`` (fx, hx, Q, R, x, P and the sigma points) — → a
  :class:`LocalFilters`: the :class:`~gpfverify.models.StateSpaceModel` (transition and Q shared by
  the filters; sensor m's H_m or hx_m and R_m; the prior of the first filter), the matching
  gpfverify family (``kf`` or ``ukf`` with the filters' α, β, κ) and each filter's own starting
  belief, so that :meth:`LocalFilters.run` runs the same local filters and fuses them.
* **Angles as the filters treat them.** filterpy knows an angle only through the residual the
  user gives it: an output is circular when the filter's ``residual_z`` wraps it — a shift of one
  output by 2π gives a residual of 0 there, not 2π — and a state component when ``residual_x``
  does. ``circular=`` / ``circular_state=`` override what is found.
* :func:`write_run_file`: the per-step records of a centralized filter (on the stacked
  measurement) and of each sensor's filter — filterpy ``Saver`` s, or mappings with the same
  keys — → the run file ``gpfverify audit`` reads (docs/run-file-format.md). filterpy exposes the
  prediction (``x_prior``, ``P_prior``), the posterior (``x``, ``P``), the innovation covariance
  ``S``, the gain ``K``, the residual ``y`` and the measurement ``z``; from them μ_y = z ⊖ y (on
  the circle for angle outputs), C_y = S and C_xy = K S (filterpy's K = C_xy S⁻¹).

What is refused rather than approximated: control inputs (a non-zero ``B``), a process–measurement
correlation (``M``), fading memory (``alpha`` ≠ 1), sigma points other than van der Merwe's scaled
or Julier's, and a square root other than filterpy's default Cholesky factor (gpfverify's sigma
points are the columns of the lower Cholesky factor, filterpy's the rows of the upper: the same
points).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import scipy.linalg
from filterpy.kalman import JulierSigmaPoints, KalmanFilter, MerweScaledSigmaPoints, UnscentedKalmanFilter

from gpfverify.adapters.objects import user_call, user_floats
from gpfverify.angles import TWO_PI, wrap_components
from gpfverify.errors import InputError
from gpfverify.filters.records import Gaussian
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.models.system import Sensor, StateSpaceModel
from gpfverify.tolerances import algebra_rtol


@dataclass(frozen=True)
class LocalFilters:
    """A filterpy system in gpfverify's terms: the ``model``, the Gaussian ``family`` (``"kf"`` or
    ``"ukf"``) with its sigma-point ``params``, and each sensor's starting belief."""

    model: StateSpaceModel
    family: str
    params: SigmaParams
    local_priors: tuple[Gaussian, ...]

    def run(self, ys, **options):
        """:func:`gpfverify.model_fusion.run_fusion` with these local filters (``options``: its keywords,
        e.g. ``methods``); the centre starts from the model's prior."""
        from gpfverify.model_fusion import run_fusion

        return run_fusion(self.model, ys, family=self.family, params=self.params,
                          local_priors=self.local_priors, **options)


def _matrix(value, dim: int, what: str) -> np.ndarray:
    """A filterpy covariance (a scalar means that multiple of the identity, as filterpy reads it)."""
    array = user_floats(value, what)
    if array.ndim == 0 or array.size == 1 and dim > 1:
        return float(array.reshape(())) * np.eye(dim)
    if array.shape != (dim, dim):
        raise InputError(f"{what} has shape {array.shape}, expected ({dim}, {dim})")
    return array


def _agreeing(values: Sequence[np.ndarray], what: str) -> np.ndarray:
    """The one value every filter has for ``what`` (to rounding); InputError naming the first that differs."""
    first = values[0]
    for m, value in enumerate(values[1:], start=1):
        scale = max(float(np.abs(first).max(initial=0.0)), 1.0)
        if value.shape != first.shape or not np.allclose(value, first, rtol=0, atol=algebra_rtol() * scale):
            raise InputError(f"filter {m}'s {what} differs from filter 0's: the sensors' filters must share "
                             f"the system's {what}")
    return first


def _circular_by_residual(residual, reference: np.ndarray, what: str) -> tuple[int, ...]:
    """The components that ``residual(a, b)`` wraps: a shift of component i by 2π gives a residual of
    0 there (an angle) or of 2π (not an angle); anything else is refused."""
    if residual is None or residual is np.subtract:
        return ()
    out = []
    for i in range(reference.size):
        shifted = reference.copy()
        shifted[i] += TWO_PI
        value = user_floats(user_call(what, residual, shifted, reference), f"what {what} returned").ravel()
        if value.size != reference.size:
            raise InputError(f"{what} returned {value.size} values for {reference.size} components")
        tol = algebra_rtol() * (TWO_PI + abs(float(reference[i])))
        if abs(value[i]) <= tol:
            out.append(i)
        elif abs(value[i] - TWO_PI) > tol:
            raise InputError(f"{what} maps a shift of component {i} by 2π to {value[i]:.6g}: neither an angle "
                             "(0) nor a plain difference (2π)")
    return tuple(out)


def _sigma_params(points) -> SigmaParams:
    if isinstance(points, MerweScaledSigmaPoints):
        params = SigmaParams(float(points.alpha), float(points.beta), float(points.kappa))
    elif isinstance(points, JulierSigmaPoints):  # x ± √((n + κ) P), W_0 = κ / (n + κ): α = 1, β = 0
        params = SigmaParams(1.0, 0.0, float(points.kappa))
    else:
        raise InputError(f"sigma points {type(points).__name__} have no gpfverify counterpart: use "
                         "MerweScaledSigmaPoints or JulierSigmaPoints")
    if points.sqrt is not scipy.linalg.cholesky:
        raise InputError("the sigma points' sqrt_method must be filterpy's default (scipy.linalg.cholesky): "
                         "gpfverify's sigma points are that factor's rows")
    return params


def _row_wise(fn, what: str, *args):
    """A filterpy per-state function (one state (D,) in, one vector out; ``what`` names it) over the
    rows of (N, D)."""
    def function(x: np.ndarray) -> np.ndarray:
        return np.array([user_floats(user_call(what, fn, row, *args), f"what {what} returned").ravel()
                         for row in np.asarray(x, dtype=float)])

    return function


def _kalman(filters: Sequence, names: Sequence[str], circular, circular_state) -> LocalFilters:
    dim = filters[0].dim_x
    for m, kf in enumerate(filters):
        if kf.B is not None and np.any(np.asarray(kf.B) != 0):
            raise InputError(f"filter {m} has a control input (B): not part of a gpfverify model")
        if np.any(np.asarray(kf.M) != 0):
            raise InputError(f"filter {m} has a process-measurement correlation (M): not part of a gpfverify model")
        if kf.alpha != 1:
            raise InputError(f"filter {m} has fading memory (alpha = {kf.alpha}): not part of a gpfverify model")
    F = _agreeing([user_floats(kf.F, f"filter {m}'s F", (dim, dim)) for m, kf in enumerate(filters)], "F")
    Q = _agreeing([_matrix(kf.Q, dim, f"filter {m}'s Q") for m, kf in enumerate(filters)], "Q")
    priors = tuple(Gaussian(user_floats(kf.x, f"filter {m}'s x").ravel(), _matrix(kf.P, dim, f"filter {m}'s P"))
                   for m, kf in enumerate(filters))
    sensors = [Sensor(user_floats(kf.H, f"filter {m}'s H", (kf.dim_z, dim)), _matrix(kf.R, kf.dim_z, f"filter {m}'s R"),
                      circular=() if circular is None else circular[m], name=name)
               for m, (kf, name) in enumerate(zip(filters, names))]
    model = StateSpaceModel(F, Q, sensors, priors[0].mean, priors[0].cov,
                            circular_state=() if circular_state is None else circular_state,
                            name=f"filterpy KalmanFilter, {len(filters)} sensors")
    return LocalFilters(model, "kf", SigmaParams(), priors)


def _unscented(filters: Sequence, names: Sequence[str], circular, circular_state) -> LocalFilters:
    first = filters[0]
    dim = first.x.size
    params = _sigma_params(first.points_fn)
    for m, ukf in enumerate(filters[1:], start=1):
        if _sigma_params(ukf.points_fn) != params:
            raise InputError(f"filter {m}'s sigma points {_sigma_params(ukf.points_fn)} differ from filter 0's "
                             f"{params}")
    priors = tuple(Gaussian(user_floats(ukf.x, f"filter {m}'s x").ravel(), _matrix(ukf.P, dim, f"filter {m}'s P"))
                   for m, ukf in enumerate(filters))
    Q = _agreeing([_matrix(ukf.Q, dim, f"filter {m}'s Q") for m, ukf in enumerate(filters)], "Q")
    transition = _row_wise(first.fx, "filter 0's fx", first._dt)
    mean = priors[0].mean
    probe = mean + np.sqrt(np.diag(priors[0].cov)) * np.linspace(-1.0, 1.0, dim)  # a state off the axes
    _agreeing([_row_wise(ukf.fx, f"filter {m}'s fx", ukf._dt)(np.stack([mean, probe]))
               for m, ukf in enumerate(filters)], "transition fx(x, dt)")
    if circular_state is None:
        circular_state = _agreeing_circular([_circular_by_residual(ukf.residual_x, mean, f"filter {m}'s residual_x")
                                             for m, ukf in enumerate(filters)], "angle state components")
    sensors = []
    for m, (ukf, name) in enumerate(zip(filters, names)):
        measure = _row_wise(ukf.hx, f"filter {m}'s hx")
        outputs = circular[m] if circular is not None else _circular_by_residual(
            ukf.residual_z, measure(mean[None, :])[0], f"filter {m}'s residual_z")
        sensors.append(Sensor(measure, _matrix(ukf.R, ukf._dim_z, f"filter {m}'s R"), circular=outputs, name=name))
    model = StateSpaceModel(transition, Q, sensors, mean, priors[0].cov, circular_state=circular_state,
                            name=f"filterpy UnscentedKalmanFilter, {len(filters)} sensors")
    return LocalFilters(model, "ukf", params, priors)


def _agreeing_circular(found: Sequence[tuple[int, ...]], what: str) -> tuple[int, ...]:
    if any(f != found[0] for f in found):
        raise InputError(f"the filters disagree on the {what}: {[list(f) for f in found]}")
    return found[0]


def system_from_filters(filters, *, circular: Sequence[Sequence[int]] | None = None,
                        circular_state: Sequence[int] | None = None) -> LocalFilters:
    """The system and local filters of one filterpy filter per sensor (module docstring):
    ``filters`` a sequence (sensor order) or a mapping name → filter, all ``KalmanFilter`` or all
    ``UnscentedKalmanFilter``. ``circular`` (per sensor, indices of its angle outputs) and
    ``circular_state`` replace what the filters' residual functions show."""
    if isinstance(filters, Mapping):
        names, chosen = [str(n) for n in filters], list(filters.values())
    elif isinstance(filters, (KalmanFilter, UnscentedKalmanFilter)):
        names, chosen = [""], [filters]
    else:
        chosen = list(filters)
        names = [""] * len(chosen)
    if not chosen:
        raise InputError("give one filterpy filter per sensor, got none")
    kinds = {type(f) for f in chosen}
    if circular is not None and len(circular) != len(chosen):
        raise InputError(f"circular needs one entry per sensor ({len(chosen)}), got {len(circular)}")
    if kinds == {KalmanFilter}:
        return _kalman(chosen, names, circular, circular_state)
    if kinds == {UnscentedKalmanFilter}:
        return _unscented(chosen, names, circular, circular_state)
    raise InputError("the sensors' filters must all be filterpy KalmanFilter or all UnscentedKalmanFilter, got "
                     + ", ".join(sorted(k.__name__ for k in kinds)))


# -- a logged run → an audit run file ----------------------------------------------------------------

_LOGGED = ("x_prior", "P_prior", "x", "P", "S", "K", "y", "z")


def _steps(log, what: str) -> dict[str, list[np.ndarray]]:
    """The per-step records of one filter's log (a filterpy Saver or a mapping of sequences)."""
    out = {}
    for key in _LOGGED:
        try:
            values = log[key]
        except (KeyError, TypeError):
            raise InputError(f"{what} has no {key!r}: log every step with filterpy's Saver (saver.save() after "
                             "update)") from None
        out[key] = [np.asarray(v, dtype=float) for v in values]
    lengths = {len(v) for v in out.values()}
    if len(lengths) != 1:
        raise InputError(f"{what} holds {sorted(lengths)} entries for different keys: one per step for each")
    return out


def _moments(step: dict[str, np.ndarray], circular: Sequence[int]) -> dict[str, list]:
    """μ_y = z ⊖ y, C_y = S, C_xy = K S (filterpy's K = C_xy S⁻¹) of one filter at one step."""
    z, y, S, K = step["z"].ravel(), step["y"].ravel(), step["S"], step["K"]
    return {"mu_y": wrap_components(z - y, circular).tolist(), "C_y": S.tolist(), "C_xy": (K @ S).tolist()}


def write_run_file(path, centre, sensors: Sequence, *, model: StateSpaceModel | None = None,
                   ks: Sequence[int] | None = None) -> Path:
    """The audit run file (``.jsonl`` or ``.npz``, docs/run-file-format.md) of a logged filterpy
    run: ``centre`` the log of a filter on the stacked measurement (its prediction is the centre's),
    ``sensors`` the log of each sensor's filter, in sensor order; each a filterpy ``Saver`` saved
    after every update, or a mapping with the keys x_prior, P_prior, x, P, S, K, y, z. ``model``
    (e.g. :attr:`LocalFilters.model`) gives the angle outputs and state components; ``ks`` the
    step indices. Every case is checked by the case reader before the file is written (atomically)."""
    from gpfverify.fusion.caseblock import case_from_dict
    from gpfverify.audit.runfile import write_run

    central = _steps(centre, "the centre's log")
    local = [_steps(log, f"sensor {m}'s log") for m, log in enumerate(sensors)]
    count = len(central["z"])
    if not local or any(len(s["z"]) != count for s in local):
        raise InputError(f"every log needs the same number of steps as the centre's ({count})")
    sensor_circular = [()] * len(local) if model is None else list(model.sensor_circular)
    if len(sensor_circular) != len(local):
        raise InputError(f"the model has {len(sensor_circular)} sensors, the logs {len(local)}")
    stacked = [] if model is None else list(model.circular)
    circular_state = [] if model is None else list(model.circular_state)
    cases = []
    for t in range(count):
        at = {key: values[t] for key, values in central.items()}
        y = at["z"].ravel()
        parts = np.concatenate([s["z"][t].ravel() for s in local])
        if parts.shape != y.shape or not np.allclose(parts, y, rtol=0, atol=algebra_rtol() * max(np.abs(y).max(), 1.0)):
            raise InputError(f"step {t}: the sensors' z stacked differ from the centre's z")
        entry: dict[str, Any] = {"central": {"mu_p": at["x_prior"].ravel().tolist(), "C_p": at["P_prior"].tolist(),
                             **_moments(at, stacked), "sizes": [s["z"][t].size for s in local]},
                 "locals": [], "y": y.tolist()}
        if stacked:
            entry["central"]["circular"] = stacked
        for s, outputs in zip(local, sensor_circular):
            step = {key: values[t] for key, values in s.items()}
            report = {"mu_p": step["x_prior"].ravel().tolist(), **_moments(step, outputs),
                      "mu_e": step["x"].ravel().tolist(), "C_e": step["P"].tolist()}
            if outputs:
                report["circular"] = list(outputs)
            entry["locals"].append(report)
        if circular_state:
            entry["circular_state"] = circular_state
        try:
            cases.append(case_from_dict(entry))
        except InputError as exc:
            raise InputError(f"step {t}: {exc}") from None
    return write_run(path, cases, ks)
