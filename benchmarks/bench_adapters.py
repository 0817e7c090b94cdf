"""How closely gpfverify's filters, run through the adapters, agree with Stone Soup's and filterpy's own
filters on the same models — the runs of tests/test_adapters_stonesoup.py and
tests/test_adapters_filterpy.py (their models and drivers are imported from there), measured rather
than asserted — and what the extras cost to import.

Each row: the largest absolute difference of the posterior means and of the posterior covariances
over a run (12 steps of a constant-velocity target; the eastern radar's bearing crosses ±π), and
the same relative to the largest mean and covariance entry. UKF rows come as ``gpfverify check``
runs a tracker (the library's α, β, κ and its weighted mean of angle-valued sigma points: Stone
Soup's atan2(Σ w sin, Σ w cos), filterpy's z_mean_fn) and with gpfverify's own mean
(wrap(r + Σ w wrap(a − r))) or defaults instead, as check ran before; the filterpy Kalman rows
start a sensor from its own x and P and from the first filter's.

    .venv/bin/python benchmarks/bench_adapters.py [--out benchmarks/results/adapters.md]
"""

from __future__ import annotations

import argparse
import functools
import os
import platform
import statistics
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests import test_adapters_filterpy as fp  # noqa: E402
from tests import test_adapters_stonesoup as ss  # noqa: E402


def row(what: str, ours, theirs) -> list[str]:
    means, covs = np.asarray(ours[0]), np.asarray(ours[1])
    ref_means, ref_covs = np.asarray(theirs[0]), np.asarray(theirs[1])
    dm, dc = np.abs(means - ref_means).max(), np.abs(covs - ref_covs).max()
    return [what, f"{dm:.2g}", f"{dm / np.abs(ref_means).max():.2g}", f"{dc:.2g}", f"{dc / np.abs(ref_covs).max():.2g}"]


def stonesoup_rows() -> list[list[str]]:
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.measurement.nonlinear import CombinedReversibleGaussianMeasurementModel
    from stonesoup.predictor.kalman import ExtendedKalmanPredictor, KalmanPredictor, UnscentedKalmanPredictor
    from stonesoup.updater.kalman import ExtendedKalmanUpdater, KalmanUpdater, UnscentedKalmanUpdater

    from gpfverify.filters.families import gaussian_family
    from gpfverify.filters.records import Gaussian
    from gpfverify.filters.sigma_points import SigmaParams

    rows = []
    linear = [LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=np.diag([4.0, 9.0])),
              LinearGaussian(ndim_state=4, mapping=(1, 3), noise_covar=np.diag([0.5, 0.5]))]
    model = ss.system(linear)
    _, ys = model.simulate(15, np.random.default_rng(2))
    stacked = LinearGaussian(ndim_state=4, mapping=(0, 2, 1, 3), noise_covar=np.diag([4.0, 9.0, 0.5, 0.5]))
    rows.append(row("Stone Soup KalmanPredictor/Updater, centralized (2 linear sensors, 15 steps)",
                    ss.gpfverify_run("kf", model, ys),
                    ss.stonesoup_run(KalmanPredictor(ss.cv_model()), KalmanUpdater(stacked), stacked, ys)))

    radars = [ss.bearing_range(ss.WEST), ss.bearing_range(ss.EAST)]
    model = ss.system(radars)
    _, ys = ss.crossing_measurements(model)
    east, block = radars[1], model.blocks[1]
    ref = ss.stonesoup_run(ExtendedKalmanPredictor(ss.cv_model()), ExtendedKalmanUpdater(east), east, ys[:, block])
    ekf = gaussian_family("ekf")
    beliefs = [Gaussian(model.prior_mean, model.prior_cov)] + [Gaussian(*b) for b in zip(*ref)]
    steps = [ekf.step(b, model.sensor_model(1), y, k=k).posterior
             for k, (b, y) in enumerate(zip(beliefs, ys[:, block]), start=1)]
    rows.append(row("Stone Soup ExtendedKalman, eastern radar, each step from Stone Soup's previous posterior",
                    ([s.mean for s in steps], [s.cov for s in steps]), ref))
    rows.append(row("Stone Soup ExtendedKalman, eastern radar, both recursions (Stone Soup's finite-difference "
                    "Jacobian amplifies rounding)", ss.gpfverify_run("ekf", model.sensor_model(1), ys[:, block]), ref))

    combined = CombinedReversibleGaussianMeasurementModel(radars)
    for alpha, beta, kappa in [(0.5, 2.0, None), (1.0, 0.0, 2.0), (0.5, 2.0, 1.0)]:
        theirs = ss.stonesoup_run(UnscentedKalmanPredictor(ss.cv_model(), alpha=alpha, beta=beta, kappa=kappa),
                                  UnscentedKalmanUpdater(combined, alpha=alpha, beta=beta, kappa=kappa), combined, ys)
        k = 3.0 - model.state_dim if kappa is None else kappa
        label = (f"Stone Soup UnscentedKalman (α, β, κ) = ({alpha:g}, {beta:g}, "
                 f"{'3 − n' if kappa is None else f'{kappa:g}'}), centralized, 2 radars")
        rows.append(row(label + ", as check runs it (its α, β, κ and atan2 angle mean)",
                        ss.gpfverify_run("ukf", model, ys, SigmaParams(alpha, beta, k, "atan2")), theirs))
        rows.append(row(label + ", its α, β, κ with gpfverify's own angle mean",
                        ss.gpfverify_run("ukf", model, ys, SigmaParams(alpha, beta, k)), theirs))
        if kappa is None:
            rows.append(row(label + ", gpfverify's defaults (1, 0, 2) as check ran before",
                            ss.gpfverify_run("ukf", model, ys), theirs))
    return rows


