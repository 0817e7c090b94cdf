"""filterpy Kalman filters as ``gpfverify check`` and ``gpfverify audit`` take them: one
``KalmanFilter`` per sensor of a constant-velocity target — a position fix, and an odometer that
logs the two velocity components and their sum (three outputs carrying two numbers' worth of
state: its cross covariance C_xy^m cannot have full column rank) — each with the system's F, Q, x,
P and its own H and R.

    gpfverify check examples/filterpy_tracker.py:filters --filter ekf --steps 30 --out out/filterpy-check

Run as a script, it runs the two sensors' filters and a centralized filter on the stacked
measurement with filterpy, logs each with filterpy's ``Saver``, and writes the run as the run file
``gpfverify audit`` reads (docs/ecosystem.md):

    python examples/filterpy_tracker.py out/filterpy-run.jsonl
"""

import sys

import numpy as np
from filterpy.kalman import KalmanFilter

F = np.kron(np.eye(2), [[1.0, 1.0], [0.0, 1.0]])                      # x = [x, vx, y, vy], 1 s steps
Q = np.kron(np.eye(2), 0.05 * np.array([[1 / 3, 1 / 2], [1 / 2, 1.0]]))
X0, P0 = np.array([0.0, 1.0, 0.0, 1.0]), np.diag([25.0, 1.0, 25.0, 1.0])
H_POSITION, R_POSITION = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]]), np.diag([4.0, 9.0])
H_VELOCITY, R_VELOCITY = np.array([[0, 1.0, 0, 0], [0, 0, 0, 1.0], [0, 1.0, 0, 1.0]]), np.diag([0.5, 0.5, 0.2])


def kalman_filter(H, R):
    kf = KalmanFilter(dim_x=4, dim_z=H.shape[0])
    kf.F, kf.Q, kf.H, kf.R = F.copy(), Q.copy(), H.copy(), R.copy()
    kf.x, kf.P = X0.reshape(4, 1).copy(), P0.copy()
    return kf


filters = {"position fix": kalman_filter(H_POSITION, R_POSITION),
           "odometer": kalman_filter(H_VELOCITY, R_VELOCITY)}


def logged_run(steps: int, seed: int = 1):
    """The centre's and the sensors' filters over a simulated run, each logged by a filterpy Saver."""
    from filterpy.common import Saver

    rng = np.random.default_rng(seed)
    centre = kalman_filter(np.vstack([H_POSITION, H_VELOCITY]), np.diag([4.0, 9.0, 0.5, 0.5, 0.2]))
    local = [kalman_filter(H_POSITION, R_POSITION), kalman_filter(H_VELOCITY, R_VELOCITY)]
    savers = [Saver(f) for f in [centre, *local]]
    x = rng.multivariate_normal(X0, P0)
    for _ in range(steps):
        x = F @ x + rng.multivariate_normal(np.zeros(4), Q)
        z = [H @ x + rng.multivariate_normal(np.zeros(len(R)), R) for H, R in
             [(H_POSITION, R_POSITION), (H_VELOCITY, R_VELOCITY)]]
        for f, y, saver in zip([centre, *local], [np.concatenate(z), *z], savers):
            f.predict()
            f.update(y)
            saver.save()
    return savers[0], savers[1:]


if __name__ == "__main__":
    from gpfverify.adapters.filterpy import system_from_filters, write_run_file

    centre, sensors = logged_run(30)
    print(write_run_file(sys.argv[1], centre, sensors, model=system_from_filters(filters).model, ks=range(1, 31)))
