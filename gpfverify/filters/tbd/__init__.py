"""Track-before-detect: Rutten's PF-TBD and the two-stage TPFTBD of seed 004."""

from gpfverify.filters.tbd.model import TbdModel
from gpfverify.filters.tbd.pf import TbdConfig, initial_belief, pf_tbd_step
from gpfverify.filters.tbd.track import TbdTrack, filter_sequence
from gpfverify.filters.tbd.two_stage import SecondStage, TwoStageStep, second_stage_update, tpf_tbd_step

__all__ = ["TbdModel", "TbdConfig", "SecondStage", "TwoStageStep", "TbdTrack", "initial_belief",
           "pf_tbd_step", "second_stage_update", "tpf_tbd_step", "filter_sequence"]
