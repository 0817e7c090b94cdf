"""Joint Gaussians of a state and N sensors' measurements, (x, y¹, …, y^N), whose cross terms
C_xy^m = Cov[x, y^m] have a designed rank — the object Proposition 1 of seed 000 is about.

Construction (valid by construction, no ``assume``): C_x is drawn SPD with bounded condition;
each C_xy^m = U_m diag(s_m) V_mᵀ (plus zero columns for decoupled components) with singular values
s_m chosen by its *kind*; the measurement covariance is the Schur-complement form

    C_y = C_xyᵀ C_x⁻¹ C_xy + R,   R SPD,

so the joint covariance [[C_x, C_xy], [C_xyᵀ, C_y]] is positive definite whatever C_xy is
(its Schur complement is R). R is either one full SPD matrix (sensor noises correlated) or
block-diagonal (independent sensor noises).

Kinds of cross term (l = l_m, D = state dimension); the guarantees are exact up to rounding:

=============  ==========================  ===============================================
kind           sizes allowed               C_xy^m
=============  ==========================  ===============================================
``full``       1 ≤ l ≤ D                   rank l, singular values in [σ/κ, σ]
``nearly``     1 ≤ l ≤ D                   rank l, smallest singular value σ · sigma_min
``deficient``  2 ≤ l, rank r ∈ [1, min(D, l − 1)]   rank r < l (includes l > D)
``zero``       1 ≤ l                       the zero matrix (rank 0)
``decoupled``  1 ≤ l, k ≥ max(1, l − D)    k measurement components uncorrelated with x and
                                           with every other component (zero columns in C_xy,
                                           zero rows/columns in R but the diagonal); the other
                                           l − k columns have full column rank
=============  ==========================  ===============================================

σ is ``cross_scale`` and κ is ``cross_condition``. ``decoupled`` is column-rank deficient yet
DMF-exact (the kernel of C_xy^m lies in the kernel of G_m C_y^m). With ``decoupled_leak`` ε > 0 a
decoupled component's noise correlates with the others' (R's off-diagonal entries in its row and
column scaled by ε instead of 0): C_xy^m keeps its zero column, but G_m C_y^m no longer vanishes on
it — a designed, O(ε) departure from exactness (ε = 0: exact; ε = 1: R as drawn).
"""

from __future__ import annotations

from dataclasses import dataclass
from collections.abc import Sequence

import numpy as np
from hypothesis import strategies as st

from gpfverify.errors import InputError
from gpfverify.linalg import cholesky, symmetrize
from gpfverify.strategies.matrices import (as_strategy, float_arrays, log_uniform,
                                           matrices_with_singular_values,
                                           spd_matrices, spread_values)

KINDS: tuple[str, ...] = ("full", "nearly", "deficient", "zero", "decoupled")
#: kinds whose cross term has full column rank (mathematically)
FULL_COLUMN_RANK_KINDS = ("full", "nearly")


@dataclass(frozen=True)
class SensorDesign:
    """What was designed for one sensor: ``kind``, measurement ``size`` l, ``rank`` of C_xy^m,
    its non-zero ``singular_values`` (decreasing) and the ``decoupled`` local component indices."""

    kind: str
    size: int
    rank: int
    singular_values: np.ndarray
    decoupled: tuple[int, ...] = ()

    @property
    def full_column_rank(self) -> bool:
        return self.rank == self.size


@dataclass(frozen=True)
class JointGaussian:
    """N([mean_x; mean_y], [[cov_x, cross_cov], [cross_covᵀ, cov_y]]) of (x, y¹, …, y^N):
    mean_x (D,), cov_x (D, D), mean_y (L,), cov_y (L, L), cross_cov (D, L), and one
    :class:`SensorDesign` per sensor (blocks in sensor order)."""

    mean_x: np.ndarray
    cov_x: np.ndarray
    mean_y: np.ndarray
    cov_y: np.ndarray
    cross_cov: np.ndarray
    sensors: tuple[SensorDesign, ...]

    @property
    def state_dim(self) -> int:
        return self.mean_x.shape[0]

    @property
    def sizes(self) -> tuple[int, ...]:
        return tuple(s.size for s in self.sensors)

    @property
    def blocks(self) -> list[slice]:
        ends = np.cumsum((0,) + self.sizes)
        return [slice(int(a), int(b)) for a, b in zip(ends[:-1], ends[1:])]

    @property
    def mean(self) -> np.ndarray:
        return np.concatenate([self.mean_x, self.mean_y])

    @property
    def cov(self) -> np.ndarray:
        return np.block([[self.cov_x, self.cross_cov], [self.cross_cov.T, self.cov_y]])

    def sensor_marginal(self, m: int) -> JointGaussian:
        """The joint Gaussian of (x, y^m) alone."""
        b = self.blocks[m]
        return JointGaussian(self.mean_x, self.cov_x, self.mean_y[b], self.cov_y[b, b],
                             self.cross_cov[:, b], (self.sensors[m],))


