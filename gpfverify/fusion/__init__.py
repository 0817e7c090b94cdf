"""Multisensor estimation fusion on plain arrays (seed 000 §3): centralized (CMF) and distributed
(DMF, Proposition 1) fusion, the DMF–CMF gap, its exactness condition and repair message, and
the baselines that use only the local posteriors (CC/CW, CI, ICI, EI, RCC-CI)."""

from gpfverify.fusion.case import (CentralPrediction, FusionCase, LocalReport, case_from_dict,
                                   case_from_records, case_to_dict, load_case)
from gpfverify.fusion.centralized import cmf_update, fusion_gain
from gpfverify.fusion.distributed import DMFResult, dmf_update
from gpfverify.fusion.exactness import (KernelSplit, SensorExactness, kernel_split, predicted_gap,
                                        repair_message)

__all__ = ["CentralPrediction", "FusionCase", "LocalReport", "case_from_dict", "case_from_records",
           "case_to_dict", "load_case", "cmf_update", "fusion_gain", "DMFResult", "dmf_update",
           "KernelSplit", "SensorExactness", "kernel_split", "predicted_gap", "repair_message"]
