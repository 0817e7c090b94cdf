"""GP residual models: Gaussian processes that learn the difference between a true and an
approximate model from training data (Ko & Fox, GP-UKF 2007 §IV "enhanced GP models"; seed 001
§1.3, eq. 16–19).

For the transition, training pairs (x_k, u_k) -> x_{k+1} and an approximate model f̂ give targets

    r_k = x_{k+1} − f̂(x_k, u_k)                                     (seed 001 eq. 18)

and the corrected model is x_{k+1} = f̂(x_k, u_k) + GP_f(ξ_k) + ε_k with ε_k ~ N(0, Σ_f(ξ_k)),
where ξ_k are the GP's input features and Σ_f the GP *predictive* variance, latent variance plus
the learned noise variance (eq. 19): the noise of the targets — the true process noise — is
learned together with the residual, so Σ_f replaces the nominal Q on the outputs the GP models.
The measurement residual z_k − ĥ(x_k) is handled the same way (Σ_h in place of R).

Features ξ = (x[state_inputs], u): a chosen subset of the state and, optionally, exogenous inputs
(the navigation system's specific force, attitude, ...). Only the ``outputs`` the residual is
known to touch are learned; the others keep the approximate model and the nominal noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gpfverify.errors import InputError
from gpfverify.gp.regression import GaussianProcess
from gpfverify.rng import generator
from gpfverify.validate import as_array


def residual_features(states: np.ndarray, inputs, state_inputs: tuple[int, ...], input_count: int) -> np.ndarray:
    """ξ = (x[state_inputs], u) for states (m, D) and inputs (m, U) or (U,) (broadcast), (m, F)."""
    parts = [states[:, list(state_inputs)]] if state_inputs else []
    if input_count:
        parts.append(np.broadcast_to(np.asarray(inputs, dtype=float), (states.shape[0], input_count)))
    return np.concatenate(parts, axis=1)


def distinct_rows(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(distinct, inverse) with distinct[inverse] == rows, for rows (m, F): a lexicographic sort
    (F stable integer-keyed passes) and a comparison of neighbours — numpy's ``unique(axis=0)``
    sorts a structured view instead, about ten times slower at a few thousand rows. Rows compare
    as floats (−0.0 equals 0.0)."""
    if rows.shape[0] == 0:
        return rows, np.zeros(0, dtype=np.intp)
    order = np.lexsort(rows.T)
    ordered = rows[order]
    starts = np.empty(rows.shape[0], dtype=bool)
    starts[0] = True
    np.any(ordered[1:] != ordered[:-1], axis=1, out=starts[1:])
    inverse = np.empty(rows.shape[0], dtype=np.intp)
    inverse[order] = np.cumsum(starts) - 1
    return ordered[starts], inverse


@dataclass(frozen=True)
class ResidualGP:
    """A fitted residual: ``gp`` maps features (m, F) to the residual of ``outputs`` (E of them).

    ``state_inputs``: indices of the state used as features (may be empty); ``input_count``: how
    many exogenous input columns follow them.
    """

    gp: GaussianProcess
    state_inputs: tuple[int, ...]
    input_count: int
    outputs: tuple[int, ...]

    def features(self, states: np.ndarray, inputs: np.ndarray | None = None) -> np.ndarray:
        return residual_features(states, inputs, self.state_inputs, self.input_count)

    def mean(self, states: np.ndarray, inputs: np.ndarray | None = None) -> np.ndarray:
        """Residual mean GP(ξ) on the learned outputs, (m, E) (unchecked hot path).

        The GP is evaluated once per *distinct* feature row: sigma points of a lower-triangular
        factor differ from the centre only in the states at and below their column, so most of a
        particle's 2D + 1 points share the features of a residual that reads few states."""
        xi = self.features(states, inputs)
        unique, inverse = distinct_rows(xi)
        if unique.shape[0] == xi.shape[0]:
            return self.gp.predict_mean(xi)
        return self.gp.predict_mean(unique)[inverse]

    def noise_var(self, states: np.ndarray, inputs: np.ndarray | None = None) -> np.ndarray:
        """Predictive variance Σ(ξ) = latent variance + learned noise variance, (m, E)."""
        _, latent = self.gp.predict(self.features(states, inputs))
        return latent + self.gp.noise_var

    def add_to(self, approx: np.ndarray, states: np.ndarray, inputs: np.ndarray | None = None) -> np.ndarray:
        """approx (m, D') with the residual mean added on ``outputs``."""
        out = np.array(approx, dtype=float, copy=True)
        out[:, list(self.outputs)] += self.mean(states, inputs)
        return out


def residual_targets(targets: np.ndarray, approx: np.ndarray, outputs) -> np.ndarray:
    """r = target − approximate prediction on ``outputs`` (eq. 18), (n, E)."""
    return (np.asarray(targets, dtype=float) - np.asarray(approx, dtype=float))[:, list(outputs)]


def fit_residual(states, targets, approx, outputs, state_inputs=(), inputs=None,
                 max_points: int | None = None, restarts: int = 2, seed=0) -> ResidualGP:
    """Fit a :class:`ResidualGP` by evidence maximisation.

    states (n, D): the states the targets were produced from; targets (n, D'): true next states
    (transition) or measurements; approx (n, D'): the approximate model at the same states;
    inputs (n, U) or None: exogenous inputs. ``max_points`` keeps a random subset of that size
    (the GP's cost grows as n³ to fit and n per prediction), drawn with ``seed``.
    """
    states = as_array(states, "states", ndim=2)
    n = states.shape[0]
    targets = as_array(targets, "targets", ndim=2)
    approx = as_array(approx, "approx", shape=targets.shape)
    if targets.shape[0] != n:
        raise InputError(f"targets must have {n} rows like states, got {targets.shape[0]}")
    outputs = tuple(int(i) for i in outputs)
    state_inputs = tuple(int(i) for i in state_inputs)
    if not outputs or not all(0 <= i < targets.shape[1] for i in outputs):
        raise InputError(f"outputs must be indices into the {targets.shape[1]} target columns, got {outputs}")
    if not all(0 <= i < states.shape[1] for i in state_inputs):
        raise InputError(f"state_inputs must be indices into the {states.shape[1]} state columns")
    u = None if inputs is None else as_array(inputs, "inputs", ndim=2)
    if u is not None and u.shape[0] != n:
        raise InputError(f"inputs must have {n} rows like states, got {u.shape[0]}")
    input_count = 0 if u is None else u.shape[1]
    if not state_inputs and not input_count:
        raise InputError("a residual GP needs at least one feature (state_inputs or inputs)")
    rng = generator(seed)
    keep = np.arange(n)
    if max_points is not None and n > max_points:
        keep = np.sort(rng.choice(n, size=max_points, replace=False))
    xi = residual_features(states[keep], None if u is None else u[keep], state_inputs, input_count)
    r = residual_targets(targets[keep], approx[keep], outputs)
    gp = GaussianProcess.fit(xi, r, restarts=restarts, seed=rng)
    return ResidualGP(gp, state_inputs, input_count, outputs)
