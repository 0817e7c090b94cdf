"""Multisensor estimation fusion (seed 000 §3): centralized (CMF) and distributed (DMF,
Proposition 1) fusion on plain arrays, the DMF–CMF gap, its exactness condition, branch offsets
and repair message, the baselines that use only the local posteriors (CC/CW, CI, ICI, EI, RCC-CI),
and CMF/DMF runs for any user model and filter family (:mod:`gpfverify.fusion.model_fusion`).

The convex-solver rules (CI, ICI, RCC-CI: cvxpy) are imported on first use of their names, so
importing the package stays cheap; RCC-CI itself is :func:`gpfverify.fusion.rcc_ci.rcc_ci`.
"""

from importlib import import_module

from gpfverify.fusion.case import (CentralPrediction, FusionCase, LocalReport, case_from_dict,
                                   case_from_records, case_to_dict, load_case)
from gpfverify.fusion.centralized import cmf_update, fusion_gain
from gpfverify.fusion.convex import convex_combination
from gpfverify.fusion.distributed import DMFResult, dmf_update
from gpfverify.fusion.ellipsoidal import ellipsoidal_intersection
from gpfverify.fusion.estimates import FusedEstimate
from gpfverify.fusion.exactness import (KernelSplit, SensorExactness, branch_offsets, equivalence_tolerance,
                                        kernel_split, predicted_gap, repair_message)
from gpfverify.fusion.model_fusion import (DMFStep, FusionRun, FusionStep, central_prediction, cmf_step,
                                           dmf_step, run_fusion)

#: names served from modules that import cvxpy, loaded on first access
_LAZY = {"covariance_intersection": "gpfverify.fusion.ci",
         "inverse_covariance_intersection": "gpfverify.fusion.ci",
         "RccCiResult": "gpfverify.fusion.rcc_ci"}


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["CentralPrediction", "FusionCase", "LocalReport", "case_from_dict", "case_from_records",
           "case_to_dict", "load_case", "cmf_update", "fusion_gain", "DMFResult", "dmf_update",
           "KernelSplit", "SensorExactness", "branch_offsets", "equivalence_tolerance", "kernel_split",
           "predicted_gap", "repair_message", "FusedEstimate", "convex_combination",
           "covariance_intersection", "inverse_covariance_intersection", "ellipsoidal_intersection",
           "RccCiResult", "DMFStep", "FusionRun", "FusionStep", "central_prediction", "cmf_step",
           "dmf_step", "run_fusion"]
