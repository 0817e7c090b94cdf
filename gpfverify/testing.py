"""Ready-made property suites for *your* fusion rule (pytest and hypothesis; the ``gpfverify``
pytest plugin, :mod:`gpfverify.pytest_plugin`, adds its options and fixtures).

Subclass a suite in a test module, under a name pytest collects, and give it your rule::

    from gpfverify.testing import EstimateRuleSuite

    class TestMyRule(EstimateRuleSuite):
        rule = staticmethod(my_rule)        # my_rule(estimates, circular_state=()) -> (mean, cov)

Every property draws its inputs with :mod:`gpfverify.strategies` (hypothesis), so a failure is
shrunk to a small counterexample; that counterexample is printed in the failure report as one line
of JSON after ``gpfverify fusion case:`` — a fusion case file (docs/fusion-case-format.md) that
``gpfverify audit`` and ``gpfverify fuse`` read — and, with ``pytest --gpfverify-cases DIR``, written
as ``DIR/<suite>-<property>.json``.

:class:`EstimateRuleSuite` — a rule fusing local estimates (x_m, P_m) into (x, P), as CC, CI and
RCC-CI do; it is called ``rule(estimates)`` with a tuple of objects with ``mean`` and ``cov``, and
``rule(estimates, circular_state=idx)`` when angle components are drawn; it returns an object with
``mean`` and ``cov`` or a pair (mean, cov).

* ``conservative for every admissible correlation``: the local errors' joint covariance J is drawn
  with the given P_m as its diagonal blocks (any PSD J is admissible: :mod:`gpfverify.strategies.estimates`);
  the rule's gains W_m = ∂x/∂x_m are read off by moving one local mean at a time (exact for a rule
  affine in the local means, as every covariance-weighted rule is; the suite checks that it is, and
  that Σ_m W_m = I), and the claimed P must dominate the true error covariance Σ_mn W_m J_mn W_nᵀ.
  The J that breaks the claim is printed with the case (the case file has no place for it).
* ``independent of the sensor order``: the same estimates in a drawn order give the same (x, P).
* ``equivariant under a rotation of the angles`` (``angles = True``): with angle components
  straddling ±π, turning every local angle by φ turns the fused angle by φ and leaves P unchanged.

:class:`CaseRuleSuite` — a distributed rule fusing one fusion step
(:class:`~gpfverify.fusion.FusionCase`: the centre's prediction and the sensors' reports), as DMF
(Liao et al. 2019, eq. 35) does; it returns the fused mean, or an object with ``mean``.

* ``reduces to CMF when the rank condition holds``: on cases whose every local C_xy^m has full
  column rank (by design), the rule's mean is CMF's, μ_p + C_xy C_y⁻¹ (y ⊖ μ_y) (Proposition 1);
* ``independent of the sensor order``;
* ``equivariant under a rotation of the angles``: with an angle state component near ±π
  (``circular_state``), turning it by φ in every mean of the case turns the fused mean by φ.

Class attributes set the draws: ``sensors`` and ``state_dim`` (inclusive ranges), ``max_condition``
(of the drawn covariances), ``angles``. The tolerances are rounding bounds scaled by the drawn
problem's conditioning (:func:`gpfverify.tolerances.algebra_rtol`); ``rtol_factor`` multiplies them
for a rule that is known to lose more (say why where you set it). The active hypothesis profile
sets the number of examples and everything else but the wall-clock checks, which a loaded
machine would fail (no deadline, no too-slow health check): ``--hypothesis-profile NAME``;
``import gpfverify.strategies.profiles`` in a ``conftest.py`` registers gpfverify's ``ci``, ``dev``
and ``thorough``.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, note, settings
from hypothesis import strategies as st

from gpfverify.angles import difference, wrap, wrap_components
from gpfverify.filters.records import Gaussian
from gpfverify.fusion.case import CentralPrediction, FusionCase, LocalReport, sensor_blocks
from gpfverify.fusion.centralized import cmf_update
from gpfverify.strategies import (KINDS, correlated_estimates, estimates_across_the_cut, fusion_cases,
                                  saving_case_on_failure)
from gpfverify.strategies.fusion import case_of_estimates
from gpfverify.tolerances import algebra_rtol

__all__ = ["EstimateRuleSuite", "CaseRuleSuite", "permuted_case"]


def _mean_cov(result) -> tuple[np.ndarray, np.ndarray]:
    """A rule's fused (mean, cov): the pair it returned, or its ``mean`` and ``cov``."""
    if not isinstance(result, tuple):
        return np.asarray(result.mean, dtype=float), np.asarray(result.cov, dtype=float)
    mean, cov = result
    return np.asarray(mean, dtype=float), np.asarray(cov, dtype=float)


