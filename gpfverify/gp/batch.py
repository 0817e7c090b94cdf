"""A batch of Gaussian processes, one per Monte Carlo run, that advance together.

In the fusion paper's experiments every run learns its own GPs from its own training trajectory
(seed 000 §4): the runs share the GPs' shapes — n training points, E outputs, D inputs — but not
their data or hyperparameters. :class:`GaussianProcessBatch` holds B such GPs stacked along a
leading run axis, so that a filter step of B runs is a few array operations instead of B calls:

* ``predict_mean`` / ``predict`` at points x (B·m, D), run b's m points against run b's GP
  (eq. 5–6; the points of a run are consecutive rows, as a sigma-point filter lays out
  (B, S, D) points flattened);
* ``predict_uncertain_batch`` at inputs N(μ_b, Σ_b), input b against run b's GP (eq. 8–11, 20:
  :func:`gpfverify.gp.moments.moment_match_stack_batch`).

What run b gets depends on run b's GP and inputs alone, never on the other runs in the batch or on
B: every operation is elementwise, a reduction along a trailing axis, an einsum whose sums run over
one run's training points, or a stacked matrix product (one BLAS call per run), and the predictive
variance whitens k* with run b's own Cholesky factor by the same triangular solve a single GP uses
(:meth:`gpfverify.linalg.Cholesky.whiten`). The kernel matrix is the sum of squared scaled
differences scipy's ``cdist`` forms for a single GP, in the same order, and the mean the same einsum,
so a run's numbers equal those of its own :class:`~gpfverify.gp.GaussianProcess` to rounding (and
are the same bits wherever ``cdist`` adds in index order without fused multiply–adds, as the wheels
of scipy 1.17 on x86-64 do).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gpfverify.errors import InputError
from gpfverify.gp.fused import whitened
from gpfverify.gp.moments import MomentMatch, moment_match_stack_batch


def _rows(per_output: np.ndarray) -> np.ndarray:
    """(B, E, m) values as (B·m, E) rows in a new C-ordered array, whatever B (for B = 1 a reshape
    would return a strided view, and numpy's reductions over it may sum in another order)."""
    return np.ascontiguousarray(np.swapaxes(per_output, 1, 2)).reshape(-1, per_output.shape[1])


class GaussianProcessBatch:
    """B GPs of one shape, one per run: ``X`` (B, n, D), ``Y`` (B, n, E), ``lengthscales``
    (B, E, D), ``signal_var`` and ``noise_var`` (B, E), ``beta`` (B, E, n), ``K_inv`` and
    ``factors_t`` (B, E, n, n) — each GP's own arrays (:class:`~gpfverify.gp.GaussianProcess`)
    stacked; ``members`` the GPs themselves, ``runs`` B."""

    def __init__(self, gps: Sequence):
        self.members = tuple(gps)
        if not self.members:
            raise InputError("a GaussianProcessBatch needs at least one GP")
        shapes = {(gp.X.shape, gp.Y.shape) for gp in self.members}
        if len(shapes) != 1:
            raise InputError("the GPs of a batch must share their shapes (training points, inputs, outputs), got "
                             + ", ".join(f"X {x} Y {y}" for x, y in sorted(shapes)))
        def stacked(name: str) -> np.ndarray:
            return np.stack([getattr(gp, name) for gp in self.members])
        self.X, self.Y, self.lengthscales = stacked("X"), stacked("Y"), stacked("lengthscales")
        self.signal_var, self.noise_var, self.beta = stacked("signal_var"), stacked("noise_var"), stacked("beta")
        self.K_inv, self.factors_t = stacked("K_inv"), stacked("factors_t")

    @property
    def runs(self) -> int:
        return len(self.members)

    @property
    def input_dim(self) -> int:
        return self.X.shape[2]

    @property
    def output_dim(self) -> int:
        return self.Y.shape[2]

    def _per_run(self, xs: np.ndarray) -> np.ndarray:
        """Points (B·m, D) as (B, m, D): run b's points are rows b·m … (b + 1)·m − 1."""
        xs = np.asarray(xs, dtype=float)
        if xs.ndim != 2 or xs.shape[1] != self.input_dim or xs.shape[0] % self.runs:
            raise InputError(f"a batch of {self.runs} GPs takes points (B·m, {self.input_dim}) with B = "
                             f"{self.runs}, got {xs.shape}")
        return xs.reshape(self.runs, -1, self.input_dim)

    def kernels(self, xs: np.ndarray) -> np.ndarray:
        """k_a(x_i, X_j) of every run's points against its training inputs: (B, E, m, n), with
        the scaled squared distance Σ_d (x_d/ℓ_d − X_d/ℓ_d)² summed in index order (seed 000 eq. 3)."""
        points = self._per_run(xs)
        inv_ell = 1.0 / self.lengthscales  # (B, E, D)
        left = points[:, None, :, :] * inv_ell[:, :, None, :]  # (B, E, m, D)
        right = self.X[:, None, :, :] * inv_ell[:, :, None, :]  # (B, E, n, D)
        sq = (left[..., :, None, 0] - right[..., None, :, 0]) ** 2
        for d in range(1, self.input_dim):
            sq += (left[..., :, None, d] - right[..., None, :, d]) ** 2
        np.exp(np.multiply(sq, -0.5, out=sq), out=sq)
        return np.multiply(sq, self.signal_var[:, :, None, None], out=sq)

    def predict_mean(self, xs: np.ndarray) -> np.ndarray:
        """Predictive means k*ᵀβ (eq. 5) at points (B·m, D), run by run: (B·m, E)."""
        return self._mean(self.kernels(xs))

    def _mean(self, kernels: np.ndarray) -> np.ndarray:
        # the sum over the training points in the order a single GP's einsum takes (the same bits)
        return np.einsum("bemn,ben->bme", kernels, self.beta).reshape(-1, self.output_dim)

    def predict(self, xs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Latent predictive means and variances (eq. 5–6) at points (B·m, D): each (B·m, E); the
        variance α² − ‖L⁻¹k*‖² whitened by each run's Cholesky factor, one triangular solve per run
        and output as :meth:`GaussianProcess.predict` does (BLAS trsv for one point per run — the
        filters' case, from one compiled loop where it is on (:func:`gpfverify.gp.fused.whitened`) —
        else trsm) and ‖L⁻¹k*‖² by the same einsum: a run's variances are its GP's bits."""
        kernels = self.kernels(xs)  # (B, E, m, n)
        white = whitened(self.factors_t, kernels[:, :, 0]) if kernels.shape[2] == 1 else None
        if white is not None:
            columns = white[..., None]  # (B, E, n, 1), each as the single GP's (n, 1)
            squares = np.einsum("beij,beij->bej", columns, columns)
        else:
            squares = np.empty(kernels.shape[:-1])  # (B, E, m)
            for b, gp in enumerate(self.members):
                for a, chol in enumerate(gp.choleskys):
                    solved = chol.whiten(kernels[b, a].T)
                    squares[b, a] = np.einsum("ij,ij->j", solved, solved)
        var = self.signal_var[:, :, None] - squares
        return self._mean(kernels), np.maximum(_rows(var), 0.0)

    def predict_uncertain(self, mu, Sigma):
        raise InputError("a batch of GPs moment-matches one input per run: use predict_uncertain_batch")

    def predict_uncertain_batch(self, mus: np.ndarray, Sigmas: np.ndarray) -> MomentMatch:
        """Exact moments (eq. 8–11, 20) at N(mus[b], Sigmas[b]) against run b's GP: mus (B, D),
        Sigmas (B, D, D) symmetric positive semidefinite (the filters' beliefs, checked where they
        are made: shapes are checked here, not definiteness)."""
        return moment_match_stack_batch([self], *self.checked_inputs(mus, Sigmas))

    def checked_inputs(self, mus, Sigmas) -> tuple[np.ndarray, np.ndarray]:
        """``mus`` (B, D) and ``Sigmas`` (B, D, D) as float arrays; InputError for other shapes."""
        mus, Sigmas = np.asarray(mus, dtype=float), np.asarray(Sigmas, dtype=float)
        if mus.shape != (self.runs, self.input_dim) or Sigmas.shape != mus.shape + (self.input_dim,):
            raise InputError(f"a batch of {self.runs} GPs takes means ({self.runs}, {self.input_dim}) and "
                             f"covariances ({self.runs}, {self.input_dim}, {self.input_dim}), got {mus.shape} "
                             f"and {Sigmas.shape}")
        return mus, Sigmas
