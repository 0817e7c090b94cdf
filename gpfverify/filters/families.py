"""The Gaussian filter families by name, for code that chooses the filter at run time (fusion over
a user's model, ``gpfverify check``).

Every family has the common protocol: ``predict(belief, model, *, k) -> Gaussian`` and
``measurement(prediction, model, *, k) -> MeasurementMoments``; a step is the shared update
(:func:`~gpfverify.filters.update.gaussian_update`) of the two, with the model's angle outputs
and state components. ``kf``, ``ekf`` and ``ukf`` take a :class:`~gpfverify.models.StateSpaceModel`,
``gp-adf`` and ``gp-ukf`` a :class:`~gpfverify.models.GPModel`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from collections.abc import Callable

from gpfverify.errors import InputError
from gpfverify.filters.ekf import ekf_measurement, ekf_predict
from gpfverify.filters.gp_adf import gp_adf_measurement, gp_adf_predict
from gpfverify.filters.gp_ukf import gp_ukf_measurement, gp_ukf_predict
from gpfverify.filters.kalman import kf_measurement, kf_predict
from gpfverify.filters.records import Gaussian, StepRecord
from gpfverify.filters.sigma_points import SigmaParams, SigmaSettings
from gpfverify.filters.ukf import ukf_measurement, ukf_predict
from gpfverify.filters.update import gaussian_update

FAMILY_NAMES = ("kf", "ekf", "ukf", "gp-adf", "gp-ukf")
#: families whose model is learned (a GPModel)
GP_FAMILIES = ("gp-adf", "gp-ukf")


@dataclass(frozen=True)
class GaussianFamily:
    """A Gaussian filter by name with its prediction and measurement-moment functions."""

    name: str
    predict: Callable
    measurement: Callable

    def step(self, belief: Gaussian, model, y, *, k: int = 1) -> StepRecord:
        """One predict–update cycle."""
        prediction = self.predict(belief, model, k=k)
        return gaussian_update(prediction, self.measurement(prediction, model, k=k), y,
                               model.circular, model.circular_state)


#: the families that draw sigma points (their ``params`` matter)
SIGMA_POINT_FAMILIES = ("ukf", "gp-ukf")


def gaussian_family(name: str, params: SigmaParams | SigmaSettings = SigmaParams()) -> GaussianFamily:
    """The family ``name`` (one of :data:`FAMILY_NAMES`, in any case: ``"GP-ADF"`` as the papers
    and ``results.json`` spell it, or ``"gp-adf"`` as on the command line); ``params`` are the
    sigma-point parameters of the unscented families, one :class:`SigmaParams` for the prediction
    and the update or a :class:`SigmaSettings` with one each."""
    name = name.lower() if isinstance(name, str) else name
    settings = SigmaSettings.of(params)
    if name == "kf":
        return GaussianFamily(name, kf_predict, kf_measurement)
    if name == "ekf":
        return GaussianFamily(name, ekf_predict, ekf_measurement)
    if name == "ukf":
        return GaussianFamily(name, partial(ukf_predict, params=settings.predict),
                              partial(ukf_measurement, params=settings.update))
    if name == "gp-adf":
        return GaussianFamily(name, gp_adf_predict, gp_adf_measurement)
    if name == "gp-ukf":
        return GaussianFamily(name, partial(gp_ukf_predict, params=settings.predict),
                              partial(gp_ukf_measurement, params=settings.update))
    raise InputError(f"filter family must be one of {', '.join(FAMILY_NAMES)}, got {name!r}")
