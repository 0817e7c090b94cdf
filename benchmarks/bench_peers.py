"""gpfverify side by side with the libraries a user would pick instead, in one process.

Every row runs the same inputs through both sides, asserts that the results agree (before any
timing), then times the two sides interleaved (ours, peer, peer, ours, …: a burst of load on the
shared machine hits both), each block of calls by process CPU time; the table gives medians and the
ratio gpfverify / peer (< 1: gpfverify is faster). BLAS is pinned to one thread before numpy is
imported.

Peers (``pip install -e .[bench]``): filterpy, scikit-learn, Stone Soup; ``particles`` (nchopin)
pins ``numpy<2`` in its metadata although it runs on numpy 2, so it is installed apart:
``pip install --no-deps particles`` (then its dependencies numba and joblib). GPy (1.13) pins
``numpy<2`` and ``scipy<=1.12`` and really needs them: it cannot share an environment with this
package's numpy 2, so it has no row.

    .venv/bin/python benchmarks/bench_peers.py [--quick] [--out benchmarks/results/peers.md]

Rows that no library publishes (PF-TBD, the flows, RCC-CI, GP-ADF / GP-UKF, a ct2d run) are
timed on their own.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import platform  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from importlib import metadata  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


# -- timing -----------------------------------------------------------------------------------------
def _block(fn, calls: int) -> float:
    start = time.process_time()
    for _ in range(calls):
        fn()
    return (time.process_time() - start) / calls


def calls_for(fn, target: float = 0.01) -> int:
    """Calls per timed block so that a block takes about ``target`` CPU seconds."""
    fn()
    one = max(_block(fn, 1), 1e-6)
    return max(1, int(target / one))


def paired(ours, peer, repeats: int, target: float = 0.01) -> tuple[float, float]:
    """Median CPU seconds per call of ``ours`` and ``peer``, timed in alternating blocks."""
    n_ours, n_peer = calls_for(ours, target), calls_for(peer, target)
    t_ours, t_peer = [], []
    for r in range(repeats):
        if r % 2:
            t_peer.append(_block(peer, n_peer))
            t_ours.append(_block(ours, n_ours))
        else:
            t_ours.append(_block(ours, n_ours))
            t_peer.append(_block(peer, n_peer))
    return float(np.median(t_ours)), float(np.median(t_peer))


def alone(fn, repeats: int, target: float = 0.01) -> float:
    n = calls_for(fn, target)
    return float(np.median([_block(fn, n) for _ in range(repeats)]))


def fmt(seconds: float) -> str:
    if seconds >= 0.1:
        return f"{seconds:.3f} s"
    if seconds >= 1e-3:
        return f"{seconds * 1e3:.2f} ms"
    return f"{seconds * 1e6:.1f} µs"


def agree(name: str, ours, peer, rtol: float, atol: float = 0.0) -> float:
    """Largest |ours − peer| relative to max(1, |peer|)… asserted within rtol·|peer| + atol."""
    ours, peer = np.asarray(ours, float), np.asarray(peer, float)
    diff = np.abs(ours - peer)
    if not np.all(diff <= rtol * np.abs(peer) + atol):
        raise AssertionError(f"{name}: results disagree, max |diff| {diff.max():.3g}")
    return float(diff.max())


class Table:
    def __init__(self):
        self.rows: list[list[str]] = []

    def ratio(self, operation, peer, ours_s, peer_s, diff, goal=""):
        self.rows.append([operation, peer, fmt(ours_s), fmt(peer_s), f"{ours_s / peer_s:.2f}", goal,
                          f"{diff:.1e}"])
        print(" | ".join(self.rows[-1]), flush=True)

    def markdown(self) -> str:
        head = ["operation", "peer", "gpfverify", "peer time", "ratio", "goal", "max |diff|"]
        lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        return "\n".join(lines + ["| " + " | ".join(r) + " |" for r in self.rows])


# -- bootstrap PF against particles -----------------------------------------------------------------
RHO, SIGMA_X, SIGMA_Y = 0.9, 1.0, 0.5


def pf_rows(table: Table, repeats: int) -> None:
    from particles import distributions as dists, state_space_models as ssm

    from gpfverify.models import linear_model

    sigma0 = SIGMA_X / np.sqrt(1 - RHO**2)

    class LinearGauss(ssm.StateSpaceModel):
        default_params = {"rho": RHO, "sigmaX": SIGMA_X, "sigmaY": SIGMA_Y, "sigma0": sigma0}

        def PX0(self):
            return dists.Normal(scale=self.sigma0)

        def PX(self, t, xp):
            return dists.Normal(loc=self.rho * xp, scale=self.sigmaX)

        def PY(self, t, xp, x):
            return dists.Normal(loc=x, scale=self.sigmaY)

    model = linear_model([[RHO]], [[1.0]], [[SIGMA_X**2]], [[SIGMA_Y**2]], [0.0], [[sigma0**2]])
    peer_model = LinearGauss()
    _, data = peer_model.simulate(400)
    ys = np.array(data, dtype=float).reshape(-1, 1)
    for n in (1000, 2000):
        pf_row(table, repeats, n, model, peer_model, ys, sigma0)


def pf_row(table: Table, repeats: int, n: int, model, peer_model, ys: np.ndarray, sigma0: float) -> None:
    import particles
    from particles import collectors, state_space_models as ssm

    from gpfverify.filters import pf_step
    from gpfverify.filters.likelihoods import measurement_loglik
    from gpfverify.filters.resampling import Particles, reweight_and_resample

    np.random.seed(0)  # particles draws from numpy's global generator
    fk = ssm.Bootstrap(ssm=peer_model, data=[float(v) for v in ys[:, 0]] * 2000)
    pf = particles.SMC(fk=fk, N=n, resampling="systematic", ESSrmin=1.0, store_history=False,
                       collect=[collectors.Moments()])
    next(pf), next(pf)
    # same particles, same measurement: the normalised weights and the weighted mean agree
    t = pf.t - 1
    x = np.asarray(pf.X, float)[:, None]
    loglik = measurement_loglik(model, ys[t % len(ys)], x, t)
    ours = reweight_and_resample(x, np.full(n, -np.log(n)) + loglik, np.random.default_rng(0), 1.0)
    diff = max(agree("PF weights", np.exp(ours.weighted.log_weights), pf.wgts.W, 1e-10, 1e-15),
               agree("PF mean", ours.mean, pf.summaries.moments[-1]["mean"], 1e-10, 1e-12))

    rng = np.random.default_rng(1)
    state = {"belief": Particles.equally_weighted(rng.normal(0, sigma0, (n, 1))), "k": 0}

    def ours_step():
        k = state["k"] = state["k"] + 1
        state["belief"] = pf_step(state["belief"], model, ys[k % len(ys)], k=k, rng=rng,
                                  resample_threshold=1.0).posterior

    t_ours, t_peer = paired(ours_step, lambda: next(pf), repeats)
    table.ratio(f"bootstrap PF step, 1-D linear-Gaussian, N = {n}", f"particles {metadata.version('particles')}",
                t_ours, t_peer, diff, "≤ 1.0")


# -- Kalman filter against filterpy -----------------------------------------------------------------
def cv_model():
    F = np.block([[np.eye(2), np.eye(2)], [np.zeros((2, 2)), np.eye(2)]])
    Q = 0.05 * np.block([[np.eye(2) / 3, np.eye(2) / 2], [np.eye(2) / 2, np.eye(2)]])
    return F, Q, np.array([0.0, -40.0, 0.0, 4.0]), np.diag([9.0, 9.0, 0.25, 0.25])


def kf_row(table: Table, repeats: int) -> None:
    from filterpy.kalman import KalmanFilter

    from gpfverify.filters import Gaussian, kf_step
    from gpfverify.models import linear_model

    F, Q, m0, P0 = cv_model()
    H, R = np.eye(2, 4), 4.0 * np.eye(2)
    model = linear_model(F, H, Q, R, m0, P0)
    truth, ys = model.simulate(50, np.random.default_rng(0))
    kf = KalmanFilter(dim_x=4, dim_z=2)
    kf.F, kf.H, kf.Q, kf.R, kf.x, kf.P = F, H, Q, R, m0.copy(), P0.copy()
    belief, diff = Gaussian(m0, P0), 0.0
    for y in ys:
        belief = kf_step(belief, model, y).posterior
        kf.predict()
        kf.update(y)
        diff = max(diff, agree("KF mean", belief.mean, kf.x, 1e-9, 1e-9),
                   agree("KF cov", belief.cov, kf.P, 1e-9, 1e-12))
    state = {"belief": Gaussian(m0, P0), "t": 0}

    def ours():
        t = state["t"] = (state["t"] + 1) % len(ys)
        state["belief"] = kf_step(state["belief"], model, ys[t], k=t + 1).posterior

    def peer():
        t = state["t"]
        kf.predict()
        kf.update(ys[t])

    t_ours, t_peer = paired(ours, peer, repeats)
    table.ratio("KF step, D = 4, L = 2", f"filterpy {metadata.version('filterpy')} KalmanFilter", t_ours, t_peer,
                diff, "≤ 1.0")


def call_counts(fn) -> tuple[int, int]:
    """(Python-level calls, C-level calls) made by one call of ``fn`` (sys.setprofile events):
    a repeatable measure of per-step overhead, independent of the machine's load."""
    counts = {"call": 0, "c_call": 0}

    def hook(frame, event, arg):
        if event in counts:
            counts[event] += 1

    fn()  # warm (first-call caches)
    sys.setprofile(hook)
    try:
        fn()
    finally:
        sys.setprofile(None)
    return counts["call"], counts["c_call"]


