"""Fusion cases (CONTRACT.md, "Fusion-case files") drawn from designed joint Gaussians.

A drawn case is one fusion step of seed 000 §3 that is *consistent*: the centre's prediction is a
:class:`~gpfverify.strategies.gaussians.JointGaussian` of (x, y¹, …, y^N); each sensor's report is
the exact local update (eq. 32–33) of its own joint Gaussian of (x, y^m) with the measurement y^m
drawn from the centre's predictive N(μ_y, C_y). Two kinds of local prior:

* ``shared`` — the sensor's prior is the centre's marginal: μ_p^m = μ_p, C_y^m and C_xy^m are the
  centre's blocks (the setting of Proposition 1 at the first step);
* ``independent`` — the sensor runs its own filter: its joint Gaussian is drawn separately with
  the same cross-term design (kind, size, rank, decoupled components) as the centre's block.

The designed rank of each *local* C_xy^m is what decides the DMF condition. Whether DMF is exact
is known by construction for ``full``/``nearly``/``decoupled`` sensors (exact) and for a single
sensor with a shared prior (G C_y (I − P) = C_xy (I − P) = 0, exact for every kind); otherwise
it depends on the drawn numbers (:attr:`DrawnCase.exact_by_design` is ``None``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from hypothesis import strategies as st

from gpfverify.filters.records import Gaussian, MeasurementMoments
from gpfverify.filters.update import gaussian_update
from gpfverify.fusion.case import CentralPrediction, FusionCase, LocalReport, case_to_dict
from gpfverify.linalg import cholesky
from gpfverify.strategies.gaussians import (FULL_COLUMN_RANK_KINDS, KINDS, JointGaussian,
                                            joint_gaussians, joint_gaussians_of)
from gpfverify.strategies.matrices import as_strategy, float_arrays

PRIORS: tuple[str, ...] = ("shared", "independent")
#: standard deviations of the drawn measurement around its predictive mean, per component
MEASUREMENT_SPREAD = 3.0


@dataclass(frozen=True)
class DrawnCase:
    """A drawn :class:`~gpfverify.fusion.case.FusionCase` with its design: the centre's joint
    Gaussian, each sensor's own joint Gaussian of (x, y^m), and the kind of local prior."""

    case: FusionCase
    central: JointGaussian
    local_joints: tuple[JointGaussian, ...]
    prior: str

    @property
    def kinds(self) -> tuple[str, ...]:
        return tuple(j.sensors[0].kind for j in self.local_joints)

    @property
    def ranks(self) -> tuple[int, ...]:
        """Designed rank of each sensor's local C_xy^m."""
        return tuple(j.sensors[0].rank for j in self.local_joints)

    @property
    def condition_holds_by_design(self) -> bool:
        """Proposition 1's condition: every local C_xy^m has full column rank (mathematically)."""
        return all(j.sensors[0].full_column_rank for j in self.local_joints)

    @property
    def exact_by_design(self) -> bool | None:
        """True when DMF = CMF for every y by construction, None when the design leaves it open."""
        if self.prior == "shared" and len(self.local_joints) == 1:
            return True
        if all(k in FULL_COLUMN_RANK_KINDS + ("decoupled",) for k in self.kinds):
            return True
        return None

    def to_dict(self) -> dict:
        """The case in the CONTRACT.md JSON form (read back by ``gpfverify audit``)."""
        return case_to_dict(self.case)


def local_report(joint: JointGaussian, y_m: np.ndarray) -> LocalReport:
    """Sensor report: the exact update (eq. 32–33) of the joint Gaussian of (x, y^m) with y^m."""
    record = gaussian_update(Gaussian(joint.mean_x, joint.cov_x),
                             MeasurementMoments(joint.mean_y, joint.cov_y, joint.cross_cov), y_m)
    return LocalReport(mu_p=joint.mean_x, mu_y=joint.mean_y, C_y=joint.cov_y, C_xy=joint.cross_cov,
                       mu_e=record.mu_e, C_e=record.C_e)


def central_prediction(joint: JointGaussian) -> CentralPrediction:
    return CentralPrediction(mu_p=joint.mean_x, C_p=joint.cov_x, mu_y=joint.mean_y, C_y=joint.cov_y,
                             C_xy=joint.cross_cov, sizes=joint.sizes)


@st.composite
def measurements(draw, joint: JointGaussian) -> np.ndarray:
    """y = μ_y + chol(C_y) z with z ∈ [−3, 3]^L (shrinks to y = μ_y)."""
    z = draw(float_arrays((joint.mean_y.shape[0],), -MEASUREMENT_SPREAD, MEASUREMENT_SPREAD))
    return joint.mean_y + cholesky(joint.cov_y, "C_y", allow_jitter=False).factor @ z


