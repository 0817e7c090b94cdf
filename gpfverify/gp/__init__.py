"""Gaussian-process core: SE-ARD regression per output and exact uncertain-input moments."""

from gpfverify.gp.moments import MomentMatch, moment_match
from gpfverify.gp.regression import FitBounds, GaussianProcess

__all__ = ["GaussianProcess", "FitBounds", "MomentMatch", "moment_match"]