def size_range(kind: str, state_dim: int, max_size: int) -> tuple[int, int]:
    """Inclusive range of measurement sizes l that ``kind`` allows (see the module table)."""
    if kind in FULL_COLUMN_RANK_KINDS:
        return 1, min(state_dim, max_size)
    if kind == "deficient":
        return 2, max_size
    if kind in ("zero", "decoupled"):
        return 1, max_size
    raise InputError(f"unknown cross-term kind {kind!r}; choose from {KINDS}")


def check_size(kind: str, size: int, state_dim: int) -> None:
    """:class:`InputError` when a sensor of ``size`` outputs cannot have a cross term of ``kind``."""
    low, high = size_range(kind, state_dim, max(size, 1))
    if not low <= size <= high:
        raise InputError(f"a {kind!r} cross term needs {low} <= l <= {high} at D = {state_dim}, "
                         f"got l = {size}")


@st.composite
def sensor_designs(draw, kind: str, size: int, state_dim: int, cross_scale: float,
                   cross_condition: float, sigma_min: float,
                   decoupled: tuple[int, ...] | None = None) -> SensorDesign:
    """The rank, singular values and decoupled components of one sensor's cross term."""
    check_size(kind, size, state_dim)
    if kind == "full":
        return SensorDesign(kind, size, size, draw(spread_values(size, cross_scale, cross_condition)))
    if kind == "nearly":
        top = draw(spread_values(size - 1, cross_scale, cross_condition)) if size > 1 else np.zeros(0)
        return SensorDesign(kind, size, size, np.concatenate([top, [cross_scale * sigma_min]]))
    if kind == "zero":
        return SensorDesign(kind, size, 0, np.zeros(0))
    if kind == "deficient":
        rank = draw(st.integers(1, min(state_dim, size - 1)))
        return SensorDesign(kind, size, rank, draw(spread_values(rank, cross_scale, cross_condition)))
    if decoupled is None:
        count = draw(st.integers(max(1, size - state_dim), size))
        decoupled = tuple(sorted(draw(st.permutations(range(size)))[:count]))
    rank = size - len(decoupled)
    return SensorDesign(kind, size, rank, draw(spread_values(rank, cross_scale, cross_condition)),
                        tuple(decoupled))


@st.composite
def cross_covariances(draw, state_dim: int, design: SensorDesign) -> np.ndarray:
    """C_xy^m (D, l) with the designed singular values; decoupled columns are exactly zero."""
    coupled = [j for j in range(design.size) if j not in design.decoupled]
    out = np.zeros((state_dim, design.size))
    out[:, coupled] = draw(matrices_with_singular_values(state_dim, len(coupled), design.singular_values))
    return out


@st.composite
def measurement_noise(draw, sizes: Sequence[int], correlated: bool, decoupled: Sequence[int],
                      max_condition: float, scale: float, leak: float = 0.0) -> np.ndarray:
    """R (L, L) SPD: full when ``correlated`` else block-diagonal per sensor; the stacked indices
    ``decoupled`` have zero rows/columns except the diagonal (a principal submatrix of an SPD
    matrix is SPD, so R stays SPD), or, with ``leak`` ε ∈ (0, 1], those off-diagonal entries scaled
    by ε: R = S M S + (I − S²) diag(M) with S = diag(ε on the decoupled indices, 1 elsewhere), SPD
    as the sum of a congruence of the drawn SPD M and a non-negative diagonal (entries between two
    decoupled indices get ε²)."""
    total = sum(sizes)
    if correlated:
        noise = draw(spd_matrices(total, max_condition, scale))
    else:
        noise = np.zeros((total, total))
        start = 0
        for size in sizes:
            noise[start:start + size, start:start + size] = draw(spd_matrices(size, max_condition, scale))
            start += size
    isolated = np.zeros(total, dtype=bool)
    isolated[list(decoupled)] = True
    if leak > 0:
        scaling = np.where(isolated, leak, 1.0)
        return symmetrize(scaling[:, None] * noise * scaling[None, :] + np.diag((1.0 - scaling ** 2) * np.diag(noise)))
    off_diagonal = (isolated[:, None] | isolated[None, :]) & ~np.eye(total, dtype=bool)
    return np.where(off_diagonal, 0.0, noise)