@st.composite
def cases_from_joint(draw, central: JointGaussian, prior: str, with_y: bool = True,
                     correlated_noise=st.booleans(), max_condition: float = 1e3) -> DrawnCase:
    """A consistent case around the centre's joint Gaussian (see the module docstring)."""
    y = draw(measurements(central))
    if prior == "shared":
        local_joints = tuple(central.sensor_marginal(m) for m in range(len(central.sensors)))
    else:
        local_joints = tuple(draw(joint_gaussians_of(central.state_dim, [design],
                                                     draw(as_strategy(correlated_noise)),
                                                     max_condition))
                             for design in central.sensors)
    reports = tuple(local_report(j, y[b]) for j, b in zip(local_joints, central.blocks))
    case = FusionCase(central_prediction(central), reports, y if with_y else None)
    return DrawnCase(case, central, local_joints, prior)


@st.composite
def fusion_cases(draw, state_dim=st.integers(1, 4), sensors=st.integers(1, 3),
                 kinds=st.sampled_from(KINDS), sizes=None, max_size: int | None = None,
                 prior=st.sampled_from(PRIORS), with_y: bool = True, cross_scale=None,
                 cross_condition: float = 1e2, sigma_min: float = 1e-6,
                 correlated_noise=st.booleans(), max_condition: float = 1e3, decoupled_leak=0.0) -> DrawnCase:
    """Consistent fusion cases with designed cross-term ranks, as :class:`DrawnCase`.

    ``prior`` is ``"shared"``, ``"independent"`` or a strategy of those; ``with_y`` includes the
    stacked measurement; every other parameter is that of
    :func:`~gpfverify.strategies.gaussians.joint_gaussians`. Guarantees: the case passes
    :func:`~gpfverify.fusion.caseblock.case_from_dict` validation (C_y, C_y^m positive definite), each
    local C_xy^m has its designed singular values, and each local posterior is the exact local
    update with the case's y.
    """
    central = draw(joint_gaussians(state_dim, sensors, kinds, sizes, max_size, cross_scale,
                                   cross_condition, sigma_min, correlated_noise, max_condition, decoupled_leak))
    return draw(cases_from_joint(central, draw(as_strategy(prior)), with_y, correlated_noise,
                                 max_condition))


def fusion_case_files(**options) -> st.SearchStrategy[dict]:
    """Fusion cases as JSON-able dicts in exactly the CONTRACT.md format (the keyword options are
    those of :func:`fusion_cases`)."""
    return fusion_cases(**options).map(DrawnCase.to_dict)


def case_of_estimates(estimates, circular_state=()) -> FusionCase:
    """Local estimates (x_m, P_m) as one fusion step whose sensors' posteriors are exactly them, so
    that ``gpfverify fuse CASE --method cc|ci|rcc-ci`` fuses these estimates and ``gpfverify audit``
    reads the step. Each sensor m measures the whole state, y^m = x + v^m, with independent noise
    R_m = P_m + P_m (C_p − P_m)⁻¹ P_m under the common prior N(μ_p, C_p), μ_p the estimates' mean
    (on the circle for ``circular_state``) and C_p = 2 λ I, λ the largest eigenvalue of any P_m: then
    C_p ≻ P_m, C_p − C_p (C_p + R_m)⁻¹ C_p = P_m, and y^m = μ_p + (C_p + R_m) C_p⁻¹ (x_m ⊖ μ_p)
    updates the prior to x_m. Angle state components are angle outputs of every sensor."""
    from gpfverify.angles import difference, weighted_mean, wrap_components

    means = np.array([np.asarray(e.mean, dtype=float) for e in estimates])
    covs = [np.asarray(e.cov, dtype=float) for e in estimates]
    n, d = means.shape
    circular_state = tuple(int(i) for i in circular_state)
    mu_p = weighted_mean(means, np.full(n, 1.0 / n), circular_state)
    c_p = 2.0 * max(float(np.linalg.eigvalsh(p)[-1]) for p in covs) * np.eye(d)
    reports, ys, blocks = [], [], []
    for x_m, p_m in zip(means, covs):
        r_m = p_m + p_m @ np.linalg.solve(c_p - p_m, p_m)
        r_m = 0.5 * (r_m + r_m.T)
        c_y = c_p + r_m
        y_m = wrap_components(mu_p + c_y @ np.linalg.solve(c_p, difference(x_m, mu_p, circular_state)),
                              circular_state)
        ys.append(y_m)
        blocks.append(c_y)
        reports.append(LocalReport(mu_p=mu_p, mu_y=mu_p, C_y=c_y, C_xy=c_p, mu_e=x_m, C_e=p_m,
                                   circular=circular_state))
    c_y_all = np.kron(np.ones((n, n)), c_p)
    for m, c_y in enumerate(blocks):
        c_y_all[m * d:(m + 1) * d, m * d:(m + 1) * d] = c_y
    central = CentralPrediction(mu_p=mu_p, C_p=c_p, mu_y=np.tile(mu_p, n), C_y=c_y_all,
                                C_xy=np.tile(c_p, (1, n)), sizes=(d,) * n,
                                circular=tuple(m * d + i for m in range(n) for i in circular_state),
                                circular_state=circular_state)
    return FusionCase(central, tuple(reports), np.concatenate(ys))
