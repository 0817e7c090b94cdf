"""An experiment's parameters as a frozen, typed, validated and documented dataclass.

Each experiment declares ``class Params(gpfverify.contract.Params)`` whose fields are made with
:func:`option`: a default, a help text, optional bounds or choices, and whether the command line
offers it. From that one declaration come

* validation when an instance is made (``__post_init__``): types, bounds, choices, then the
  class's own :meth:`Params.check` — an invalid value raises :class:`~gpfverify.errors.InputError`
  naming the option as the command line spells it (``--kappa must be at least 3, got 2``);
* the command-line options of ``gpfverify reproduce NAME`` (:func:`add_arguments`,
  :func:`from_arguments`): ``--field-name`` with the field's type, default and help;
* the record in ``results.json`` and ``manifest.json`` (:meth:`Params.to_json`), read back with
  :meth:`Params.from_json` — numbers and lists only, never prose: a constant the paper fixes is a
  field with its value (``process_noise_var = 5.0``), not a sentence describing it.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import types
import typing
from typing import Any, Literal, Self, Union

from gpfverify.contract.serial import from_json, to_json
from gpfverify.errors import InputError


def option(default: Any, help: str, *, minimum: float | None = None, maximum: float | None = None,
           above: float | None = None, choices: tuple | None = None, cli: bool = True) -> Any:
    """A field of a :class:`Params` dataclass: ``default`` (immutable: tuples, not lists), the
    ``help`` text of its command-line option and of the documentation, bounds (``minimum`` ≤ value
    ≤ ``maximum``, value > ``above``; for a tuple, every entry) or ``choices`` checked on every
    instance, and whether the command line offers it (``cli``; scalar fields and tuples of scalars,
    ``--snr 2 4 6``, are offered)."""
    return dataclasses.field(default=default, metadata={
        "help": help, "minimum": minimum, "maximum": maximum, "above": above, "choices": choices,
        "cli": cli})


def flag_name(name: str) -> str:
    """The command-line spelling of a field: ``test_steps`` -> ``--test-steps``."""
    return "--" + name.replace("_", "-")


@dataclasses.dataclass(frozen=True)
class Params:
    """Base of every experiment's parameters (see the module docstring)."""

    def __post_init__(self) -> None:
        hints = typing.get_type_hints(type(self))
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            # the typed reader checks the type and turns lists into tuples
            checked = from_json(hints[field.name], to_json(value), flag_name(field.name))
            if checked != value or type(checked) is not type(value):
                object.__setattr__(self, field.name, checked)
            _check_bounds(field, checked)
        self.check()

    def check(self) -> None:
        """Relations between fields; subclasses raise :class:`InputError` naming the options."""

    def to_json(self) -> dict[str, Any]:
        """The parameters as JSON data (field name -> value)."""
        return to_json(self)

    @classmethod
    def from_json(cls, data: Any) -> Self:
        """Parameters from :meth:`to_json`'s output (missing fields take their defaults)."""
        return from_json(cls, data, "params")

    def replace(self, **changes: Any) -> Self:
        """A copy with ``changes`` applied, validated again."""
        return dataclasses.replace(self, **changes)


def _check_bounds(field: dataclasses.Field, value: Any) -> None:
    meta, name = field.metadata, flag_name(field.name)
    if value is None or not meta:
        return
    if meta.get("choices") is not None and value not in meta["choices"]:
        raise InputError(f"{name} must be one of {list(meta['choices'])}, got {value!r}")
    numbers = value if isinstance(value, tuple) else (value,)
    for v in numbers:
        if not isinstance(v, (int, float)) or isinstance(v, bool):
            continue
        if isinstance(v, float) and not math.isfinite(v):
            raise InputError(f"{name} must be finite, got {v}")
        if meta.get("minimum") is not None and v < meta["minimum"]:
            raise InputError(f"{name} must be at least {meta['minimum']:g}, got {v:g}")
        if meta.get("maximum") is not None and v > meta["maximum"]:
            raise InputError(f"{name} must be at most {meta['maximum']:g}, got {v:g}")
        if meta.get("above") is not None and v <= meta["above"]:
            raise InputError(f"{name} must be greater than {meta['above']:g}, got {v:g}")


