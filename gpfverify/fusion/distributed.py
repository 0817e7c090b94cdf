"""Distributed measurement fusion (DMF, seed 000 Proposition 1, eq. 35) on plain arrays.

The centre runs its own prediction (μ_p, C_p, μ_y, C_y, C_xy) and receives from each sensor
μ_p^m, μ_y^m, C_y^m, C_xy^m, μ_e^m. With G = C_xy C_y⁻¹ in column blocks G_m,

    μ_e = μ_p + Σ_m G_m (μ_y^m ⊖ μ_y(m)) + Σ_m G_m C_y^m A_m (μ_e^m − μ_p^m)       (eq. 35)
              [+ Σ_m G_m C_y^m (I − P_m) k_m   with the repair messages k_m, see exactness.py]
    C_e = C_p − G C_xyᵀ                                                                (as CMF)

A_m = (C_xy^m)⁺ is the Moore–Penrose inverse of C_xy^m truncated at the rank the rank rule decides
(:class:`~gpfverify.fusion.exactness.RankRule`), in C_xy^m's own SVD — eq. 35 as the paper writes
it, whichever rule decided the rank (the default ``canonical`` rule decides it without units; the
inverse itself depends on units when the rank is lost, docs/fusion-definitions.md). The unit-free
variant (``unit_free=True``, canonical rule only) truncates in the whitened coordinates instead; it
is reported under its own name, never as DMF. Default rule: an explicit ``rank_rule``, else an
explicit ``rank_tol`` (absolute), else the case's ``rank_tol`` (absolute), else canonical — the
one default of every entry point (the experiments pass their rule explicitly).

Computed as μ_p + G v with v stacked from the per-sensor terms (one product with G). ⊖ wraps the
angle outputs (``locals[m].circular``) to (−π, π]; the local update already wrapped y^m − μ_y^m.
Angle state components (the case's ``circular_state``): μ_e^m − μ_p^m is taken on the circle and
the fused mean's components are wrapped to (−π, π], as CMF's are.
Wrapping the two terms separately can land on another branch than CMF's wrap(y^m − μ_y(m)): see
:func:`~gpfverify.fusion.exactness.branch_offsets`.
"""

from __future__ import annotations

from dataclasses import dataclass
from collections.abc import Sequence

import numpy as np

from gpfverify.angles import difference, wrap_components
from gpfverify.errors import InputError
from gpfverify.fusion.case import FusionCase
from gpfverify.fusion.centralized import fused_covariance, fusion_gain
from gpfverify.fusion.exactness import (FusedScale, RankRule, SensorExactness, analyse_sensors, fused_scale,
                                        resolve_rank_rule)
from gpfverify.runtime import one_blas_thread


@dataclass(frozen=True)
class DMFResult:
    """DMF posterior ``mean`` (D,), ``cov`` (D, D), the central ``gain`` G (D, L), the per-sensor
    exactness evidence, whether repair messages were used, the ``rank_rule`` that decided, whether
    this is the ``unit_free`` variant, and the central step's ``scale`` (:class:`FusedScale`)."""

    mean: np.ndarray
    cov: np.ndarray
    gain: np.ndarray
    sensors: tuple[SensorExactness, ...]
    repaired: bool
    rank_rule: RankRule | None = None
    unit_free: bool = False
    scale: FusedScale | None = None

    @property
    def condition_holds(self) -> bool:
        """Proposition 1's sufficient condition: every C_xy^m has full column rank."""
        return all(s.full_column_rank for s in self.sensors)

    @property
    def exact(self) -> bool:
        """The necessary-and-sufficient condition G_m C_y^m (I − P_m) = 0 for every sensor."""
        return all(s.exact for s in self.sensors)


@one_blas_thread
def dmf_update(case: FusionCase, repair_messages: Sequence[np.ndarray] | None = None,
               rank_tol: float | None = None, rank_rule: RankRule | str | None = None,
               unit_free: bool = False) -> DMFResult:
    """Eq. 35 on ``case`` under ``rank_rule`` (a :class:`~gpfverify.fusion.exactness.RankRule` or
    its string, e.g. ``"numpy"``; or an absolute ``rank_tol``; default the case's ``rank_tol``,
    else canonical); with ``repair_messages`` (one l_m-vector k_m per sensor, from
    :func:`~gpfverify.fusion.exactness.repair_message` under the same rule) the repaired rule that
    equals CMF whatever the ranks. The centre applies the kernel projector I − P_m to each message,
    so the whole w_m works as well as its kernel component. ``unit_free`` computes the unit-free
    variant instead of eq. 35 (canonical rule only)."""
    central = case.central
    gain = fusion_gain(central)
    rule = resolve_rank_rule(case, rank_rule, rank_tol)
    scale = fused_scale(central)
    sensors = analyse_sensors(case, gain, rank_rule=rule, unit_free=unit_free, scale=scale)
    mean = fused_mean(case, gain, sensors, repair_messages)
    return DMFResult(mean, fused_covariance(central, gain), gain, sensors, repair_messages is not None, rule,
                     unit_free, scale)


def fused_mean(case: FusionCase, gain: np.ndarray, sensors: Sequence[SensorExactness],
               repair_messages: Sequence[np.ndarray] | None = None) -> np.ndarray:
    """Eq. 35's mean (repaired with ``repair_messages``) from the sensors' splits already computed
    (:func:`dmf_update`'s; the audit reuses them for the repaired mean)."""
    central = case.central
    if repair_messages is not None and len(repair_messages) != len(case.locals):
        raise InputError(f"repair_messages needs {len(case.locals)} entries, got {len(repair_messages)}")
    parts = []
    for s, block, local in zip(sensors, central.blocks, case.locals):
        recovered = s.split.pinv @ difference(local.mu_e, local.mu_p, case.circular_state)
        if repair_messages is not None:
            k_m = np.asarray(repair_messages[s.index], dtype=float)
            if k_m.shape != local.mu_y.shape:
                raise InputError(f"repair message {s.index} must be the kernel component of w_m "
                                 f"({local.mu_y.shape[0]} entries), got shape {k_m.shape}")
            recovered = recovered + s.split.kernel_component(k_m)
        parts.append(difference(local.mu_y, central.mu_y[block], local.circular) + local.C_y @ recovered)
    return wrap_components(central.mu_p + gain @ np.concatenate(parts), case.circular_state)
