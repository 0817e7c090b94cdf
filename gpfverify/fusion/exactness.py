r"""When the distributed rule (seed 000 eq. 35) reproduces centralized fusion, and how to repair it.

Notation (written for the orthogonal SVD split; the canonical split below keeps every formula
with N_mᵀ replaced by Ñ_mᵀ). Sensor m's local update (eq. 32) is μ_e^m − μ_p^m = C_xy^m w_m with the *whitened local
innovation* w_m = (C_y^m)⁻¹ (y^m ⊖ μ_y^m) ∈ ℝ^{l_m}, where ⊖ is the difference with sensor m's angle
outputs (``circular``) wrapped to (−π, π]. With the thin SVD C_xy^m = U S Vᵀ at rank
r_m, let P_m = (C_xy^m)⁺ C_xy^m = V_r V_rᵀ (projector onto range(C_xy^mᵀ)) and N_m an orthonormal
basis of ker C_xy^m (l_m − r_m columns, I − P_m = N_m N_mᵀ). G = C_xy C_y⁻¹ (central) is split
into column blocks G_m.

Gap. Since (C_xy^m)⁺(μ_e^m − μ_p^m) = P_m w_m, the DMF mean (eq. 35) is
μ_p + Σ_m G_m (μ_y^m ⊖ μ_y(m)) + Σ_m G_m C_y^m P_m w_m, while CMF (eq. 36) is
μ_p + Σ_m G_m (y^m ⊖ μ_y(m)). Without angles y^m − μ_y(m) = (μ_y^m − μ_y(m)) + C_y^m w_m, hence

    μ_DMF − μ_CMF = Σ_m G_m C_y^m (P_m − I) w_m = −Σ_m (G_m C_y^m N_m)(N_mᵀ w_m).

Angles: branch offsets. On an angle output j of sensor m write a = wrap(μ_y^m − μ_y(m))_j (DMF's
first term), b = wrap(y^m − μ_y^m)_j (the local innovation, (C_y^m w_m)_j) and
c = wrap(y^m − μ_y(m))_j (CMF's innovation). Since a ≡ μ_y^m − μ_y(m) and b ≡ y^m − μ_y^m modulo 2π,
a + b ≡ y^m − μ_y(m) ≡ c; and a, b ∈ (−π, π] give a + b ∈ (−2π, 2π], so c = wrap(a + b) and

    a + b − c = 2π n_j,   n_j = 0 if a + b ∈ (−π, π],  +1 if a + b > π,  −1 if a + b ≤ −π.

So with full column rank (P_m = I) DMF's block-m innovation a + b equals CMF's c exactly when the
sum of the two separately wrapped terms stays in (−π, π]; otherwise they differ by 2π n_j on output
j. In general (any rank) the block-m innovations differ by 2π n_m − C_y^m N_m N_mᵀ w_m, and

    μ_DMF − μ_CMF = Σ_m [2π G_m n_m − (G_m C_y^m N_m)(N_mᵀ w_m)]          (:func:`predicted_gap`),

n_m ∈ {−1, 0, 1}^{l_m} the *branch offsets* (:func:`branch_offsets`; zero on non-angle outputs).
Both wrapped terms are small when the central and local predictions agree and the measurement is
near its prediction, so a nonzero offset means |a| + |b| > π: predictions or innovations of
more than π/2 on an angle. Repair messages do not remove it (they restore only (I − P_m) w_m).

Exactness. As y^m ranges over ℝ^{l_m}, w_m does too, independently per sensor; so DMF = CMF for
every measurement iff every *gap gain* G_m C_y^m N_m is zero, i.e. ker C_xy^m ⊆ ker G_m C_y^m.
Full column rank (N_m empty, Proposition 1) is sufficient, not necessary: a measurement component
uncorrelated with the state and with every other component has a zero column in C_xy^m and still
leaves DMF exact. Full column rank needs l_m ≤ D (rank C_xy^m ≤ min(D, l_m)).

Rank rules (:class:`RankRule`). Which singular directions of C_xy^m count as rank is a choice:

* ``canonical`` (the one default of the library, check, audit and fuse;
  τ = :data:`~gpfverify.tolerances.CANONICAL_RANK_TOL`):
  the canonical correlations of state and sensor output under the sensor's predicted joint,
  ρ_i = σ_i(K_m), K_m = L_p⁻¹ C_xy^m L_y⁻ᵀ with C_p^m = L_p L_pᵀ, C_y^m = L_y L_yᵀ (Cholesky
  factors of the equilibrated matrices, triangular solves; :func:`~gpfverify.linalg.canonical_correlations`);
  rank = #{ρ_i > τ}. Unit-free: rescaling state or measurement coordinates (x → S_x x,
  y → S_y y, any invertible S) gives L_p → S_x L_p Q, L_y → S_y L_y Q' (Q, Q' orthogonal), so
  K_m → Qᵀ K_m Q' and ρ do not change. C_p^m is the sensor's own prior covariance: recovered from
  C_e^m when the case has it, C_p^m = C_e^m + C_xy^m (C_y^m)⁻¹ C_xy^mᵀ (eq. 16 rearranged), else the
  centre's C_p (then ρ are the correlations *as if* the sensor's prior were the centre's; still
  unit-free, possibly above 1 when the two priors disagree). Which one was used is reported
  (``"local C_p from C_e"`` / ``"central C_p"``).
* ``absolute`` (tol): singular values of C_xy^m above tol (a case's ``rank_tol`` means this);
* ``numpy``: singular values above numpy's matrix_rank rule σ_max · max(D, l_m) · eps.

The last two depend on units: a bearing in microradians instead of radians multiplies its column
of C_xy^m by 1e6. They are kept, bit for bit as before, for the experiments' reference numbers.

Kernel split (DMF's inverse). Whichever rule decides the rank r, eq. 35's inverse is the
Moore–Penrose inverse of C_xy^m truncated at r in C_xy^m's own SVD C_xy^m = U S Vᵀ:
A_m = (C_xy^m)⁺ = V_r S_r⁻¹ U_rᵀ, P_m = A_m C_xy^m = V_r V_rᵀ (orthogonal), N_m = V_⊥ orthonormal
(``kernel_split``, and ``canonical_split`` by default). With full column rank this is a left inverse
and DMF does not depend on units; when the rank is lost it does ((S_x C S_y)⁺ ≠ S_y⁻¹ C⁺ S_x⁻¹
for a rank-deficient C), and the audit says by how much (docs/fusion-definitions.md). Under the
canonical rule the computation's rounding does not depend on units either: at full column rank the
left inverse applied is the whitened one below (equal to (C_xy^m)⁺ on range(C_xy^m), where
μ_e^m − μ_p^m lies), and when the rank is lost C_xy^m's own SVD comes from the Jacobi SVD
(:func:`~gpfverify.linalg.graded_svd`), accurate for matrices graded by units on both sides. The
SVD rules keep numpy's SVD (the experiments' reference numbers, bit for bit).

The unit-free variant (``canonical_split(..., unit_free=True)``; never reported as DMF) truncates in
the whitened coordinates instead. Let K_m = U diag(ρ) Vᵀ (full SVD), r the rank, and

    A_m = L_y⁻ᵀ V_r diag(ρ_r)⁻¹ U_rᵀ L_p⁻¹,   N_m = L_y⁻ᵀ V_⊥,   Ñ_m = L_y V_⊥ = C_y^m N_m.

Then A_m C_xy^m = L_y⁻ᵀ V_r V_rᵀ L_yᵀ =: P_m exactly, an oblique projector orthogonal in the metric
of C_y^m, I − P_m = N_m Ñ_mᵀ with Ñ_mᵀ N_m = I, and the gap formula above holds with N_mᵀ w_m
replaced by Ñ_mᵀ w_m = V_⊥ᵀ L_y⁻¹ (y^m ⊖ μ_y^m), the dropped canonical coordinates of the innovation.
For a consistent report A_m returns the minimum-C_y^m-norm solution of C_xy^m w = μ_e^m − μ_p^m, and
under rescaling A_m → S_y⁻¹ A_m S_x⁻¹: its mean and gap transform as states do.

Exactness verdict (every rule; docs/fusion-definitions.md). The gap gain
R_m = ‖L_p⁻¹ G_m C_y^m Π_m L_y⁻ᵀ‖₂ (L_p, L_y the factors of the central C_p and of C_y^m, Π_m the
projector onto the kernel the rule dropped, in the metric the rule decides in: whitened for the
canonical rule, Π_m = L_y⁻ᵀ V_⊥ V_⊥ᵀ L_yᵀ; C_xy^m's own for the SVD rules, Π_m = N_m N_mᵀ) is the gap in
prior standard deviations of the fused state per unit whitened innovation; the sensor is exact
when it is within the rounding bound of its computation
(:func:`~gpfverify.fusion.rounding.exactness_bound`: the fused estimate's own rounding, the computed
G and the computed kernel's angle) and that bound resolves the condition (at most
:data:`~gpfverify.tolerances.RESOLVABLE_GAP`). The gap's own rounding bound, in the same units, is
:func:`equivalence_tolerance`; "reproduced" compares the observed :func:`gap_size` with it.

Repair. The part of w_m that eq. 35 cannot recover is its kernel component (I − P_m) w_m: μ_e^m −
μ_p^m determines w_m only on range(P_m). The repair message (:func:`repair_message`) is that
component itself, k_m = (I − P_m) w_m = N_m Ñ_mᵀ w_m, an l_m-vector: it depends on the projector
only, never on the sign or rotation of a kernel basis (the l_m − r_m coordinates Ñ_mᵀ w_m would).
The centre adds G_m C_y^m (I − P_m) k_m — applying the projector again, so k_m or the whole w_m
give the same result — and recovers CMF exactly (branch offsets aside). Sensor and centre must
use the same rank rule and covariance (:func:`sensor_split`).

Numerics. A singular value (SVD rules) or canonical correlation (canonical rule) at or below the
tolerance counts as zero and the generalised inverse in eq. 35 uses the same decision.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg as sla

from gpfverify.angles import TWO_PI, difference, wrap
from gpfverify.errors import InputError, NumericalError
from gpfverify.fusion.case import CentralPrediction, FusionCase, LocalReport
from gpfverify.fusion.centralized import fusion_gain
from gpfverify.fusion.rounding import (FusedRounding, SensorTerms, estimate_floor, exactness_bound, gap_bound,
                                      left_inverse_error, svd_inverse_error)
from gpfverify.linalg import (CanonicalCorrelations, RankReport, canonical_correlations, correlation_condition,
                              equilibrated_cholesky, graded_svd, lower_solve, right_solve_spd, solve_spd,
                              symmetrize)
from gpfverify.tolerances import CANONICAL_RANK_TOL, RESOLVABLE_GAP, numpy_rank_tol

#: the rank rules :class:`RankRule` knows
RULE_NAMES: tuple[str, ...] = ("canonical", "absolute", "numpy")
#: which prior covariance whitened the state for the canonical correlations
COVARIANCE_LOCAL = "local C_p from C_e"
COVARIANCE_CENTRAL = "central C_p"


@dataclass(frozen=True)
class RankRule:
    """How the rank of each C_xy^m is decided (module docstring, "Rank rules"):

    * ``RankRule("canonical", tau)`` — canonical correlations ρ_i > tau (unit-free; ``tol``
      defaults to :data:`~gpfverify.tolerances.CANONICAL_RANK_TOL`, must be in [0, 1));
    * ``RankRule("absolute", tol)`` — singular values of C_xy^m > tol (tol ≥ 0 required);
    * ``RankRule("numpy")`` — singular values > σ_max · max(D, l_m) · eps (no tol).

    Invalid combinations raise :class:`~gpfverify.errors.InputError`."""

    name: str
    tol: float | None = None

    def __post_init__(self):
        if self.name not in RULE_NAMES:
            raise InputError(f"unknown rank rule {self.name!r}; choose from {', '.join(RULE_NAMES)}")
        tol = self.tol
        if self.name == "numpy":
            if tol is not None:
                raise InputError("the numpy rank rule takes no tolerance (it is sigma_max * max(D, l) * eps)")
            return
        if tol is None:
            if self.name == "absolute":
                raise InputError("the absolute rank rule needs a tolerance, e.g. absolute:1e-9")
            tol = CANONICAL_RANK_TOL
        if isinstance(tol, bool) or not isinstance(tol, (int, float, np.floating, np.integer)):
            raise InputError(f"rank rule tolerance must be a number, got {tol!r}")
        tol = float(tol)
        if not np.isfinite(tol) or tol < 0:
            raise InputError(f"rank rule tolerance must be a finite number >= 0, got {tol!r}")
        if self.name == "canonical" and tol >= 1:
            raise InputError(f"a canonical-correlation threshold must be in [0, 1), got {tol!r}")
        object.__setattr__(self, "tol", tol)

    @property
    def unit_free(self) -> bool:
        return self.name == "canonical"

    @property
    def spec(self) -> str:
        """The string :func:`parse_rank_rule` reads back (``"numpy"``, ``"canonical:1.49e-08"`` …)."""
        return self.name if self.tol is None else f"{self.name}:{self.tol!r}"

    def describe(self) -> str:
        if self.name == "canonical":
            return (f"canonical correlations of state and sensor output > tau = {self.tol:.3g} "
                    "(unit-free)")
        if self.name == "absolute":
            return f"explicit absolute tolerance {self.tol:g} on the singular values of C_xy^m"
        return "numpy matrix_rank rule: sigma_max * max(D, l_m) * eps (absolute, per matrix)"

    def __str__(self) -> str:
        return self.spec


#: the library's and the audit's default rule
DEFAULT_RANK_RULE = RankRule("canonical")
#: numpy's matrix_rank rule (the experiments' rule)
NUMPY_RANK_RULE = RankRule("numpy")


def parse_rank_rule(text: str) -> RankRule:
    """``"canonical"``, ``"canonical:1e-6"``, ``"absolute:1e-9"`` or ``"numpy"`` as a
    :class:`RankRule`; anything else raises :class:`~gpfverify.errors.InputError`."""
    if not isinstance(text, str):
        raise InputError(f"a rank rule must be a string like 'canonical:1e-6', got {text!r}")
    name, sep, value = text.strip().partition(":")
    name = name.strip().lower()
    if name not in RULE_NAMES:
        raise InputError(f"unknown rank rule {text!r}; use canonical[:TAU], absolute:TOL or numpy")
    if not sep:
        return RankRule(name)
    try:
        tol = float(value)
    except ValueError:
        raise InputError(f"rank rule {text!r}: {value.strip()!r} is not a number") from None
    return RankRule(name, tol)


def as_rank_rule(rule) -> RankRule | None:
    """``rule`` as a :class:`RankRule`: None stays None, strings go through :func:`parse_rank_rule`."""
    if rule is None or isinstance(rule, RankRule):
        return rule
    if isinstance(rule, str):
        return parse_rank_rule(rule)
    raise InputError(f"rank_rule must be a RankRule or a string like 'canonical:1e-6', got {rule!r}")


def resolve_rank_rule(case: FusionCase | None, rank_rule=None, rank_tol: float | None = None,
                      default: RankRule = DEFAULT_RANK_RULE) -> RankRule:
    """The rule that decides: an explicit ``rank_rule``, else an explicit absolute ``rank_tol``,
    else the case's ``rank_tol`` (absolute, CONTRACT.md), else ``default`` (canonical). Giving both
    ``rank_rule`` and ``rank_tol`` is an InputError."""
    rule = as_rank_rule(rank_rule)
    if rule is not None and rank_tol is not None:
        raise InputError("give rank_rule or rank_tol, not both")
    if rule is not None:
        return rule
    if rank_tol is not None:
        return RankRule("absolute", rank_tol)
    if case is not None and case.rank_tol is not None:
        return RankRule("absolute", case.rank_tol)
    return default


@dataclass(frozen=True)
class KernelSplit:
    """C_xy^m split at its rank (module docstring, "Kernel split"): ``rank`` (rank, singular
    values of C_xy^m, the tolerance in the rule's own units — τ for the canonical rule),
    ``pinv`` (l, D) the truncated generalised inverse A_m with A_m C_xy^m = P_m, ``kernel_basis``
    N_m (l, l − r) and ``cokernel`` Ñ_m (l, l − r) with I − P_m = N_m Ñ_mᵀ (None: Ñ_m = N_m,
    the orthogonal SVD split). Canonical splits also carry the ``correlations`` ρ, the
    ``covariance`` used (:data:`COVARIANCE_LOCAL` / :data:`COVARIANCE_CENTRAL`), the
    ``whitening`` and the ``whitened_inverse`` A_m = L_y⁻ᵀ V_r diag(ρ_r)⁻¹ U_rᵀ L_p⁻¹ (the unit-free
    variant's; ``pinv`` itself unless the rank was lost)."""

    rank: RankReport
    pinv: np.ndarray
    kernel_basis: np.ndarray
    cokernel: np.ndarray | None = None
    rule: RankRule = NUMPY_RANK_RULE
    correlations: np.ndarray | None = None
    covariance: str | None = None
    whitening: CanonicalCorrelations | None = None
    whitened_inverse: np.ndarray | None = None

    @property
    def whitened_kernel(self) -> np.ndarray | None:
        """V_⊥ (l, l − r): the dropped canonical directions, an orthonormal basis of the kernel in
        the whitened output coordinates z = L_y⁻¹ y (canonical splits; None for the SVD rules)."""
        if self.whitening is None or self.rule.name != "canonical":
            return None
        return self.whitening.v[:, self.rank.rank:]

    @property
    def dual_basis(self) -> np.ndarray:
        """Ñ_m (= N_m for the orthogonal split)."""
        return self.kernel_basis if self.cokernel is None else self.cokernel

    def kernel_component(self, w: np.ndarray) -> np.ndarray:
        """(I − P_m) w = N_m (Ñ_mᵀ w): basis-free (any N_m Q, Ñ_m Q with Q orthogonal gives the same)."""
        return self.kernel_basis @ (self.dual_basis.T @ w)


def _cross_cov_svd(cross_cov: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The full SVD of C_xy^m, the one route every rank rule takes for σ(C_xy^m): the recorded
    singular values are the same bits under every rule (LAPACK's route without singular vectors
    rounds differently)."""
    return np.linalg.svd(cross_cov, full_matrices=True)


def _moore_penrose_at_rank(u: np.ndarray, s: np.ndarray, vt: np.ndarray, rank: int) -> np.ndarray:
    """(C)⁺ truncated at ``rank`` in C's own SVD C = U diag(s) Vᵀ: V_r diag(s_r)⁻¹ U_rᵀ — the
    Moore–Penrose inverse eq. 35 writes, whichever rule decided the rank."""
    return (vt[:rank].T / s[:rank]) @ u[:, :rank].T


def kernel_split(cross_cov: np.ndarray, tol: float | None = None) -> KernelSplit:
    """Orthogonal SVD split of a sensor's cross covariance C_xy^m (D, l) with absolute tolerance
    ``tol`` (default numpy's matrix_rank rule): the ``absolute``/``numpy`` rules."""
    u, s, vt = _cross_cov_svd(cross_cov)
    used = numpy_rank_tol(s, cross_cov.shape) if tol is None else float(tol)
    r = int(np.sum(s > used))
    rule = NUMPY_RANK_RULE if tol is None else RankRule("absolute", float(tol))
    return KernelSplit(RankReport(r, s, used, cross_cov.shape), _moore_penrose_at_rank(u, s, vt, r), vt[r:].T,
                       rule=rule)


def canonical_split(cross_cov: np.ndarray, prior_cov: np.ndarray, cov_y: np.ndarray,
                    tol: float = CANONICAL_RANK_TOL, covariance: str | None = None,
                    unit_free: bool = False) -> KernelSplit:
    """Split of C_xy^m (D, l) at the rank the canonical correlations under C_p^m (D, D) and C_y^m
    (l, l) decide, rank = #{ρ_i > tol} (a unit-free decision), computed so that its rounding does
    not depend on units either (module docstring, "Kernel split"):

    * full column rank: eq. 35's inverse drops nothing and is a left inverse; the one applied is
      A_m = L_y⁻ᵀ V diag(ρ)⁻¹ Uᵀ L_p⁻¹ from the canonical SVD (solves, no inverses), which equals
      (C_xy^m)⁺ on range(C_xy^m), where μ_e^m − μ_p^m lies;
    * rank lost: (C_xy^m)⁺ truncated at that rank in C_xy^m's own SVD (eq. 35 as written; N_m = V_⊥
      orthonormal), the SVD computed by :func:`~gpfverify.linalg.graded_svd`;
    * ``unit_free``: the truncation in the whitened coordinates instead (module docstring, "The
      unit-free variant").

    The recorded singular values are numpy's, as under every rule."""
    cc = canonical_correlations(prior_cov, cov_y, cross_cov, ("C_p^m", "C_y^m"))
    rho = cc.correlations
    r = int(np.sum(rho > tol))
    _, s, _ = _cross_cov_svd(cross_cov)
    rank, rule = RankReport(r, s, float(tol), cross_cov.shape), RankRule("canonical", float(tol))
    d, l = cross_cov.shape
    v_r, v_perp = cc.v[:, :r], cc.v[:, r:]
    whitened = cc.y_from_whitened(v_r / rho[:r]) @ cc.x_dual(cc.u[:, :r]).T if r else np.zeros((l, d))
    if unit_free or r == l:
        return KernelSplit(rank, whitened, cc.y_from_whitened(v_perp), cc.y_factor_times(v_perp), rule, rho,
                           covariance, cc, whitened)
    u, sg, vt = graded_svd(cross_cov)
    return KernelSplit(rank, _moore_penrose_at_rank(u, sg, vt, r), vt[r:].T, None, rule, rho, covariance, cc,
                       whitened)


def sensor_prior_covariance(local: LocalReport, central_cov: np.ndarray | None = None
                            ) -> tuple[np.ndarray, str]:
    """(C_p^m, which) for the canonical rule: C_e^m + C_xy^m (C_y^m)⁻¹ C_xy^mᵀ when the report has
    C_e^m (eq. 16 rearranged; ``"local C_p from C_e"``), else ``central_cov`` (``"central C_p"``).
    InputError when neither is available."""
    if local.C_e is not None:
        return symmetrize(local.C_e + right_solve_spd(local.C_xy, local.C_y, "local C_y") @ local.C_xy.T), \
            COVARIANCE_LOCAL
    if central_cov is None:
        raise InputError("the canonical rank rule needs the sensor's prior covariance: the report has "
                         "no C_e and no central C_p was given")
    return np.asarray(central_cov, dtype=float), COVARIANCE_CENTRAL


def sensor_split(local: LocalReport, rule: RankRule, central_cov: np.ndarray | None = None,
                 unit_free: bool = False) -> KernelSplit:
    """Sensor m's kernel split under ``rule``; the canonical rule whitens with the sensor's C_p^m
    (:func:`sensor_prior_covariance`), falling back to ``central_cov`` when the recovered C_p^m is
    not positive definite even with jitter. ``unit_free`` (canonical rule only) asks for the
    unit-free variant's split instead of the Moore–Penrose one."""
    if unit_free and rule.name != "canonical":
        raise InputError(f"the unit-free variant of DMF needs the canonical rank rule, not {rule.name!r}")
    if rule.name == "numpy":
        return kernel_split(local.C_xy)
    if rule.name == "absolute":
        return kernel_split(local.C_xy, rule.tol)
    assert rule.tol is not None  # RankRule.__post_init__ sets the canonical default
    prior, which = sensor_prior_covariance(local, central_cov)
    try:
        return canonical_split(local.C_xy, prior, local.C_y, rule.tol, which, unit_free)
    except NumericalError:
        if which != COVARIANCE_LOCAL or central_cov is None:
            raise
        return canonical_split(local.C_xy, np.asarray(central_cov, dtype=float), local.C_y, rule.tol,
                               COVARIANCE_CENTRAL, unit_free)


@dataclass(frozen=True)
class SensorExactness:
    """Exactness evidence for sensor ``index``: its kernel split, the gap gain G_m C_y^m N_m
    (D, l − r, state units per unit of Ñ_mᵀ w_m), its 2-norm ``residual`` and the tolerance ``tol``
    that decides ``exact`` — both whitened by L_p⁻¹ (unit-free) under the canonical rule."""

    index: int
    split: KernelSplit
    gap_gain: np.ndarray
    residual: float
    tol: float

    @property
    def exact(self) -> bool:
        """The residual is within its rounding bound, and that bound resolves the condition (at
        most :data:`~gpfverify.tolerances.RESOLVABLE_GAP`; in units where the computed kernel is too
        uncertain the verdict is "not exact", never a false "exact")."""
        return self.residual <= self.tol <= RESOLVABLE_GAP

    @property
    def full_column_rank(self) -> bool:
        return self.split.rank.full_column_rank

    @property
    def repair_dim(self) -> int:
        return self.split.kernel_basis.shape[1]


@dataclass(frozen=True)
class FusedScale:
    """The centre's step in its own units (docs/fusion-definitions.md, "Rounding bound"):
    ``whitening`` holds the canonical correlations of the central prediction, so that L_p⁻¹
    measures a state difference in prior standard deviations (unit-free)."""

    whitening: CanonicalCorrelations

    def whiten(self, a: np.ndarray) -> np.ndarray:
        """L_p⁻¹ a."""
        return self.whitening.whiten_x(np.asarray(a, dtype=float))

    @functools.cached_property
    def inverse(self) -> np.ndarray:
        """L_p⁻¹ (D, D), formed once per step: every rounding magnitude goes through it."""
        return self.whiten(np.eye(self.whitening.u.shape[0]))

    @property
    def factor_y(self) -> np.ndarray:
        """L_y (L, L), the central C_y's equilibrated factor diag(d) L_c."""
        return self.whitening.scale_y[:, None] * self.whitening.factor_y

    def rounding(self, gain: np.ndarray, central: CentralPrediction) -> FusedRounding:
        """This step as a :class:`~gpfverify.fusion.rounding.FusedRounding` of one step."""
        return FusedRounding(self.inverse[None], gain[None], central.mu_p[None], central.mu_y[None])


def fused_scale(central: CentralPrediction) -> FusedScale:
    """:class:`FusedScale` of the central prediction."""
    return FusedScale(canonical_correlations(central.C_p, central.C_y, central.C_xy, ("C_p", "C_y")))


def _norm2(a: np.ndarray) -> float:
    return float(np.linalg.norm(a, 2)) if a.size else 0.0


def _factor_conditions(whitening: CanonicalCorrelations) -> float:
    """κ(L_p,c) + κ(L_y,c): how much the two equilibrated whitenings of the canonical SVD can
    amplify rounding (unit-free)."""
    return sum(float(np.linalg.cond(f)) if f.size else 1.0 for f in (whitening.factor_x, whitening.factor_y))


def sensor_factor(split: KernelSplit, cov_y: np.ndarray) -> np.ndarray:
    """L_y^m = diag(d) L_c (l, l), the equilibrated Cholesky factor of C_y^m (the canonical split's
    own, else factored here)."""
    whitening = split.whitening
    d_y, l_y = ((whitening.scale_y, whitening.factor_y) if whitening is not None
                else equilibrated_cholesky(cov_y, "local C_y"))
    return d_y[:, None] * l_y


def _exactness_evidence(fused: FusedRounding, floor: np.ndarray, gain_condition: float, block: slice,
                        gain_times_cov: np.ndarray, cov_y: np.ndarray, split: KernelSplit) -> tuple[float, float]:
    """(residual, bound) of the kernel-inclusion condition for one sensor (module docstring,
    "Exactness verdict"): residual R_m = ‖L_p⁻¹ G_m C_y^m Π_m L_y⁻ᵀ‖₂, the gap in prior standard
    deviations per unit whitened innovation through the kernel projector Π_m of the rank rule, and
    its rounding bound :func:`~gpfverify.fusion.rounding.exactness_bound`. The canonical rule
    decides and projects in whitened coordinates (Π_m = L_y⁻ᵀ V_⊥ V_⊥ᵀ L_yᵀ: ω_m = 1, and V_⊥ from
    the canonical SVD, θ_m = (κ(L_p,c) + κ(L_y,c)) ρ_1/ρ_r); the SVD rules in C_xy^m's own
    coordinates (Π_m = N_m N_mᵀ: ω_m = ‖L_yᵀN_m‖ ‖L_y⁻¹N_m‖, θ_m = σ_1/σ_r ‖L_y‖ ‖L_y⁻¹N_m‖)."""
    basis = split.kernel_basis
    if not basis.shape[1]:
        return 0.0, 0.0
    factor = sensor_factor(split, cov_y)
    whitened_gain = fused.inverse[0] @ fused.gain[0, :, block] @ factor                      # L_p⁻¹ G_m L_y^m
    r = split.rank.rank
    kernel = split.whitened_kernel
    if kernel is not None:
        assert split.whitening is not None and split.correlations is not None  # a canonical split
        residual = _norm2(whitened_gain @ kernel)
        rho = split.correlations
        obliqueness, angle = 1.0, (_factor_conditions(split.whitening) * float(rho[0] / rho[r - 1]) if r else 0.0)
    else:
        dual = lower_solve(factor, split.dual_basis)                                          # L_y⁻¹ N_m
        residual = _norm2(whitened_gain @ (factor.T @ basis) @ dual.T)
        s = split.rank.singular_values
        obliqueness = _norm2(factor.T @ basis) * _norm2(dual)
        angle = float(s[0] / s[r - 1]) * _norm2(factor) * _norm2(dual) if r else 0.0
    bound = exactness_bound(fused, floor, np.array([gain_condition]), block, factor[None],
                            np.array([obliqueness]), np.array([angle]))
    return residual, float(bound[0])


def analyse_sensors(case: FusionCase, gain: np.ndarray, rank_tol: float | None = None,
                    rank_rule=None, unit_free: bool = False, scale: FusedScale | None = None
                    ) -> tuple[SensorExactness, ...]:
    """Kernel split, gap gain and exactness evidence of every sensor under the rule
    :func:`resolve_rank_rule` picks (``rank_rule``, else absolute ``rank_tol``, else
    ``case.rank_tol``, else canonical); ``unit_free`` for the unit-free variant's splits."""
    rule = resolve_rank_rule(case, rank_rule, rank_tol)
    central = case.central
    scale = fused_scale(central) if scale is None else scale
    fused = scale.rounding(gain, central)
    floor = gain_condition = None  # the estimate's own rounding, computed when a sensor has a kernel
    out = []
    for m, (block, local) in enumerate(zip(central.blocks, case.locals)):
        split = sensor_split(local, rule, central.C_p, unit_free)
        gain_times_cov = gain[:, block] @ local.C_y
        residual = tol = 0.0
        if split.kernel_basis.shape[1]:
            if floor is None or gain_condition is None:
                floor = estimate_floor(fused, scale.factor_y[None])
                gain_condition = correlation_condition(central.C_y)
            residual, tol = _exactness_evidence(fused, floor, gain_condition, block, gain_times_cov, local.C_y,
                                                split)
        out.append(SensorExactness(m, split, gain_times_cov @ split.kernel_basis, residual, tol))
    return tuple(out)


def whitened_innovation(local: LocalReport, y_m: np.ndarray) -> np.ndarray:
    """w_m = (C_y^m)⁻¹ (y^m ⊖ μ_y^m), the vector the local update multiplies by C_xy^m (angle
    outputs wrapped)."""
    return solve_spd(local.C_y, difference(y_m, local.mu_y, local.circular), "local C_y")


def repair_message(local: LocalReport, y_m: np.ndarray, rank_tol: float | None = None, *,
                   rank_rule=None, prior_cov: np.ndarray | None = None,
                   split: KernelSplit | None = None) -> np.ndarray:
    """What sensor m sends besides eq. 34 so that DMF is exact: the kernel component
    k_m = (I − P_m) w_m (an l_m-vector in an (l_m − r_m)-dimensional subspace; basis-free).

    The split is ``split`` when given, else the one :func:`sensor_split` computes under
    ``rank_rule`` (or absolute ``rank_tol``; default canonical); the canonical rule whitens with the
    C_p^m recovered from ``local.C_e`` or, without C_e, with ``prior_cov``. Sensor and centre must
    use the same rule (and covariance)."""
    if split is None:
        split = sensor_split(local, resolve_rank_rule(None, rank_rule, rank_tol), prior_cov)
    return split.kernel_component(whitened_innovation(local, y_m))


def branch_offsets(case: FusionCase) -> tuple[np.ndarray, ...]:
    """Per sensor the integers n_m ∈ {−1, 0, 1}^{l_m} with
    wrap(μ_y^m − μ_y(m)) + wrap(y^m − μ_y^m) − wrap(y^m − μ_y(m)) = 2π n_m on the angle outputs
    (zero elsewhere; module docstring, "branch offsets"). Needs ``case.y``."""
    out = []
    for m, (block, local) in enumerate(zip(case.central.blocks, case.locals)):
        n = np.zeros(local.mu_y.shape[0], dtype=int)
        if local.circular:
            j = list(local.circular)
            central_part = wrap(local.mu_y[j] - case.central.mu_y[block][j])
            total = central_part + wrap(case.local_measurement(m)[j] - local.mu_y[j])
            n[j] = np.rint((total - wrap(total)) / TWO_PI).astype(int)
        out.append(n)
    return tuple(out)


def sensor_gap(case: FusionCase, sensor: SensorExactness, gain: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Sensor m's share of μ_DMF − μ_CMF: 2π G_m n_m − (G_m C_y^m N_m)(Ñ_mᵀ w_m) (needs ``case.y``)."""
    w = whitened_innovation(case.locals[sensor.index], case.local_measurement(sensor.index))
    g_m = gain[:, case.central.blocks[sensor.index]]
    return TWO_PI * (g_m @ offsets) - sensor.gap_gain @ (sensor.split.dual_basis.T @ w)


def predicted_gap(case: FusionCase, sensors: tuple[SensorExactness, ...], gain: np.ndarray | None = None
                  ) -> np.ndarray:
    """Closed-form μ_DMF − μ_CMF = Σ_m [2π G_m n_m − (G_m C_y^m N_m)(Ñ_mᵀ w_m)], the sum of
    :func:`sensor_gap` (``gain`` G defaults to the case's; needs ``case.y``)."""
    gain = fusion_gain(case.central) if gain is None else gain
    gap = np.zeros(case.state_dim)
    for s, n in zip(sensors, branch_offsets(case)):
        gap += sensor_gap(case, s, gain, n)
    return gap


def local_consistency_residual(case: FusionCase, m: int) -> np.ndarray:
    """μ_e^m − μ_p^m − C_xy^m w_m (w_m from the wrapped innovation): zero when the logged local
    posterior is the local update with the logged y (eq. 32); when it is not, the observed gap
    need not equal the predicted one."""
    local = case.locals[m]
    change = difference(local.mu_e, local.mu_p, case.circular_state)
    return change - local.C_xy @ whitened_innovation(local, case.local_measurement(m))


def sensor_terms(case: FusionCase, sensor: SensorExactness) -> SensorTerms:
    """Sensor m's operands of the step's rounding bound (one step, B = 1; docs/fusion-definitions.md,
    "Rounding bound"). The bound is the step's rounding *when DMF is exact*; there G_m C_y^m annuls
    every kernel component, so eq. 35's Moore–Penrose inverse and the whitened one move the state
    alike, and a canonical split's operands are those of the whitened one, A_m = L_y⁻ᵀ V_r
    diag(ρ_r)⁻¹ U_rᵀ L_p⁻¹, whose magnitudes do not change with units. Its reconstruction error
    e_m: :func:`~gpfverify.fusion.rounding.left_inverse_error` (two triangular solves with the
    equilibrated factors and the canonical SVD, amplified by ρ_1/ρ_r), plus, when the rank was lost
    and the Jacobi SVD computed eq. 35's inverse, that SVD's componentwise backward error carried by
    A_m, ‖ |L_yᵀ A_m| (|C_xy^m| |r_m| + |μ_e^m − μ_p^m|) ‖. Under the SVD rules the operands are
    numpy's SVD's own (:func:`~gpfverify.fusion.rounding.svd_inverse_error`; they depend on units,
    as those rules do). A sensor with a kernel adds the gap its exactness bound lets through,
    τ_m ‖z_m‖ (needs ``case.y``)."""
    local = case.locals[sensor.index]
    split = sensor.split
    factor = sensor_factor(split, local.C_y)
    change = difference(local.mu_e, local.mu_p, case.circular_state)
    inverse = split.pinv if split.whitened_inverse is None else split.whitened_inverse
    recovered = inverse @ change
    r = split.rank.rank
    if not r:
        error = 0.0
    elif split.whitened_inverse is None:
        error = float(svd_inverse_error(split.rank.singular_values[None], r, factor[None], recovered[None])[0])
    else:
        rho = split.correlations
        assert split.whitening is not None and rho is not None  # a canonical split
        condition = _factor_conditions(split.whitening) * (1.0 + float(rho[0] / rho[r - 1]))
        error = float(left_inverse_error(np.array([condition]), factor[None], recovered[None])[0])
        if inverse is not split.pinv:  # the Jacobi SVD's Moore–Penrose inverse
            error += float(sla.norm(np.abs(factor.T @ inverse) @ (np.abs(local.C_xy) @ np.abs(recovered)
                                                                   + np.abs(change))))
    accepted = None
    if split.kernel_basis.shape[1]:  # the gap an exact-judged kernel may leave: τ_m ‖z_m‖
        innovation = difference(case.local_measurement(sensor.index), local.mu_y, local.circular)
        whitened = lower_solve(factor, innovation)                                            # z_m = L_y⁻¹ (…)
        accepted = np.array([sensor.tol * float(sla.norm(whitened))])
    return SensorTerms(case.central.blocks[sensor.index], local.mu_y[None], local.mu_p[None], local.mu_e[None],
                       local.C_y[None], local.C_xy[None], inverse[None], recovered[None], factor[None],
                       np.array([correlation_condition(local.C_y)]), np.array([error]), accepted)


def equivalence_tolerance(case: FusionCase, gain: np.ndarray, sensors: tuple[SensorExactness, ...],
                          scale: FusedScale | None = None) -> float:
    """Rounding bound on ‖L_p⁻¹(μ_DMF − μ_CMF)‖₂, in prior standard deviations, when DMF is exact
    at the rank rule used (docs/fusion-definitions.md, "Rounding bound";
    :func:`~gpfverify.fusion.rounding.gap_bound`, the same function the batched audit uses).
    Needs ``case.y``."""
    c = case.central
    scale = fused_scale(c) if scale is None else scale
    if case.y is None:
        raise InputError("the rounding bound of the gap needs the measurement y")
    bound = gap_bound(scale.rounding(gain, c), case.y[None], [sensor_terms(case, s) for s in sensors])
    return float(bound[0])


def gap_size(case: FusionCase, gap: np.ndarray, scale: FusedScale | None = None) -> float:
    """‖L_p⁻¹ gap‖₂: a state difference in prior standard deviations (unit-free)."""
    scale = fused_scale(case.central) if scale is None else scale
    return float(sla.norm(scale.whiten(gap)))


def rescaled_case(case: FusionCase, state_scale, output_scale) -> FusionCase:
    """The same fusion step in other units: x → S_x x and y → S_y y with S_x = diag(state_scale)
    (D positive numbers) and S_y = diag(output_scale) (L, stacked; sensor m's block scales its
    outputs), e.g. 1e6 on a bearing for radians → microradians. Means scale as their variable,
    covariances as S C S; the case's absolute ``rank_tol`` is kept as it is (it has no units to
    follow). Angle outputs and angle state components must keep scale 1 (wrapping is in radians):
    InputError otherwise."""
    s_x = np.asarray(state_scale, dtype=float)
    s_y = np.asarray(output_scale, dtype=float)
    c = case.central
    if s_x.shape != (case.state_dim,) or s_y.shape != c.mu_y.shape:
        raise InputError(f"scales must have shapes ({case.state_dim},) and {c.mu_y.shape}, "
                         f"got {s_x.shape} and {s_y.shape}")
    if not (np.all(np.isfinite(s_x)) and np.all(s_x > 0) and np.all(np.isfinite(s_y)) and np.all(s_y > 0)):
        raise InputError("scales must be finite and positive")
    if c.circular and np.any(s_y[list(c.circular)] != 1.0):
        raise InputError(f"angle outputs {list(c.circular)} must keep scale 1 (wrapping is in radians)")
    if c.circular_state and np.any(s_x[list(c.circular_state)] != 1.0):
        raise InputError(f"angle state components {list(c.circular_state)} must keep scale 1 (wrapping is in radians)")
    central = CentralPrediction(s_x * c.mu_p, c.C_p * np.outer(s_x, s_x), s_y * c.mu_y,
                                c.C_y * np.outer(s_y, s_y), c.C_xy * np.outer(s_x, s_y), c.sizes, c.circular,
                                c.circular_state)
    reports = []
    for block, r in zip(c.blocks, case.locals):
        s_m = s_y[block]
        reports.append(replace(r, mu_p=s_x * r.mu_p, mu_y=s_m * r.mu_y, C_y=r.C_y * np.outer(s_m, s_m),
                               C_xy=r.C_xy * np.outer(s_x, s_m), mu_e=s_x * r.mu_e,
                               C_e=None if r.C_e is None else r.C_e * np.outer(s_x, s_x)))
    return FusionCase(central, tuple(reports), None if case.y is None else s_y * case.y, case.rank_tol)
