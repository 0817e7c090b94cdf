"""GP evidence maximisation written in casadi and solved with IPOPT: a cross-check of
:meth:`GaussianProcess.fit` (L-BFGS-B on hand-written gradients).

For one output with θ = (log ℓ_1..log ℓ_D, log α², log σ_ε²):

    −log p(y | X, θ) = ½ yᵀK⁻¹y + ½ log|K| + (n/2) log 2π,
    K = α² exp(−½ Σ_d (x_id − x_jd)²/ℓ_d²) + σ_ε² I,

with log|K| = 2 Σ log diag(R) from the Cholesky factor RᵀR = K, and the gradient by casadi's
automatic differentiation (independent of the analytic gradient in :mod:`gpfverify.gp.regression`).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

_LOG_2PI = float(np.log(2.0 * np.pi))


def neg_log_evidence_function(x: np.ndarray, y: np.ndarray) -> ca.Function:
    """casadi Function θ (D+2,) -> (−log evidence, its gradient) for data x (n, D), y (n,)."""
    n, d = x.shape
    theta = ca.SX.sym("theta", d + 2)
    scaled: ca.SX | int = 0
    for k in range(d):
        diff = x[:, k][:, None] - x[:, k][None, :]
        scaled = scaled + ca.DM(diff**2) * ca.exp(-2 * theta[k])
    kernel = ca.exp(theta[d]) * ca.exp(-0.5 * scaled) + ca.exp(theta[d + 1]) * ca.DM.eye(n)
    upper = ca.chol(kernel)  # RᵀR = K
    white = ca.solve(ca.transpose(upper), ca.DM(y))  # R⁻ᵀ y
    nll = 0.5 * ca.dot(white, white) + ca.sum1(ca.log(ca.diag(upper))) + 0.5 * n * _LOG_2PI
    return ca.Function("neg_log_evidence", [theta], [nll, ca.gradient(nll, theta)], ["theta"], ["nll", "grad"])


@dataclass(frozen=True)
class IpoptResult:
    theta: np.ndarray
    nll: float
    status: str


def maximise_evidence(x: np.ndarray, y: np.ndarray, start: np.ndarray,
                      box: list[tuple[float, float]]) -> IpoptResult:
    """IPOPT on −log evidence from ``start`` within the box ``box`` on θ (quiet)."""
    theta = ca.SX.sym("theta", len(start))
    nll = neg_log_evidence_function(x, y)(theta)[0]
    solver = ca.nlpsol("evidence", "ipopt", {"x": theta, "f": nll},
                       {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes"})
    lo, hi = np.array([b[0] for b in box]), np.array([b[1] for b in box])
    sol = solver(x0=start, lbx=lo, ubx=hi)
    return IpoptResult(np.array(sol["x"]).ravel(), float(sol["f"]), solver.stats()["return_status"])
