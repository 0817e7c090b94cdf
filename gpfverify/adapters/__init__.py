"""Trackers from other libraries as gpfverify systems: Stone Soup and filterpy.

The adapters live in :mod:`gpfverify.adapters.stonesoup` and :mod:`gpfverify.adapters.filterpy`
(extras ``gpfverify[stonesoup]``, ``gpfverify[filterpy]``). This module imports neither library:
:func:`as_state_space_model` recognises a loaded object by the package its types come from and
imports the one adapter it needs, so ``gpfverify check`` on a plain
:class:`~gpfverify.models.StateSpaceModel` never loads Stone Soup or filterpy.

Whatever the user's objects do while the adapters read them — a filterpy ``hx`` or ``residual_z``
that raises, an ``H`` of the wrong shape, a Stone Soup model whose ``function`` raises — is an
:class:`~gpfverify.errors.InputError` naming the object (:func:`user_call`, :func:`user_floats`):
the user's error, exit status 2, never "a bug".
"""

from __future__ import annotations

from collections.abc import Mapping

from gpfverify.errors import GpfverifyError, InputError
from gpfverify.models.system import StateSpaceModel

#: the libraries whose objects :func:`as_state_space_model` turns into a model
LIBRARIES = ("stonesoup", "filterpy")

#: what a system object may be, for messages
ACCEPTED = ("a gpfverify.models.StateSpaceModel, Stone Soup models (a transition model, measurement models, "
            "a GaussianState prior and a timedelta, or objects holding them: docs/ecosystem.md) or filterpy "
            "filters (one KalmanFilter or UnscentedKalmanFilter per sensor)")


def _library(obj: object) -> str | None:
    """The library (one of :data:`LIBRARIES`) whose type ``obj`` or, for a mapping or sequence, one
    of its items is an instance of; None for anything else."""
    if isinstance(obj, Mapping):
        items = list(obj.values())
    elif isinstance(obj, (list, tuple)):
        items = list(obj)
    else:
        items = [obj]
    for item in items:
        if isinstance(item, (list, tuple)) and item is not obj:
            found = _library(item)
            if found:
                return found
        for cls in type(item).__mro__:
            top = cls.__module__.split(".")[0]
            if top in LIBRARIES:
                return top
    return None


def as_state_space_model(obj: object, what: str = "the system") -> StateSpaceModel:
    """The :class:`~gpfverify.models.StateSpaceModel` that ``obj`` describes: ``obj`` itself, or a
    Stone Soup or filterpy description of a system turned into one
    (:func:`gpfverify.adapters.stonesoup.system_from_objects`,
    :func:`gpfverify.adapters.filterpy.system_from_filters`). Anything else is an
    :class:`~gpfverify.errors.InputError` naming ``what`` and what it is."""
    if isinstance(obj, StateSpaceModel):
        return obj
    library = _library(obj)
    if library is None:
        raise InputError(f"{what} is a {type(obj).__name__}, not {ACCEPTED}")
    try:
        if library == "stonesoup":
            from gpfverify.adapters.stonesoup import system_from_objects

            return system_from_objects(obj)
        from gpfverify.adapters.filterpy import system_from_filters

        return system_from_filters(obj).model
    except GpfverifyError as exc:
        raise InputError(f"{what}: {exc}") from exc