def _mean(result) -> np.ndarray:
    """A rule's fused mean: the array it returned, or its ``mean`` (a Gaussian, a fused estimate)."""
    if isinstance(result, (np.ndarray, list, tuple)):
        return np.asarray(result, dtype=float)
    return np.asarray(result.mean, dtype=float)


class _Suite:
    rule: Callable | None = None
    sensors: tuple[int, int] = (2, 4)
    state_dim: tuple[int, int] = (1, 3)
    max_condition: float = 1e3
    angles: bool = True
    rtol_factor: float = 1.0

    def _rule(self) -> Callable:
        rule = type(self).rule  # a plain function or a staticmethod: never bound to the suite
        if rule is None:
            raise TypeError(f"{type(self).__name__} must set rule = staticmethod(your_rule)")
        return rule

    def _case_name(self, prop: str) -> str:
        return f"{type(self).__name__}-{prop}"

    def _rtol(self, condition: float) -> float:
        return self.rtol_factor * algebra_rtol(condition)

    def __init_subclass__(cls, **kwargs):
        """Give every subclass its own hypothesis test per property (``test_<name>`` for each
        ``_property_<name>``): one wrapped function shared by several suites would mix their
        examples in hypothesis's database and fail its ``differing_executors`` health check."""
        super().__init_subclass__(**kwargs)
        for attribute in dir(cls):
            if attribute.startswith("_property_"):
                name = "test_" + attribute.removeprefix("_property_")
                setattr(cls, name, _test(cls, name, getattr(cls, attribute)))


def _test(cls: type, name: str, prop: Callable) -> Callable:
    def test(self, data):
        return prop(self, data)

    test.__name__, test.__qualname__, test.__doc__ = name, f"{cls.__qualname__}.{name}", prop.__doc__
    test.__module__ = cls.__module__
    # wall-clock limits say nothing about a rule on a busy machine: no deadline, no too-slow
    # health check; one shrunk counterexample per property (hypothesis would otherwise report each
    # distinct assertion a rule trips, and which ones it meets depends on the processor's rounding);
    # everything else (examples, database, derandomisation) is the active profile's
    return settings(deadline=None, suppress_health_check=[HealthCheck.too_slow], report_multiple_bugs=False)(
        given(data=st.data())(test))


