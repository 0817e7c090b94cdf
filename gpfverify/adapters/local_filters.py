"""A tracker from another library in gpfverify's terms, with what its filters carry.

A Stone Soup tracker or a set of filterpy filters is more than a system: its filters are a
family (Kalman, extended, unscented), draw their own sigma points (Stone Soup's predictor and
updater each with α, β, κ, filterpy's ``MerweScaledSigmaPoints`` or ``JulierSigmaPoints``), average
angles their library's way (:data:`gpfverify.angles.ANGLE_MEANS`) and start from their own beliefs
(each filterpy filter's x and P). :class:`LocalFilters` carries all of it with the
:class:`~gpfverify.models.StateSpaceModel`, so that ``gpfverify check`` and :meth:`LocalFilters.run`
run the filters as written, and say where each setting came from (``origin``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from gpfverify.filters.records import Gaussian
from gpfverify.filters.sigma_points import SigmaSettings
from gpfverify.models.system import StateSpaceModel


@dataclass(frozen=True)
class LocalFilters:
    """A system with its library's filters: the ``model``; the Gaussian ``family`` of the filters
    (``"kf"``, ``"ekf"`` or ``"ukf"``; None when the objects name no filter); the sigma points
    ``params`` of its prediction and update with the library's angle mean (None for a gpfverify
    model, which brings none: gpfverify's defaults or the user's choice apply); each sensor's
    filter's own start ``local_priors`` (None: every filter starts from the model's prior); the
    ``library`` ("stonesoup", "filterpy", "" for a gpfverify model) and ``origin``, a sentence per
    setting ("sigma_points", "starts", "family") saying where it was read."""

    model: StateSpaceModel
    family: str | None = None
    params: SigmaSettings | None = None
    local_priors: tuple[Gaussian, ...] | None = None
    library: str = ""
    origin: Mapping[str, str] = field(default_factory=dict)

    def run(self, ys, **options):
        """:func:`gpfverify.model_fusion.run_fusion` with these local filters (``options``: its keywords,
        e.g. ``methods``, and any of the filters' settings to run otherwise); the centre starts from
        the model's prior."""
        from gpfverify.model_fusion import run_fusion

        mine = {"family": self.family or "ukf", "local_priors": self.local_priors}
        if self.params is not None:
            mine["params"] = self.params
        return run_fusion(self.model, ys, **{**mine, **options})