def kf_profile(repeats: int) -> list[list[str]]:
    """Where the KF step's time goes, next to filterpy's predict and update."""
    from filterpy.kalman import KalmanFilter

    from gpfverify.filters import Gaussian, kf_step
    from gpfverify.filters.kalman import _joint
    from gpfverify.filters.update import check_belief, condition
    from gpfverify.models import linear_model

    F, Q, m0, P0 = cv_model()
    H, R = np.eye(2, 4), 4.0 * np.eye(2)
    model = linear_model(F, H, Q, R, m0, P0)
    y = np.array([1.0, -38.0])
    belief = Gaussian(m0, P0)
    joint = _joint(model)

    def joint_product():
        half = joint.A.dot(belief.cov).dot(joint.half_A_T) + joint.half_B
        return belief.mean.dot(joint.A_T), half + half.T

    mean, cov = joint_product()
    kf = KalmanFilter(dim_x=4, dim_z=2)
    kf.F, kf.H, kf.Q, kf.R, kf.x, kf.P = F, H, Q, R, m0.copy(), P0.copy()
    parts = [("gpfverify: whole step", lambda: kf_step(belief, model, y)),
             ("  the model's joint map A, Aᵀ/2, B/2 (cached per model)", lambda: _joint(model)),
             ("  belief check", lambda: check_belief(belief, 4)),
             ("  predicted joint N(Aμ, ACAᵀ + B), symmetric", joint_product),
             ("  update (y check, Cholesky, one solve, one Gram product, record)",
              lambda: condition(mean[:4], cov[:4, :4], mean[4:], cov[4:, 4:], cov[:4, 4:], y)),
             ("filterpy: predict()", kf.predict),
             ("filterpy: update(z) (no checks, no symmetrisation)", lambda: kf.update(y))]
    rows = []
    for name, fn in parts:
        py, c = call_counts(fn)
        rows.append([name, fmt(alone(fn, repeats)), str(py), str(c)])
    return rows


