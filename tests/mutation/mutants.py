"""The mutants of the numerical core: each replaces one exact snippet of one file (which must occur
exactly once) and names the property tests that are expected to notice.

A mutant is *killed by a property* when a hypothesis test (``@given``) fails on the mutated copy;
a failure of a plain test (a fixed example) is recorded but does not count. A mutant that no
property kills carries a ``note`` saying why (an equivalent change, or what no property draws);
the kill table prints it.
"""

from __future__ import annotations

from dataclasses import dataclass

GP = ("property_tests/test_gp_properties.py", "property_tests/test_gp_stack_properties.py")
FILTER = ("property_tests/test_filter_properties.py",)
FUSION = ("property_tests/test_fusion_prop1.py", "property_tests/test_fusion_baselines.py")
BASELINES = ("property_tests/test_fusion_baselines.py",)
RANK = ("property_tests/test_rank_oracles.py", "property_tests/test_fusion_prop1.py",
        "property_tests/test_rank_rule_properties.py")
UNSCENTED = ("property_tests/test_unscented_oracles.py", "property_tests/test_filter_properties.py")
RESAMPLING = ("property_tests/test_resampling_properties.py", "property_tests/test_filter_properties.py")
ANGLES = ("property_tests/test_unscented_oracles.py", "property_tests/test_fusion_angles.py")
ORACLES = ("property_tests/test_rank_oracles.py", "property_tests/test_fusion_prop1.py")


