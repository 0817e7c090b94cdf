"""Local estimates (x_m, P_m) of one state with an admissible joint error covariance, for the
covariance-based fusion baselines (CC/CW, CI, RCC-CI).

The estimation errors e_m = x_m − x of N sensors have a joint covariance J (N·D, N·D) whose
diagonal blocks are the reported P_m. J is *admissible* when it is positive semidefinite; it is
drawn as

    J = (1 − c) · B + c · (𝟙𝟙ᵀ ⊗ S),   B SPD (N·D), S SPD (D), c ∈ [0, 1],

a convex combination of PSD matrices (so PSD by construction): c = 0 gives arbitrary correlation
from B, c → 1 makes the errors identical (fully correlated, J singular). Every P_m = J_mm is
positive definite because B and S are.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from hypothesis import strategies as st

from gpfverify.angles import wrap
from gpfverify.filters.records import Gaussian
from gpfverify.linalg import symmetrize
from gpfverify.strategies.matrices import as_strategy, float_arrays, spd_matrices, unit_floats


@dataclass(frozen=True)
class CorrelatedEstimates:
    """``estimates`` (x_m, P_m) per sensor and the admissible joint error covariance
    ``joint_cov`` (N·D, N·D) whose diagonal blocks are the P_m; ``shared_weight`` is c."""

    estimates: tuple[Gaussian, ...]
    joint_cov: np.ndarray
    shared_weight: float

    @property
    def state_dim(self) -> int:
        return self.estimates[0].mean.shape[0]

    def error_cov_of(self, gains) -> np.ndarray:
        """Covariance of Σ_m W_m e_m for gains W_m (D, D): Σ_mn W_m J_mn W_nᵀ — the true error
        covariance of the linear fusion x̂ = Σ_m W_m x_m when Σ_m W_m = I."""
        w = np.concatenate([np.asarray(g, dtype=float) for g in gains], axis=1)
        return symmetrize(w @ self.joint_cov @ w.T)


@st.composite
def correlated_estimates(draw, count=st.integers(2, 4), state_dim=st.integers(1, 4),
                         max_condition: float = 1e3, shared_weight=None,
                         mean_bound: float = 10.0) -> CorrelatedEstimates:
    """N local estimates with an admissible cross-correlation (see the module docstring).

    ``count`` N and ``state_dim`` D are ints or strategies; ``max_condition`` bounds the condition
    numbers of B and S (hence every P_m's is ≤ max_condition); ``shared_weight`` c is a float in
    [0, 1] or a strategy (default: drawn in [0, 1]). Means are drawn in [−mean_bound, mean_bound].
    Guarantees: every P_m symmetric positive definite; J symmetric PSD with J_mm = P_m.
    """
    n, d = draw(as_strategy(count)), draw(as_strategy(state_dim))
    c = float(draw(unit_floats(0.0, 1.0) if shared_weight is None else as_strategy(shared_weight)))
    base = draw(spd_matrices(n * d, max_condition))
    shared = draw(spd_matrices(d, max_condition))
    joint = symmetrize((1.0 - c) * base + c * np.kron(np.ones((n, n)), shared))
    means = draw(float_arrays((n, d), -mean_bound, mean_bound))
    estimates = tuple(Gaussian(means[m], joint[m * d:(m + 1) * d, m * d:(m + 1) * d].copy())
                      for m in range(n))
    return CorrelatedEstimates(estimates, joint, c)


def estimate_pairs(state_dim=st.integers(1, 4), **options) -> st.SearchStrategy[CorrelatedEstimates]:
    """Two local estimates with an admissible cross-correlation (options of
    :func:`correlated_estimates`)."""
    return correlated_estimates(count=2, state_dim=state_dim, **options)


@dataclass(frozen=True)
class AngleEstimates:
    """Correlated local estimates (``drawn``) whose ``circular_state`` components are angles that
    straddle the ±π cut."""

    drawn: CorrelatedEstimates
    circular_state: tuple[int, ...]

    @property
    def estimates(self) -> tuple[Gaussian, ...]:
        return self.drawn.estimates

    def rotated(self, angle: float) -> tuple[Gaussian, ...]:
        """The estimates with every angle component turned by ``angle`` (wrapped)."""
        idx = list(self.circular_state)
        out = []
        for e in self.estimates:
            mean = e.mean.copy()
            mean[idx] = wrap(mean[idx] + angle)
            out.append(Gaussian(mean, e.cov))
        return tuple(out)


@st.composite
def estimates_across_the_cut(draw, count=st.integers(2, 4), state_dim=st.integers(1, 4),
                             max_condition: float = 1e3, spread: float = 0.5) -> AngleEstimates:
    """:func:`correlated_estimates` with one or more components made angles near ±π: sensor m's
    angle is wrap(π + δ_m), δ_m drawn in [−spread, spread] (spread < π/2, so the local angles lie
    within half a turn of each other and, for most draws, on both sides of the cut)."""
    drawn = draw(correlated_estimates(count, state_dim, max_condition))
    d = drawn.state_dim
    angles = tuple(sorted(draw(st.sets(st.integers(0, d - 1), min_size=1, max_size=d))))
    offsets = draw(float_arrays((len(drawn.estimates), len(angles)), -spread, spread))
    estimates = []
    for e, delta in zip(drawn.estimates, offsets):
        mean = e.mean.copy()
        mean[list(angles)] = wrap(np.pi + delta)
        estimates.append(Gaussian(mean, e.cov))
    return AngleEstimates(CorrelatedEstimates(tuple(estimates), drawn.joint_cov, drawn.shared_weight), angles)