def filterpy_rows() -> list[list[str]]:
    from gpfverify.filters.sigma_points import SigmaParams

    rows = []
    R0, R1 = np.diag([4.0, 9.0]), np.diag([0.5, 0.5])
    system = fp.adapter.system_from_filters([fp.kalman(fp.H_POSITION, R0), fp.kalman(fp.H_VELOCITY, R1)])
    _, ys = fp.simulate(system.model)
    fused = system.run(ys, methods=("cmf", "dmf"))
    means, covs, _ = fp.filterpy_run(fp.kalman(np.vstack([fp.H_POSITION, fp.H_VELOCITY]),
                                               np.diag([4.0, 9.0, 0.5, 0.5])), ys)
    rows.append(row("filterpy KalmanFilter, centralized (2 linear sensors, 12 steps) vs gpfverify's CMF",
                    (fused.means("cmf"), [s.estimate("cmf").cov for s in fused.steps]), (means, covs)))
    kalman = [fp.kalman(fp.H_POSITION, R0), fp.kalman(fp.H_VELOCITY, R1)]
    kalman[1].x, kalman[1].P = np.array([[-4.0], [-2.0], [6.0], [0.0]]), np.diag([100.0, 4.0, 60.0, 2.0])
    system = fp.adapter.system_from_filters(kalman)
    means, covs, _ = fp.filterpy_run(kalman[1], ys[:, system.model.blocks[1]])
    for label, starts in (("from its own x and P, as check runs it", None),
                          ("from filter 0's x and P, as check ran before", [system.local_priors[0]] * 2)):
        fused = system.run(ys, methods=("cmf", "dmf"), **({} if starts is None else {"local_priors": starts}))
        rows.append(row(f"filterpy KalmanFilter, the velocity sensor started {label}",
                        (fused.local_means(1), [s.local[1].C_e for s in fused.steps]), (means, covs)))
    R_radar = np.diag([4.0, 0.02**2])

    def atan2_mean(sigmas, weights):
        mean = weights @ sigmas
        mean[1] = np.arctan2(weights @ np.sin(sigmas[:, 1]), weights @ np.cos(sigmas[:, 1]))
        return mean

    for alpha, beta, kappa in [(0.3, 2.0, 0.1), (1.0, 0.0, 2.0)]:
        label = f"filterpy UnscentedKalmanFilter (α, β, κ) = ({alpha:g}, {beta:g}, {kappa:g}), range-bearing"
        for name, mean_fn in [("filterpy's default z_mean_fn (the plain mean)", None),
                              ("z_mean_fn = atan2 of sines and cosines (the filterpy book's)", atan2_mean),
                              ("z_mean_fn = gpfverify's angle mean", fp.mean_bearing)]:
            make = functools.partial(fp.unscented, fp.range_bearing, R_radar, alpha, beta, kappa,
                                     residual_z=fp.residual_bearing, z_mean_fn=mean_fn)
            system = fp.adapter.system_from_filters([make()])
            _, ys = fp.simulate(system.model)
            means, covs, _ = fp.filterpy_run(make(), ys)
            for how, settings in (("as check runs it (the mean recognised)", system.params),
                                  ("with gpfverify's own angle mean", SigmaParams(alpha, beta, kappa))):
                fused = system.run(ys, methods=("cmf", "dmf"), params=settings)
                rows.append(row(f"{label}, {name}, {how}",
                                (fused.local_means(0), [s.local[0].C_e for s in fused.steps]), (means, covs)))
    return rows


def import_seconds(module: str, repeats: int = 5) -> tuple[float, float]:
    """Median wall time of a fresh ``python -c 'import numpy, MODULE'`` and of ``import numpy`` alone."""
    def once(code: str) -> float:
        start = time.perf_counter()
        subprocess.run([sys.executable, "-c", code], check=True)
        return time.perf_counter() - start

    times = [(once(f"import numpy, {module}"), once("import numpy")) for _ in range(repeats)]
    return statistics.median(t for t, _ in times), statistics.median(b for _, b in times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    load_before = os.getloadavg()
    header = ["comparison", "max |Δ mean|", "relative", "max |Δ cov|", "relative"]
    rows = stonesoup_rows() + filterpy_rows()
    imports = [(m, *import_seconds(m)) for m in ("gpfverify.adapters.stonesoup", "gpfverify.adapters.filterpy")]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    lines += ["", "| fresh process, `import numpy, MODULE` | median seconds | `import numpy` alone |", "|---|---|---|"]
    lines += [f"| `{m}` | {t:.2f} | {b:.2f} |" for m, t, b in imports]
    versions = ", ".join(f"{p} {metadata.version(p)}" for p in ("numpy", "stonesoup", "filterpy"))
    load_after = os.getloadavg()
    text = (f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}; {versions}.\n"
            f"Load average (1, 5, 15 min) before: {', '.join(f'{v:.2f}' for v in load_before)}; after: "
            f"{', '.join(f'{v:.2f}' for v in load_after)}.\n\n" + "\n".join(lines) + "\n")
    print(text)
    if args.out is not None:
        args.out.write_text(text)


if __name__ == "__main__":
    main()
