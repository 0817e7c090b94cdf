"""``gpfverify.adapters.filterpy`` against filterpy itself.

* Two sensors' ``KalmanFilter`` s: the local filters gpfverify runs through the adapter equal filterpy's
  own predict/update at every step, and CMF equals a filterpy KalmanFilter on the stacked measurement,
  to rounding.
* Two sensors' ``UnscentedKalmanFilter`` s (van der Merwe's points with matched α, β, κ; a bearing
  wrapped by the user's ``residual_z`` and averaged by their ``z_mean_fn``, written here as gpfverify's
  documented circular mean): the same, across the bearing's ±π cut.
* The angle outputs are read off the residual functions; a residual that is neither a difference nor a
  wrap is refused.
* A logged run (filterpy ``Saver`` s of the centre and of each sensor) becomes a run file that
  ``gpfverify audit`` reads, whose CMF is filterpy's centralized posterior.
* ``gpfverify check SYSTEM.py:NAME`` accepts a list of filterpy filters as it is.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from filterpy.common import Saver
from filterpy.kalman import KalmanFilter, MerweScaledSigmaPoints, UnscentedKalmanFilter

from gpfverify.adapters import filterpy as adapter
from gpfverify.angles import wrap
from gpfverify.errors import InputError
from gpfverify.tolerances import algebra_rtol

F = np.kron(np.eye(2), [[1.0, 1.0], [0.0, 1.0]])  # constant velocity, state [x, vx, y, vy]
Q = np.kron(np.eye(2), 0.05 * np.array([[1 / 3, 1 / 2], [1 / 2, 1.0]]))
X0 = np.array([5.0, -3.0, -3.0, 0.6])
P0 = np.diag([25.0, 1.0, 25.0, 1.0])
EAST = np.array([250.0, 0.0])
H_POSITION = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
H_VELOCITY = np.array([[0, 1.0, 0, 0], [0, 0, 0, 1.0]])


def kalman(H, R):
    kf = KalmanFilter(dim_x=4, dim_z=H.shape[0])
    kf.F, kf.Q, kf.H, kf.R, kf.x, kf.P = F.copy(), Q.copy(), H.copy(), R.copy(), X0.reshape(4, 1).copy(), P0.copy()
    return kf


def fx(x, dt):
    return F @ x


def range_bearing(x):
    d = x[[0, 2]] - EAST
    return np.array([np.hypot(*d), np.arctan2(d[1], d[0])])  # range, then bearing


def position(x):
    return x[[0, 2]]


def residual_bearing(a, b):
    out = np.subtract(a, b)
    out[1] = (out[1] + np.pi) % (2 * np.pi) - np.pi
    return out


def mean_bearing(sigmas, weights):
    """gpfverify's circular mean, written again: relative to the first point, r + Σ w wrap(a − r)."""
    mean = weights @ sigmas
    r = sigmas[0, 1]
    mean[1] = r + weights @ ((sigmas[:, 1] - r + np.pi) % (2 * np.pi) - np.pi)
    return mean


def unscented(hx, R, alpha, beta, kappa, **angles):
    ukf = UnscentedKalmanFilter(dim_x=4, dim_z=R.shape[0], dt=1.0, hx=hx, fx=fx,
                                points=MerweScaledSigmaPoints(4, alpha, beta, kappa), **angles)
    ukf.Q, ukf.R, ukf.x, ukf.P = Q.copy(), R.copy(), X0.copy(), P0.copy()
    return ukf


def filterpy_run(kf, ys):
    """filterpy's own filter over ys: posterior means and covariances, and its Saver."""
    saver = Saver(kf)
    means, covs = [], []
    for y in ys:
        kf.predict()
        kf.update(y)
        saver.save()
        means.append(np.asarray(kf.x, dtype=float).ravel())
        covs.append(np.array(kf.P, dtype=float))
    return np.array(means), np.array(covs), saver


