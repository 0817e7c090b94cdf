"""What the common model protocol costs per filter step.

Every function of a :class:`~gpfverify.models.StateSpaceModel` is wrapped in a
:class:`~gpfverify.models.ModelFunction` whose call checks the output's shape and finiteness and
turns an exception in the user's code into an ``InputError`` naming the part; a filter step also
checks the model's type once. This script times, on the reference three-sensor tracker
(``gpfverify.scenarios.three_sensor``; a linear model with the same sizes for the KF):

* one KF, EKF, UKF and SR-UKF step (median, single-threaded BLAS);
* one call of the stacked measurement function through the model against the same user
  functions called directly: the protocol's cost, and its share of a UKF step.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from _timing import median_cpu_seconds, publish  # noqa: E402
from gpfverify.filters.ekf import ekf_step  # noqa: E402
from gpfverify.filters.kalman import kf_step  # noqa: E402
from gpfverify.filters.records import Gaussian  # noqa: E402
from gpfverify.filters.sr_ukf import SqrtGaussian, sr_ukf_step  # noqa: E402
from gpfverify.filters.ukf import ukf_step  # noqa: E402
from gpfverify.models import linear_model  # noqa: E402
from gpfverify.scenarios.three_sensor import (SENSOR_RANGE, SENSOR_RANGE_BEARING, cv_matrices,  # noqa: E402
                                              range_bearing, range_only, three_sensor_model)

CALLS = 2000


def per_call(fn) -> float:
    return median_cpu_seconds(lambda: [fn() for _ in range(CALLS)], repeats=7) / CALLS


def main(out: Path | None) -> None:
    model = three_sensor_model()
    belief = Gaussian(model.prior_mean, model.prior_cov)
    y = model.simulate(1, np.random.default_rng(0))[1][0]
    F, Q = cv_matrices(1.0, 0.05)
    H = np.vstack([np.eye(2, 4), np.eye(2, 4), np.eye(1, 4)])
    linear = linear_model(F, H, Q, model.R, model.prior_mean, model.prior_cov, sizes=model.sizes)
    sqrt_belief = SqrtGaussian(belief.mean, np.linalg.cholesky(belief.cov))
    steps = {"KF (linear, same sizes)": lambda: kf_step(belief, linear, y),
             "EKF": lambda: ekf_step(belief, model, y),
             "UKF": lambda: ukf_step(belief, model, y),
             "SR-UKF": lambda: sr_ukf_step(sqrt_belief, model, y)}
    points = np.random.default_rng(1).normal(size=(9, 4))  # the UKF's 2D + 1 sigma points
    position = np.eye(2, 4)
    raw = (lambda x: x @ position.T, range_bearing(SENSOR_RANGE_BEARING), range_only(SENSOR_RANGE))
    direct = per_call(lambda: np.concatenate([fn(points) for fn in raw], axis=-1))
    wrapped = per_call(lambda: model.h(points))
    overhead = wrapped - direct
    rows = [[name, f"{per_call(fn) * 1e6:.1f}"] for name, fn in steps.items()]
    rows.append(["stacked h through the model (9 points)", f"{wrapped * 1e6:.1f}"])
    rows.append(["the same user functions called directly", f"{direct * 1e6:.1f}"])
    ukf = per_call(steps["UKF"])
    # a UKF step calls f once (a matrix here: no checks) and the stacked h once
    rows.append(["protocol overhead per UKF step (one stacked h call), share of the step",
                 f"{overhead * 1e6:.1f} ({overhead / ukf:.1%})"])
    publish(["operation", "µs per call (median CPU)"], rows, out)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path)
    main(parser.parse_args().out)
