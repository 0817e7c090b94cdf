"""Calls into the user's Stone Soup and filterpy objects, for the adapters: whatever the objects
do is an :class:`~gpfverify.errors.InputError` naming the object, the user's error (exit status 2),
never "a bug"."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from gpfverify.errors import GpfverifyError, InputError


def user_call(what: str, fn: Callable[..., Any], *args, **kwargs) -> Any:
    """``fn(*args, **kwargs)``, a method or function of the user's objects described by ``what``
    (``"filter 0's hx"``): an exception it raises becomes an InputError naming it."""
    try:
        return fn(*args, **kwargs)
    except GpfverifyError:
        raise
    except Exception as exc:  # the user's object: its failure is the user's error, named
        text = " ".join(str(exc).split())
        raise InputError(f"{what} raised {type(exc).__name__}" + (f": {text}" if text else "")) from exc


def user_floats(value, what: str, shape: tuple[int, ...] | None = None) -> np.ndarray:
    """A user's array (``what``, e.g. ``"filter 1's H"``) as real floats, reshaped to ``shape`` when
    it holds as many numbers: InputError when it is not numeric, complex, or of another size."""
    try:
        array = np.asarray(value)
    except (TypeError, ValueError):
        raise InputError(f"{what} is not an array of real numbers") from None
    if np.iscomplexobj(array) or (array.dtype == object and any(isinstance(v, complex) for v in array.flat)):
        raise InputError(f"{what} holds complex numbers; it must hold real numbers")
    try:
        array = array.astype(float)
    except (TypeError, ValueError):
        raise InputError(f"{what} is not an array of real numbers") from None
    if shape is not None and array.shape != shape:
        if array.size != int(np.prod(shape)):
            raise InputError(f"{what} has shape {array.shape}, expected {shape}")
        array = array.reshape(shape)
    return array
