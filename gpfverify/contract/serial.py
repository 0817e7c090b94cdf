"""JSON for typed records: one writer (:func:`to_json`) and one reader (:func:`from_json`) for the
frozen dataclasses of :mod:`gpfverify.contract` and of every experiment.

Supported field types: ``bool``, ``int``, ``float``, ``str``, ``None``, ``Literal[...]``, unions
with ``None``, ``tuple[T, ...]`` / ``tuple[A, B]``, ``list[T]``, ``dict[str, T]`` and nested
dataclasses. Tuples are written as JSON lists and read back as tuples, so
``from_json(T, to_json(x)) == x`` for every record ``x`` of type ``T``. numpy scalars and arrays
are written as numbers and (nested) lists. Reading is strict: a missing field without default,
an unknown field or a value of the wrong type raises :class:`~gpfverify.errors.InputError`
naming its path (``params.kappa``).
"""

from __future__ import annotations

import dataclasses
import functools
import types
import typing
from typing import Any, Literal, TypeVar, Union

import numpy as np

from gpfverify.errors import InputError

T = TypeVar("T")


def to_json(value: Any) -> Any:
    """``value`` as plain JSON data (dict, list, str, int, float, bool, None)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: to_json(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, dict):
        return {str(k): to_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_json(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


@functools.cache
def _hints(cls: Any) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def from_json(tp: Any, data: Any, path: str = "value") -> Any:
    """``data`` (as :func:`to_json` writes it) read back as type ``tp``."""
    origin = typing.get_origin(tp)
    if tp is Any:
        return data
    if dataclasses.is_dataclass(tp) and isinstance(tp, type):
        return _dataclass_from_json(tp, data, path)
    if origin in (Union, types.UnionType):
        options = typing.get_args(tp)
        if data is None and type(None) in options:
            return None
        errors = []
        for option in options:
            if option is type(None):
                continue
            try:
                return from_json(option, data, path)
            except InputError as exc:
                errors.append(str(exc))
        raise InputError(errors[0] if len(errors) == 1 else f"{path}: {data!r} matches none of {tp}")
    if origin is Literal:
        if data not in typing.get_args(tp):
            raise InputError(f"{path} must be one of {list(typing.get_args(tp))}, got {data!r}")
        return data
    if origin is tuple:
        args = typing.get_args(tp)
        _need(isinstance(data, list), path, "a list", data)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(from_json(args[0], v, f"{path}[{i}]") for i, v in enumerate(data))
        _need(len(data) == len(args), path, f"a list of {len(args)}", data)
        return tuple(from_json(a, v, f"{path}[{i}]") for i, (a, v) in enumerate(zip(args, data)))
    if origin is list:
        (item,) = typing.get_args(tp)
        _need(isinstance(data, list), path, "a list", data)
        return [from_json(item, v, f"{path}[{i}]") for i, v in enumerate(data)]
    if origin is dict:
        key, item = typing.get_args(tp)
        _need(isinstance(data, dict), path, "an object", data)
        return {k: from_json(item, v, f"{path}.{k}") for k, v in data.items()}
    if tp is bool:
        _need(isinstance(data, bool), path, "true or false", data)
        return data
    if tp is int:
        _need(isinstance(data, int) and not isinstance(data, bool), path, "an integer", data)
        return data
    if tp is float:
        _need(isinstance(data, (int, float)) and not isinstance(data, bool), path, "a number", data)
        return float(data)
    if tp is str:
        _need(isinstance(data, str), path, "a string", data)
        return data
    if tp is type(None):
        _need(data is None, path, "null", data)
        return None
    raise TypeError(f"{path}: no JSON reader for type {tp!r}")


def _need(ok: bool, path: str, what: str, data: Any) -> None:
    if not ok:
        shown = repr(data) if len(repr(data)) <= 60 else repr(data)[:57] + "..."
        raise InputError(f"{path} must be {what}, got {shown}")


def _dataclass_from_json(cls: Any, data: Any, path: str) -> Any:
    _need(isinstance(data, dict), path, "an object", data)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - set(fields))
    if unknown:
        raise InputError(f"{path}: unknown field(s) {unknown} for {cls.__name__}")
    hints = _hints(cls)
    values = {}
    for name, field in fields.items():
        if name in data:
            values[name] = from_json(hints[name], data[name], f"{path}.{name}")
        elif field.default is dataclasses.MISSING and field.default_factory is dataclasses.MISSING:
            raise InputError(f"{path}: missing field {name!r} of {cls.__name__}")
    return cls(**values)

