"""Random fusion cases with known structure, for tests, property tests and benchmarks.

Central prediction: a random joint Gaussian of (x, y¹, …, y^N), so C_y has cross-sensor blocks.
Sensor m: its own local prior N(μ_p^m, C_p^m) and a linear-Gaussian view y^m = H_m x + b_m + v^m
with rank(H_m) = ``ranks[m]`` (default min(D, l_m)), so rank C_xy^m = rank(C_p^m H_mᵀ) is known;
μ_e^m, C_e^m are its exact local update (eq. 32–33) with a y drawn from the local predictive.
``decoupled`` lists stacked measurement indices made uncorrelated with the state and with every
other component (centrally and locally): rank-deficient yet exact for DMF.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gpfverify.fusion.case import CentralPrediction, FusionCase, LocalReport
from gpfverify.linalg import right_solve_spd, symmetrize


def random_spd(rng: np.random.Generator, n: int, floor: float = 0.1) -> np.ndarray:
    """A A ᵀ / n + floor·I with standard normal A (n, n + 2)."""
    a = rng.normal(size=(n, n + 2))
    return symmetrize(a @ a.T / n + floor * np.eye(n))


def random_rank_matrix(rng: np.random.Generator, rows: int, cols: int, rank: int,
                       condition: float | None = None) -> np.ndarray:
    """A (rows, cols) matrix of exactly the given rank: a product of Gaussian factors, or, with
    ``condition``, random orthonormal factors around singular values geomspace(1, 1/condition)."""
    if condition is None:
        return rng.normal(size=(rows, rank)) @ rng.normal(size=(rank, cols))
    u, _ = np.linalg.qr(rng.normal(size=(rows, rank)))
    v, _ = np.linalg.qr(rng.normal(size=(cols, rank)))
    return (u * np.geomspace(1.0, 1.0 / condition, rank)) @ v.T


def _decouple(cov: np.ndarray, indices) -> np.ndarray:
    out = cov.copy()
    for j in indices:
        keep = out[j, j]
        out[j, :] = 0.0
        out[:, j] = 0.0
        out[j, j] = keep
    return out


def random_local(rng, state_dim: int, size: int, rank: int, decoupled=(),
                 condition: float | None = None) -> tuple[LocalReport, np.ndarray]:
    """One sensor's report and its raw measurement y^m (see module docstring); ``condition`` sets
    the spread of H_m's singular values (with C_p^m = I, that of C_xy^m on its range)."""
    mu_p = rng.normal(size=state_dim)
    c_p = np.eye(state_dim) if condition is not None else random_spd(rng, state_dim)
    h = random_rank_matrix(rng, size, state_dim, rank, condition)
    h[list(decoupled)] = 0.0
    r = _decouple(random_spd(rng, size), decoupled)
    c_xy = c_p @ h.T
    c_y = symmetrize(h @ c_p @ h.T + r)
    mu_y = h @ mu_p + rng.normal(size=size)
    y = mu_y + np.linalg.cholesky(c_y) @ rng.normal(size=size)
    k = right_solve_spd(c_xy, c_y)
    local = LocalReport(mu_p=mu_p, mu_y=mu_y, C_y=c_y, C_xy=c_xy, mu_e=mu_p + k @ (y - mu_y),
                        C_e=symmetrize(c_p - k @ c_xy.T))
    return local, y


def random_case(rng: np.random.Generator, state_dim: int, sizes: Sequence[int],
                ranks: Sequence[int] | None = None, decoupled: Sequence[int] = (),
                with_y: bool = True, cross_condition: float | None = None) -> FusionCase:
    """A consistent random :class:`FusionCase` (see module docstring); ``cross_condition`` makes
    every C_xy^m have that condition number on its range."""
    sizes = tuple(int(s) for s in sizes)
    ranks = [min(state_dim, s) for s in sizes] if ranks is None else list(ranks)
    total = sum(sizes)
    joint = random_spd(rng, state_dim + total)
    joint = _decouple(joint, [state_dim + j for j in decoupled])
    central = CentralPrediction(mu_p=rng.normal(size=state_dim), C_p=joint[:state_dim, :state_dim],
                                mu_y=rng.normal(size=total), C_y=joint[state_dim:, state_dim:],
                                C_xy=joint[:state_dim, state_dim:], sizes=sizes)
    locals_, ys, start = [], [], 0
    for size, rank in zip(sizes, ranks):
        mine = [j - start for j in decoupled if start <= j < start + size]
        local, y = random_local(rng, state_dim, size, rank, mine, cross_condition)
        locals_.append(local)
        ys.append(y)
        start += size
    return FusionCase(central, tuple(locals_), np.concatenate(ys) if with_y else None)
