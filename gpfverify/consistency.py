"""Filter consistency tests: NEES, NIS, their averages over Monte Carlo runs or over time, and a
conservativeness check for covariance-intersection-type fusion results.

After Bar-Shalom, Li & Kirubarajan, *Estimation with Applications to Tracking and Navigation*
(Wiley, 2001), §5.4.2 (NEES) and §5.4.3 (NIS). A filter is *consistent* when its errors are
zero-mean with the covariance it reports.

Normalised statistics (one per run r and step k):

    NEES  ε_k = (x_k ⊖ x̂_k)ᵀ P_k⁻¹ (x_k ⊖ x̂_k),     x_k the true state, (x̂_k, P_k) the estimate;
    NIS   ν_kᵀ S_k⁻¹ ν_k,   ν_k = y_k ⊖ μ_y,k,       S_k = C_y,k (the predicted measurement covariance,
                                                      noise included);

⊖ is the difference with the angle components wrapped to (−π, π] (:func:`gpfverify.angles.difference`;
``circular_state`` for NEES, ``circular`` outputs for NIS). The quadratic forms are computed as
‖L⁻¹ e‖² with P = L Lᵀ (a Cholesky factor and a triangular solve, never an inverse). For a
consistent filter on a linear-Gaussian model ε_k ~ χ²(D) and the NIS ~ χ²(L) exactly.

Averages (:class:`Consistency`; D the state or measurement dimension):

* over R independent Monte Carlo runs at each step, ANEES/ANIS ε̄_k = (1/R) Σ_r ε_r,k with
  R·ε̄_k ~ χ²(R·D); the two-sided interval at level 1 − α is
  [χ²_{R·D}(α/2), χ²_{R·D}(1 − α/2)] / R  (``level`` = 0.95: the 2.5 % and 97.5 % quantiles);
* over the T steps of one run, ε̄ = (1/T) Σ_k ε_k with T·ε̄ ~ χ²(T·D), the same interval with
  T·D degrees of freedom and divisor T. Exact for the NIS of the optimal filter (its innovations
  are white); for the NEES successive errors are correlated and the χ² law is approximate, as in
  Bar-Shalom et al.

Each average gives a :class:`ChiSquareTest`: one averaged value per step (or per run), the bounds,
the degrees of freedom and the level. Its :meth:`~ChiSquareTest.verdict` counts the values outside
the bounds: with n tests each outside with probability 1 − level under consistency, the count is
Binomial(n, 1 − level) and the filter is rejected when P(count ≥ observed) ≤ α (default
α = 1 − level; for a single value this is exactly the two-sided interval test). The binomial law is
exact for independent tests (runs, or the steps of the ANIS of the optimal filter) and approximate
for the steps of an ANEES (correlated through the recursion). A rejected filter is *optimistic*
(too many values above the upper bound: covariance too small) or *pessimistic* (below the lower
bound: covariance too large).

Conservativeness (:func:`conservativeness`), for CI, ICI, RCC-CI and other rules whose covariance
is meant to be an upper bound: is the claimed P ⪰ Σ = E[e eᵀ], the true error second moment?
From R Monte Carlo errors e_r with whitened z_r = L_r⁻¹ e_r (P_r = L_r L_rᵀ; one P or one per run),

    λ̂ = λ_max(M),   M = (1/R) Σ_r z_r z_rᵀ   (= λ_max(P^{-1/2} Ê P^{-1/2}) for a common P,
                                               Ê = (1/R) Σ_r e_r e_rᵀ).

Under H0 (e_r ~ N(0, Σ_r) independent, Σ_r ⪯ P_r) z_r = A_r^{1/2} g_r with A_r ⪯ I and g_r standard
normal, so R·M = Xᵀ X for an R × D matrix X whose largest singular value is a 1-Lipschitz function
of the g_r with E s_max(X) ≤ √R + √D (Gordon's bound for A_r = I, Davidson & Szarek 2001, Thm II.13;
extended to A_r ⪯ I by the Sudakov–Fernique inequality, the increments being dominated). Gaussian
concentration then gives P(s_max ≥ √R + √D + t) ≤ exp(−t²/2) (Vershynin 2012, Cor. 5.35), hence

    P(λ̂ > (√R + √D + t)² / R) ≤ 1 − level   for t = √(2 ln(1 / (1 − level))).

This bound is rigorous (no asymptotics, no resampling) for Gaussian errors and holds at the boundary
Σ = P, so a violation is evidence of an under-estimated covariance in the direction of the top
eigenvector. It assumes zero-mean Gaussian errors (exact on linear-Gaussian models, approximate
otherwise); it is one-sided (a very pessimistic P passes). The guarantee costs power: at D = 2,
R = 50 and Σ = P no exceedance of the level-0.95 bound occurred in 4000 repetitions, and the
bound is (1 + √(D/R) + t/√R)² (≈ 1.34 for R = 600, D = 2), so only under-estimation by more than
that factor is reliably flagged; the statistic is reported for finer judgement.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gpfverify.angles import difference
from gpfverify.errors import InputError
from gpfverify.tolerances import ALGEBRA_RTOL, MONTE_CARLO_SIGMAS
from gpfverify.validate import SYMMETRY_RTOL, as_array, as_indices

#: default level of the two-sided χ² intervals (Bar-Shalom et al.'s 95 % region)
DEFAULT_LEVEL: float = 0.95
#: Level whose false-alarm probability matches ``tolerances.MONTE_CARLO_SIGMAS`` standard errors of
#: a normal estimate, 1 − 2 Φ(−MONTE_CARLO_SIGMAS) (≈ 1 − 5.7e-7 for 5): for assertions in tests
#: (``assert_consistent(..., alpha=1 − STRICT_LEVEL)`` or a test built at this level).
STRICT_LEVEL: float = 1.0 - math.erfc(MONTE_CARLO_SIGMAS / math.sqrt(2.0))  # 1 − 2Φ(−k)

CONSISTENT, OPTIMISTIC, PESSIMISTIC = "consistent", "optimistic", "pessimistic"
CONSERVATIVE, NOT_CONSERVATIVE = "conservative", "not conservative"


# -- validation --------------------------------------------------------------------------------

def _probability(value, name: str) -> float:
    """A float strictly inside (0, 1)."""
    try:
        p = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number in (0, 1), got {value!r}") from None
    if not (0.0 < p < 1.0):  # also rejects NaN
        raise InputError(f"{name} must be in the open interval (0, 1), got {value!r}")
    return p


def _cholesky(covs: np.ndarray, name: str) -> np.ndarray:
    """Lower Cholesky factors of a stack of covariances (..., D, D); InputError naming ``name`` (and
    the first offending index) when one is not symmetric or not positive definite."""
    scale = np.maximum(np.abs(covs).max(axis=(-2, -1), initial=0.0), np.finfo(float).tiny)
    asym = np.abs(covs - np.swapaxes(covs, -1, -2)).max(axis=(-2, -1), initial=0.0)
    bad = asym > SYMMETRY_RTOL * scale
    if np.any(bad):
        where = tuple(int(i) for i in np.argwhere(bad)[0])
        raise InputError(f"{name} is not symmetric" + (f" at index {where}" if where else ""))
    sym = 0.5 * (covs + np.swapaxes(covs, -1, -2))
    try:
        return np.linalg.cholesky(sym)
    except np.linalg.LinAlgError:
        pass
    lowest = np.linalg.eigvalsh(sym)[..., 0]
    first = np.unravel_index(int(np.argmin(lowest)), lowest.shape)
    where = tuple(int(i) for i in first)
    raise InputError(f"{name} is not positive definite" + (f" at index {where}" if where else "")
                     + f" (min eigenvalue {lowest[first]:.3g})")


def _squared_whitened(errors: np.ndarray, covs: np.ndarray, name: str) -> np.ndarray:
    """eᵀ P⁻¹ e = ‖L⁻¹ e‖² over the leading axes (triangular solve, no inverse)."""
    factor = _cholesky(covs, name)
    white = np.linalg.solve(factor, errors[..., None])[..., 0]
    return np.einsum("...i,...i->...", white, white)


def _runs_steps(value, name: str, dim: int | None = None) -> np.ndarray:
    """A finite (R, T, D) array; a single run (T, D) becomes (1, T, D)."""
    arr = as_array(value, name)
    if arr.ndim == 2:
        arr = arr[None]
    if arr.ndim != 3:
        raise InputError(f"{name} must have shape (T, D) or (R, T, D), got {np.shape(value)}")
    if 0 in arr.shape:
        raise InputError(f"{name} must not be empty, got shape {np.shape(value)}")
    if dim is not None and arr.shape[-1] != dim:
        raise InputError(f"{name} must have {dim} entries in its last axis, got shape {np.shape(value)}")
    return arr


def _matching(value, name: str, shape: tuple[int, ...], single_run: bool) -> np.ndarray:
    """A finite array of exactly ``shape`` (R, T, ...) — (T, ...) accepted for a single run."""
    arr = as_array(value, name)
    if single_run and arr.shape == shape[1:]:
        arr = arr[None]
    if arr.shape != shape:
        want = shape[1:] if single_run else shape
        raise InputError(f"{name} must have shape {want}, got {np.shape(value)}")
    return arr


def chi2_interval(dof: int, divisor: float, level: float = DEFAULT_LEVEL) -> tuple[float, float]:
    """Two-sided interval [χ²_dof((1 − level)/2), χ²_dof((1 + level)/2)] / divisor: the quantiles
    2 P⁻¹(dof/2, ·) and 2 Q⁻¹(dof/2, ·) of the regularised incomplete gamma function, as
    scipy.stats.chi2 computes them (scipy.special: without scipy.stats' second of import)."""
    level = _probability(level, "level")
    if int(dof) != dof or dof < 1:
        raise InputError(f"dof must be a positive integer, got {dof!r}")
    tail = 0.5 * (1.0 - level)
    from scipy.special import gammainccinv, gammaincinv

    return float(2.0 * gammaincinv(0.5 * dof, tail) / divisor), float(2.0 * gammainccinv(0.5 * dof, tail) / divisor)


# -- results -----------------------------------------------------------------------------------

@dataclass(frozen=True)
class ChiSquareTest:
    """Averaged normalised errors against their two-sided χ² interval.

    ``name`` ("ANEES", "ANIS", "time-averaged NEES", "time-averaged NIS"); ``values`` (n,) the
    averages (one per step for an average over runs, one per run for an average over time);
    ``lower``, ``upper`` the interval on each value (module docstring); ``samples`` the number of
    normalised errors in each average (R or T); ``dim`` the state or measurement dimension;
    ``dof`` = samples · dim, the degrees of freedom of samples · value ~ χ²(dof); ``level``."""

    name: str
    values: np.ndarray
    lower: float
    upper: float
    samples: int
    dim: int
    dof: int
    level: float

    @property
    def expected(self) -> int:
        """E[value] = dim under consistency."""
        return self.dim

    @property
    def inside(self) -> np.ndarray:
        """Boolean (n,): lower ≤ value ≤ upper."""
        return (self.values >= self.lower) & (self.values <= self.upper)

    @property
    def n_above(self) -> int:
        return int(np.count_nonzero(self.values > self.upper))

    @property
    def n_below(self) -> int:
        return int(np.count_nonzero(self.values < self.lower))

    @property
    def fraction_inside(self) -> float:
        return float(np.mean(self.inside))

    def p_value(self) -> float:
        """P(Binomial(n, 1 − level) ≥ number of values outside the interval)."""
        outside = self.n_above + self.n_below
        if outside == 0:
            return 1.0
        from scipy.special import bdtrc  # the binomial survival function scipy.stats.binom.sf uses

        return float(bdtrc(outside - 1, self.values.size, 1.0 - self.level))

    def verdict(self, alpha: float | None = None) -> str:
        """"consistent", "optimistic" or "pessimistic": rejected when :meth:`p_value` ≤ ``alpha``
        (default 1 − level; compared up to rounding, ``tolerances.ALGEBRA_RTOL`` relative), then
        named after the side with more values outside (ties: optimistic, the unsafe side)."""
        alpha = 1.0 - self.level if alpha is None else _probability(alpha, "alpha")
        if self.p_value() > alpha * (1.0 + ALGEBRA_RTOL):
            return CONSISTENT
        return OPTIMISTIC if self.n_above >= self.n_below else PESSIMISTIC

    def passed(self, alpha: float | None = None) -> bool:
        return self.verdict(alpha) == CONSISTENT

    def summary(self, alpha: float | None = None) -> str:
        """One readable paragraph: the verdict, the interval, the counts and the extreme values."""
        v = self.values
        return (f"{self.name}: {self.verdict(alpha)} — {v.size - self.n_above - self.n_below} of "
                f"{v.size} value(s) inside [{self.lower:.4g}, {self.upper:.4g}] "
                f"(level {self.level:g}, {self.samples} sample(s) x dim {self.dim} = {self.dof} dof, "
                f"expected {self.expected}); {self.n_above} above, {self.n_below} below; "
                f"min {v.min():.4g}, mean {v.mean():.4g}, max {v.max():.4g}; "
                f"binomial p-value of the count outside {self.p_value():.3g}")


@dataclass(frozen=True)
class Consistency:
    """Normalised errors ``values`` (R, T) of R runs over T steps, ``kind`` "NEES" or "NIS",
    ``dim`` the dimension D of the state (NEES) or measurement (NIS). Build with
    :meth:`from_estimates`, :meth:`from_records`, :meth:`from_fusion`, :meth:`nis` or
    :meth:`nis_from_records`; test with :meth:`average_over_runs` or :meth:`average_over_time`."""

    kind: str
    values: np.ndarray
    dim: int

    @property
    def runs(self) -> int:
        return self.values.shape[0]

    @property
    def steps(self) -> int:
        return self.values.shape[1]

    def average_over_runs(self, level: float = DEFAULT_LEVEL) -> ChiSquareTest:
        """ANEES / ANIS at every step, (1/R) Σ_r ε_r,k (T,), against χ²(R·D)/R."""
        lower, upper = chi2_interval(self.runs * self.dim, self.runs, level)
        return ChiSquareTest("A" + self.kind, self.values.mean(axis=0), lower, upper, self.runs,
                             self.dim, self.runs * self.dim, float(level))

    def average_over_time(self, level: float = DEFAULT_LEVEL) -> ChiSquareTest:
        """Time-averaged NEES / NIS of every run, (1/T) Σ_k ε_r,k (R,), against χ²(T·D)/T."""
        lower, upper = chi2_interval(self.steps * self.dim, self.steps, level)
        return ChiSquareTest("time-averaged " + self.kind, self.values.mean(axis=1), lower, upper,
                             self.steps, self.dim, self.steps * self.dim, float(level))

    # -- constructors ----------------------------------------------------------------------

    @classmethod
    def from_estimates(cls, truth, means, covs, *, circular_state: Sequence[int] = ()) -> Consistency:
        """NEES of estimates ``means`` (R, T, D), ``covs`` (R, T, D, D) of the states ``truth``
        (R, T, D); a single run may be given as (T, D), (T, D, D). ``circular_state``: the angle
        components (wrapped differences)."""
        x = _runs_steps(truth, "truth")
        single = np.ndim(truth) == 2
        R, T, D = x.shape
        m = _matching(means, "means", (R, T, D), single)
        P = _matching(covs, "covs", (R, T, D, D), single)
        err = difference(x, m, as_indices(circular_state, D, "circular_state"))
        return cls("NEES", _squared_whitened(err, P, "covs"), D)

    @classmethod
    def from_records(cls, truth, records, *, circular_state: Sequence[int] = ()) -> Consistency:
        """NEES of per-step estimate objects: ``records[r][t]`` (or ``records[t]`` for a single run
        with ``truth`` (T, D)) with ``mean`` and ``cov`` — :class:`~gpfverify.filters.records.Gaussian`,
        a fused estimate (CMF/DMF posterior, CW, CI, ICI, RCC-CI results), a particle filter's
        :class:`~gpfverify.filters.resampling.ParticleStep` — or a
        :class:`~gpfverify.filters.records.StepRecord` (its posterior μ_e, C_e)."""
        single = np.ndim(truth) == 2
        nested = [records] if single else records
        means, covs = _collect(nested, "records", _posterior_fields)
        return cls.from_estimates(truth, means, covs, circular_state=circular_state)

    @classmethod
    def from_fusion(cls, truth, runs, method: str, *, circular_state: Sequence[int] = ()) -> Consistency:
        """NEES of the fused estimates of ``method`` ("cmf", "dmf", "cc", "ci", ...; gpfverify.fusion.names) of
        :class:`~gpfverify.model_fusion.FusionRun`\\ s ``runs`` (one per run; a single run
        with ``truth`` (T, D)); use the model's ``circular_state``."""
        single = np.ndim(truth) == 2
        runs = [runs] if single else list(runs)
        for r, run in enumerate(runs):
            if not hasattr(run, "steps"):
                raise InputError(f"runs[{r}] must be a FusionRun, got {type(run).__name__}")
        records = [[s.estimate(method) for s in run.steps] for run in runs]
        return cls.from_records(truth, records[0] if single else records, circular_state=circular_state)

    @classmethod
    def nis(cls, measurements, predicted, innovation_covs, *, circular: Sequence[int] = ()) -> Consistency:
        """NIS of ``measurements`` (R, T, L) against the predicted measurements ``predicted``
        (R, T, L) with covariances ``innovation_covs`` S = C_y (R, T, L, L); a single run as
        (T, L), (T, L, L). ``circular``: the angle outputs (wrapped innovations)."""
        y = _runs_steps(measurements, "measurements")
        single = np.ndim(measurements) == 2
        R, T, L = y.shape
        mu = _matching(predicted, "predicted", (R, T, L), single)
        S = _matching(innovation_covs, "innovation_covs", (R, T, L, L), single)
        nu = difference(y, mu, as_indices(circular, L, "circular"))
        return cls("NIS", _squared_whitened(nu, S, "innovation_covs"), L)

    @classmethod
    def nis_from_records(cls, measurements, records, *, circular: Sequence[int] = ()) -> Consistency:
        """NIS from step records with ``mu_y`` and ``C_y`` (:class:`~gpfverify.filters.records.StepRecord`,
        e.g. a fusion run's ``steps[t].cmf`` or ``steps[t].local[m]``): ``records[r][t]``, or
        ``records[t]`` for a single run with ``measurements`` (T, L)."""
        single = np.ndim(measurements) == 2
        nested = [records] if single else records
        mu, S = _collect(nested, "records", _measurement_fields)
        return cls.nis(measurements, mu, S, circular=circular)


def _posterior_fields(obj):
    if hasattr(obj, "mean") and hasattr(obj, "cov"):
        return obj.mean, obj.cov
    if hasattr(obj, "mu_e") and hasattr(obj, "C_e"):
        return obj.mu_e, obj.C_e
    return None


def _measurement_fields(obj):
    if hasattr(obj, "mu_y") and hasattr(obj, "C_y"):
        return obj.mu_y, obj.C_y
    return None


def _collect(nested, name: str, fields) -> tuple[np.ndarray, np.ndarray]:
    """Two nested lists [r][t] of the fields of ``nested[r][t]``; InputError naming the element."""
    firsts, seconds = [], []
    try:
        runs = list(nested)
    except TypeError:
        raise InputError(f"{name} must be a sequence (over runs) of sequences (over steps)") from None
    for r, run in enumerate(runs):
        try:
            steps = list(run)
        except TypeError:
            raise InputError(f"{name}[{r}] must be a sequence over steps, got {type(run).__name__}") from None
        row_a, row_b = [], []
        for t, obj in enumerate(steps):
            got = fields(obj)
            if got is None:
                raise InputError(f"{name}[{r}][{t}] ({type(obj).__name__}) has no "
                                 + ("mean/cov (or mu_e/C_e)" if fields is _posterior_fields else "mu_y/C_y"))
            row_a.append(np.asarray(got[0], dtype=float))
            row_b.append(np.asarray(got[1], dtype=float))
        firsts.append(row_a)
        seconds.append(row_b)
    try:
        return np.array(firsts), np.array(seconds)
    except ValueError:
        raise InputError(f"{name}: every run must have the same number of steps and every step "
                         f"the same dimension") from None


# -- conservativeness ---------------------------------------------------------------------------

@dataclass(frozen=True)
class ConservativenessTest:
    """Is the claimed covariance an upper bound on the true error second moment? (module docstring)

    ``eigenvalues`` (D,) ascending of M = (1/R) Σ_r z_r z_rᵀ (z_r the errors whitened by the
    claimed covariances); ``statistic`` = λ_max(M); ``bound`` = (√R + √D + t)²/R with
    t = √(2 ln(1/(1 − level))), exceeded with probability ≤ 1 − level when P ⪰ Σ; ``direction``
    (D,) the unit state-space direction v of the largest ratio vᵀ Ê v / vᵀ P v (None when the
    claimed covariance differs between runs); ``samples`` R, ``dim`` D, ``level``."""

    eigenvalues: np.ndarray
    statistic: float
    bound: float
    samples: int
    dim: int
    level: float
    direction: np.ndarray | None

    @property
    def passed(self) -> bool:
        return self.statistic <= self.bound

    def verdict(self) -> str:
        """"conservative" (no evidence against P ⪰ Σ) or "not conservative"."""
        return CONSERVATIVE if self.passed else NOT_CONSERVATIVE

    def summary(self) -> str:
        where = "" if self.direction is None else f" along {np.array2string(self.direction, precision=3)}"
        return (f"conservativeness: {self.verdict()} — largest ratio of the sample error second "
                f"moment to the claimed covariance {self.statistic:.4g}{where} against the bound "
                f"{self.bound:.4g} (level {self.level:g}, {self.samples} runs, dim {self.dim}; "
                f"smallest ratio {self.eigenvalues[0]:.4g})")


def conservativeness_bound(samples: int, dim: int, level: float = DEFAULT_LEVEL) -> float:
    """(√R + √D + t)² / R, t = √(2 ln(1/(1 − level))): an upper (1 − level) bound on λ_max of the
    whitened sample second moment of R Gaussian errors in D dimensions when P ⪰ Σ."""
    level = _probability(level, "level")
    t = math.sqrt(2.0 * math.log(1.0 / (1.0 - level)))
    return (math.sqrt(samples) + math.sqrt(dim) + t) ** 2 / samples


def estimation_errors(truth, means, circular_state: Sequence[int] = ()) -> np.ndarray:
    """truth ⊖ means over the last axis (angle components wrapped); equal shapes (..., D)."""
    x = as_array(truth, "truth")
    if x.ndim < 1 or x.shape[-1] == 0:
        raise InputError(f"truth must have a non-empty last axis, got shape {x.shape}")
    m = as_array(means, "means", shape=x.shape)
    return difference(x, m, as_indices(circular_state, x.shape[-1], "circular_state"))


def conservativeness(errors, claimed_cov, level: float = DEFAULT_LEVEL) -> ConservativenessTest:
    """Test P ⪰ E[e eᵀ] from Monte Carlo errors ``errors`` (R, D) at one step (truth ⊖ estimate
    of R independent runs, :func:`estimation_errors`) and the claimed covariance ``claimed_cov``,
    one (D, D) or one per run (R, D, D). See the module docstring for the statistic and its bound."""
    level = _probability(level, "level")
    e = as_array(errors, "errors", ndim=2)
    R, D = e.shape
    if R < 1 or D < 1:
        raise InputError(f"errors must have shape (R, D) with R, D >= 1, got {e.shape}")
    P = as_array(claimed_cov, "claimed_cov")
    if P.shape not in ((D, D), (R, D, D)):
        raise InputError(f"claimed_cov must have shape ({D}, {D}) or ({R}, {D}, {D}), got {P.shape}")
    factor = _cholesky(P, "claimed_cov")
    common = P.ndim == 2
    if common:
        white = np.linalg.solve(factor, e.T).T
    else:
        white = np.linalg.solve(factor, e[..., None])[..., 0]
    moment = white.T @ white / R
    eigenvalues, vectors = np.linalg.eigh(0.5 * (moment + moment.T))
    direction = None
    if common:  # generalised eigenvector Ê v = λ P v: v = L⁻ᵀ u
        v = np.linalg.solve(factor.T, vectors[:, -1])
        direction = v / np.linalg.norm(v)
        direction = direction * (1.0 if direction[np.argmax(np.abs(direction))] > 0 else -1.0)
    return ConservativenessTest(eigenvalues, float(eigenvalues[-1]), conservativeness_bound(R, D, level),
                                R, D, level, direction)


# -- pytest helper --------------------------------------------------------------------------------

def assert_consistent(result, *, alpha: float | None = None, what: str = "") -> None:
    """AssertionError with the result's summary unless ``result`` passes: a :class:`ChiSquareTest`
    (verdict "consistent" at ``alpha``, default 1 − level) or a :class:`ConservativenessTest`
    (statistic within its bound; ``alpha`` does not apply). ``what`` prefixes the message."""
    prefix = f"{what}: " if what else ""
    if isinstance(result, ChiSquareTest):
        if not result.passed(alpha):
            raise AssertionError(prefix + result.summary(alpha))
    elif isinstance(result, ConservativenessTest):
        if alpha is not None:
            raise InputError("alpha does not apply to a ConservativenessTest (its level is fixed)")
        if not result.passed:
            raise AssertionError(prefix + result.summary())
    else:
        raise InputError(f"result must be a ChiSquareTest or ConservativenessTest, got {type(result).__name__}")
