"""Sensitivity of the DMF mean (eq. 35) to what each sensor reports, by casadi's automatic
differentiation of :func:`~gpfverify.symbolic.casadi_forms.dmf_function`.

For sensor m the Jacobians of μ_DMF with respect to μ_e^m and μ_p^m are ±G_m C_y^m (C_xy^m)⁺, so

    ‖∂μ_DMF/∂μ_e^m‖₂ ≤ ‖G_m C_y^m‖₂ / σ_min(C_xy^m)

(the condition-number bound): a report whose cross term is nearly rank deficient amplifies any
error in its μ_e^m by up to 1/σ_min, and the Jacobian with respect to C_xy^m itself grows like
‖μ_e^m − μ_p^m‖ / σ_min² (derivative of the pseudo-inverse).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from gpfverify.errors import InputError
from gpfverify.symbolic.casadi_forms import REPORTED, dmf_function


@dataclass(frozen=True)
class SensorSensitivity:
    """Sensor ``index``: spectral norms of ∂μ_DMF/∂(reported quantity) (matrices flattened
    column-major by casadi: the norm is of the D × (entries) Jacobian), σ_min(C_xy^m) and the
    bound ‖G_m C_y^m‖₂ / σ_min on the μ_e^m Jacobian."""

    index: int
    jacobian_norms: dict[str, float]
    sigma_min: float
    mu_e_bound: float


def _inputs(case) -> list[np.ndarray]:
    c = case.central
    values = [c.mu_p, c.mu_y, c.C_y, c.C_xy]
    for local in case.locals:
        values += [getattr(local, k) for k in REPORTED]
    return values


def dmf_jacobians(case) -> tuple[ca.Function, list[np.ndarray], list[np.ndarray]]:
    """(the DMF Function, its input values, the Jacobian of μ_DMF w.r.t. every input) at ``case``
    (a :class:`~gpfverify.fusion.case.FusionCase`)."""
    d, sizes = case.state_dim, tuple(case.central.sizes)
    for m, (l, local) in enumerate(zip(sizes, case.locals)):
        s = np.linalg.svd(local.C_xy, compute_uv=False)
        if l > d or s[-1] == 0.0:
            raise InputError(f"sensor {m}: C_xy^m ({d}x{l}) has no full column rank; the DMF of eq. 35 "
                             "with (C_xy^m)⁺ = R⁻¹Qᵀ is not defined there")
    dmf = dmf_function(d, sizes)
    values = _inputs(case)
    symbols = [ca.SX.sym(f"in{k}", *dmf.size_in(k)) for k in range(dmf.n_in())]
    mean = dmf(*symbols)
    jac = ca.Function("dmf_jac", symbols, [ca.jacobian(mean, ca.vec(s)) for s in symbols])
    return dmf, values, [np.array(j) for j in jac(*values)]


def dmf_sensitivity(case) -> tuple[SensorSensitivity, ...]:
    """Per-sensor Jacobian norms of the fused mean (see the module docstring). Raises
    :class:`InputError` if some C_xy^m lacks full column rank (l_m > D or a zero singular value)."""
    _, _, jacobians = dmf_jacobians(case)
    gain = np.linalg.solve(case.central.C_y, case.central.C_xy.T).T
    out, start = [], 0
    for m, local in enumerate(case.locals):
        l = local.C_y.shape[0]
        block = jacobians[4 + 5 * m: 9 + 5 * m]
        norms = {name: float(np.linalg.norm(j, 2)) for name, j in zip(REPORTED, block)}
        sigma_min = float(np.linalg.svd(local.C_xy, compute_uv=False)[-1])
        bound = float(np.linalg.norm(gain[:, start:start + l] @ local.C_y, 2)) / sigma_min
        out.append(SensorSensitivity(m, norms, sigma_min, bound))
        start += l
    return tuple(out)
