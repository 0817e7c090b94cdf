"""A system whose functions change with the step index k is filtered as it is or refused: the GP
families learn GPs of the state alone, so a check with ``--filter gp-adf`` or ``gp-ukf`` on a
system whose sensors depend on k is refused in one line saying why (it once learned a k-free
system silently and reported "reproduced, condition held at 10 of 10 steps" for a system that
loses rank at 6 of them); a function that takes k but does not use it, or a system filtered with
its own functions, runs. Dependence is found by calling a numpy function at every step (to
rounding) and from the expression for casadi and sympy."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
import sympy as sp

from gpfverify.cli import main
from gpfverify.errors import InputError
from gpfverify.models import Sensor, StateSpaceModel, learn_gp_model

SYSTEM = '''
import numpy as np
from gpfverify.models import Sensor, StateSpaceModel

def switching(x, k):            # the second output is switched off at every odd step
    return np.stack([x[:, 0], (k % 2 == 0) * x[:, 1]], axis=1)

def ignores_k(x, k):
    return x[:, :2].copy()

def system(measure):
    return StateSpaceModel(0.9 * np.eye(2), 0.1 * np.eye(2), [Sensor(measure, 0.01 * np.eye(2)),
                           Sensor(lambda x: x[:, :1] + x[:, 1:], [[0.1]])], np.zeros(2), np.eye(2))

switched = system(switching)
steady = system(ignores_k)
'''


def _model(measure):
    return StateSpaceModel(0.9 * np.eye(2), 0.1 * np.eye(2), [Sensor(measure, 0.01 * np.eye(2))], np.zeros(2),
                           np.eye(2))


def test_a_dependence_on_k_is_found_at_the_step_where_it_shows():
    late = _model(lambda x, k: x * (1.0 if k < 7 else 2.0))
    assert late.step_dependence(range(1, 7)) is None
    assert "between k = 1 and k = 7" in late.step_dependence(range(1, 12))
    assert _model(lambda x, k: x + 0.0 * k).step_dependence(range(1, 50)) is None
    assert _model(lambda x: 2.0 * x).step_dependence(range(1, 50)) is None


def test_casadi_and_sympy_dependence_is_read_from_the_expression():
    x, k = ca.SX.sym("x", 2), ca.SX.sym("k")
    uses = StateSpaceModel.from_casadi(x, 0.9 * x, 0.1 * np.eye(2), [Sensor(x * ca.cos(k), 0.01 * np.eye(2))],
                                       np.zeros(2), np.eye(2), step=k)
    assert "expression contains k" in uses.step_dependence([1, 2])
    unused = StateSpaceModel.from_casadi(x, 0.9 * x, 0.1 * np.eye(2), [Sensor(2 * x, 0.01 * np.eye(2))],
                                         np.zeros(2), np.eye(2), step=k)
    assert unused.step_dependence([1, 2]) is None
    a, b, j = sp.symbols("a b j")
    model = StateSpaceModel.from_sympy([a, b], [0.9 * a, 0.9 * b], 0.1 * np.eye(2),
                                       [Sensor([a, b * sp.cos(j)], 0.01 * np.eye(2))], np.zeros(2), np.eye(2), step=j)
    assert "sensor 0 measure depends on the step k" in model.step_dependence([1, 2])


def test_learning_a_gp_model_of_a_step_dependent_system_is_refused():
    with pytest.raises(InputError, match=r"learn_gp_model learns GPs of the state alone, but sensor 0 measure "
                                         r"depends on the step k .*filter with ukf or ekf"):
        learn_gp_model(_model(lambda x, k: x * (k % 3)), 20, np.random.default_rng(0))


@pytest.mark.parametrize("family", ["gp-adf", "gp-ukf"])
def test_check_refuses_a_gp_family_on_a_step_dependent_system_in_one_line(tmp_path, capsys, family):
    (tmp_path / "system.py").write_text(SYSTEM)
    out = tmp_path / "out"
    status = main(["check", f"{tmp_path / 'system.py'}:switched", "--filter", family, "--steps", "10",
                   "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1
    assert (f"--filter {family} learns GPs of the state alone, but sensor 0 measure depends on the step k "
            "(its values at the same states differ between k = 1 and k = 2)") in err[0]
    assert not out.exists()


def test_the_same_system_runs_with_its_own_functions_and_k_free_systems_learn(tmp_path, capsys):
    (tmp_path / "system.py").write_text(SYSTEM)
    assert main(["check", f"{tmp_path / 'system.py'}:switched", "--filter", "ukf", "--steps", "6",
                 "--methods", "cmf,dmf", "--json"]) == 0
    capsys.readouterr()
    assert main(["check", f"{tmp_path / 'system.py'}:steady", "--filter", "gp-adf", "--steps", "3",
                 "--train-points", "30", "--fit-points", "30", "--restarts", "1", "--methods", "cmf,dmf",
                 "--json"]) == 0
