"""Multisensor estimation fusion (seed 000 §3): centralized (CMF) and distributed (DMF,
Proposition 1) fusion on plain arrays, the DMF–CMF gap, its exactness condition, branch offsets
and repair message, and the baselines that use only the local posteriors (CC/CW, CI, ICI, EI,
RCC-CI). CMF/DMF runs for any user model and filter family, audited at every step, sit above the
audit in :mod:`gpfverify.model_fusion` (``from gpfverify.model_fusion import run_fusion``).

The convex-solver rules (CI, ICI, RCC-CI: cvxpy) are imported on first use of their names, so
importing the package stays cheap; RCC-CI itself is :func:`gpfverify.fusion.rcc_ci.rcc_ci`.
"""

import warnings
from importlib import import_module

from gpfverify.fusion.case import CentralPrediction, FusionCase, LocalReport, case_to_dict
from gpfverify.fusion.caseblock import case_from_dict, case_from_records, load_case
from gpfverify.fusion.centralized import cmf_update, fusion_gain
from gpfverify.fusion.convex import convex_combination
from gpfverify.fusion.distributed import DMFResult, dmf_update
from gpfverify.fusion.ellipsoidal import ellipsoidal_intersection
from gpfverify.fusion.estimates import FusedEstimate
from gpfverify.fusion.exactness import (KernelSplit, SensorExactness, branch_offsets, equivalence_tolerance,
                                        kernel_split, predicted_gap, repair_message)

#: names served from modules that import cvxpy, loaded on first access
_LAZY = {"covariance_intersection": "gpfverify.fusion.ci",
         "inverse_covariance_intersection": "gpfverify.fusion.ci",
         "RccCiResult": "gpfverify.fusion.rcc_ci"}


#: names that moved out of this package -> their new home; served from there with a DeprecationWarning
#: for one release (0.1.x): the model run sits above the audit it runs and the run-file module is the
#: audit's (docs/architecture.md)
_MOVED = {**dict.fromkeys(("DMFStep", "FusionRun", "FusionStep", "central_prediction", "cmf_step", "dmf_step",
                           "run_fusion"), "gpfverify.model_fusion"),
          "runfile": "gpfverify.audit.runfile"}


def _moved(name: str):
    """The object ``name`` names in its new home (the two imports the layers contract allows this
    package, pyproject.toml)."""
    if name == "runfile":
        from gpfverify.audit import runfile

        return runfile
    from gpfverify import model_fusion

    return getattr(model_fusion, name)


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(import_module(_LAZY[name]), name)
    if name in _MOVED:
        new = _MOVED[name] if name == "runfile" else f"{_MOVED[name]}.{name}"
        warnings.warn(f"gpfverify.fusion.{name} moved to {new}; the old name goes in the next release",
                      DeprecationWarning, stacklevel=2)
        return _moved(name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["CentralPrediction", "FusionCase", "LocalReport", "case_from_dict", "case_from_records",
           "case_to_dict", "load_case", "cmf_update", "fusion_gain", "DMFResult", "dmf_update",
           "KernelSplit", "SensorExactness", "branch_offsets", "equivalence_tolerance", "kernel_split",
           "predicted_gap", "repair_message", "FusedEstimate", "convex_combination",
           "covariance_intersection", "inverse_covariance_intersection", "ellipsoidal_intersection",
           "RccCiResult"]
