"""Rutten's standard track-before-detect scenario (Rutten, Ristic & Gordon, FUSION 2005; seed 004 §3).

20 × 20 cells (Δ = 1), blur Σ = 0.7, q1 = 0.001, q2 = 0.01, T = 1, P_b = P_d = 0.05, 30 frames, the
target present in frames 7–22 (1-based, inclusive). Seed 004's parameter table was lost in
extraction; the remaining values are interpretations, each a named field:

* the target appears at s = [4.2, 0.45, 7.2, 0.25, I₀], I₀ = 20 (the example of Ristic, Arulampalam
  & Gordon, *Beyond the Kalman Filter*, ch. 11, which Rutten's scenario follows) and moves by the
  model's own near-constant-velocity dynamics (process noise Q drawn per run);
* the SNR is set, as in seed 004, through the noise variance σ², with a stated convention:
  ``"peak"`` — SNR = 10 log10(a² / σ²), a = Δ² I₀ / (2πΣ²) the peak pixel of the blurred target
  (Ristic et al.); ``"intensity"`` — SNR = 10 log10(I₀² / σ²) (total intensity: the literature's
  10 log10(I²/σ²) with I read as the integrated intensity); ``"energy"`` — SNR = 10 log10(E / σ²),
  E = Σ_c h_c² the target's energy over the cells (matched-filter detection theory), for a target
  centred on a cell with the point spread not truncated: E = a² (Σ_{i ∈ ℤ} exp(−i²Δ²/Σ²))²;
* the birth density's intensity range is [I₀/2, 3I₀/2] and its velocity range ±1 cell/frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from gpfverify.errors import InputError
from gpfverify.filters.tbd.model import INTENSITY, STATE_DIM, TbdModel

SNR_CONVENTIONS = ("peak", "intensity", "energy")


@dataclass(frozen=True)
class TbdScenario:
    """Frames are numbered 1 … ``frames``; the target exists in ``first_frame`` … ``last_frame``."""

    frames: int = 30
    first_frame: int = 7
    last_frame: int = 22
    initial_state: tuple[float, ...] = (4.2, 0.45, 7.2, 0.25, 20.0)

    def __post_init__(self):
        if not 1 <= self.first_frame <= self.last_frame <= self.frames:
            raise InputError(f"need 1 <= first_frame <= last_frame <= frames, got "
                             f"{self.first_frame}, {self.last_frame}, {self.frames}")
        if len(self.initial_state) != STATE_DIM:
            raise InputError(f"initial_state must have {STATE_DIM} entries, got {len(self.initial_state)}")

    @property
    def intensity(self) -> float:
        return float(self.initial_state[INTENSITY])

    @property
    def present(self) -> np.ndarray:
        """Boolean (frames,): frame k+1 has the target."""
        k = np.arange(1, self.frames + 1)
        return (k >= self.first_frame) & (k <= self.last_frame)


@dataclass(frozen=True)
class TbdSequence:
    """images (K, n, n); truth (K, 5) (NaN rows where the target is absent); present (K,)."""

    images: np.ndarray
    truth: np.ndarray
    present: np.ndarray


def noise_std_for_snr(snr_db: float, intensity: float, model: TbdModel, convention: str = "peak") -> float:
    """σ such that the target of ``intensity`` has the given SNR under ``convention``."""
    if convention not in SNR_CONVENTIONS:
        raise InputError(f"snr convention must be one of {SNR_CONVENTIONS}, got {convention!r}")
    if convention == "intensity":
        signal = float(intensity)
    else:
        signal = float(model.amplitude(intensity))
        if convention == "energy":
            signal *= math.sqrt(energy_factor(model))
    return signal / 10.0 ** (float(snr_db) / 20.0)


def energy_factor(model: TbdModel) -> float:
    """E / a²: the energy Σ_c h_c² of a target centred on a cell over its peak pixel squared, the
    point spread not truncated, (Σ_{i ∈ ℤ} exp(−i²Δ²/Σ²))² (the sum taken to |i|Δ ≤ 10Σ)."""
    reach = math.ceil(10.0 * model.blur / model.cell_size)
    i = np.arange(-reach, reach + 1)
    return float(np.sum(np.exp(-((i * model.cell_size / model.blur) ** 2)))) ** 2


def scenario_model(snr_db: float, scenario: TbdScenario = TbdScenario(), convention: str = "peak",
                   base: TbdModel = TbdModel()) -> TbdModel:
    """``base`` with σ set for the SNR and the birth intensity range [I₀/2, 3I₀/2]."""
    i0 = scenario.intensity
    return replace(base, noise_std=noise_std_for_snr(snr_db, i0, base, convention),
                   intensity_range=(0.5 * i0, 1.5 * i0))


def simulate(model: TbdModel, scenario: TbdScenario, rng: np.random.Generator, target: bool = True) -> TbdSequence:
    """Images of one run: white noise N(0, σ²) on every cell plus, when ``target``, the blurred
    target in frames first_frame … last_frame."""
    n = model.grid_size
    present = scenario.present if target else np.zeros(scenario.frames, dtype=bool)
    truth = np.full((scenario.frames, STATE_DIM), np.nan)
    images = model.noise_std * rng.standard_normal((scenario.frames, n, n))
    if target:
        state = np.asarray(scenario.initial_state, dtype=float)[None, :]
        for k in np.flatnonzero(present):
            if k > scenario.first_frame - 1:
                state = model.propagate(state, rng)
            truth[k] = state[0]
            images[k] += model.expected_image(state[0])
    return TbdSequence(images, truth, present)
