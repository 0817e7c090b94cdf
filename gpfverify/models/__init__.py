"""Users' own systems: the state-space model every filter and fusion rule takes (SPEC §6).

* :class:`StateSpaceModel` and :class:`Sensor`: known functions (numpy callables, matrices,
  casadi or sympy expressions), full Q and R, angle outputs and state components;
* :class:`GPModel`: a system learned as Gaussian processes (:func:`fit_gp_model` from samples,
  :func:`learn_gp_model` from a :class:`StateSpaceModel`), for the GP-ADF and GP-UKF families;
  :func:`batch_gp_models` the GP models of several Monte Carlo runs as one, stepped together.
"""

from gpfverify.models.functions import ModelFunction
from gpfverify.models.learned import GPModel, batch_gp_models, fit_capped, fit_gp_model, learn_gp_model
from gpfverify.models.system import Sensor, StateSpaceModel, linear_model

__all__ = ["ModelFunction", "Sensor", "StateSpaceModel", "linear_model", "GPModel", "batch_gp_models",
           "fit_capped", "fit_gp_model", "learn_gp_model"]