def _scalar_type(tp: Any) -> tuple[Any, bool]:
    """(the scalar type behind ``tp``, whether None is allowed) or (None, False) for non-scalars."""
    origin = typing.get_origin(tp)
    optional = False
    if origin in (Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        optional = len(args) < len(typing.get_args(tp))
        if len(args) != 1:
            return None, False
        tp, origin = args[0], typing.get_origin(args[0])
    if origin is Literal:
        return tp, optional
    return (tp, optional) if tp in (bool, int, float, str) else (None, False)


def _sequence_type(tp: Any) -> tuple[Any, str | int | None]:
    """(the scalar entry type, argparse ``nargs``) of ``tuple[T, ...]`` (any count) or of a
    fixed-length ``tuple[T, T, ...]`` of one scalar type T; (None, None) otherwise."""
    if typing.get_origin(tp) is not tuple:
        return None, None
    args = typing.get_args(tp)
    items = args[:1] if len(args) == 2 and args[1] is Ellipsis else args
    if not items or len(set(items)) != 1:
        return None, None
    item, optional = _scalar_type(items[0])
    if item is None or optional or item is bool:
        return None, None
    return item, "*" if items is not args else len(args)


def cli_fields(cls: type[Params]) -> list[dataclasses.Field]:
    """The fields the command line offers: scalars and tuples of one scalar type."""
    hints = typing.get_type_hints(cls)
    return [f for f in dataclasses.fields(cls)
            if f.metadata.get("cli", True)
            and (_scalar_type(hints[f.name])[0] is not None or _sequence_type(hints[f.name])[0] is not None)]


def add_arguments(parser: argparse.ArgumentParser, cls: type[Params]) -> None:
    """One option per command-line field of ``cls`` (defaults shown in the help)."""
    hints = typing.get_type_hints(cls)
    defaults = cls()
    for field in cli_fields(cls):
        default = getattr(defaults, field.name)
        item, nargs = _sequence_type(hints[field.name])
        if item is not None:  # a tuple: --name V1 V2 ... (read back as a tuple by the Params)
            shown = " ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in default) or "none"
            many: dict[str, Any] = {"dest": field.name, "default": default, "nargs": nargs,
                                    "help": f"{field.metadata.get('help', '')} (default {shown})"}
            if typing.get_origin(item) is Literal:
                many.update(choices=list(typing.get_args(item)), type=type(typing.get_args(item)[0]))
            else:
                many["type"] = item
            parser.add_argument(flag_name(field.name), **many)
            continue
        tp, optional = _scalar_type(hints[field.name])
        shown = "none" if default is None else f"{default:g}" if isinstance(default, float) else str(default)
        help_text = f"{field.metadata.get('help', '')} (default {shown})"
        if tp is bool:
            parser.add_argument(flag_name(field.name), dest=field.name, action=argparse.BooleanOptionalAction,
                                default=default, help=help_text)
            continue
        kwargs: dict[str, Any] = {"dest": field.name, "default": default, "help": help_text}
        if typing.get_origin(tp) is Literal:
            kwargs["choices"] = list(typing.get_args(tp))
            kwargs["type"] = type(typing.get_args(tp)[0])
        else:
            kwargs["type"] = _optional_parser(tp) if optional else tp
            if field.metadata.get("choices") is not None:
                kwargs["choices"] = list(field.metadata["choices"])
        parser.add_argument(flag_name(field.name), **kwargs)


def _optional_parser(tp: type) -> Any:
    def parse(text: str) -> Any:
        return None if text.strip().lower() == "none" else tp(text)
    parse.__name__ = tp.__name__
    return parse


def from_arguments(cls: type[Params], args: argparse.Namespace) -> Params:
    """The parameters from parsed options (every command-line field of ``cls``)."""
    return cls(**{f.name: getattr(args, f.name) for f in cli_fields(cls)})


def describe(cls: type[Params]) -> list[tuple[str, str, str]]:
    """(option, default, help) for every field, for documentation pages."""
    defaults = cls()
    return [(flag_name(f.name) if f in cli_fields(cls) else f.name, repr(getattr(defaults, f.name)),
             f.metadata.get("help", "")) for f in dataclasses.fields(cls)]
