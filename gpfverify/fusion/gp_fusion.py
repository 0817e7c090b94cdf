"""CMF and DMF with GP models (seed 000 §3): GP-ADF and GP-UKF versions.

The central measurement model is the stack of the sensors' measurement GPs
(:class:`~gpfverify.gp.GaussianProcessStack`): one GP per output with a shared uncertain input, so
the central C_y carries cross-sensor blocks.

* :func:`cmf_step`: the chosen filter's prediction from the fused belief, the stacked measurement
  moments, and the update with the stacked y (eq. 15–16 / 30–31).
* :func:`dmf_step`: the centre's own prediction and stacked moments from the previous fused
  posterior, then eq. 35 with each sensor's local record (μ_p^m, μ_y^m, C_y^m, C_xy^m, μ_e^m),
  C_e as in CMF. Returns the fused record and the per-sensor rank/exactness diagnostics.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import Sequence

import numpy as np

from gpfverify.errors import InputError
from gpfverify.filters.gp_adf import gp_adf_measurement, gp_adf_predict
from gpfverify.filters.gp_ukf import gp_ukf_measurement, gp_ukf_predict
from gpfverify.filters.records import Gaussian, MeasurementMoments, StepRecord
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.filters.update import gaussian_update
from gpfverify.fusion.case import CentralPrediction, FusionCase, LocalReport
from gpfverify.fusion.distributed import DMFResult, dmf_update
from gpfverify.gp import GaussianProcessStack
from gpfverify.validate import as_vector

METHODS = ("gp-adf", "gp-ukf")


def _filter(method: str, params: SigmaParams):
    if method == "gp-adf":
        return gp_adf_predict, gp_adf_measurement
    if method == "gp-ukf":
        return partial(gp_ukf_predict, params=params), partial(gp_ukf_measurement, params=params)
    raise InputError(f"method must be one of {METHODS}, got {method!r}")


def central_prediction(belief: Gaussian, transition_gp, sensor_gps: Sequence, method: str = "gp-adf",
                       params: SigmaParams = SigmaParams()) -> tuple[Gaussian, CentralPrediction]:
    """The centre's prediction N(μ_p, C_p) and stacked measurement moments from a fused belief."""
    predict, measure = _filter(method, params)
    stack = GaussianProcessStack(sensor_gps)
    prediction = predict(belief, transition_gp)
    moments = measure(prediction, stack)
    return prediction, CentralPrediction(prediction.mean, prediction.cov, moments.mu_y, moments.C_y,
                                         moments.C_xy, tuple(stack.sizes))


def cmf_step(belief: Gaussian, transition_gp, sensor_gps: Sequence, y, method: str = "gp-adf",
             params: SigmaParams = SigmaParams()) -> StepRecord:
    """One centralized-fusion cycle with the stacked measurement ``y`` (L,)."""
    prediction, central = central_prediction(belief, transition_gp, sensor_gps, method, params)
    return gaussian_update(prediction, MeasurementMoments(central.mu_y, central.C_y, central.C_xy), y)


@dataclass(frozen=True)
class DMFStep:
    """The fused ``record`` (central prediction and moments, DMF posterior), the fusion ``case``
    the centre saw and the eq. 35 ``result`` with per-sensor rank/exactness diagnostics."""

    record: StepRecord
    case: FusionCase
    result: DMFResult


def dmf_step(central_belief: Gaussian, local_records: Sequence[StepRecord], transition_gp,
             sensor_gps: Sequence, method: str = "gp-adf", params: SigmaParams = SigmaParams(),
             y=None, rank_tol: float | None = None) -> DMFStep:
    """One distributed-fusion cycle (eq. 35). ``local_records[m]`` is sensor m's step record from
    its own filter; ``y`` (stacked, optional) is kept in the case for gap diagnostics only."""
    if len(local_records) != len(sensor_gps):
        raise InputError(f"{len(sensor_gps)} sensor GPs but {len(local_records)} local records")
    _, central = central_prediction(central_belief, transition_gp, sensor_gps, method, params)
    locals_ = tuple(LocalReport(r.mu_p, r.mu_y, r.C_y, r.C_xy, r.mu_e, r.C_e) for r in local_records)
    for m, (r, size) in enumerate(zip(locals_, central.sizes)):
        if r.C_xy.shape != (central.mu_p.shape[0], size):
            raise InputError(f"local record {m} has C_xy of shape {r.C_xy.shape}, expected "
                             f"{(central.mu_p.shape[0], size)}")
    stacked = None if y is None else as_vector(y, "y", int(np.sum(central.sizes)))
    case = FusionCase(central, locals_, stacked, rank_tol)
    result = dmf_update(case)
    record = StepRecord(central.mu_p, central.C_p, central.mu_y, central.C_y, central.C_xy,
                        result.mean, result.cov)
    return DMFStep(record, case, result)
