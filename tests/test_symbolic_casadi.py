"""The casadi second implementation against numpy (small sizes), and the sensitivity API."""

import numpy as np
import pytest

from gpfverify.fusion.synthetic import random_case
from gpfverify.symbolic.crosscheck import CROSSCHECKS
from gpfverify.symbolic.sensitivity import dmf_sensitivity
from gpfverify.tolerances import algebra_rtol


@pytest.mark.parametrize("name", list(CROSSCHECKS))
def test_casadi_agrees_with_numpy(name):
    certificate = CROSSCHECKS[name]("small", seed=3)
    assert certificate.claim == name
    assert certificate.status == "checked", certificate.detail


def test_sensitivity_of_a_sensor_with_more_outputs_than_states_uses_the_fixed_rank_pinv():
    case = random_case(np.random.default_rng(0), 2, (3, 1))
    wide, narrow = dmf_sensitivity(case)
    assert wide.rank == 2 and wide.jacobian_norms["C_xy"] is None
    assert narrow.rank == 1 and narrow.jacobian_norms["C_xy"] is not None
    for s in (wide, narrow):
        assert s.jacobian_norms["mu_e"] <= s.mu_e_bound * (1 + algebra_rtol(1.0 / s.sigma_r))
