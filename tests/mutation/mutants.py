"""The mutants of the numerical core: each replaces one exact snippet of one file (which must occur
exactly once) and names the property tests that are expected to notice.

A mutant is *killed by a property* when a hypothesis test (``@given``) fails on the mutated copy;
a failure of a plain test (a fixed example) is recorded but does not count.
"""

from __future__ import annotations

from dataclasses import dataclass

GP = ("property_tests/test_gp_properties.py", "property_tests/test_gp_stack_properties.py")
FILTER = ("property_tests/test_filter_properties.py",)
FUSION = ("property_tests/test_fusion_prop1.py", "property_tests/test_fusion_baselines.py")
BASELINES = ("property_tests/test_fusion_baselines.py",)
RANK = ("property_tests/test_fusion_prop1.py", "property_tests/test_rank_rule_properties.py")


@dataclass(frozen=True)
class Mutant:
    name: str
    area: str
    path: str
    old: str
    new: str
    tests: tuple[str, ...]


MUTANTS: tuple[Mutant, ...] = (
    Mutant("model-uncertainty term dropped", "moments", "gpfverify/gp/moments.py",
           "block[on_diagonal] += _model_uncertainty(", "block[on_diagonal] += 0.0 * _model_uncertainty(", GP),
    Mutant("stack cross-GP blocks zeroed", "stack cross blocks", "gpfverify/gp/moments.py",
           "            rows, cols = offsets[g] + ia, offsets[h] + ib\n",
           "            blocks = blocks if g == h else 0.0 * blocks\n            rows, cols = offsets[g] + ia, offsets[h] + ib\n",
           GP),
    Mutant("expm1(d) replaced by exp(d) - 1", "expm1 path", "gpfverify/gp/moments.py",
           "centred = np.expm1(exponent, out=exponent)", "centred = np.exp(exponent) - 1.0", GP),
    Mutant("log-space branch: expm1(d) replaced by d", "expm1 path (log space)", "gpfverify/gp/moments.py",
           "np.exp(log_base) * np.expm1(np.minimum(exponent, EXPM1_SAFE))",
           "np.exp(log_base) * np.minimum(exponent, EXPM1_SAFE)", GP),
    Mutant("fused kernel: expm1(r) replaced by exp(r) - 1", "expm1 path (fused kernel)",
           "gpfverify/gp/fused_kernels.py", "p = _expm1_reduced_compiled(r)", "p = np.exp(r) - 1.0", GP),
    Mutant("fused kernel: trace term dropped", "moments (fused kernel)", "gpfverify/gp/fused_kernels.py",
           "trace[b, p] = _dot(acc_trace, q_a[b, p])",
           "trace[b, p] = 0.0 * _dot(acc_trace, q_a[b, p])", GP),
    Mutant("fused kernel: the input's own term left out of a row's exponent", "moments (fused kernel)",
           "gpfverify/gp/fused_kernels.py", "row[b, p, i] = -0.5 * t_a[b, a, i] + 0.5 * quadratic + const[b, p]",
           "row[b, p, i] = -0.5 * t_a[b, a, i] + const[b, p]", GP),
    Mutant("fused kernel: a symmetric pair's off-diagonal terms counted once", "moments (fused kernel)",
           "gpfverify/gp/fused_kernels.py", "weight, weight_trace = 2.0 * u[b, p, i],",
           "weight, weight_trace = 1.0 * u[b, p, i],", GP),
    Mutant("fused first moments: Σ ignored in the cross covariance", "moments (fused kernel)",
           "gpfverify/gp/fused_kernels.py", "acc += sigma[b, k, m] * solved[m]",
           "acc += (1.0 if k == m else 0.0) * solved[m]", GP),
    Mutant("fused first moments: |ΣΛ⁻¹ + I|^(-1/2) as ^(-1/4)", "moments (fused kernel)",
           "gpfverify/gp/fused_kernels.py", "value = log_signal_var[a] - 0.5 * logdet - 0.5 * maha",
           "value = log_signal_var[a] - 0.25 * logdet - 0.5 * maha", GP),
    Mutant("fused kernel: |R| left out of a pair's constant", "moments (fused kernel)",
           "gpfverify/gp/fused_kernels.py", "const[b, p] = 0.5 * (b_logdet_a[b, ia[p]] + b_logdet_b[b, ib[p]] - r_logdet)",
           "const[b, p] = 0.5 * (b_logdet_a[b, ia[p]] + b_logdet_b[b, ib[p]])", GP),
    Mutant("cross covariance sign flipped", "moments", "gpfverify/gp/moments.py",
           "return _FirstMoments(mean, sigma @ solved.T,", "return _FirstMoments(mean, -(sigma @ solved.T),", GP),
    Mutant("|ΣΛ⁻¹ + I|^(-1/2) as ^(-1/4)", "moments", "gpfverify/gp/moments.py",
           "- 0.5 * b_logdet[:, None]", "- 0.25 * b_logdet[:, None]", GP),
    Mutant("Σ ignored in the cross covariance", "moments", "gpfverify/gp/moments.py",
           "return _FirstMoments(mean, sigma @ solved.T,", "return _FirstMoments(mean, solved.T,", GP),
    Mutant("Σ ignored in the first moments (q at Σ = 0)", "moments", "gpfverify/gp/moments.py",
           "b_inv, b_ratio, b_logdet = _shifted(sigma * inv_ell[:, :, None] * inv_ell[:, None, :])",
           "b_inv, b_ratio, b_logdet = _shifted(0.0 * sigma * inv_ell[:, :, None] * inv_ell[:, None, :])", GP),
    Mutant("Gaussian update: half the covariance reduction", "filters' update", "gpfverify/filters/update.py",
           "return StepRecord(mu_p, C_p, mu_y, C_y, C_xy, mu_e, C_p - spread)",
           "return StepRecord(mu_p, C_p, mu_y, C_y, C_xy, mu_e, C_p - 0.5 * spread)", FILTER),
    Mutant("Gaussian update: innovation sign flipped", "filters' update", "gpfverify/filters/update.py",
           "mu_e = mu_p + shift", "mu_e = mu_p - shift", FILTER),
    Mutant("eq. 35: G_m(μ_y^m − μ_y(m)) dropped", "eq. 35", "gpfverify/fusion/distributed.py",
           "parts.append(difference(local.mu_y, central.mu_y[block], local.circular) + local.C_y @ recovered)",
           "parts.append(local.C_y @ recovered)", FUSION),
    Mutant("eq. 35: C_xy^mᵀ for the pseudo-inverse", "eq. 35", "gpfverify/fusion/distributed.py",
           "recovered = s.split.pinv @ difference(local.mu_e, local.mu_p, case.circular_state)",
           "recovered = local.C_xy.T @ difference(local.mu_e, local.mu_p, case.circular_state)", FUSION),
    Mutant("gap formula sign flipped", "gap", "gpfverify/fusion/exactness.py",
           "return TWO_PI * (g_m @ offsets) - sensor.gap_gain @ (", "return TWO_PI * (g_m @ offsets) + sensor.gap_gain @ (",
           FUSION),
    Mutant("exactness tolerance × 1e6", "exactness tolerance", "gpfverify/fusion/exactness.py",
           "return self.residual <= self.tol", "return self.residual <= 1e6 * self.tol", FUSION),
    Mutant("canonical rank threshold × 1e3", "rank decision", "gpfverify/fusion/exactness.py",
           "r = int(np.sum(rho > tol))", "r = int(np.sum(rho > 1e3 * tol))", RANK),
    Mutant("SVD rank: ≥ instead of >", "rank decision", "gpfverify/fusion/exactness.py",
           "r = int(np.sum(s > used))", "r = int(np.sum(s >= 0.0 * used))", RANK),
    Mutant("CI: two-sensor weight fixed at ½", "CI weights", "gpfverify/fusion/ci.py",
           "    omega = minimise_convex_on_unit_interval(\n        criterion_derivative(criterion, jd.column_norms, q, lambda w: 1.0 - 1.0 / mu))",
           "    omega = 0.5", BASELINES),
    Mutant("RCC-CI: ellipsoid constraint with b_m instead of 2b_m", "RCC-CI constraint",
           "gpfverify/fusion/rcc_ci.py", "cp.trace(A[m] @ delta) + 2 * b[m] @ x + d[m] <= 0",
           "cp.trace(A[m] @ delta) + b[m] @ x + d[m] <= 0", BASELINES),
    Mutant("systematic resampling: one uniform per particle", "resampling", "gpfverify/filters/resampling.py",
           "positions = (rng.uniform() + np.arange(n)) / n", "positions = np.sort(rng.uniform(size=n))", FILTER),
    Mutant("systematic resampling: searchsorted side left", "resampling", "gpfverify/filters/resampling.py",
           'np.searchsorted(cumulative, positions, side="right")', 'np.searchsorted(cumulative, positions, side="left")',
           FILTER),
    Mutant("convex combination: mean from unweighted average", "CW", "gpfverify/fusion/convex.py",
           "return wrapped(FusedEstimate(fused.mean, fused.cov), circular_state)",
           "return wrapped(FusedEstimate(sum(e.mean for e in checked) / len(checked), fused.cov), circular_state)",
           BASELINES),
)