# -- UKF against filterpy and Stone Soup --------------------------------------------------------------
SENSOR = np.array([-100.0, 0.0])  # bearings stay far from ±π: both sides average them linearly there
R_RB = np.diag([1.0, 0.02**2])


def range_bearing(x):
    dx, dy = x[:, 0] - SENSOR[0], x[:, 1] - SENSOR[1]
    return np.stack([np.hypot(dx, dy), np.arctan2(dy, dx)], axis=1)


def ukf_rows(table: Table, repeats: int) -> None:
    from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

    from gpfverify.angles import wrap
    from gpfverify.filters import Gaussian, ukf_step
    from gpfverify.models import Sensor, StateSpaceModel

    F, Q, m0, P0 = cv_model()
    model = StateSpaceModel(transition=F, process_cov=Q,
                            sensors=[Sensor(range_bearing, R_RB, circular=[1], name="range-bearing")],
                            prior_mean=m0, prior_cov=P0)
    _, ys = model.simulate(30, np.random.default_rng(1))

    def residual_z(a, b):
        d = np.subtract(a, b)
        d[1] = wrap(d[1])
        return d

    points = MerweScaledSigmaPoints(4, alpha=1.0, beta=0.0, kappa=2.0)  # = SigmaParams()
    ukf = UnscentedKalmanFilter(dim_x=4, dim_z=2, dt=1.0, hx=lambda x: range_bearing(x[None])[0],
                                fx=lambda x, dt: F @ x, points=points, residual_z=residual_z)
    ukf.Q, ukf.R = Q, R_RB

    def peer_step(y):
        ukf.predict()  # filterpy 2 redraws the sigma points from N(x_prior, P_prior), as ours
        ukf.update(y)

    ukf.x, ukf.P = m0.copy(), P0.copy()
    belief, diff = Gaussian(m0, P0), 0.0
    for y in ys:
        belief = ukf_step(belief, model, y).posterior
        peer_step(y)
        diff = max(diff, agree("UKF mean", belief.mean, ukf.x, 1e-8, 1e-8),
                   agree("UKF cov", belief.cov, ukf.P, 1e-8, 1e-10))
    state = {"belief": Gaussian(m0, P0), "t": 0}

    def ours():
        t = state["t"] = (state["t"] + 1) % len(ys)
        if t == 0:
            state["belief"] = Gaussian(m0, P0)
        state["belief"] = ukf_step(state["belief"], model, ys[t], k=t + 1).posterior

    def peer():
        t = state["t"]
        if t == 0:
            ukf.x, ukf.P = m0.copy(), P0.copy()
        peer_step(ys[t])

    t_ours, t_peer = paired(ours, peer, repeats)
    table.ratio("UKF step, range–bearing (D = 4, L = 2)", f"filterpy {metadata.version('filterpy')} "
                "UnscentedKalmanFilter", t_ours, t_peer, diff, "keep ≤ 1")
    try:
        stonesoup_row(table, repeats, model, ys, m0, P0, F, Q)
    except ImportError as exc:
        print(f"Stone Soup row skipped: {exc}")


