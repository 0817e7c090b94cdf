"""Multisensor estimation fusion on plain arrays (seed 000 §3): centralized (CMF) and distributed
(DMF, Proposition 1) fusion, the DMF–CMF gap, its exactness condition and repair message, and
the baselines that use only the local posteriors (CC/CW, CI, ICI, EI, RCC-CI).

The GP-ADF / GP-UKF versions of CMF and DMF live in :mod:`gpfverify.fusion.gp_fusion`; RCC-CI is
:func:`gpfverify.fusion.rcc_ci.rcc_ci` (the module keeps its name in the package namespace).
"""

from gpfverify.fusion.case import (CentralPrediction, FusionCase, LocalReport, case_from_dict,
                                   case_from_records, case_to_dict, load_case)
from gpfverify.fusion.centralized import cmf_update, fusion_gain
from gpfverify.fusion.ci import covariance_intersection, inverse_covariance_intersection
from gpfverify.fusion.convex import convex_combination
from gpfverify.fusion.distributed import DMFResult, dmf_update
from gpfverify.fusion.ellipsoidal import ellipsoidal_intersection
from gpfverify.fusion.estimates import FusedEstimate
from gpfverify.fusion.exactness import (KernelSplit, SensorExactness, equivalence_tolerance,
                                        kernel_split, predicted_gap, repair_message)
from gpfverify.fusion.rcc_ci import RccCiResult

__all__ = ["CentralPrediction", "FusionCase", "LocalReport", "case_from_dict", "case_from_records",
           "case_to_dict", "load_case", "cmf_update", "fusion_gain", "DMFResult", "dmf_update",
           "KernelSplit", "SensorExactness", "equivalence_tolerance", "kernel_split", "predicted_gap",
           "repair_message", "FusedEstimate", "convex_combination", "covariance_intersection",
           "inverse_covariance_intersection", "ellipsoidal_intersection", "RccCiResult"]
