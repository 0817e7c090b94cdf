"""Sensitivity of the DMF mean (eq. 35) to what each sensor reports, by casadi's automatic
differentiation of :func:`~gpfverify.symbolic.casadi_forms.dmf_function`.

For sensor m the Jacobians of μ_DMF with respect to μ_e^m and μ_p^m are ±G_m C_y^m (C_xy^m)⁺, so

    ‖∂μ_DMF/∂μ_e^m‖₂ ≤ ‖G_m C_y^m‖₂ / σ_r(C_xy^m)

(σ_r the smallest singular value kept at the rank tolerance; σ_min for full column rank): a
report whose cross term is nearly rank deficient amplifies any error in its μ_e^m by up to
1/σ_r. The Jacobian with respect to C_xy^m involves the derivative of the pseudo-inverse, up to
‖μ_e^m − μ_p^m‖/σ_min² in general; for a consistent report (μ_e^m − μ_p^m = C_xy^m w_m, in the
range of C_xy^m) the 1/σ² part cancels and it grows like ‖w_m‖/σ_min. For a sensor without full
column rank at the tolerance the pseudo-inverse is taken at that fixed rank (SVD,
:func:`gpfverify.fusion.exactness.kernel_split`) and held constant: the Jacobian with respect to
C_xy^m is then not defined (None).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from gpfverify.fusion.exactness import kernel_split
from gpfverify.symbolic.casadi_forms import REPORTED, dmf_function


@dataclass(frozen=True)
class SensorSensitivity:
    """Sensor ``index``: spectral norms of ∂μ_DMF/∂(reported quantity) (matrices flattened
    column-major by casadi: the norm is of the D × (entries) Jacobian; None where undefined),
    the numerical ``rank`` of C_xy^m, its smallest kept singular value ``sigma_r`` and the bound
    ‖G_m C_y^m‖₂ / σ_r on the μ_e^m Jacobian."""

    index: int
    jacobian_norms: dict[str, float | None]
    rank: int
    sigma_r: float
    mu_e_bound: float


@dataclass(frozen=True)
class DMFJacobians:
    """μ_DMF's Jacobian with respect to every input of the DMF Function, by input name."""

    function: ca.Function
    values: list[np.ndarray]
    by_name: dict[str, np.ndarray]


def dmf_jacobians(case, rank_tol: float | None = None) -> DMFJacobians:
    """Jacobians of μ_DMF at ``case`` (a :class:`~gpfverify.fusion.case.FusionCase`); sensors
    without full column rank at ``rank_tol`` (default ``case.rank_tol``, else numpy's rule) use
    their fixed-rank SVD pseudo-inverse as a constant input."""
    tol = case.rank_tol if rank_tol is None else rank_tol
    splits = [kernel_split(local.C_xy, tol) for local in case.locals]
    given = tuple(m for m, s in enumerate(splits) if not s.rank.full_column_rank)
    dmf = dmf_function(case.state_dim, tuple(case.central.sizes), given)
    c = case.central
    values = [c.mu_p, c.mu_y, c.C_y, c.C_xy]
    for m, local in enumerate(case.locals):
        values += [getattr(local, k) for k in REPORTED] + ([splits[m].pinv] if m in given else [])
    symbols = [ca.SX.sym(dmf.name_in(k), *dmf.size_in(k)) for k in range(dmf.n_in())]
    mean = dmf(*symbols)
    jac = ca.Function("dmf_jac", symbols, [ca.jacobian(mean, ca.vec(s)) for s in symbols])
    names = [dmf.name_in(k) for k in range(dmf.n_in())]
    return DMFJacobians(dmf, values, {n: np.array(j) for n, j in zip(names, jac(*values))})


def dmf_sensitivity(case, rank_tol: float | None = None) -> tuple[SensorSensitivity, ...]:
    """Per-sensor Jacobian norms of the fused mean and the σ_r bound (module docstring)."""
    tol = case.rank_tol if rank_tol is None else rank_tol
    jacobians = dmf_jacobians(case, tol).by_name
    gain = np.linalg.solve(case.central.C_y, case.central.C_xy.T).T
    out = []
    for m, (block, local) in enumerate(zip(case.central.blocks, case.locals)):
        split = kernel_split(local.C_xy, tol)
        fixed_rank = not split.rank.full_column_rank
        norms = {k: (None if fixed_rank and k == "C_xy" else float(np.linalg.norm(jacobians[f"{k}{m}"], 2)))
                 for k in REPORTED}
        rank = split.rank.rank
        sigma_r = float(split.rank.singular_values[rank - 1]) if rank else 0.0
        scale = float(np.linalg.norm(gain[:, block] @ local.C_y, 2))
        out.append(SensorSensitivity(m, norms, rank, sigma_r, scale / sigma_r if rank else float("inf")))
    return tuple(out)