def stonesoup_row(table, repeats, model, ys, m0, P0, F, Q) -> None:
    from datetime import datetime, timedelta

    from stonesoup.models.measurement.nonlinear import CartesianToBearingRange
    from stonesoup.models.transition.linear import LinearGaussianTimeInvariantTransitionModel
    from stonesoup.predictor.kalman import UnscentedKalmanPredictor
    from stonesoup.types.detection import Detection
    from stonesoup.types.hypothesis import SingleHypothesis
    from stonesoup.types.state import GaussianState
    from stonesoup.updater.kalman import UnscentedKalmanUpdater

    from gpfverify.filters import Gaussian, ukf_step

    PERM = np.eye(4)[[0, 2, 1, 3]]  # ours [x, y, vx, vy] -> Stone Soup [x, vx, y, vy]
    # Stone Soup's measurement is [bearing, range] with the sensor at translation_offset
    measure = CartesianToBearingRange(ndim_state=4, mapping=(0, 2), noise_covar=np.diag([R_RB[1, 1], R_RB[0, 0]]),
                                      translation_offset=np.array([[SENSOR[0]], [SENSOR[1]]]))
    params = {"alpha": 1.0, "beta": 0.0, "kappa": 2.0}
    transition = LinearGaussianTimeInvariantTransitionModel(transition_matrix=PERM @ F @ PERM.T,
                                                            covariance_matrix=PERM @ Q @ PERM.T)
    predictor = UnscentedKalmanPredictor(transition, **params)
    updater = UnscentedKalmanUpdater(measure, **params)
    t0 = datetime(2026, 1, 1)

    def peer_step(prior, y, k):
        prediction = predictor.predict(prior, timestamp=t0 + timedelta(seconds=k))
        detection = Detection(np.array([[y[1]], [y[0]]]), timestamp=prediction.timestamp, measurement_model=measure)
        return updater.update(SingleHypothesis(prediction, detection))

    prior = GaussianState((PERM @ m0)[:, None], PERM @ P0 @ PERM.T, timestamp=t0)
    belief, diff = Gaussian(m0, P0), 0.0
    for k, y in enumerate(ys, 1):
        belief = ukf_step(belief, model, y, k=k).posterior
        prior = peer_step(prior, y, k)
        mean = PERM.T @ np.asarray(prior.state_vector, float)[:, 0]
        cov = PERM.T @ np.asarray(prior.covar, float) @ PERM
        # Stone Soup averages a Bearing as atan2(Σ w sin θ, Σ w cos θ), ours as the central point plus the
        # weighted wrapped deviations from it: two circular means that differ at third order in the spread
        # of the bearings (over the 30 steps, ≈ 1e-5 of the largest entry), not at rounding level
        diff = max(diff, agree("Stone Soup UKF mean", belief.mean, mean, 0.0, 1e-4 * np.abs(mean).max()),
                   agree("Stone Soup UKF cov", belief.cov, cov, 0.0, 1e-4 * np.abs(cov).max()))
    state = {"ours": Gaussian(m0, P0), "peer": GaussianState((PERM @ m0)[:, None], PERM @ P0 @ PERM.T, timestamp=t0),
             "t": 0, "k": 0}

    def ours():
        t = state["t"] = (state["t"] + 1) % len(ys)
        state["ours"] = ukf_step(Gaussian(m0, P0) if t == 0 else state["ours"], model, ys[t], k=t + 1).posterior

    def peer():
        k = state["k"] = state["k"] + 1
        state["peer"] = peer_step(state["peer"], ys[k % len(ys)], k)

    t_ours, t_peer = paired(ours, peer, repeats)
    table.ratio("UKF step, range–bearing (D = 4, L = 2)", f"Stone Soup {metadata.version('stonesoup')} "
                "UnscentedKalman predictor + updater", t_ours, t_peer, diff, "keep ≤ 1")


# -- GP regression against scikit-learn ----------------------------------------------------------------
def gp_data(n: int = 300, seed: int = 0):
    rng = np.random.default_rng(seed)
    X = rng.uniform(-3, 3, (n, 2))
    y = np.sin(X[:, 0]) * np.cos(0.5 * X[:, 1]) + 0.1 * rng.normal(size=n)
    return X, y


