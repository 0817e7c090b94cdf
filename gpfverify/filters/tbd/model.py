"""Track-before-detect model of Rutten, Ristic & Gordon (FUSION 2005), as used by seed 004 §1.

State s = [x, ẋ, y, ẏ, I] (position, velocity, intensity), near-constant velocity (seed 004 eq. 1–4):

    s_k = F s_{k−1} + v_k,  F = blkdiag(F_cv, F_cv, 1),  F_cv = [[1, T], [0, 1]],
    Q = blkdiag(q1 [[T³/3, T²/2], [T²/2, T]], q1 [[T³/3, T²/2], [T²/2, T]], q2 T).

Existence E_k ∈ {0, 1} is a Markov chain with birth P_b = P{E_k=1 | E_{k−1}=0} and death
P_d = P{E_k=0 | E_{k−1}=1} (eq. 5–7).

Image (eq. 8–9): an n × n grid of cells of size Δ × Δ with centres (iΔ, jΔ), i, j = 0 … n−1;

    z^{(i,j)} = h^{(i,j)}(s) + w^{(i,j)},  w ~ N(0, σ²) independent,
    h^{(i,j)}(s) = Δ² I / (2πΣ²) · exp(−((iΔ − x)² + (jΔ − y)²) / (2Σ²))   for (i, j) ∈ C(s),

and h = 0 outside the patch C(s) of (2p+1)² cells centred on the cell nearest to (x, y) (Rutten's
truncated point spread; cells outside the image are not measured). The likelihood ratio of the
image against "no target" is therefore a product over the patch only:

    L(z | s) = Π_{(i,j) ∈ C(s)} exp(h (2z − h) / (2σ²)).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from gpfverify.errors import InputError
from gpfverify.filters import runs

STATE_DIM = 5
#: indices of x, y and intensity in the state [x, ẋ, y, ẏ, I]
POS = (0, 2)
INTENSITY = 4


@dataclass(frozen=True)
class PatchSpread:
    """The truncated point spread (eq. 9) of N particles on their own patches, in separable form:

        h^{(c_x + a, c_y + b)}(s) = amplitude · along_x[p + a] · along_y[p + b],   |a|, |b| ≤ p,

    with (c_x, c_y) = (``centre_x``, ``centre_y``) the particle's nearest cell; a factor is zero
    where its cell is off the image. Computed once per particle set by
    :meth:`TbdModel.patch_spread` and shared by the likelihood and the second-stage measurement.
    """

    centre_x: np.ndarray  # (N,) int
    centre_y: np.ndarray  # (N,) int
    along_x: np.ndarray  # (2p+1, N): particles last, so numpy's inner loops run over N
    along_y: np.ndarray  # (2p+1, N)
    amplitude: np.ndarray  # (N,)


@dataclass(frozen=True)
class TbdModel:
    """All model constants of the TBD problem (units: cells, frames).

    grid_size n, cell_size Δ, blur Σ, noise_std σ, q1, q2, T, p_birth P_b, p_death P_d,
    patch_radius p (likelihood patch (2p+1)²). The birth density p_b is uniform: position over the
    image, each velocity component on [−velocity_max, velocity_max], intensity on
    ``intensity_range``.
    """

    grid_size: int = 20
    cell_size: float = 1.0
    blur: float = 0.7
    noise_std: float = 1.0
    q1: float = 0.001
    q2: float = 0.01
    period: float = 1.0
    p_birth: float = 0.05
    p_death: float = 0.05
    patch_radius: int = 2
    velocity_max: float = 1.0
    intensity_range: tuple[float, float] = (10.0, 30.0)

    def __post_init__(self):
        if int(self.grid_size) != self.grid_size or self.grid_size < 1:
            raise InputError(f"grid_size must be a positive integer, got {self.grid_size}")
        if int(self.patch_radius) != self.patch_radius or self.patch_radius < 0:
            raise InputError(f"patch_radius must be a non-negative integer, got {self.patch_radius}")
        for name in ("cell_size", "blur", "noise_std", "period", "velocity_max"):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0:
                raise InputError(f"{name} must be positive and finite, got {value}")
        for name in ("q1", "q2"):
            value = getattr(self, name)
            if not np.isfinite(value) or value < 0:
                raise InputError(f"{name} must be non-negative and finite, got {value}")
        for name in ("p_birth", "p_death"):
            value = getattr(self, name)
            if not 0.0 < value < 1.0:
                raise InputError(f"{name} must lie in (0, 1), got {value}")
        lo, hi = self.intensity_range
        if not 0 <= lo < hi:
            raise InputError(f"intensity_range must be (low, high) with 0 <= low < high, got {self.intensity_range}")

    # ---- dynamics ---------------------------------------------------------------------------
    @cached_property
    def transition_matrix(self) -> np.ndarray:
        """F (eq. 3)."""
        T = self.period
        cv = np.array([[1.0, T], [0.0, 1.0]])
        F = np.zeros((STATE_DIM, STATE_DIM))
        F[0:2, 0:2] = cv
        F[2:4, 2:4] = cv
        F[4, 4] = 1.0
        return F

    @cached_property
    def process_cov(self) -> np.ndarray:
        """Q (eq. 4)."""
        T = self.period
        block = self.q1 * np.array([[T**3 / 3, T**2 / 2], [T**2 / 2, T]])
        Q = np.zeros((STATE_DIM, STATE_DIM))
        Q[0:2, 0:2] = block
        Q[2:4, 2:4] = block
        Q[4, 4] = self.q2 * T
        return Q

    @cached_property
    def process_factor(self) -> np.ndarray:
        """Lower factor of Q (Q has full rank when q1, q2 > 0; zero rows otherwise)."""
        eigval, eigvec = np.linalg.eigh(self.process_cov)
        return eigvec * np.sqrt(np.clip(eigval, 0.0, None))

    def propagate(self, states: np.ndarray, rng: runs.Streams) -> np.ndarray:
        """Draws of s_k ~ N(F s_{k−1}, Q) for every row of ``states`` (N, 5), or of (B, N, 5) with
        one Generator per run (:mod:`gpfverify.filters.runs`)."""
        noise = runs.normal(rng, states.shape[-2:]) @ self.process_factor.T
        return states @ self.transition_matrix.T + noise

    # ---- sensor -----------------------------------------------------------------------------
    @property
    def cell_count(self) -> int:
        return self.grid_size * self.grid_size

    @property
    def image_extent(self) -> tuple[float, float]:
        """(low, high) of the imaged interval on each axis: [−Δ/2, (n − ½)Δ]."""
        return -0.5 * self.cell_size, (self.grid_size - 0.5) * self.cell_size

    def in_image(self, states: np.ndarray) -> np.ndarray:
        """Whether each state's position (columns 0 and 2 of ``states`` (..., N, 5)) lies in the
        imaged region :attr:`image_extent` on both axes, (..., N) bool."""
        lo, hi = self.image_extent
        position = states[..., [0, 2]]
        return np.all((position >= lo) & (position <= hi), axis=-1)

    def amplitude(self, intensity) -> np.ndarray:
        """Peak of the point spread, Δ² I / (2πΣ²) (eq. 9)."""
        return self.cell_size**2 * np.asarray(intensity, dtype=float) / (2.0 * np.pi * self.blur**2)

    def nearest_cell(self, coordinate: np.ndarray) -> np.ndarray:
        """Index of the cell whose centre is nearest (integers, possibly outside 0 … n−1)."""
        return np.rint(np.asarray(coordinate) / self.cell_size).astype(np.int64)

    def spread_factor(self, coordinate: np.ndarray, cells: np.ndarray) -> np.ndarray:
        """exp(−(cΔ − x)² / (2Σ²)) for coordinates x and integer cells c broadcast against each
        other, with no truncation (the one evaluation every other method uses)."""
        factor = cells * self.cell_size - coordinate
        factor /= self.blur
        np.square(factor, out=factor)
        factor *= -0.5
        return np.exp(factor, out=factor)

    def axis_spread(self, coordinate: np.ndarray, cells: np.ndarray) -> np.ndarray:
        """Separable factor exp(−(cΔ − x)² / (2Σ²)) of the point spread for each (particle, cell),
        zero where the cell is off the image or outside the particle's patch.

        coordinate (N,), cells (N, W) or (W,) -> (N, W).
        """
        coordinate = np.asarray(coordinate, dtype=float)[:, None]
        cells = np.broadcast_to(cells, (coordinate.shape[0], np.shape(cells)[-1]))
        inside = (cells >= 0) & (cells < self.grid_size)
        in_patch = np.abs(cells - self.nearest_cell(coordinate)) <= self.patch_radius
        return np.where(inside & in_patch, self.spread_factor(coordinate, cells), 0.0)

    @cached_property
    def patch_offsets(self) -> np.ndarray:
        """−p … p, the cells of a patch relative to its centre along one axis."""
        return np.arange(-self.patch_radius, self.patch_radius + 1)

    def patch_cells(self, coordinate: np.ndarray) -> np.ndarray:
        """Cell indices of each particle's patch along one axis, (N, 2p+1) (may leave the image)."""
        return self.nearest_cell(coordinate)[:, None] + self.patch_offsets

    def patch_spread(self, states: np.ndarray) -> PatchSpread:
        """The point spread of every particle (N, 5) on its own patch (see :class:`PatchSpread`)."""
        centres, factors = [], []
        for axis in POS:
            coordinate = states[:, axis]
            centre = self.nearest_cell(coordinate)
            cells = self.patch_offsets[:, None] + centre
            factor = self.spread_factor(coordinate, cells)
            factor *= cells.view(np.uint64) < self.grid_size  # × 0 off the image (negative cells wrap to huge)
            centres.append(centre)
            factors.append(factor)
        return PatchSpread(centres[0], centres[1], factors[0], factors[1], self.amplitude(states[:, INTENSITY]))

    def expected_image(self, state: np.ndarray) -> np.ndarray:
        """h(s) over the whole image, (n, n) indexed [i_x, i_y], for one state (5,)."""
        cells = np.arange(self.grid_size)
        gx = self.axis_spread(state[POS[0]:POS[0] + 1], cells)[0]
        gy = self.axis_spread(state[POS[1]:POS[1] + 1], cells)[0]
        return float(self.amplitude(state[INTENSITY])) * np.outer(gx, gy)

    def measurement_on_patch(self, spread: PatchSpread, axis_x: np.ndarray, axis_y: np.ndarray,
                             particles: np.ndarray) -> np.ndarray:
        """h^{(i,j)}(s) on the patch axis_x × axis_y (cells on the image, row-major) for the
        particles with indices ``particles`` (M,) of ``spread`` (:meth:`patch_spread`, whose
        factors are read, not recomputed), (len(axis_x) · len(axis_y), M) — particles last.

        axis_x (W,) and axis_y (V,) are one patch for every particle; (W, M) and (V, M) give each
        particle its own patch (column m the cells of particle m: the patches of many runs' second
        stages at once)."""
        gx = self._on_cells(spread.centre_x, spread.along_x, axis_x, particles)
        gy = self._on_cells(spread.centre_y, spread.along_y, axis_y, particles)
        gx *= spread.amplitude[particles]
        return (gx[:, None, :] * gy[None, :, :]).reshape(gx.shape[0] * gy.shape[0], particles.size)

    def _on_cells(self, centre: np.ndarray, along: np.ndarray, cells: np.ndarray, particles: np.ndarray) -> np.ndarray:
        """Patch factors ``along`` (2p+1, N) of the particles ``particles`` (M,) read at image
        cells c, (W,) for all of them or (W, M) one column per particle: the factor of cell c is
        along[c − centre + p] when |c − centre| ≤ p, else 0, (W, M)."""
        cells = cells[:, None] if cells.ndim == 1 else cells
        index = (cells + self.patch_radius) - centre[particles]
        inside = index.view(np.uint64) < along.shape[0]  # below 0 wraps to huge
        index *= along.shape[1]
        index += particles
        values = np.take(along, index, mode="clip")
        values *= inside
        return values

    def log_likelihood_ratio(self, states: np.ndarray, image: np.ndarray,
                             spread: PatchSpread | None = None) -> np.ndarray:
        """log L(z | s) for every particle, summed over its own (2p+1)² patch, (N,); or (B, N) for
        the particles (B, N, 5) of B runs, each against its own image (B, n, n).

        log L = Σ_{(i,j) ∈ C(s)} (h z − h²/2) / σ², with h = a g_x(i) g_y(j) separable, so the
        quadratic term is a² (Σ_i g_x²)(Σ_j g_y²) / 2 and the linear one a g_xᵀ Z_patch g_y.
        ``spread``, when given, is ``patch_spread`` of the particles (all runs' rows in order).

        The linear term is summed one patch row i at a time (arrays of (2p+1) × N, not (2p+1)² × N).
        Z_patch is read from the run's image framed by 2p zero cells on every side, at the patch
        centre clipped to p cells beyond the image: a cell off the image has a zero factor, so
        whichever pixel a clipped centre's patch reads adds nothing.
        """
        flat = states.reshape(-1, states.shape[-1])
        spread = self.patch_spread(flat) if spread is None else spread
        gx, gy, amp = spread.along_x, spread.along_y, spread.amplitude
        p = self.patch_radius
        framed = np.pad(image.reshape((-1,) + image.shape[-2:]), ((0, 0), (2 * p, 2 * p), (2 * p, 2 * p)))
        width = framed.shape[-1]
        pixels = framed.reshape(-1)
        runs = flat.shape[0] // states.shape[-2]
        first = np.repeat(np.arange(runs) * width * width, states.shape[-2])  # each run's framed image
        first += (np.clip(spread.centre_x, -p, self.grid_size - 1 + p) + p) * width
        first += np.clip(spread.centre_y, -p, self.grid_size - 1 + p) + p
        columns = self.patch_offsets[:, None] + p + first  # the pixels of patch row i, moved on a row each time
        linear = np.zeros(first.shape)
        for i in range(gx.shape[0]):
            row = pixels[columns]
            row *= gy
            linear += gx[i] * row.sum(axis=0)
            columns += width
        linear *= amp
        quadratic = 0.5 * amp**2 * (gx * gx).sum(axis=0) * (gy * gy).sum(axis=0)
        return ((linear - quadratic) / self.noise_std**2).reshape(states.shape[:-1])
