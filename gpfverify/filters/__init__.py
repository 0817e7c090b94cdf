"""Filters as pure step functions on typed records, one protocol for all:

    step(belief, model, measurement, *, k, rng, <parameters>) -> record,  record.posterior = next belief

Gaussian beliefs (:class:`Gaussian`) for the KF, EKF, UKF, GP-ADF and GP-UKF (records:
:class:`StepRecord`), square-root Gaussian beliefs (:class:`SqrtGaussian`) for the SR-UKF. The
model is a :class:`gpfverify.models.StateSpaceModel` (a :class:`gpfverify.models.GPModel` for the
GP families). :func:`run_filter` iterates any step over a measurement sequence.
"""

from gpfverify.filters.driver import FilterRun, run_filter
from gpfverify.filters.ekf import ekf_measurement, ekf_predict, ekf_step
from gpfverify.filters.families import FAMILY_NAMES, GaussianFamily, gaussian_family
from gpfverify.filters.gp_adf import gp_adf_measurement, gp_adf_predict, gp_adf_step
from gpfverify.filters.gp_ukf import gp_ukf_measurement, gp_ukf_predict, gp_ukf_step
from gpfverify.filters.kalman import kf_measurement, kf_predict, kf_step
from gpfverify.filters.records import Gaussian, MeasurementMoments, StepRecord
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.filters.sr_ukf import SqrtGaussian, SqrtStepRecord, sr_ukf_step
from gpfverify.filters.ukf import ukf_measurement, ukf_predict, ukf_step
from gpfverify.filters.update import gaussian_update

__all__ = ["FilterRun", "run_filter", "ekf_measurement", "ekf_predict", "ekf_step", "FAMILY_NAMES",
           "GaussianFamily", "gaussian_family", "gp_adf_measurement", "gp_adf_predict", "gp_adf_step",
           "gp_ukf_measurement", "gp_ukf_predict", "gp_ukf_step", "kf_measurement", "kf_predict", "kf_step",
           "Gaussian", "MeasurementMoments", "StepRecord", "SigmaParams", "SqrtGaussian", "SqrtStepRecord",
           "sr_ukf_step", "ukf_measurement", "ukf_predict", "ukf_step", "gaussian_update"]
