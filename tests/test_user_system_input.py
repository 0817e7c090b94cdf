"""What a user's system and logged measurements may be: a singular process noise is sampled with
the right covariance; SYSTEM.py imports helper modules next to it (sys.path restored); a function
written for one state gets a message saying functions take rows; measurements of text, booleans
or complex numbers, and a measurement function returning complex values, are refused."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gpfverify.errors import InputError
from gpfverify.models import Sensor, StateSpaceModel, linear_model
from gpfverify.systems import load_system
from gpfverify.tolerances import monte_carlo_atol

ROOT = Path(__file__).resolve().parents[1]
TRACKER = f"{ROOT / 'examples' / 'three_sensor_system.py'}:tracker"


def test_a_singular_process_noise_is_sampled_with_its_covariance():
    """Q of rank 1 (noise drives the velocity only, through a shared direction): no Cholesky factor
    exists; the sample covariance of the transition noise must match Q by Monte Carlo tolerance."""
    direction = np.array([0.0, 1.0, 2.0])
    Q = np.outer(direction, direction)
    system = linear_model(np.eye(3), np.eye(3)[:1], Q, [[1.0]])
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.cholesky(Q)
    n = 20000
    noise = system.sample_transition(np.zeros((n, 3)), 1, np.random.default_rng(0))
    # oracle: the entries of outer(v, v) for each draw; their means estimate Q
    products = noise[:, :, None] * noise[:, None, :]
    atol = monte_carlo_atol(products.std(axis=0), n)
    assert np.all(np.abs(products.mean(axis=0) - Q) <= atol)
    assert np.abs(noise[:, 0]).max() == 0.0            # a component without noise stays put
    states, _ = system.simulate(3, np.random.default_rng(1))
    assert np.all(np.isfinite(states))


def test_the_system_folder_is_on_the_path_while_it_loads(tmp_path):
    (tmp_path / "valid_helper_params.py").write_text("NOISE = 0.5\n")
    (tmp_path / "system.py").write_text(
        "import numpy as np\nimport valid_helper_params\nfrom gpfverify.models import linear_model\n"
        "system = linear_model(np.eye(2), np.eye(2), np.eye(2), valid_helper_params.NOISE * np.eye(2))\n")
    before = list(sys.path)
    model = load_system(f"{tmp_path / 'system.py'}:system")
    assert sys.path == before
    np.testing.assert_array_equal(model.R, 0.5 * np.eye(2))


def test_a_function_written_for_one_state_is_told_that_functions_take_rows():
    sensor = Sensor(lambda x: np.array([x[0], x[1], x[2]]), np.eye(3), name="per-state")
    with pytest.raises(InputError, match=r"raised IndexError: .*functions take a batch of states as rows, "
                                         r"x of shape \(N, D\)"):
        StateSpaceModel(np.eye(2), np.eye(2), [sensor], np.zeros(2), np.eye(2))


def test_a_measurement_function_returning_complex_values_is_refused():
    sensor = Sensor(lambda x: np.sqrt(x[:, :1] - 1.0 + 0j), [[1.0]], name="complex")
    with pytest.raises(InputError, match="sensor 0 \\(complex\\) measure returned complex numbers"):
        StateSpaceModel(np.eye(2), np.eye(2), [sensor], np.zeros(2), np.eye(2))


@pytest.mark.parametrize("y, what", [(np.full((4, 4), "1.0"), "text"), (np.ones((4, 4), dtype=bool), "booleans"),
                                     (np.ones((4, 4)) + 1j, "complex numbers")])
def test_measurements_that_are_not_real_numbers_are_refused(tmp_path, y, what):
    path = tmp_path / "logged.npz"
    np.savez(path, y=y)
    result = subprocess.run([sys.executable, "-m", "gpfverify", "check", TRACKER, "--measurements", str(path),
                             "--json"], capture_output=True, text=True)
    assert result.returncode == 2 and result.stdout == "" and result.stderr.count("\n") == 1
    assert f"must be numeric (real numbers), got {what}" in result.stderr


def test_training_data_with_a_filter_that_learns_nothing_is_refused(tmp_path):
    path = tmp_path / "training.npz"
    np.savez(path, x=np.zeros((10, 4)), y=np.zeros((10, 4)))
    result = subprocess.run([sys.executable, "-m", "gpfverify", "check", TRACKER, "--filter", "ukf", "--training",
                             str(path), "--steps", "2", "--json"], capture_output=True, text=True)
    assert result.returncode == 2 and result.stdout == "" and result.stderr.count("\n") == 1
    assert "--filter ukf uses the system's own functions and would ignore it" in result.stderr