class EstimateRuleSuite(_Suite):
    """Properties of a rule fusing local estimates (module docstring)."""

    def _fuse(self, estimates, circular_state: Sequence[int] = ()) -> tuple[np.ndarray, np.ndarray]:
        rule = self._rule()
        result = rule(tuple(estimates), circular_state=tuple(circular_state)) if circular_state else rule(
            tuple(estimates))
        return _mean_cov(result)

    def _estimates(self, data):
        return data.draw(correlated_estimates(count=st.integers(*self.sensors), state_dim=st.integers(*self.state_dim),
                                              max_condition=self.max_condition), label="estimates")

    def _property_conservative_for_every_admissible_correlation(self, data):
        drawn = self._estimates(data)
        estimates = drawn.estimates
        with saving_case_on_failure(case_of_estimates(estimates), self._case_name("conservative"), show=True):
            mean, cov = self._fuse(estimates)
            condition = max(np.linalg.cond(e.cov) for e in estimates) * np.linalg.cond(cov)
            rtol = self._rtol(condition)
            scale = max(np.abs(e.mean).max() for e in estimates) + 1.0
            step = scale  # a move of one local mean by its own scale: exact gains for an affine rule
            gains, moved_twice = [], []
            for m, e in enumerate(estimates):
                columns, twice = [], []
                for j in range(e.mean.size):
                    for factor, out in ((1.0, columns), (2.0, twice)):
                        moved = list(estimates)
                        shifted = e.mean.copy()
                        shifted[j] += factor * step
                        moved[m] = Gaussian(shifted, e.cov)
                        out.append((self._fuse(moved)[0] - mean) / (factor * step))
                gains.append(np.array(columns).T)
                moved_twice.append(np.array(twice).T)
            gain_tol = rtol * (np.abs(mean).max() + scale) / step * 4
            np.testing.assert_allclose(np.concatenate(moved_twice, axis=1), np.concatenate(gains, axis=1), rtol=0,
                                       atol=gain_tol, err_msg="the rule is not affine in the local means: its "
                                       "true error covariance is not Σ W_m J_mn W_nᵀ")
            np.testing.assert_allclose(sum(gains), np.eye(mean.size), rtol=0, atol=gain_tol * len(gains),
                                       err_msg="the rule's gains do not sum to I: it is biased")
            true_cov = drawn.error_cov_of(gains)
            slack = float(np.linalg.eigvalsh(cov - true_cov)[0])
            if slack < -rtol * np.abs(cov).max():
                note(f"joint error covariance J of the local errors: {json.dumps(drawn.joint_cov.tolist())}")
            assert slack >= -rtol * np.abs(cov).max(), (
                f"claimed P − true error covariance has eigenvalue {slack:.3g} < 0: the rule is not conservative "
                f"for this admissible correlation")

    def _property_independent_of_the_sensor_order(self, data):
        estimates = self._estimates(data).estimates
        order = data.draw(st.permutations(range(len(estimates))), label="order")
        with saving_case_on_failure(case_of_estimates(estimates), self._case_name("order"), show=True):
            mean, cov = self._fuse(estimates)
            mean2, cov2 = self._fuse([estimates[i] for i in order])
            rtol = self._rtol(max(np.linalg.cond(e.cov) for e in estimates) * np.linalg.cond(cov))
            np.testing.assert_allclose(mean2, mean, rtol=0, atol=rtol * (np.abs(mean).max() + 1.0))
            np.testing.assert_allclose(cov2, cov, rtol=0, atol=rtol * np.abs(cov).max())

    def _property_equivariant_under_a_rotation_of_the_angles(self, data):
        if not self.angles:
            pytest.skip("angles = False: the rule has no angle components")
        drawn = data.draw(estimates_across_the_cut(count=st.integers(*self.sensors),
                                                   state_dim=st.integers(*self.state_dim),
                                                   max_condition=self.max_condition), label="estimates")
        phi = data.draw(st.floats(-np.pi, np.pi), label="rotation")
        angles = drawn.circular_state
        with saving_case_on_failure(case_of_estimates(drawn.estimates, angles), self._case_name("angles"), show=True):
            mean, cov = self._fuse(drawn.estimates, angles)
            turned, turned_cov = self._fuse(drawn.rotated(phi), angles)
            expected = mean.copy()
            expected[list(angles)] = wrap(mean[list(angles)] + phi)
            rtol = self._rtol(max(np.linalg.cond(e.cov) for e in drawn.estimates) * np.linalg.cond(cov))
            np.testing.assert_allclose(difference(turned, expected, angles), 0.0, rtol=0,
                                       atol=rtol * (np.abs(mean).max() + np.pi))
            np.testing.assert_allclose(turned_cov, cov, rtol=0, atol=rtol * np.abs(cov).max())


def permuted_case(case: FusionCase, order: Sequence[int]) -> FusionCase:
    """The same fusion step with the sensors in ``order`` (a permutation of their indices)."""
    c = case.central
    blocks = sensor_blocks(c.sizes)
    rows = np.concatenate([np.arange(c.mu_y.size)[blocks[m]] for m in order])
    sizes = tuple(c.sizes[m] for m in order)
    new_blocks = sensor_blocks(sizes)
    circular = tuple(new_blocks[i].start + j for i, m in enumerate(order) for j in case.locals[m].circular)
    central = CentralPrediction(c.mu_p, c.C_p, c.mu_y[rows], c.C_y[np.ix_(rows, rows)], c.C_xy[:, rows], sizes,
                                tuple(sorted(circular)), c.circular_state)
    return FusionCase(central, tuple(case.locals[m] for m in order), None if case.y is None else case.y[rows],
                      case.rank_tol)


