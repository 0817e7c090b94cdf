"""A stack of GPs with separate training sets, seen as one multi-output GP.

Centralized fusion (seed 000 §3) predicts the stacked measurement y = [y¹; …; y^N] with the stack
of the sensors' measurement GPs. The GPs are independent given x, but at an uncertain input x they
share, so C_y has cross-sensor blocks Cov[f_a, f_b] = β_aᵀ Q^{ab} β_b − M_a M_b
(:func:`gpfverify.gp.moments.moment_match_stack`).
"""

from __future__ import annotations

import numpy as np

from gpfverify.errors import InputError
from gpfverify.gp.moments import MomentMatch, moment_match_stack, moment_match_stack_batch
from gpfverify.gp.regression import checked_batch
from gpfverify.validate import as_covariance, as_vector


class GaussianProcessStack:
    """Duck-type compatible with :class:`~gpfverify.gp.regression.GaussianProcess` for prediction:
    ``predict``, ``predict_mean``, ``predict_uncertain``, ``noise_var``, ``signal_var``,
    ``output_dim``, ``input_dim``; ``sizes`` gives each member's number of outputs."""

    def __init__(self, gps):
        self.gps = tuple(gps)
        if not self.gps:
            raise InputError("a GaussianProcessStack needs at least one GP")
        if len({getattr(gp, "runs", None) for gp in self.gps}) != 1:
            raise InputError("stacked GPs must all be single GPs or all batches of the same runs")
        dims = {gp.input_dim for gp in self.gps}
        if len(dims) != 1:
            raise InputError(f"stacked GPs must share the input dimension, got {sorted(dims)}")

    @property
    def input_dim(self) -> int:
        return self.gps[0].input_dim

    @property
    def sizes(self) -> list[int]:
        return [gp.output_dim for gp in self.gps]

    @property
    def output_dim(self) -> int:
        return sum(self.sizes)

    @property
    def runs(self) -> int | None:
        """B when the members are :class:`~gpfverify.gp.batch.GaussianProcessBatch`\\ es of B runs,
        else None."""
        return getattr(self.gps[0], "runs", None)

    @property
    def noise_var(self) -> np.ndarray:
        """(E,), or (B, E) for a stack of batches."""
        return np.concatenate([gp.noise_var for gp in self.gps], axis=-1)

    @property
    def signal_var(self) -> np.ndarray:
        return np.concatenate([gp.signal_var for gp in self.gps], axis=-1)

    def predict(self, Xs) -> tuple[np.ndarray, np.ndarray]:
        parts = [gp.predict(Xs) for gp in self.gps]
        return np.concatenate([m for m, _ in parts], axis=1), np.concatenate([v for _, v in parts], axis=1)

    def predict_mean(self, Xs: np.ndarray) -> np.ndarray:
        return np.concatenate([gp.predict_mean(Xs) for gp in self.gps], axis=1)

    def predict_uncertain(self, mu, Sigma) -> MomentMatch:
        m = as_vector(mu, "mu", self.input_dim)
        s = as_covariance(Sigma, "Sigma", self.input_dim)
        return moment_match_stack(self.gps, m, s)

    def predict_uncertain_batch(self, mus, Sigmas) -> MomentMatch:
        """Joint moments at many Gaussian inputs (see
        :meth:`GaussianProcess.predict_uncertain_batch`)."""
        if self.runs is not None:  # batches of runs' GPs check what they take (the filters' beliefs)
            return moment_match_stack_batch(self.gps, *self.gps[0].checked_inputs(mus, Sigmas))
        m, s = checked_batch(mus, Sigmas, self.input_dim)
        return moment_match_stack_batch(self.gps, m, s)
