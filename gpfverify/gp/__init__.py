"""Gaussian-process core: SE-ARD regression per output and exact uncertain-input moments."""

from gpfverify.gp.moments import MomentMatch, moment_match, moment_match_batch, moment_match_stack
from gpfverify.gp.regression import FitBounds, GaussianProcess
from gpfverify.gp.stack import GaussianProcessStack

__all__ = ["GaussianProcess", "GaussianProcessStack", "FitBounds", "MomentMatch", "moment_match",
           "moment_match_batch", "moment_match_stack"]
