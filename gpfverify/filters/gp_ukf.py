"""GP-UKF (Ko, Klein, Fox, Haehnel, IROS 2007; seed 000 eq. 21–31): an unscented Kalman filter
whose models are the *means* of trained GPs and whose noise comes from the GP variances.

* prediction: sigma points X_{k−1} of N(μ_e, C_e) through the transition GP mean (eq. 21);
  Q_k = GP_h^Σ(μ_e) (eq. 22), the transition GP's predictive variance at the previous mean;
  μ_p, C_p by the unscented weights (eq. 23–24);
* measurement: sigma points X̂_k redrawn from N(μ_p, C_p) through the measurement GP mean
  (eq. 25); R_k = GP_g^Σ(μ_p) (eq. 26); μ_y, C_y = … + R_k, C_xy (eq. 27–29);
* update (eq. 30–31): :func:`~gpfverify.filters.update.gaussian_update`.

Interpretation (the text leaves it open): GP^Σ is the predictive variance of a *new noisy target*,
i.e. the latent variance plus the GP's learned noise variance σ_ε², as diagonal matrices, so that
Q and R tend to the learned system and measurement noise where the training data are dense.
Sigma-point parameters default to α = 1, β = 0, κ = 2 (:class:`SigmaParams`). The model is a
:class:`~gpfverify.models.GPModel`; angle outputs and state components are handled as in the UKF
(circular sigma-point means, wrapped deviations and innovation), and the GPs are evaluated with the
angles on the branch of their training data (:meth:`GPModel.on_training_branch`). Beliefs may
carry leading batch axes.
"""

from __future__ import annotations

import numpy as np

from gpfverify.filters.records import Gaussian, MeasurementMoments, StepRecord
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.filters.ukf import unscented_transform
from gpfverify.filters.update import check_belief, gaussian_update
from gpfverify.linalg import symmetrize
from gpfverify.models.learned import GPModel
from gpfverify.models.system import require_model
from gpfverify.runtime import one_blas_thread


def gp_noise_covariance(gp, means: np.ndarray) -> np.ndarray:
    """diag(latent predictive variance + learned noise) of ``gp`` at every mean (..., D):
    (..., E, E) — GP^Σ of eq. 22 and 26 (for a batch of runs' GPs, means (B, D), run b's at b)."""
    _, var = gp.predict(means.reshape(-1, means.shape[-1]))
    total = var.reshape(means.shape[:-1] + (gp.output_dim,)) + gp.noise_var
    return total[..., :, None] * np.eye(gp.output_dim)


def gp_ukf_predict(belief: Gaussian, model, *, k: int = 1, params: SigmaParams = SigmaParams()) -> Gaussian:
    """N(μ_p, C_p), eq. 21–24."""
    require_model(model, GPModel, "GP-UKF")
    gp = model.transition
    belief = check_belief(belief, gp.input_dim)
    mean, cov, _ = unscented_transform(belief, lambda x: gp.predict_mean(model.on_training_branch(x)), params,
                                       model.circular_state, model.circular_state)
    return Gaussian(mean, symmetrize(cov + gp_noise_covariance(gp, model.on_training_branch(belief.mean))))


def gp_ukf_measurement(prediction: Gaussian, model, *, k: int = 1,
                       params: SigmaParams = SigmaParams()) -> MeasurementMoments:
    """(μ_y, C_y, C_xy), eq. 25–29, with sigma points redrawn from N(μ_p, C_p)."""
    require_model(model, GPModel, "GP-UKF")
    gp = model.measurement
    prediction = check_belief(prediction, gp.input_dim, "prediction")
    mu_y, C_y, C_xy = unscented_transform(prediction, lambda x: gp.predict_mean(model.on_training_branch(x)),
                                          params, model.circular_state, model.circular)
    noise = gp_noise_covariance(gp, model.on_training_branch(prediction.mean))
    return MeasurementMoments(mu_y, symmetrize(C_y + noise), C_xy)


@one_blas_thread
def gp_ukf_step(belief: Gaussian, model, y, *, k: int = 1, params: SigmaParams = SigmaParams()) -> StepRecord:
    """One GP-UKF predict–update cycle on a :class:`~gpfverify.models.GPModel`."""
    prediction = gp_ukf_predict(belief, model, k=k, params=params)
    return gaussian_update(prediction, gp_ukf_measurement(prediction, model, k=k, params=params), y,
                           model.circular, model.circular_state)
