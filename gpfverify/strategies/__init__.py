"""Public hypothesis strategies for property-based tests of fusion rules and filters — ours and
yours. Requires hypothesis (``pip install gpfverify[test]``).

Every drawn object is valid by construction (no ``assume``): matrices are built from their factors
with the spectrum chosen first.

Matrices (:mod:`~gpfverify.strategies.matrices`)
    ``spd_matrices(dim, max_condition, scale)``, ``orthonormal_matrices(rows, cols)``,
    ``matrices_with_singular_values(rows, cols, s)``.
Joint Gaussians (:mod:`~gpfverify.strategies.gaussians`)
    ``joint_gaussians(state_dim, sensors, kinds, ...)`` — (x, y¹, …, y^N) whose cross terms C_xy^m
    have a designed rank: ``full``, ``nearly`` (σ_min at a chosen scale), ``deficient``, ``zero``,
    ``decoupled`` (deficient yet DMF-exact).
Fusion cases (:mod:`~gpfverify.strategies.fusion`)
    ``fusion_cases(...)`` -> :class:`DrawnCase` (a consistent :class:`~gpfverify.fusion.FusionCase`
    with its design), ``fusion_case_files(...)`` -> dicts in the CONTRACT.md case-file format.
Local estimates (:mod:`~gpfverify.strategies.estimates`)
    ``correlated_estimates(count, state_dim, ...)``, ``estimate_pairs(state_dim)`` — (x_m, P_m) with
    an admissible (PSD) joint error covariance; ``estimates_across_the_cut(...)`` -> :class:`AngleEstimates`,
    the same with angle components straddling ±π.
Models (:mod:`~gpfverify.strategies.models`)
    ``gaussian_processes``, ``gaussian_inputs``, ``linear_gaussian_models``, ``sigma_params``,
    ``angle_models`` (a linear-Gaussian model with an angle state and an angle output, a batch of
    beliefs near ±π), ``batched_beliefs`` (B Gaussian beliefs stacked on a leading axis).
Corners (:mod:`~gpfverify.strategies.corners`)
    ``singular_covariances`` (noise of designed rank), ``chunk_sizes`` (a batch cut into blocks),
    ``mixed_angle_states`` (angles and lengths, differences beyond π), ``lists_with_twins`` (equal
    but distinct elements), ``uneven_points`` (components of very different sizes),
    ``weights_with_ess`` (a known effective sample size).
Counterexamples (:mod:`~gpfverify.strategies.counterexamples`)
    ``saving_case_on_failure(case, name)`` writes a failing property's shrunk case as a case file.
Profiles (:mod:`~gpfverify.strategies.profiles`)
    the ``ci``, ``dev`` and ``thorough`` settings profiles (registered on import).
"""

from gpfverify.strategies.counterexamples import saving_case_on_failure, write_case
from gpfverify.strategies.corners import (DesignedWeights, MixedStates, chunk_sizes, lists_with_twins,
                                          mixed_angle_states, singular_covariances, uneven_points, weights_with_ess)
from gpfverify.strategies.estimates import (AngleEstimates, CorrelatedEstimates, correlated_estimates,
                                            estimate_pairs, estimates_across_the_cut)
from gpfverify.strategies.fusion import PRIORS, DrawnCase, fusion_case_files, fusion_cases
from gpfverify.strategies.gaussians import KINDS, JointGaussian, SensorDesign, joint_gaussians
from gpfverify.strategies.matrices import (matrices_with_singular_values, orthonormal_matrices,
                                           spd_matrices)
from gpfverify.strategies.models import (AngleModel, GPStackCase, LinearGaussianModel, angle_models,
                                         batched_beliefs, gaussian_inputs, gaussian_processes, gp_stacks,
                                         linear_gaussian_models, psd_matrices, sigma_params)
from gpfverify.strategies.profiles import PROFILES, load_profile, register_profiles, scaled_examples

__all__ = ["saving_case_on_failure", "write_case", "AngleEstimates", "CorrelatedEstimates",
           "correlated_estimates", "estimate_pairs", "estimates_across_the_cut", "PRIORS", "DrawnCase",
           "fusion_case_files", "fusion_cases", "KINDS",
           "JointGaussian", "SensorDesign", "joint_gaussians", "matrices_with_singular_values",
           "orthonormal_matrices", "spd_matrices", "LinearGaussianModel", "gaussian_inputs",
           "gaussian_processes", "gp_stacks", "GPStackCase", "linear_gaussian_models", "psd_matrices", "sigma_params",
           "AngleModel", "angle_models", "batched_beliefs",
           "DesignedWeights", "MixedStates", "chunk_sizes", "lists_with_twins", "mixed_angle_states",
           "singular_covariances", "uneven_points", "weights_with_ess",
           "PROFILES", "load_profile", "register_profiles", "scaled_examples"]