def gp_rows(table: Table, repeats: int) -> None:
    import sklearn
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

    from gpfverify.gp import GaussianProcess

    X, y = gp_data()
    kernel = ConstantKernel(1.0, (1e-5, 1e5)) * RBF([1.0, 1.0], (1e-5, 1e5)) + WhiteKernel(0.01, (1e-10, 1e2))

    def sk_fit():
        return GaussianProcessRegressor(kernel, n_restarts_optimizer=3, random_state=0).fit(X, y)

    ours_gp, sk = GaussianProcess.fit(X, y, restarts=4, seed=0), sk_fit()
    # the same optimum: each side's best log evidence, both evaluated by scikit-learn
    theta = np.log(np.concatenate([[ours_gp.signal_var[0]], ours_gp.lengthscales[0], [ours_gp.noise_var[0]]]))
    diff = agree("GP fit log evidence", sk.log_marginal_likelihood(theta), sk.log_marginal_likelihood_value_,
                 1e-5, 1e-6)
    t_ours, t_peer = paired(lambda: GaussianProcess.fit(X, y, restarts=4, seed=0), sk_fit, max(5, repeats // 4),
                            target=0.0)
    table.ratio("GP fit, n = 300, D = 2, 4 starts, same optimum", f"scikit-learn {sklearn.__version__}", t_ours,
                t_peer, diff, "keep ≤ 1")

    # predict at 1000 points, fixed hyperparameters on both sides (latent mean and variance)
    ell, s2, n2 = np.array([1.3, 2.1]), 0.8, 0.01
    gp = GaussianProcess(X, y, ell[None], [s2], [n2])
    sk = GaussianProcessRegressor(ConstantKernel(s2, "fixed") * RBF(ell, "fixed"), alpha=n2, optimizer=None).fit(X, y)
    xs = np.random.default_rng(3).uniform(-3, 3, (1000, 2))
    mean, var = gp.predict(xs)
    sk_mean, sk_std = sk.predict(xs, return_std=True)
    diff = max(agree("predict mean", mean[:, 0], sk_mean, 1e-9, 1e-10),
               agree("predict var", var[:, 0], sk_std**2, 1e-7, 1e-10))
    t_ours, t_peer = paired(lambda: gp.predict(xs), lambda: sk.predict(xs, return_std=True), repeats)
    table.ratio("GP `predict` (mean, variance) at 1000 points, n = 300", f"scikit-learn {sklearn.__version__}",
                t_ours, t_peer, diff, "≤ 1.0")


# -- predict_uncertain against a vectorised port of gp-adf's gp0 ----------------------------------------
class Gp0Port:
    """gp0.m of Deisenroth's gp-adf toolbox, vectorised as a numpy user would write it: K⁻¹ and β
    once (as in the toolbox, outside the timed call), then per output the mean and the
    input-output covariance, and per output pair (i ≥ j) the n × n matrix
    L = exp(k_i + k_jᵀ + maha(ii, −ij, R⁻¹Σ/2)) (maha by the |a|² + |b|² − 2abᵀ expansion, as in
    the toolbox), S_ij = t β_iᵀ L β_j, S_ii −= t tr(K_i⁻¹ L) − α_i²; S −= M Mᵀ."""

    def __init__(self, X, Y, ell, s2, n2):
        self.X, self.ell, self.s2 = X, ell, s2
        n = X.shape[0]
        self.iK, self.beta = [], []
        for a in range(Y.shape[1]):
            inp = X / ell[a]
            sq = np.sum(inp**2, 1)
            K = s2[a] * np.exp(-0.5 * (sq[:, None] + sq[None, :] - 2 * inp @ inp.T))
            L = np.linalg.cholesky(K + n2[a] * np.eye(n))
            iL = np.linalg.inv(L)
            self.iK.append(iL.T @ iL)
            self.beta.append(self.iK[a] @ Y[:, a])

    def __call__(self, m, s):
        X, ell, s2 = self.X, self.ell, self.s2
        E, D = ell.shape
        inp = X - m
        M, V, k = np.zeros(E), np.zeros((D, E)), np.zeros((X.shape[0], E))
        for i in range(E):
            iL = np.diag(1 / ell[i])
            x_in = inp @ iL
            B = iL @ s @ iL + np.eye(D)
            t = np.linalg.solve(B.T, x_in.T).T
            lb = np.exp(-np.sum(x_in * t, 1) / 2) * self.beta[i]
            c = s2[i] / np.sqrt(np.linalg.det(B))
            M[i] = np.sum(lb) * c
            V[:, i] = (t @ iL).T @ lb * c
            k[:, i] = np.log(s2[i]) - np.sum(x_in * x_in, 1) / 2
        S = np.zeros((E, E))
        for i in range(E):
            ii = inp / ell[i] ** 2
            for j in range(i + 1):
                R = s @ np.diag(ell[i] ** -2.0 + ell[j] ** -2.0) + np.eye(D)
                t = 1 / np.sqrt(np.linalg.det(R))
                ij = -inp / ell[j] ** 2
                Q = np.linalg.solve(R, s) / 2
                maha = (np.sum((ii @ Q) * ii, 1)[:, None] + np.sum((ij @ Q) * ij, 1)[None, :]
                        - 2 * ii @ Q @ ij.T)
                L = np.exp(k[:, i][:, None] + k[:, j][None, :] + maha)
                S[i, j] = t * self.beta[i] @ L @ self.beta[j]
                S[j, i] = S[i, j]
            S[i, i] -= t * np.sum(self.iK[i] * L) - s2[i]
        return M, S - np.outer(M, M), s @ V


def moments_profile(repeats: int) -> list[list[str]]:
    """Where predict_uncertain's time goes (n = 300, D = 2, E = 4), next to the floor: the whole
    call on the fused kernel and on the numpy reference path, the kernel alone, and numpy's
    exp / expm1 over the call's own exponents."""
    import gpfverify.gp.fused as fused
    import gpfverify.gp.moments as mm
    from gpfverify.gp import GaussianProcess

    rng = np.random.default_rng(0)
    n, d, e = 300, 2, 4
    X = rng.uniform(-3, 3, (n, d))
    Y = np.sin(X @ rng.normal(size=(d, e)))
    gp = GaussianProcess(X, Y, rng.uniform(0.5, 2, (e, d)), rng.uniform(0.5, 2, e), np.full(e, 0.01))
    mu, sigma = np.array([0.2, -0.1]), np.array([[0.3, 0.1], [0.1, 0.2]])
    pairs = e * (e + 1) // 2
    saved = fused.enabled
    fused.enabled = False
    mm.moment_match(gp, mu, sigma)  # the numpy path leaves expm1(d_ij) in its workspace
    exponents = np.log1p(mm._WORKSPACE.buffer[:pairs * n * n])  # the d_ij of that call (timing only)
    fused.enabled = saved
    kernel_args = []
    if fused.AVAILABLE:
        from gpfverify.gp import fused_kernels

        real = fused_kernels.centred_sums
        fused_kernels.centred_sums = lambda *a: (kernel_args.append(a), real(*a))[1]
        mm.moment_match(gp, mu, sigma)
        fused_kernels.centred_sums = real
    uniform = rng.uniform(-2.0, 0.0, exponents.size)
    out = np.empty_like(exponents)

    def numpy_path():
        fused.enabled = False
        try:
            mm.moment_match(gp, mu, sigma)
        finally:
            fused.enabled = saved

    parts = [("whole call (fused kernel)" if saved else "whole call (numpy path: numba not installed)",
              lambda: mm.moment_match(gp, mu, sigma)),
             ("whole call on the numpy reference path", numpy_path)]
    parts += [("  the fused kernel alone (all n² work: exponents, expm1, sums, traces, whitening)",
               lambda a=a: real(*a)) for a in kernel_args[:1]]
    parts += [("numpy exp over the same count (the floor)", lambda: np.exp(uniform, out=out)),
              ("numpy exp over this call's exponents d_ij", lambda: np.exp(exponents, out=out)),
              ("numpy expm1 over this call's exponents d_ij", lambda: np.expm1(exponents, out=out))]
    return [[name, fmt(alone(fn, repeats))] for name, fn in parts]


#: function → the part of a ct2d run it stands for (cumulative CPU under cProfile)
CT2D_PARTS = (("GP moment matching (GP-ADF predict and update, CMF/DMF central prediction)",
               "moments.py", "moment_match_stack_batch"),
              ("  of which the fused n² kernel", "fused_kernels.py", "centred_sums"),
              ("GP-UKF (sigma points through the GP means and variances)", "gp_ukf.py", "gp_ukf_measurement"),
              ("", "gp_ukf.py", "gp_ukf_predict"),
              ("RCC-CI solves (Clarabel)", "rcc_ci.py", "rcc_ci"),
              ("DMF update (eq. 35)", "distributed.py", "dmf_update"),
              ("rank analysis of every sensor (exactness)", "exactness.py", "analyse_sensors"),
              ("GP training (evidence maximisation)", "learned.py", "fit_gp_model"))


def ct2d_profile(runs: int, kappa: int = 300) -> list[list[str]]:
    """Where one ct2d run's time goes: the cumulative time of the functions in
    :data:`CT2D_PARTS` as a share of the whole run, under cProfile (which inflates the many small
    calls, so the shares matter, not the seconds)."""
    import cProfile
    import pstats

    from gpfverify.papers.fusion import ct2d_experiment as ct2d

    params = ct2d.Params(kappa=kappa)
    ct2d.run_one(params, np.random.SeedSequence(0))  # warm: compiled kernels, caches
    profile = cProfile.Profile()
    profile.enable()
    for seed in np.random.SeedSequence(1).spawn(runs):
        ct2d.run_one(params, seed)
    profile.disable()
    stats = pstats.Stats(profile).stats  # type: ignore[attr-defined]
    total = max(v[3] for (path, _, name), v in stats.items() if name == "run_one" and path.endswith("ct2d.py"))
    shares: dict[str, float] = {}
    label = ""
    for part, path, name in CT2D_PARTS:
        label = part or label
        cumulative = sum(v[3] for (p, _, n), v in stats.items() if n == name and p.endswith(path))
        shares[label] = shares.get(label, 0.0) + cumulative
    rows = [[label, f"{100 * t / total:.0f} %"] for label, t in shares.items()]
    counted = sum(t for label, t in shares.items() if not label.startswith("  "))
    rows.append(["everything else (filter bookkeeping, records, sensor simulation, CW, metrics)",
                 f"{100 * (total - counted) / total:.0f} %"])
    return rows


def moments_rows(table: Table, repeats: int) -> dict:
    from gpfverify.gp import GaussianProcess
    from gpfverify.gp.moments import moment_match, moment_match_batch
    from gpfverify.tolerances import algebra_rtol

    rng = np.random.default_rng(0)
    n, d, e = 300, 2, 4
    X = rng.uniform(-3, 3, (n, d))
    Y = np.sin(X @ rng.normal(size=(d, e)))
    ell, s2, n2 = rng.uniform(0.5, 2, (e, d)), rng.uniform(0.5, 2, e), np.full(e, 0.01)
    gp = GaussianProcess(X, Y, ell, s2, n2)
    port = Gp0Port(X, Y, ell, s2, n2)
    mu, sigma = np.array([0.2, -0.1]), np.array([[0.3, 0.1], [0.1, 0.2]])
    ours, ref = moment_match(gp, mu, sigma), port(mu, sigma)
    diff = max(agree("predict_uncertain mean", ours.mean, ref[0], 1e-9, 1e-10),
               agree("predict_uncertain cov", ours.cov, ref[1], 1e-7, 1e-9),
               agree("predict_uncertain cross", ours.cross_cov, ref[2], 1e-9, 1e-10))
    t_ours, t_peer = paired(lambda: moment_match(gp, mu, sigma), lambda: port(mu, sigma), repeats)
    table.ratio(f"`predict_uncertain`, n = {n}, D = {d}, E = {e}", "vectorised port of gp-adf's gp0", t_ours, t_peer,
                diff, "≤ 0.5")

    # the accelerator against the numpy reference path of the same call
    import gpfverify.gp.fused as fused

    if fused.AVAILABLE:
        def reference_path():
            fused.enabled = False
            try:
                return moment_match(gp, mu, sigma)
            finally:
                fused.enabled = True

        ref_np = reference_path()
        # same algebra, different rounding: to cond(K)'s rounding of each entry's scale √(P_aa P_bb) + |P_ab|
        rtol = algebra_rtol(max(np.linalg.cond(k) for k in gp.K_inv))
        diag = np.sqrt(np.abs(np.diag(ref_np.cov)))
        diff_np = max(agree("fused vs numpy cov", ours.cov, ref_np.cov, rtol, rtol * np.outer(diag, diag)),
                      agree("fused vs numpy mean", ours.mean, ref_np.mean, rtol, rtol * diag))
        t_fused, t_numpy = paired(lambda: moment_match(gp, mu, sigma), reference_path, repeats)
        table.ratio(f"`predict_uncertain`, n = {n}, D = {d}, E = {e} (fused kernel)",
                    "its own numpy reference path", t_fused, t_numpy, diff_np, "")

    # the floor: E(E+1)/2 · n² exponentials, numpy exp, same process
    count = e * (e + 1) // 2 * n * n
    numbers = rng.uniform(-2.0, 0.0, count)
    out = np.empty_like(numbers)
    t_ours2, t_exp = paired(lambda: moment_match(gp, mu, sigma), lambda: np.exp(numbers, out=out), repeats)
    table.ratio(f"`predict_uncertain`, n = {n}, E = {e}", f"numpy exp over E(E+1)/2·n² = {count:,} numbers",
                t_ours2, t_exp, 0.0, "≤ 1.5")

    # batched over many (μ, Σ) pairs: per-pair cost against the single call
    pairs = 9
    mus = mu + 0.3 * rng.normal(size=(pairs, d))
    sigmas = np.stack([sigma * (0.5 + i / pairs) for i in range(pairs)])
    batch = moment_match_batch(gp, mus, sigmas)
    singles = [moment_match(gp, m, s) for m, s in zip(mus, sigmas)]
    diff = max(max(agree("batch mean", batch.mean[i], singles[i].mean, 1e-12, 1e-13),
                   agree("batch cov", batch.cov[i], singles[i].cov, 1e-11, 1e-13),
                   agree("batch cross", batch.cross_cov[i], singles[i].cross_cov, 1e-12, 1e-13)) for i in range(pairs))
    t_batch, t_single = paired(lambda: moment_match_batch(gp, mus, sigmas),
                               lambda: [moment_match(gp, m, s) for m, s in zip(mus, sigmas)], repeats)
    table.ratio(f"batched `predict_uncertain`, {pairs} (μ, Σ) pairs, per pair", "the single call per pair",
                t_batch / pairs, t_single / pairs, diff, "< 1")
    return {"exp_seconds": t_exp, "ours_seconds": t_ours2}


# -- audit start-up -------------------------------------------------------------------------------------
def audit_row(table: Table, repeats: int) -> None:
    import json
    import tempfile

    from gpfverify.fusion.case import case_to_dict
    from gpfverify.fusion.synthetic import random_case

    case = random_case(np.random.default_rng(0), 4, [2, 2, 2])
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "case.json"
        path.write_text(json.dumps(case_to_dict(case)))
        cli = [sys.executable, "-m", "gpfverify", "audit", str(path)]
        base = [sys.executable, "-c", "import numpy, scipy.linalg"]
        assert subprocess.run(cli, capture_output=True, cwd=ROOT).returncode == 0

        def wall(cmd):
            """CPU seconds (user + system) of the child process: unlike its wall time, not
            stretched by the other processes of the shared machine."""
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            subprocess.run(cmd, capture_output=True, cwd=ROOT, check=True)
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)

        t_cli, t_base = [], []
        for r in range(max(7, repeats // 3)):
            pair = (cli, base) if r % 2 == 0 else (base, cli)
            times = [wall(c) for c in pair]
            t_cli.append(times[0] if r % 2 == 0 else times[1])
            t_base.append(times[1] if r % 2 == 0 else times[0])
    table.ratio("`gpfverify audit CASE.json`, whole process (CPU)", "`python -c \"import numpy, scipy.linalg\"`",
                float(np.median(t_cli)), float(np.median(t_base)), 0.0, "≤ 2")


# -- rows no library publishes --------------------------------------------------------------------------
def own_rows(repeats: int, ct2d_runs: int) -> list[list[str]]:
    from gpfverify.filters import Gaussian, edh_step, gp_adf_step, gp_ukf_step, ie_pff_step
    from gpfverify.filters.flows import uniform_steps
    from gpfverify.filters.resampling import Particles
    from gpfverify.filters.tbd import TbdConfig, initial_belief, pf_tbd_step
    from gpfverify.fusion.rcc_ci import rcc_ci
    from gpfverify.models import learn_gp_model
    from gpfverify.papers.particle_flow.bearing_scenario import INITIAL_STATE, bearing_model
    from gpfverify.papers.tbd.scenario import TbdScenario, scenario_model, simulate
    from gpfverify.scenarios.three_sensor import three_sensor_model

    rows = []
    scenario = TbdScenario()
    tbd_model = scenario_model(6.0, scenario)
    images = simulate(tbd_model, scenario, np.random.default_rng(0)).images
    config = TbdConfig(2000)
    rng = np.random.default_rng(1)
    state = {"belief": initial_belief(tbd_model, config, rng), "k": 0}

    def tbd_frame():
        k = state["k"] = state["k"] % len(images) + 1
        if k == 1:
            state["belief"] = initial_belief(tbd_model, config, rng)
        state["belief"] = pf_tbd_step(state["belief"], tbd_model, images[k - 1], k=k, rng=rng,
                                      config=config).posterior

    rows.append(["PF-TBD per frame, N = 2000, 20 × 20 grid, 6 dB", fmt(alone(tbd_frame, repeats))])

    bearing = bearing_model(0.05, 0.1, 0.01)
    z = bearing.h(INITIAL_STATE[None, :], 1)[0] + 0.01
    steps = uniform_steps(20)
    for count in (50, 500):
        start = INITIAL_STATE + rng.standard_normal((count, 4)) @ np.sqrt(bearing.prior_cov)
        edh_belief = Particles.equally_weighted(start, ekf_cov=bearing.prior_cov)
        rows.append([f"EDH step, N = {count}, 20 λ-steps (bearing-only, D = 4)",
                     fmt(alone(lambda b=edh_belief: edh_step(b, bearing, z, k=1, rng=rng, step_sizes=steps), repeats))])
        ie_belief = Particles.equally_weighted(start)
        rows.append([f"IE-PFF step, N = {count}, 20 λ-steps",
                     fmt(alone(lambda b=ie_belief: ie_pff_step(b, bearing, z, k=1, rng=rng, step_sizes=steps),
                               repeats))])

    ests = [Gaussian(np.array([0.1, -0.2]), np.array([[2.0, 0.3], [0.3, 1.0]])),
            Gaussian(np.array([-0.1, 0.25]), np.array([[1.0, -0.2], [-0.2, 1.5]]))]
    rows.append(["RCC-CI per solve, 2 sensors, D = 2 (Clarabel)", fmt(alone(lambda: rcc_ci(ests), repeats))])

    model = three_sensor_model()
    gp_model = learn_gp_model(model, 200, np.random.default_rng(2), restarts=1)
    _, ys = model.simulate(20, np.random.default_rng(3))
    for name, step in (("GP-ADF", gp_adf_step), ("GP-UKF", gp_ukf_step)):
        gstate = {"belief": Gaussian(model.prior_mean, model.prior_cov), "t": -1}

        def gp_step(step=step, gstate=gstate):
            t = gstate["t"] = (gstate["t"] + 1) % len(ys)
            prior = Gaussian(model.prior_mean, model.prior_cov) if t == 0 else gstate["belief"]
            gstate["belief"] = step(prior, gp_model, ys[t], k=t + 1).posterior

        rows.append([f"{name} step, three-sensor tracker learned from 200 samples (D = 4, L = 5)",
                     fmt(alone(gp_step, repeats))])

    if ct2d_runs:
        from gpfverify.papers.fusion import ct2d_experiment as ct2d

        params = ct2d.Params(kappa=300)
        cpu = []
        for seed in np.random.SeedSequence(1).spawn(ct2d_runs):
            start = time.process_time()
            ct2d.run_one(params, seed)
            cpu.append(time.process_time() - start)
        rows.append([f"ct2d run, κ = 300 (12 methods, training included; median of {ct2d_runs})",
                     f"{np.median(cpu):.2f} CPU-s (goal ≤ 1.0)"])
    return rows


def versions() -> str:
    names = ("numpy", "scipy", "filterpy", "particles", "scikit-learn", "stonesoup", "numba")
    found = []
    for name in names:
        try:
            found.append(f"{name} {metadata.version(name)}")
        except metadata.PackageNotFoundError:
            found.append(f"{name} (not installed)")
    return ", ".join(found)


def cpu() -> str:
    """The processor's model name and its widest vector unit (from /proc/cpuinfo where there is one):
    numpy's exp and the compiled kernel use AVX-512 where the processor has it, so the same code
    times differently on another processor."""
    try:
        info = Path("/proc/cpuinfo").read_text(encoding="utf-8")
    except OSError:
        return platform.processor() or "processor unknown"
    model = next((line.split(":", 1)[1].strip() for line in info.splitlines() if line.startswith("model name")),
                 "processor unknown")
    flags = next((line.split(":", 1)[1].split() for line in info.splitlines() if line.startswith("flags")), [])
    widest = "AVX-512" if "avx512f" in flags else "AVX2" if "avx2" in flags else "no AVX2"
    return f"{model} ({widest})"


def main() -> None:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=41, help="timed blocks per side (median)")
    parser.add_argument("--ct2d-runs", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="few repeats, no ct2d run")
    parser.add_argument("--only", nargs="*", default=None,
                        help="sections: pf kf ukf gp moments audit own profile (default: all)")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    repeats = 7 if args.quick else args.repeats
    only = set(args.only or ("pf", "kf", "ukf", "gp", "moments", "audit", "own", "profile"))
    load_before = os.getloadavg()
    table = Table()
    floor = {}
    if "pf" in only:
        pf_rows(table, repeats)
    if "kf" in only:
        kf_row(table, repeats)
    if "ukf" in only:
        ukf_rows(table, repeats)
    if "gp" in only:
        gp_rows(table, repeats)
    if "moments" in only:
        floor = moments_rows(table, repeats)
    if "audit" in only:
        audit_row(table, repeats)
    own = own_rows(repeats, 0 if args.quick else args.ct2d_runs) if "own" in only else []
    profiles = []
    if "profile" in only:
        profiles = [("KF step, D = 4, L = 2 (median CPU per call)", ["part", "CPU per call", "Python calls", "C calls"],
                     kf_profile(repeats)),
                    ("`predict_uncertain`, n = 300, D = 2, E = 4 (median CPU per call)", ["part", "CPU per call"],
                     moments_profile(repeats))]
        if not args.quick and args.ct2d_runs:
            profiles.append(("one ct2d run, κ = 300 (share of the run's CPU under cProfile)", ["part", "share"],
                             ct2d_profile(args.ct2d_runs)))
    load_after = os.getloadavg()
    lines = [
        f"Machine: {platform.machine()}, {cpu()}, {os.cpu_count()} cores, Python {platform.python_version()}; "
        f"{versions()}; one BLAS thread.",
        f"Load average (1, 5, 15 min) before: {', '.join(f'{x:.2f}' for x in load_before)}; "
        f"after: {', '.join(f'{x:.2f}' for x in load_after)}.",
        f"Process CPU time per call, median of {repeats} blocks per side, the two sides interleaved; "
        "ratio = gpfverify / peer; results asserted to agree before timing (max |diff|).",
        "", table.markdown(), ""]
    if floor:
        lines.append(f"Exponential floor: {fmt(floor['exp_seconds'])} for the exponentials alone, "
                     f"`predict_uncertain` {fmt(floor['ours_seconds'])}.\n")
    if own:
        lines += ["Rows no library publishes (process CPU time per call, median):", "",
                  "| operation | gpfverify |", "|---|---|"] + [f"| {a} | {b} |" for a, b in own] + [""]
    for title, head, rows in profiles:
        lines += [f"Profile: {title}", "",
                  "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        lines += ["| " + " | ".join(r) + " |" for r in rows] + [""]
    text = "\n".join(lines)
    print(text)
    if args.out:
        args.out.write_text(text, encoding="utf-8")


if __name__ == "__main__":
    main()
