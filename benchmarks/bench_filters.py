"""Gaussian filter steps: gpfverify's batched UKF / GP-UKF / GP-ADF against a straightforward
per-belief loop with explicit inverses.

Cases: one UKF step for N beliefs of a 4-state, 2-output nonlinear model (what the unscented
particle filter does per time step), and one GP-UKF and GP-ADF step for the 200 test cases of the
gpadf-scalar benchmark. Each pair is checked to agree before timing.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from _timing import median_seconds, publish
from gpfverify.papers.gpadf_scalar.experiment import fit_models
from gpfverify.filters.gp_adf import gp_adf_step
from gpfverify.filters.gp_ukf import gp_ukf_step
from gpfverify.filters.records import Gaussian
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.filters.ukf import ukf_step
from gpfverify.models import GPModel, Sensor, StateSpaceModel
from gpfverify.papers.gpadf_scalar.scenario import ScalarSetting, draw_cases, draw_training_data

inv = np.linalg.inv


def _nonlinear_model(d: int = 4, l: int = 2) -> StateSpaceModel:
    """Range and bearing of the first two states (the bearing is not marked as an angle: the
    reference UKF below does not wrap, and the test beliefs stay far from the ±π cut)."""
    a = np.eye(d) + 0.1 * np.diag(np.ones(d - 1), 1)
    return StateSpaceModel(
        lambda x: np.sin(x) + x @ a.T, 0.01 * np.eye(d),
        [Sensor(lambda x: np.stack([np.hypot(x[:, 0], x[:, 1]), np.arctan2(x[:, 1], x[:, 0])], axis=-1)[:, :l],
                np.diag([0.1, 0.01])[:l, :l], name="range-bearing")],
        prior_mean=np.full(d, 2.0), prior_cov=0.05 * np.eye(d))


def reference_ukf(mean, cov, y, f, h, Q, R, params):
    """One textbook UKF step for one belief: explicit sigma points, loops, np.linalg.inv.
    ``R`` may be a function of the predicted mean."""
    d = mean.size
    lam = params.alpha**2 * (d + params.kappa) - d
    wm = np.full(2 * d + 1, 0.5 / (d + lam))
    wm[0] = lam / (d + lam)
    wc = wm.copy()
    wc[0] += 1 - params.alpha**2 + params.beta

    def points(m, c):
        root = np.linalg.cholesky((d + lam) * c)
        return [m] + [m + root[:, i] for i in range(d)] + [m - root[:, i] for i in range(d)]

    fx = [f(p) for p in points(mean, cov)]
    mp = sum(w * v for w, v in zip(wm, fx))
    cp = sum(w * np.outer(v - mp, v - mp) for w, v in zip(wc, fx)) + Q
    xs = points(mp, cp)
    hy = [h(p) for p in xs]
    my = sum(w * v for w, v in zip(wm, hy))
    cy = sum(w * np.outer(v - my, v - my) for w, v in zip(wc, hy)) + (R(mp) if callable(R) else R)
    cxy = sum(w * np.outer(p - mp, v - my) for w, p, v in zip(wc, xs, hy))
    gain = cxy @ inv(cy)
    return mp + gain @ (y - my), cp - gain @ cy @ gain.T


def reference_gp_ukf(mean, cov, y, transition_gp, measurement_gp, params):
    """GP-UKF for one belief through the reference UKF, predicting each sigma point separately;
    Q at the belief's mean, R at the predicted mean."""
    q = np.diag(transition_gp.predict(mean[None])[1][0] + transition_gp.noise_var)
    return reference_ukf(mean, cov, y, lambda x: transition_gp.predict(x[None])[0][0],
                         lambda x: measurement_gp.predict(x[None])[0][0], q,
                         lambda m: np.diag(measurement_gp.predict(m[None])[1][0] + measurement_gp.noise_var),
                         params)


def _agreement(record, refs) -> float:
    means = np.array([m for m, _ in refs])
    covs = np.array([c for _, c in refs])
    return float(max(np.abs(record.mu_e - means).max(), np.abs(record.C_e - covs).max()))


def main() -> None:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path)
    parser.add_argument("--repeats", type=int, default=10)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    params = SigmaParams()
    rows = []

    model = _nonlinear_model()
    f1 = lambda x: model.f(x[None], 0)[0]  # noqa: E731
    h1 = lambda x: model.h(x[None], 0)[0]  # noqa: E731
    for n in (100, 1000):
        belief = Gaussian(rng.uniform(1, 3, (n, 4)), np.broadcast_to(0.05 * np.eye(4), (n, 4, 4)).copy())
        ys = model.h(belief.mean, 0) + 0.1 * rng.normal(size=(n, 2))

        def ours(belief=belief, ys=ys):
            return ukf_step(belief, model, ys, k=0, params=params)

        def ref(belief=belief, ys=ys, n=n):
            return [reference_ukf(belief.mean[i], belief.cov[i], ys[i], f1, h1, model.Q, model.R, params)
                    for i in range(n)]

        agree = _agreement(ours(), ref())
        t_ours, t_ref = median_seconds(ours, args.repeats), median_seconds(ref, max(3, args.repeats // 3), 1)
        rows.append([f"UKF step, {n} beliefs, D=4, L=2", f"{t_ours * 1e3:.2f}", f"{t_ref * 1e3:.1f}",
                     f"{t_ref / t_ours:.1f}x", f"{agree:.1e}"])

    setting = ScalarSetting()
    transition_gp, measurement_gp = fit_models(draw_training_data(setting, rng), 1, rng)
    cases = draw_cases(setting, rng)
    n = cases.prior_mean.size
    belief = Gaussian(cases.prior_mean[:, None], np.full((n, 1, 1), setting.prior_std**2))
    ys = cases.y1[:, None]
    gp_model = GPModel(transition_gp, [measurement_gp])

    def gp_ukf_ours():
        return gp_ukf_step(belief, gp_model, ys, k=1, params=params)

    def gp_ukf_ref():
        return [reference_gp_ukf(belief.mean[i], belief.cov[i], ys[i], transition_gp, measurement_gp, params)
                for i in range(n)]

    agree = _agreement(gp_ukf_ours(), gp_ukf_ref())
    t_ours, t_ref = median_seconds(gp_ukf_ours, args.repeats), median_seconds(gp_ukf_ref, 3, 1)
    rows.append([f"GP-UKF step, {n} scalar test cases, 100 training points", f"{t_ours * 1e3:.2f}",
                 f"{t_ref * 1e3:.1f}", f"{t_ref / t_ours:.1f}x", f"{agree:.1e}"])
    t_adf = median_seconds(lambda: gp_adf_step(belief, gp_model, ys, k=1), 3, 1)
    rows.append([f"GP-ADF step, {n} scalar test cases (one moment match per case)", f"{t_adf * 1e3:.1f}",
                 "", "", ""])

    publish(["case", "gpfverify ms (median)", "reference ms", "speed-up", "max |diff|"], rows, args.out)


if __name__ == "__main__":
    main()
