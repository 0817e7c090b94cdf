"""Strategies that reach the corners where slips hide: singular noise, batches cut into chunks of
any sizes, states mixing angles and lengths whose differences exceed π, lists with equal yet
distinct elements (two models with the same ``repr``), unevenly scaled difference steps, and weight
vectors whose effective sample size is known in closed form.

Each draws its object *with* what a property needs to check it independently (the designed rank,
the designed N_eff, the twins' positions), so that no property has to ask the code under test.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from hypothesis import strategies as st

from gpfverify.linalg import symmetrize
from gpfverify.strategies.matrices import as_strategy, float_arrays, log_uniform, orthonormal_matrices


@st.composite
def singular_covariances(draw, dim: int, rank=None, low: float = 1e-2, high: float = 1.0) -> np.ndarray:
    """A PSD (dim, dim) matrix of designed rank r < dim (default: drawn in [0, dim − 1]): Q diag(λ) Qᵀ
    with dim − r eigenvalues exactly zero — noise that is perfectly known along some directions."""
    r = draw(as_strategy(rank if rank is not None else st.integers(0, dim - 1)))
    q = draw(orthonormal_matrices(dim))
    values = np.zeros(dim)
    values[:r] = [draw(log_uniform(low, high)) for _ in range(r)]
    return symmetrize((q * values) @ q.T)


@st.composite
def chunk_sizes(draw, total) -> tuple[int, ...]:
    """Positive chunk sizes adding up to ``total`` (a number or a strategy), uneven and in any order:
    how a batch of runs is cut when it is processed in blocks."""
    n = draw(as_strategy(total))
    cuts = sorted(draw(st.sets(st.integers(1, max(n - 1, 1)), max_size=max(n - 1, 0)))) if n > 1 else []
    bounds = [0, *cuts, n]
    return tuple(b - a for a, b in zip(bounds, bounds[1:]))


@dataclass(frozen=True)
class MixedStates:
    """Two sets of states (N, D) whose components ``angles`` are angles in (−π, π] and the rest
    lengths; ``first − second`` exceeds π in absolute value on at least one length component, and
    the angle components straddle ±π: a routine that wraps a length, or misses an angle, differs."""

    first: np.ndarray
    second: np.ndarray
    angles: tuple[int, ...]

    def difference(self) -> np.ndarray:
        """first − second with the angle components wrapped into (−π, π] (written here, with numpy's
        remainder, independently of gpfverify.angles)."""
        diff = self.first - self.second
        a = list(self.angles)
        diff[:, a] = np.pi - np.remainder(np.pi - diff[:, a], 2.0 * np.pi)
        return diff


@st.composite
def mixed_angle_states(draw, dim=st.integers(2, 4), count=st.integers(1, 6), length_scale: float = 50.0) -> MixedStates:
    """:class:`MixedStates`: at least one angle and one length component; lengths in ±``length_scale``
    with one difference beyond π forced; angles near ±π (within 0.5), on either side of the cut."""
    d, n = draw(as_strategy(dim)), draw(as_strategy(count))
    angles = tuple(sorted(draw(st.sets(st.integers(0, d - 1), min_size=1, max_size=d - 1))))
    first = draw(float_arrays((n, d), -length_scale, length_scale))
    second = draw(float_arrays((n, d), -length_scale, length_scale))
    lengths = [i for i in range(d) if i not in angles]
    beyond = draw(st.sampled_from(lengths))
    jump = draw(st.floats(np.pi + 0.1, 2 * length_scale)) * draw(st.sampled_from([-1.0, 1.0]))
    second[:, beyond] = first[:, beyond] - jump
    for i in angles:
        near_cut = draw(float_arrays((2, n), -0.5, 0.5))
        first[:, i] = np.pi - np.abs(near_cut[0]) if draw(st.booleans()) else -np.pi + np.abs(near_cut[0]) + 1e-3
        second[:, i] = -np.pi + np.abs(near_cut[1]) + 1e-3 if draw(st.booleans()) else np.pi - np.abs(near_cut[1])
    return MixedStates(first, second, angles)


@st.composite
def lists_with_twins(draw, elements: st.SearchStrategy, min_size: int = 2, max_size: int = 5):
    """(items, twins): a list of drawn elements in which at least one element occurs twice as equal
    but distinct objects (``make`` applied to the same parameters twice: two library models with the
    same ``repr``); ``twins`` is the set of positions that have an equal partner."""
    params = draw(st.lists(elements, min_size=min_size - 1, max_size=max_size - 1))
    copy_of = draw(st.integers(0, len(params) - 1))
    at = draw(st.integers(0, len(params)))
    items = [*params[:at], params[copy_of], *params[at:]]
    twins = frozenset(i for i, p in enumerate(items) if sum(q == p for q in items) > 1)
    return items, twins


@st.composite
def uneven_points(draw, dim=st.integers(1, 4), spread: float = 1e4):
    """A point (dim,) whose components differ in size by up to ``spread`` (a central-difference step
    proportional to max(1, |x_j|) is then uneven across the components), zeros and signs included."""
    d = draw(as_strategy(dim))
    sizes = np.array([draw(st.sampled_from([0.0, 1.0])) or draw(log_uniform(1e-3, spread)) for _ in range(d)])
    signs = np.array([draw(st.sampled_from([-1.0, 1.0])) for _ in range(d)])
    return sizes * signs


@dataclass(frozen=True)
class DesignedWeights:
    """Unnormalised log weights (N,) (shuffled, shifted by an arbitrary constant, −inf allowed) whose
    effective sample size 1 / Σ w_i² of the normalised weights is ``ess`` by construction: ``heavy``
    particles share the mass ``share`` equally and the others share 1 − share equally."""

    log_weights: np.ndarray
    heavy: int
    share: float
    ess: float


@st.composite
def weights_with_ess(draw, count=st.integers(2, 40)) -> DesignedWeights:
    """:class:`DesignedWeights`: N_eff = 1 / (s² / k + (1 − s)² / (N − k)), from N (all equal, s = k/N)
    down to 1 (one particle holding every weight, the others exactly zero)."""
    n = draw(as_strategy(count))
    k = draw(st.integers(1, n - 1))
    share = draw(st.one_of(st.just(1.0), st.just(k / n), st.floats(k / n, 1.0)))
    rest = 1.0 - share
    ess = 1.0 / (share**2 / k + rest**2 / (n - k))
    with np.errstate(divide="ignore"):
        logs = np.array([np.log(share / k)] * k + [np.log(rest / (n - k)) if rest > 0 else -np.inf] * (n - k))
    order = np.array(draw(st.permutations(range(n))))
    offset = draw(st.floats(-50.0, 50.0))
    return DesignedWeights(logs[order] + offset, k, share, float(ess))
