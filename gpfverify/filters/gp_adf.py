"""GP assumed density filter (GP-ADF; Deisenroth, Huber, Hanebeck, ICML 2009; seed 000 Lemma 1,
eq. 15–19).

The transition function x_k = h(x_{k−1}) + w and the measurement function y = g(x) + v are GPs
trained on data. GP-ADF propagates the belief with the *exact* moments of the GP prediction at a
Gaussian input (:meth:`GaussianProcess.predict_uncertain`, eq. 8–11 and 20):

* prediction (eq. 18–19): μ_p = E[h(x_{k−1})], C_p = Cov[h(x_{k−1})] + Σ_w, with x_{k−1} ~
  N(μ_e, C_e) and Σ_w = diag(σ_ε²) of the transition GP (its learned noise);
* measurement: μ_y = E[g(x_k)], C_y = Cov[g(x_k)] + Σ_v (the measurement GP's learned noise),
  C_xy = Cov[x_k, g(x_k)] (eq. 20), with x_k ~ N(μ_p, C_p);
* update (eq. 15–16): :func:`~gpfverify.filters.update.gaussian_update`.

The model is a :class:`~gpfverify.models.GPModel` (validated when built): its ``transition`` GP
and its ``measurement`` GP (one sensor's GP, or the stack of several, whose joint moments carry
the cross-sensor blocks of centralized fusion). Angle outputs: y − μ_y is wrapped in the update;
angle outputs of μ_y and angle state components (``circular_state``) of μ_p and μ_e are wrapped
to (−π, π]; the GPs are
moment-matched at the belief with its angles on the branch of their training data
(:meth:`GPModel.on_training_branch`: a mean shift by whole turns, which leaves C_xy unchanged).
Beliefs may carry leading batch axes; each belief in a batch is moment-matched separately.
"""

from __future__ import annotations

import numpy as np

from gpfverify.angles import wrap_components
from gpfverify.filters.records import Gaussian, MeasurementMoments, StepRecord
from gpfverify.filters.update import check_belief, gaussian_update
from gpfverify.linalg import symmetrize
from gpfverify.models.learned import GPModel
from gpfverify.models.system import require_model
from gpfverify.runtime import one_blas_thread


def moment_match_batched(gp, belief: Gaussian, name: str = "belief") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact moments of the GP at every belief of a batch: mean (..., E), latent cov (..., E, E),
    cross_cov (..., D, E). ``name`` labels the belief in input errors."""
    belief = check_belief(belief, gp.input_dim, name)
    batch = belief.mean.shape[:-1]
    d, e = gp.input_dim, gp.output_dim
    if not batch:
        mm = gp.predict_uncertain(belief.mean, belief.cov)
        return mm.mean, mm.cov, mm.cross_cov
    if not hasattr(gp, "predict_uncertain_batch"):  # a user's duck-typed GP: one call per belief
        mean, cov, cross = np.empty(batch + (e,)), np.empty(batch + (e, e)), np.empty(batch + (d, e))
        for index in np.ndindex(batch):
            one = gp.predict_uncertain(belief.mean[index], belief.cov[index])
            mean[index], cov[index], cross[index] = one.mean, one.cov, one.cross_cov
        return mean, cov, cross
    mm = gp.predict_uncertain_batch(belief.mean.reshape(-1, d), belief.cov.reshape(-1, d, d))
    return (mm.mean.reshape(batch + (e,)), mm.cov.reshape(batch + (e, e)),
            mm.cross_cov.reshape(batch + (d, e)))


def noise_matrix(gp) -> np.ndarray:
    """diag(σ_ε²) of a GP's learned noise: (E, E), or (B, E, E) for a batch of runs' GPs."""
    return gp.noise_var[..., :, None] * np.eye(gp.output_dim)


def gp_adf_predict(belief: Gaussian, model, *, k: int = 1) -> Gaussian:
    """N(μ_p, C_p), eq. 18–19: moment matching at the belief plus the learned transition noise
    (``k`` is accepted for the common protocol; a GP model does not depend on it)."""
    require_model(model, GPModel, "GP-ADF")
    belief = check_belief(belief, model.state_dim)
    mean, cov, _ = moment_match_batched(model.transition, Gaussian(model.on_training_branch(belief.mean), belief.cov))
    return Gaussian(wrap_components(mean, model.circular_state), symmetrize(cov + noise_matrix(model.transition)))


def gp_adf_measurement(prediction: Gaussian, model, *, k: int = 1) -> MeasurementMoments:
    """(μ_y, C_y, C_xy) at N(μ_p, C_p): exact moments plus the learned measurement noise."""
    require_model(model, GPModel, "GP-ADF")
    gp = model.measurement
    prediction = check_belief(prediction, model.state_dim, "prediction")
    mu_y, cov, cross = moment_match_batched(gp, Gaussian(model.on_training_branch(prediction.mean), prediction.cov),
                                            "prediction")
    return MeasurementMoments(wrap_components(mu_y, model.circular), symmetrize(cov + noise_matrix(gp)), cross)


@one_blas_thread
def gp_adf_step(belief: Gaussian, model, y, *, k: int = 1) -> StepRecord:
    """One GP-ADF predict–update cycle (Lemma 1) on a :class:`~gpfverify.models.GPModel`."""
    prediction = gp_adf_predict(belief, model, k=k)
    return gaussian_update(prediction, gp_adf_measurement(prediction, model, k=k), y, model.circular,
                           model.circular_state)