@st.composite
def joint_gaussians_of(draw, state_dim: int, designs: Sequence[SensorDesign],
                       correlated_noise: bool = True, max_condition: float = 1e3,
                       mean_bound: float = 10.0, decoupled_leak: float = 0.0) -> JointGaussian:
    """A :class:`JointGaussian` for fixed per-sensor designs (see the module docstring);
    ``decoupled_leak`` must lie in [0, 1] (:class:`InputError` otherwise)."""
    if not 0.0 <= decoupled_leak <= 1.0:
        raise InputError(f"decoupled_leak must lie in [0, 1], got {decoupled_leak!r}")
    cov_x = draw(spd_matrices(state_dim, max_condition, draw(log_uniform(0.1, 10.0))))
    cross = np.concatenate([draw(cross_covariances(state_dim, d)) for d in designs], axis=1)
    offsets = np.cumsum((0,) + tuple(d.size for d in designs))
    decoupled = [int(offsets[m]) + j for m, d in enumerate(designs) for j in d.decoupled]
    noise = draw(measurement_noise([d.size for d in designs], correlated_noise, decoupled,
                                   max_condition, draw(log_uniform(0.01, 1.0)), decoupled_leak))
    whitened = np.linalg.solve(cholesky(cov_x, "cov_x", allow_jitter=False).factor, cross)
    cov_y = symmetrize(whitened.T @ whitened + noise)
    total = sum(d.size for d in designs)
    return JointGaussian(mean_x=draw(float_arrays((state_dim,), -mean_bound, mean_bound)), cov_x=cov_x,
                         mean_y=draw(float_arrays((total,), -mean_bound, mean_bound)), cov_y=cov_y,
                         cross_cov=cross, sensors=tuple(designs))


@st.composite
def sensor_layouts(draw, state_dim: int, sensors, kinds, max_size: int,
                   sizes: Sequence[int] | None = None) -> tuple[tuple[str, int], ...]:
    """(kind, size) per sensor: ``kinds`` a kind, a sequence of kinds or a strategy of kinds;
    ``sizes`` fixed (checked against the kinds) or drawn within what each kind allows."""
    count = len(sizes) if sizes is not None else draw(as_strategy(sensors))
    if isinstance(kinds, str):
        chosen = [kinds] * count
    elif isinstance(kinds, st.SearchStrategy):
        chosen = [draw(kinds) for _ in range(count)]
    else:
        chosen = list(kinds)
        if len(chosen) != count:
            raise InputError(f"{len(chosen)} kinds given for {count} sensors")
    if sizes is None:
        sizes = []
        for kind in chosen:
            low, high = size_range(kind, state_dim, max_size)
            if low > high:
                raise InputError(f"a {kind!r} cross term needs l >= {low} but max_size is {max_size}")
            sizes.append(draw(st.integers(low, high)))
    for kind, size in zip(chosen, sizes):
        check_size(kind, size, state_dim)
    return tuple(zip(chosen, (int(s) for s in sizes)))


@st.composite
def joint_gaussians(draw, state_dim=st.integers(1, 4), sensors=st.integers(1, 3),
                    kinds=st.sampled_from(KINDS), sizes: Sequence[int] | None = None,
                    max_size: int | None = None, cross_scale=None, cross_condition: float = 1e2,
                    sigma_min: float = 1e-6, correlated_noise=st.booleans(),
                    max_condition: float = 1e3, decoupled_leak=0.0) -> JointGaussian:
    """Joint Gaussians of (x, y¹, …, y^N) with designed cross-term ranks.

    Parameters (ints/floats or strategies where noted):

    * ``state_dim`` D (int or strategy), ``sensors`` N (int or strategy; ignored when ``sizes``
      is given);
    * ``kinds`` — one of :data:`KINDS`, a sequence (one per sensor) or a strategy drawn per sensor;
    * ``sizes`` — fixed l_m (checked against the kinds), else drawn in the kind's range with
      ``max_size`` (default D + 2) as upper bound;
    * ``cross_scale`` σ — largest singular value of each cross term (default log-uniform in
      [0.1, 10]); ``cross_condition`` κ — ratio of its extreme singular values for ``full`` and
      ``deficient``; ``sigma_min`` — smallest singular value of a ``nearly`` term, relative to σ (float or
      strategy, drawn once per joint Gaussian);
    * ``correlated_noise`` — whether R couples the sensors (bool or strategy);
    * ``max_condition`` — bound on the condition numbers of C_x and R;
    * ``decoupled_leak`` — ε of the module docstring (float or strategy, drawn once per joint
      Gaussian; default 0, decoupled components exactly decoupled).

    Guarantees: the joint covariance is symmetric positive definite; every C_xy^m has exactly the
    designed singular values (to rounding); see the module docstring for each kind.
    """
    d = draw(as_strategy(state_dim))
    layout = draw(sensor_layouts(d, sensors, kinds, d + 2 if max_size is None else max_size, sizes))
    scale = draw(log_uniform(0.1, 10.0) if cross_scale is None else as_strategy(cross_scale))
    smallest = float(draw(as_strategy(sigma_min)))
    designs = [draw(sensor_designs(kind, size, d, scale, cross_condition, smallest))
               for kind, size in layout]
    return draw(joint_gaussians_of(d, designs, draw(as_strategy(correlated_noise)), max_condition,
                                   decoupled_leak=float(draw(as_strategy(decoupled_leak)))))