def _turned(case: FusionCase, index: int, angle: float) -> FusionCase:
    """``case`` with state component ``index`` an angle and turned by ``angle`` in every mean."""
    def turn(v: np.ndarray) -> np.ndarray:
        out = v.copy()
        out[index] = wrap(v[index] + angle)
        return out

    c = case.central
    central = replace(c, mu_p=turn(c.mu_p), circular_state=(index,))
    reports = tuple(LocalReport(turn(r.mu_p), r.mu_y, r.C_y, r.C_xy, turn(r.mu_e),
                                r.C_e, r.circular) for r in case.locals)
    return FusionCase(central, reports, case.y, case.rank_tol)


class CaseRuleSuite(_Suite):
    """Properties of a rule fusing one fusion step (module docstring)."""

    sensors = (1, 3)

    def _fuse(self, case: FusionCase) -> np.ndarray:
        return _mean(self._rule()(case))

    def _rtol_of(self, case: FusionCase) -> float:
        locals_ = max(np.linalg.cond(r.C_y) for r in case.locals)
        return self._rtol(np.linalg.cond(case.central.C_y) * np.linalg.cond(case.central.C_p) * locals_)

    def _case(self, data, kinds=None) -> FusionCase:
        return data.draw(fusion_cases(state_dim=st.integers(*self.state_dim), sensors=st.integers(*self.sensors),
                                      kinds=st.sampled_from(KINDS if kinds is None else kinds),
                                      max_condition=self.max_condition), label="case").case

    def _property_reduces_to_cmf_when_the_rank_condition_holds(self, data):
        case = self._case(data, kinds=("full",))
        with saving_case_on_failure(case, self._case_name("cmf"), show=True):
            mean = self._fuse(case)
            cmf = cmf_update(case.central, case.y).mean
            factor = np.linalg.cholesky(case.central.C_p)
            gap = np.linalg.norm(np.linalg.solve(factor, difference(mean, cmf, case.circular_state)))
            size = np.linalg.norm(np.linalg.solve(factor, np.abs(cmf) + np.abs(case.central.mu_p))) + 1.0
            assert gap <= self._rtol_of(case) * size, (
                f"the rule differs from CMF by {gap:.3g} prior standard deviations although every sensor's "
                "C_xy^m has full column rank (Proposition 1)")

    def _property_independent_of_the_sensor_order(self, data):
        case = self._case(data)
        order = data.draw(st.permutations(range(len(case.locals))), label="order")
        with saving_case_on_failure(case, self._case_name("order"), show=True):
            mean = self._fuse(case)
            again = self._fuse(permuted_case(case, order))
            scale = np.abs(mean).max() + np.sqrt(np.abs(case.central.C_p).max())
            np.testing.assert_allclose(difference(again, mean, case.circular_state), 0.0, rtol=0,
                                       atol=self._rtol_of(case) * scale)

    def _property_equivariant_under_a_rotation_of_the_angles(self, data):
        if not self.angles:
            pytest.skip("angles = False: the rule has no angle components")
        case = self._case(data)
        index = data.draw(st.integers(0, case.state_dim - 1), label="angle component")
        near_cut = np.pi - case.central.mu_p[index] + data.draw(st.floats(-0.5, 0.5), label="offset from π")
        phi = data.draw(st.floats(-np.pi, np.pi), label="rotation")
        at_cut = _turned(case, index, near_cut)
        with saving_case_on_failure(at_cut, self._case_name("angles"), show=True):
            mean = self._fuse(at_cut)
            turned = self._fuse(_turned(at_cut, index, phi))
            expected = wrap_components(mean + np.eye(case.state_dim)[index] * phi, (index,))
            scale = np.abs(mean).max() + np.pi + np.sqrt(np.abs(case.central.C_p).max())
            np.testing.assert_allclose(difference(turned, expected, (index,)), 0.0, rtol=0,
                                       atol=self._rtol_of(case) * scale)
