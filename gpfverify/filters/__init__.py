"""Filters as pure step functions on typed records, one protocol for all:

    step(belief, model, measurement, *, k, rng, <parameters>) -> record,  record.posterior = next belief

Gaussian beliefs (:class:`Gaussian`) for the KF, EKF, UKF, GP-ADF and GP-UKF (records:
:class:`StepRecord`), square-root Gaussian beliefs (:class:`SqrtGaussian`) for the SR-UKF, weighted
particles (:class:`Particles`, records :class:`ParticleStep`) for the PF, UPF, GPSR-UPF, EDH,
IE-PFF and the track-before-detect filters (:mod:`gpfverify.filters.tbd`). The model is a
:class:`gpfverify.models.StateSpaceModel` (a :class:`gpfverify.models.GPModel` for the GP
families). :func:`run_filter` iterates any step over a measurement sequence; every particle filter
resamples with :func:`systematic_resample` when N_eff < threshold · N (default
:data:`RESAMPLE_THRESHOLD`).
"""

from gpfverify.filters.driver import FilterRun, run_filter
from gpfverify.filters.ekf import ekf_measurement, ekf_predict, ekf_step
from gpfverify.filters.families import FAMILY_NAMES, GaussianFamily, gaussian_family
from gpfverify.filters.flows import edh_step, exponential_steps, ie_pff_step, uniform_steps
from gpfverify.filters.gp_adf import gp_adf_measurement, gp_adf_predict, gp_adf_step
from gpfverify.filters.gp_ukf import gp_ukf_measurement, gp_ukf_predict, gp_ukf_step
from gpfverify.filters.gpsr_upf import GPResidualModel, gpsr_upf_step, sr_ukf_proposal
from gpfverify.filters.kalman import kf_measurement, kf_predict, kf_step
from gpfverify.filters.pf import pf_step
from gpfverify.filters.records import Gaussian, MeasurementMoments, StepRecord
from gpfverify.filters.resampling import (RESAMPLE_THRESHOLD, Particles, ParticleStep, effective_sample_size,
                                          systematic_resample)
from gpfverify.filters.sigma_points import SigmaParams, SigmaSettings
from gpfverify.filters.sr_ukf import SqrtGaussian, SqrtStepRecord, sr_ukf_step
from gpfverify.filters.ukf import ukf_measurement, ukf_predict, ukf_step
from gpfverify.filters.update import gaussian_update
from gpfverify.filters.upf import ukf_proposal, upf_step

__all__ = ["FilterRun", "run_filter", "ekf_measurement", "ekf_predict", "ekf_step", "FAMILY_NAMES",
           "GaussianFamily", "gaussian_family", "gp_adf_measurement", "gp_adf_predict", "gp_adf_step",
           "gp_ukf_measurement", "gp_ukf_predict", "gp_ukf_step", "kf_measurement", "kf_predict", "kf_step",
           "Gaussian", "MeasurementMoments", "StepRecord", "SigmaParams", "SigmaSettings", "SqrtGaussian",
           "SqrtStepRecord", "sr_ukf_step", "ukf_measurement", "ukf_predict", "ukf_step", "gaussian_update",
           "edh_step", "exponential_steps", "ie_pff_step", "uniform_steps", "GPResidualModel", "gpsr_upf_step",
           "sr_ukf_proposal", "pf_step", "RESAMPLE_THRESHOLD", "Particles", "ParticleStep",
           "effective_sample_size", "systematic_resample", "ukf_proposal", "upf_step"]