def simulate(model, steps=12, seed=5):
    return model.simulate(steps, np.random.default_rng(seed), x0=X0)


def assert_agree(means, covs, ref_means, ref_covs):
    rtol = algebra_rtol(max(np.linalg.cond(c) for c in ref_covs))
    diff = means - ref_means
    scale = np.abs(ref_means).max() + np.sqrt(np.abs(ref_covs).max())
    np.testing.assert_allclose(diff, 0.0, rtol=0, atol=rtol * scale)
    np.testing.assert_allclose(covs, ref_covs, rtol=0, atol=rtol * np.abs(ref_covs).max())


def test_two_kalman_filters_and_their_fusion_equal_filterpys():
    R0, R1 = np.diag([4.0, 9.0]), np.diag([0.5, 0.5])
    system = adapter.system_from_filters({"position": kalman(H_POSITION, R0), "velocity": kalman(H_VELOCITY, R1)})
    assert system.family == "kf" and [s.name for s in system.model.sensors] == ["position", "velocity"]
    _, ys = simulate(system.model)
    fused = system.run(ys, methods=("cmf", "dmf"))
    for m, (H, R) in enumerate([(H_POSITION, R0), (H_VELOCITY, R1)]):
        means, covs, _ = filterpy_run(kalman(H, R), ys[:, system.model.blocks[m]])
        assert_agree(fused.local_means(m), np.array([s.local[m].C_e for s in fused.steps]), means, covs)
    means, covs, _ = filterpy_run(kalman(np.vstack([H_POSITION, H_VELOCITY]), np.diag([4.0, 9.0, 0.5, 0.5])), ys)
    assert_agree(fused.means("cmf"), np.array([s.estimate("cmf").cov for s in fused.steps]), means, covs)
    # both sensors' C_xy have full column rank: DMF is CMF too (Proposition 1)
    assert_agree(fused.means("dmf"), np.array([s.estimate("dmf").cov for s in fused.steps]), means, covs)


@pytest.mark.parametrize("alpha, beta, kappa", [(1.0, 0.0, 2.0), (0.5, 2.0, 1.0)])
def test_two_unscented_filters_equal_filterpys_across_the_bearing_cut(alpha, beta, kappa):
    angle = {"residual_z": residual_bearing, "z_mean_fn": mean_bearing}
    R_radar, R_fix = np.diag([4.0, 0.02**2]), 4.0 * np.eye(2)
    system = adapter.system_from_filters([unscented(range_bearing, R_radar, alpha, beta, kappa, **angle),
                                          unscented(position, R_fix, alpha, beta, kappa)])
    assert system.family == "ukf"
    assert (system.params.alpha, system.params.beta, system.params.kappa) == (alpha, beta, kappa)
    assert system.model.sensor_circular == ((1,), ())  # read off residual_z
    _, ys = simulate(system.model)
    bearings = ys[:, 1]
    assert np.any(bearings > 3.0) and np.any(bearings < -3.0)  # the bearing crosses ±π
    fused = system.run(ys, methods=("cmf", "dmf"))
    for m, (hx, R, extra) in enumerate([(range_bearing, R_radar, angle), (position, R_fix, {})]):
        means, covs, _ = filterpy_run(unscented(hx, R, alpha, beta, kappa, **extra), ys[:, system.model.blocks[m]])
        assert_agree(fused.local_means(m), np.array([s.local[m].C_e for s in fused.steps]), means, covs)

    def stacked(x):
        return np.concatenate([range_bearing(x), position(x)])

    centre = unscented(stacked, np.diag([4.0, 0.02**2, 4.0, 4.0]), alpha, beta, kappa, **angle)
    means, covs, _ = filterpy_run(centre, ys)
    assert_agree(fused.means("cmf"), np.array([s.estimate("cmf").cov for s in fused.steps]), means, covs)