@dataclass(frozen=True)
class Mutant:
    name: str
    area: str
    path: str
    old: str
    new: str
    tests: tuple[str, ...]
    note: str = ""


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
           "trace[b, p] = white_sq + _dot(acc_trace, q_a[b, p])",
           "trace[b, p] = white_sq + 0.0 * _dot(acc_trace, q_a[b, p])", GP),
    Mutant("fused kernel: whitening without the factor's diagonal", "moments (fused kernel)",
           "gpfverify/gp/fused_kernels.py", "x_i = white[i] / factors_t[a, i, i]", "x_i = white[i]", GP),
    Mutant("‖L⁻¹q‖² left out of the traces", "moments", "gpfverify/gp/moments.py",
           "return cov, traces + _whitened_squares(gp_a, first_a.q[:, ia], diagonal)", "return cov, traces", GP),
    Mutant("fused kernel: the input's own term left out of a row's exponent", "moments (fused kernel)",
           "gpfverify/gp/fused_kernels.py", "row[b, p, i] = -0.5 * t_a[b, a, i] + 0.5 * quadratic_a[i] + const[b, p]",
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
    # angles: wrapped differences and circular means forgotten
    Mutant("eq. 35: μ_y^m − μ_y(m) left unwrapped", "angles (eq. 35)", "gpfverify/fusion/distributed.py",
           "parts.append(difference(local.mu_y, central.mu_y[block], local.circular) + local.C_y @ recovered)",
           "parts.append((local.mu_y - central.mu_y[block]) + local.C_y @ recovered)", ANGLES),
    Mutant("eq. 35: μ_e^m − μ_p^m of an angle state left unwrapped", "angles (eq. 35)",
           "gpfverify/fusion/distributed.py",
           "recovered = s.split.pinv @ difference(local.mu_e, local.mu_p, case.circular_state)",
           "recovered = s.split.pinv @ (local.mu_e - local.mu_p)", ANGLES),
    Mutant("DMF: angle state of the fused mean not wrapped", "angles (eq. 35)", "gpfverify/fusion/distributed.py",
           "return wrap_components(central.mu_p + gain @ np.concatenate(parts), case.circular_state)",
           "return central.mu_p + gain @ np.concatenate(parts)", ANGLES),
    Mutant("CMF: y − μ_y of angle outputs left unwrapped", "angles (CMF)", "gpfverify/fusion/centralized.py",
           "innovation = difference(y, central.mu_y, central.circular)", "innovation = y - central.mu_y", ANGLES),
    Mutant("circular mean: deviations from the reference not wrapped", "angles", "gpfverify/angles.py",
           "deviations = wrap(points[..., idx] - reference)", "deviations = points[..., idx] - reference", ANGLES),
    Mutant("wrap to [0, 2π) instead of (−π, π]", "angles", "gpfverify/angles.py",
           "wrapped = np.pi - np.mod(np.pi - np.asarray(angle, dtype=float), TWO_PI)",
           "wrapped = np.mod(np.asarray(angle, dtype=float), TWO_PI)", ANGLES),
    Mutant("Gaussian update: innovation of angle outputs left unwrapped", "angles (update)",
           "gpfverify/filters/update.py",
           "innovation = difference(y, mu_y, circular) if len(circular) else y - mu_y", "innovation = y - mu_y",
           ANGLES),
    Mutant("unscented transform: output deviations left unwrapped", "angles (UKF)",
           "gpfverify/filters/sigma_points.py", "dy = difference(points_y, mean_y[..., None, :], circular_y)",
           "dy = points_y - mean_y[..., None, :]", ANGLES),
    Mutant("UKF prediction: angle state treated as linear after the transition", "angles (UKF)",
           "gpfverify/filters/ukf.py", "model.circular_state, model.circular_state)", "model.circular_state, ())",
           ANGLES),
    Mutant("model: circular_state dropped when the model is built", "models", "gpfverify/models/system.py",
           'set_("circular_state", as_indices(self.circular_state, d, "circular_state"))',
           'set_("circular_state", ())', ANGLES),
    # the unscented transform: sigma-point parameters and batches
    Mutant("UKF: β dropped from the central covariance weight", "sigma points", "gpfverify/filters/sigma_points.py",
           "wc[0] = wm[0] + 1.0 - self.alpha**2 + self.beta", "wc[0] = wm[0] + 1.0 - self.alpha**2", UNSCENTED),
    Mutant("UKF: λ with α instead of α²", "sigma points", "gpfverify/filters/sigma_points.py",
           "return self.alpha**2 * (dim + self.kappa) - dim", "return self.alpha * (dim + self.kappa) - dim",
           UNSCENTED),
    Mutant("UKF: sigma-point spread √(D + κ) instead of √(D + λ)", "sigma points",
           "gpfverify/filters/sigma_points.py", "scale = dim + params.lam(dim)", "scale = dim + params.kappa",
           UNSCENTED),
    Mutant("UKF: 1 − α² left out of the central covariance weight", "sigma points",
           "gpfverify/filters/sigma_points.py", "wc[0] = wm[0] + 1.0 - self.alpha**2 + self.beta",
           "wc[0] = wm[0] + self.beta", UNSCENTED),
    Mutant("UKF: C_y symmetrised over the wrong axis of a batch", "sigma points (batches)",
           "gpfverify/filters/sigma_points.py", "0.5 * (cov_y + np.swapaxes(cov_y, -1, -2))",
           "0.5 * (cov_y + np.swapaxes(cov_y, 0, -1))", UNSCENTED),
    Mutant("symmetrize over the first two axes of a batch", "linalg (batches)", "gpfverify/linalg.py",
           "return 0.5 * (a + a.swapaxes(-1, -2))", "return 0.5 * (a + a.swapaxes(0, 1))", UNSCENTED),
    Mutant("model: sensor noise covariances reduced to their diagonals", "models", "gpfverify/models/system.py",
           "return sla.block_diag(*(s.noise_cov for s in self.sensors))",
           "return sla.block_diag(*(np.diag(np.diag(s.noise_cov)) for s in self.sensors))", UNSCENTED),
    # resampling as a randomised algorithm
    Mutant("systematic resampling: a fixed offset of ½ instead of a random one", "resampling",
           "gpfverify/filters/resampling.py", "positions = (rng.uniform() + np.arange(n)) / n",
           "positions = (0.5 + np.arange(n)) / n", RESAMPLING),
    Mutant("log-sum-exp: the count of maximal terms left out", "resampling (weights)",
           "gpfverify/filters/resampling.py", "return float(np.log1p(scaled.sum() / count) + np.log(count) + a_max)",
           "return float(np.log1p(scaled.sum() / count) + a_max)", RESAMPLING),
    Mutant("weights normalised by the largest instead of the sum", "resampling (weights)",
           "gpfverify/filters/resampling.py", "    return log_weights - total\n",
           "    return log_weights - log_weights.max()\n", RESAMPLING),
    # rank rules, exactness, repair
    Mutant("numpy rank rule: min(D, l) for max(D, l)", "tolerances (rank)", "gpfverify/tolerances.py",
           "return float(s.max(initial=0.0) * max(shape) * EPS)",
           "return float(s.max(initial=0.0) * min(shape) * EPS)", RANK),
    Mutant("exactness tolerance × 1e6 on the numpy/absolute rules", "exactness tolerance",
           "gpfverify/fusion/exactness.py",
           "out.append(SensorExactness(m, split, gain_times_cov @ split.kernel_basis, residual, tol))",
           "out.append(SensorExactness(m, split, gain_times_cov @ split.kernel_basis, residual,\n"
           "                                   tol if rule.name == \"canonical\" else 1e6 * tol))", ORACLES),
    Mutant("canonical rule: C_p^m taken as C_e^m (information not added back)", "rank decision",
           "gpfverify/fusion/exactness.py",
           "return symmetrize(local.C_e + right_solve_spd(local.C_xy, local.C_y, \"local C_y\") @ local.C_xy.T), \\",
           "return symmetrize(local.C_e), \\", RANK),
    Mutant("canonical rule: default τ = eps instead of √eps", "tolerances (rank)", "gpfverify/tolerances.py",
           "CANONICAL_RANK_TOL: float = float(np.sqrt(EPS))", "CANONICAL_RANK_TOL: float = float(EPS)", RANK),
    Mutant("repair: P_m w sent instead of (I − P_m) w", "repair message", "gpfverify/fusion/exactness.py",
           "return self.kernel_basis @ (self.dual_basis.T @ w)",
           "return w - self.kernel_basis @ (self.dual_basis.T @ w)", ORACLES),
    Mutant("eq. 35: pseudo-inverse multiplies by the singular values", "eq. 35", "gpfverify/fusion/exactness.py",
           "return (vt[:rank].T / s[:rank]) @ u[:, :rank].T", "return (vt[:rank].T * s[:rank]) @ u[:, :rank].T",
           ORACLES),
    # the audit
    Mutant("audit: repaired mean without the repair messages", "audit", "gpfverify/audit.py",
           "repaired = fused_mean(case, dmf.gain, dmf.sensors, messages)",
           "repaired = fused_mean(case, dmf.gain, dmf.sensors)", FUSION),
    Mutant("audit: gap taken as CMF − DMF", "audit", "gpfverify/audit.py",
           "gap = difference(dmf.mean, cmf.mean, case.circular_state)",
           "gap = difference(cmf.mean, dmf.mean, case.circular_state)", FUSION),
    Mutant("audit: exact reported as full column rank", "audit", "gpfverify/audit.py",
           "gap_gain_norm=s.residual, exactness_tol=s.tol, exact=s.exact,",
           "gap_gain_norm=s.residual, exactness_tol=s.tol, exact=s.full_column_rank,", FUSION),
    # GP regression
    Mutant("SE kernel: exp(−d²) instead of exp(−d²/2)", "gp kernel", "gpfverify/gp/kernels.py",
           "np.exp(np.multiply(sq, -0.5, out=sq), out=sq)", "np.exp(np.multiply(sq, -1.0, out=sq), out=sq)", GP),
    Mutant("SE kernel: distances scaled by 1/ℓ² instead of 1/ℓ", "gp kernel", "gpfverify/gp/kernels.py",
           "inv_ell = 1.0 / np.asarray(lengthscales, dtype=float)  # (E, D)",
           "inv_ell = 1.0 / np.asarray(lengthscales, dtype=float) ** 2  # (E, D)", GP),
    Mutant("GP predictive variance adds the explained part", "gp prediction", "gpfverify/gp/regression.py",
           'var[:, a] = self.signal_var[a] - np.einsum("ij,ij->j", v, v)',
           'var[:, a] = self.signal_var[a] + np.einsum("ij,ij->j", v, v)', GP),
)
