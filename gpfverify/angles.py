"""Angles on the circle: wrapping, differences and weighted means of angle-valued components.

An output (or state component) marked *circular* is an angle in radians. Every difference of two
such values is taken on the circle and wrapped to (−π, π]:

    wrap(a) = π − ((π − a) mod 2π)                      (wrap(π) = π, wrap(−π) = π)

A weighted mean of angles (a sigma-point or particle mean) is taken relative to a reference value
r (the first point, e.g. the central sigma point):

    mean = wrap(r + Σ_i w_i wrap(a_i − r)),   Σ_i w_i = 1,

which is exactly equivariant under a rotation a ↦ a + φ (the reference rotates with the points)
and equals the ordinary weighted mean whenever all points lie within π of r without crossing the
cut. Unlike atan2(Σ w sin, Σ w cos) it stays well defined for the negative zeroth weight of the
scaled unscented transform, and it equals the linear mean exactly for points that need no wrap.

Other libraries average angles their own way, and a tracker written in one is checked as it is
(:data:`ANGLE_MEANS`, the ``angle_mean`` of :class:`~gpfverify.filters.sigma_points.SigmaParams`):

* ``"reference"`` — the mean above, gpfverify's own;
* ``"atan2"`` — atan2(Σ_i w_i sin a_i, Σ_i w_i cos a_i), Stone Soup's ``Angle.average`` (the
  circular mean of the weighted unit vectors; undefined when they cancel);
* ``"linear"`` — Σ_i w_i a_i as the numbers are, filterpy's default ``x_mean_fn`` / ``z_mean_fn``
  (its ``residual_z`` wraps the deviations but not the mean: points on both sides of the cut
  average to about 0 instead of ±π).

All three agree to second order in the points' spread when no point crosses the cut; each result
is wrapped to (−π, π].

Ground floor: imports nothing from the package.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

TWO_PI = 2.0 * np.pi


def wrap(angle) -> np.ndarray:
    """Angles wrapped to (−π, π]. (π − a) mod 2π rounds to 2π for an a just above π (a tiny
    negative remainder plus 2π), which would give −π: that one value is moved up by 2π (exactly π)."""
    wrapped = np.pi - np.mod(np.pi - np.asarray(angle, dtype=float), TWO_PI)
    return wrapped + np.where(wrapped == -np.pi, TWO_PI, 0.0)


def difference(a, b, circular: Sequence[int]) -> np.ndarray:
    """a − b over the last axis, with the components listed in ``circular`` (distinct indices)
    wrapped to (−π, π]."""
    diff = np.subtract(a, b, dtype=float)
    if len(circular) == 0:
        return diff
    if len(circular) == diff.shape[-1]:  # every component is an angle
        return wrap(diff)
    idx = list(circular)
    diff[..., idx] = wrap(diff[..., idx])
    return diff


def wrap_components(values, circular: Sequence[int]) -> np.ndarray:
    """``values`` with the components listed in ``circular`` (last axis) wrapped to (−π, π]."""
    if len(circular) == 0:
        return np.asarray(values, dtype=float)
    values = np.array(values, dtype=float)
    idx = list(circular)
    values[..., idx] = wrap(values[..., idx])
    return values


#: the weighted means of angles a filter may use (module docstring)
ANGLE_MEANS = ("reference", "atan2", "linear")


def weighted_mean(points: np.ndarray, weights: np.ndarray, circular: Sequence[int],
                  angle_mean: str = "reference") -> np.ndarray:
    """Σ_s w_s points[..., s, :] with the ``circular`` components averaged by ``angle_mean`` (one of
    :data:`ANGLE_MEANS`: by default on the circle relative to the first point; module docstring)
    and wrapped to (−π, π]. points (..., S, E), weights (S,) summing to one."""
    points = np.asarray(points, dtype=float)
    mean = np.einsum("s,...se->...e", weights, points)
    if len(circular):
        idx = list(circular)
        angles = points[..., idx]
        if angle_mean == "reference":
            reference = angles[..., :1, :]
            deviations = wrap(angles - reference)
            mean[..., idx] = wrap(reference[..., 0, :] + np.einsum("s,...se->...e", weights, deviations))
        elif angle_mean == "atan2":
            mean[..., idx] = wrap(np.arctan2(np.einsum("s,...se->...e", weights, np.sin(angles)),
                                             np.einsum("s,...se->...e", weights, np.cos(angles))))
        elif angle_mean == "linear":
            mean[..., idx] = wrap(mean[..., idx])
        else:
            raise ValueError(f"angle_mean must be one of {ANGLE_MEANS}, got {angle_mean!r}")
    return mean