def test_angles_are_read_off_the_residual_functions():
    def heading_residual(a, b):
        out = np.subtract(a, b)
        out[3] = wrap(out[3])
        return out

    ukf = unscented(range_bearing, np.diag([4.0, 1e-4]), 1.0, 0.0, 2.0, residual_z=residual_bearing,
                    residual_x=heading_residual)
    system = adapter.system_from_filters([ukf])
    assert system.model.sensor_circular == ((1,),) and system.model.circular_state == (3,)
    assert adapter.system_from_filters([ukf], circular=[()]).model.sensor_circular == ((),)  # overridden

    def halving(a, b):
        return np.subtract(a, b) / 2

    with pytest.raises(InputError, match="neither an angle"):
        adapter.system_from_filters([unscented(range_bearing, np.eye(2), 1.0, 0.0, 2.0, residual_z=halving)])


def test_what_gpfverify_has_no_counterpart_for_is_refused():
    kf = kalman(H_POSITION, np.eye(2))
    kf.B = np.ones((4, 1))
    with pytest.raises(InputError, match="control input"):
        adapter.system_from_filters([kf])
    other = kalman(H_VELOCITY, np.eye(2))
    other.F = F * 1.01
    with pytest.raises(InputError, match="filter 1's F differs"):
        adapter.system_from_filters([kalman(H_POSITION, np.eye(2)), other])
    with pytest.raises(InputError, match="all be filterpy KalmanFilter or all UnscentedKalmanFilter"):
        adapter.system_from_filters([kalman(H_POSITION, np.eye(2)), unscented(position, np.eye(2), 1.0, 0.0, 2.0)])


def test_a_logged_run_becomes_a_run_file_that_audit_reads(tmp_path):
    from gpfverify.commands.audit import audit_run_file

    angle = {"residual_z": residual_bearing, "z_mean_fn": mean_bearing}
    R_radar, R_fix = np.diag([4.0, 0.02**2]), 4.0 * np.eye(2)
    system = adapter.system_from_filters([unscented(range_bearing, R_radar, 1.0, 0.0, 2.0, **angle),
                                          unscented(position, R_fix, 1.0, 0.0, 2.0)])
    _, ys = simulate(system.model, steps=8)
    _, _, radar = filterpy_run(unscented(range_bearing, R_radar, 1.0, 0.0, 2.0, **angle), ys[:, :2])
    _, _, fix = filterpy_run(unscented(position, R_fix, 1.0, 0.0, 2.0), ys[:, 2:])

    def stacked(x):
        return np.concatenate([range_bearing(x), position(x)])

    centre_means, _, centre = filterpy_run(unscented(stacked, np.diag([4.0, 0.02**2, 4.0, 4.0]), 1.0, 0.0, 2.0,
                                                     **angle), ys)
    path = adapter.write_run_file(tmp_path / "run.jsonl", centre, [radar, fix], model=system.model,
                                  ks=range(1, 9))
    _, steps, summary = audit_run_file(path)
    assert summary["steps"] == 8 and [s["k"] for s in steps] == list(range(1, 9))
    # the audit's CMF, recomputed from the logged moments and y, is filterpy's centralized posterior
    cmf = np.array([s["cmf_mean"] for s in steps])
    # C_xy = K S carries the rounding of filterpy's S⁻¹: cond(S) relative
    rtol = algebra_rtol(max(np.linalg.cond(S) for S in centre["S"]) * max(np.linalg.cond(P) for P in centre["P_prior"]))
    np.testing.assert_allclose(cmf, centre_means, rtol=0, atol=rtol * np.abs(centre_means).max())
    first = json.loads(path.read_text().splitlines()[0])
    assert first["central"]["circular"] == [1] and first["locals"][0]["circular"] == [1]


def test_a_log_without_the_measurement_moments_is_refused(tmp_path):
    with pytest.raises(InputError, match="has no 'S'"):
        adapter.write_run_file(tmp_path / "run.jsonl", {"x_prior": [], "P_prior": [], "x": [], "P": []}, [])


