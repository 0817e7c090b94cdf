"""System files (``gpfverify check SYSTEM.py:NAME``) that tests of the command line write and run."""

#: a linear system of two sensors, two outputs each (``:system``)
LINEAR_SYSTEM = '''
import numpy as np
from gpfverify.models import linear_model
F = np.array([[1.0, 1.0], [0.0, 0.95]])
H = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.5, -1.0]])
Q = np.array([[0.2, 0.05], [0.05, 0.1]])
R = np.diag([0.5, 0.3, 0.4, 0.2])
system = linear_model(F, H, Q, R, prior_mean=[1.0, 0.5], prior_cov=np.eye(2), sizes=(2, 2))
'''

#: a system (``:system``) whose file runs ``{at_import}`` when it loads and whose second sensor's
#: measurement function ``h`` runs ``{in_measurement}`` from its call ``{after} + 1`` on (format it)
MEASURING_SYSTEM = '''
import os, sys
import numpy as np
from gpfverify.models import Sensor, StateSpaceModel
calls = [0]
{at_import}
def h(x):
    calls[0] += 1
    if calls[0] > {after}:
        {in_measurement}
    return x[:, :1]
system = StateSpaceModel(transition=np.eye(2), process_cov=0.1 * np.eye(2),
                         sensors=[Sensor(np.eye(2), np.eye(2)), Sensor(h, [[1.0]])],
                         prior_mean=[0.0, 0.0], prior_cov=np.eye(2))
'''
