"""The casadi second implementation against numpy (small sizes), and the sensitivity API."""

import numpy as np
import pytest

from gpfverify.errors import InputError
from gpfverify.fusion.synthetic import random_case
from gpfverify.symbolic.crosscheck import CROSSCHECKS
from gpfverify.symbolic.sensitivity import dmf_sensitivity


@pytest.mark.parametrize("name", list(CROSSCHECKS))
def test_casadi_agrees_with_numpy(name):
    certificate = CROSSCHECKS[name]("small", seed=3)
    assert certificate.claim == name
    assert certificate.status == "checked", certificate.detail


def test_sensitivity_rejects_a_sensor_with_more_outputs_than_states():
    case = random_case(np.random.default_rng(0), 2, (3,))
    with pytest.raises(InputError):
        dmf_sensitivity(case)