SYSTEM_FILE = '''
import numpy as np
from filterpy.kalman import KalmanFilter

def sensor(H, R):
    kf = KalmanFilter(dim_x=4, dim_z=2)
    kf.F = np.kron(np.eye(2), [[1.0, 1.0], [0.0, 1.0]])
    kf.Q = np.kron(np.eye(2), 0.05 * np.array([[1 / 3, 1 / 2], [1 / 2, 1.0]]))
    kf.H, kf.R = np.array(H, dtype=float), np.array(R, dtype=float)
    kf.x, kf.P = np.array([[0.0], [1.0], [0.0], [1.0]]), np.diag([25.0, 1.0, 25.0, 1.0])
    return kf

filters = [sensor([[1, 0, 0, 0], [0, 0, 1, 0]], np.diag([4.0, 9.0])),
           sensor([[0, 1, 0, 0], [0, 0, 0, 1]], np.diag([0.5, 0.5]))]
'''


def test_check_accepts_filterpy_filters_as_they_are(tmp_path, capsys):
    from gpfverify.cli import main

    (tmp_path / "kf.py").write_text(SYSTEM_FILE)
    assert main(["check", f"{tmp_path / 'kf.py'}:filters", "--filter", "ekf", "--steps", "5", "--methods",
                 "cmf,dmf", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["steps"] == 5 and out["exact_steps"] == 5  # both C_xy of full column rank: DMF exact


# -- what the user's filters do is the user's error -------------------------------------------------

FAILING_FILTERS = '''
import numpy as np
from filterpy.kalman import KalmanFilter, MerweScaledSigmaPoints, UnscentedKalmanFilter

def fx(x, dt):
    return x

def hx(x):
    return x[:1]

def broken_hx(x):
    raise ValueError("hx of mine fails")

def broken_residual(a, b):
    raise RuntimeError("residual of mine fails")

def unscented(h, residual=None):
    ukf = UnscentedKalmanFilter(dim_x=2, dim_z=1, dt=1.0, fx=fx, hx=h, points=MerweScaledSigmaPoints(2, 0.5, 2.0, 1.0))
    ukf.Q, ukf.R, ukf.P = 0.1 * np.eye(2), np.eye(1), np.eye(2)
    if residual is not None:
        ukf.residual_z = residual
    return ukf

def kalman(H):
    kf = KalmanFilter(dim_x=2, dim_z=1)
    kf.F, kf.Q, kf.R, kf.H = np.eye(2), 0.1 * np.eye(2), np.eye(1), np.asarray(H, dtype=float)
    return kf

hx_raises = [unscented(broken_hx), unscented(hx)]
residual_raises = [unscented(hx, broken_residual), unscented(hx)]
wrong_H = [kalman(np.ones((3, 3))), kalman([[1.0, 0.0]])]
complex_H = [kalman([[1.0, 0.0]]), kalman([[1.0, 0.0]])]
complex_H[1].H = np.array([[1.0 + 1j, 0.0]])
'''


@pytest.mark.parametrize("name, message", [
    ("hx_raises", "filter 0's hx raised ValueError: hx of mine fails"),
    ("residual_raises", "filter 0's residual_z raised RuntimeError: residual of mine fails"),
    ("wrong_H", "filter 0's H has shape (3, 3), expected (1, 2)"),
    ("complex_H", "filter 1's H holds complex numbers; it must hold real numbers"),
])
def test_a_filter_whose_functions_or_matrices_fail_is_the_users_error(tmp_path, capsys, name, message):
    from gpfverify.cli import main

    (tmp_path / "filters.py").write_text(FAILING_FILTERS)
    assert main(["check", f"{tmp_path / 'filters.py'}:{name}", "--steps", "3", "--json"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.splitlines() == [f"gpfverify check: error: filters.py:{name}: {message}"], err
