"""An experiment's parameters as a frozen, typed, validated and documented dataclass.

Each experiment declares ``class Params(gpfverify.contract.Params)`` whose fields are made with
:func:`option`: a default, a help text, optional bounds or choices, and whether the command line
offers it. From that one declaration come

* validation when an instance is made (``__post_init__``): types, bounds, choices, then the
  class's own :meth:`Params.check` — an invalid value raises :class:`~gpfverify.errors.InputError`
  naming the option as the command line spells it (``--train-points must be at least 3, got 2``);
* the command-line options of ``gpfverify reproduce NAME`` (:func:`add_arguments`,
  :func:`from_arguments`): ``--field-name`` with the field's type, default and help — or the
  field's ``flag`` where the record's name is not the option's (one meaning has one option name
  in every command: the training-sample count is ``--train-points`` everywhere, the sigma-point κ
  ``--sigma-kappa``, while the record keeps the paper's symbol, ``kappa``, so that results written
  before read the same); older spellings stay accepted as ``aliases`` (a name a published command
  line uses, silently) or ``deprecated`` (with a one-line note on stderr);
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
           above: float | None = None, choices: tuple | None = None, cli: bool = True,
           flag: str | None = None, aliases: tuple[str, ...] = (), deprecated: tuple[str, ...] = ()) -> Any:
    """A field of a :class:`Params` dataclass: ``default`` (immutable: tuples, not lists), the
    ``help`` text of its command-line option and of the documentation, bounds (``minimum`` ≤ value
    ≤ ``maximum``, value > ``above``; for a tuple, every entry) or ``choices`` checked on every
    instance, and whether the command line offers it (``cli``; scalar fields and tuples of scalars,
    ``--snr 2 4 6``, are offered). ``flag`` is the option's name when it is not the field's
    (``flag="train-points"`` for a field ``kappa``); ``aliases`` are further names the option keeps
    without comment (one a published command line uses), ``deprecated`` older names it still takes
    with a note on stderr (all without their leading ``--``)."""
    return dataclasses.field(default=default, metadata={
        "help": help, "minimum": minimum, "maximum": maximum, "above": above, "choices": choices,
        "cli": cli, "flag": flag, "aliases": aliases, "deprecated": deprecated})


def flag_name(name: str) -> str:
    """The command-line spelling of a field name without a ``flag`` of its own: ``test_steps`` ->
    ``--test-steps`` (:func:`field_flag` for any field)."""
    return "--" + name.replace("_", "-")


def field_flag(field: dataclasses.Field) -> str:
    """The command-line option of a field: its ``flag`` or its name with dashes."""
    return "--" + field.metadata["flag"] if field.metadata.get("flag") else flag_name(field.name)


class DeprecatedOption(argparse.Action):
    """An older name of an option, still accepted: stores into the option's ``dest`` as the option
    does and prints one note on stderr naming the option's name now."""

    def __init__(self, option_strings, dest, *, current: str, **kwargs) -> None:
        self.current = current
        super().__init__(option_strings, dest, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        from gpfverify.streams import diagnostics

        print(f"{parser.prog}: note: {option_string} is deprecated, the same option is now {self.current}",
              file=diagnostics())
        setattr(namespace, self.dest, values)


def add_deprecated(parser: argparse.ArgumentParser, names: tuple[str, ...], option: argparse.Action) -> None:
    """Accept each of ``names`` (with their ``--``) as a deprecated spelling of ``option``, an
    argument already added to ``parser`` that stores one value (or a list, ``nargs``); hidden from
    ``--help``, whose text of ``option`` names them."""
    same = {key: getattr(option, key) for key in ("type", "nargs", "choices", "metavar")
            if getattr(option, key) is not None}
    for name in names:
        parser.add_argument(name, dest=option.dest, action=DeprecatedOption, current=option.option_strings[0],
                            default=argparse.SUPPRESS, help=argparse.SUPPRESS, **same)


@dataclasses.dataclass(frozen=True)
class Params:
    """Base of every experiment's parameters (see the module docstring)."""

    def __post_init__(self) -> None:
        hints = typing.get_type_hints(type(self))
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            # the typed reader checks the type and turns lists into tuples
            checked = from_json(hints[field.name], to_json(value), field_flag(field))
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

    def cli_options(self, always: tuple[str, ...] = ()) -> list[str]:
        """The command-line options that give these parameters from the defaults (every
        command-line field whose value differs, by :func:`field_flag`): ``["--kappa", "30"]``;
        the fields named in ``always`` are given at their value even where it is the default."""
        defaults = type(self)()
        out: list[str] = []
        for field in cli_fields(type(self)):
            value = getattr(self, field.name)
            if value == getattr(defaults, field.name) and field.name not in always:
                continue
            if isinstance(value, bool):
                out.append(field_flag(field) if value else "--no-" + field_flag(field)[2:])
                continue
            out.append(field_flag(field))
            values = value if isinstance(value, tuple) else (value,)
            out += ["none" if v is None else f"{v!r}" if isinstance(v, float) else str(v) for v in values]
        return out


def _check_bounds(field: dataclasses.Field, value: Any) -> None:
    meta, name = field.metadata, field_flag(field)
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


def add_arguments(parser: argparse.ArgumentParser, cls: type[Params], only: tuple[str, ...] | None = None) -> None:
    """One option per command-line field of ``cls`` (or of the fields named in ``only``; defaults
    shown in the help), by its :func:`field_flag`, its ``aliases`` and its ``deprecated`` names."""
    hints = typing.get_type_hints(cls)
    defaults = cls()
    for field in cli_fields(cls):
        if only is not None and field.name not in only:
            continue
        default = getattr(defaults, field.name)
        names = [field_flag(field), *(f"--{a}" for a in field.metadata.get("aliases", ()))]
        deprecated = tuple(f"--{a}" for a in field.metadata.get("deprecated", ()))
        formerly = f"; formerly {', '.join(deprecated)}" if deprecated else ""
        item, nargs = _sequence_type(hints[field.name])
        kwargs: dict[str, Any] = {"dest": field.name, "default": default}
        if field.metadata.get("flag"):  # argparse would name the value after the field
            kwargs["metavar"] = field.metadata["flag"].upper().replace("-", "_")
        if item is not None:  # a tuple: --name V1 V2 ... (read back as a tuple by the Params)
            shown = " ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in default) or "none"
            kwargs["nargs"], tp, optional = nargs, item, False
        else:
            tp, optional = _scalar_type(hints[field.name])
            shown = "none" if default is None else f"{default:g}" if isinstance(default, float) else str(default)
        kwargs["help"] = f"{field.metadata.get('help', '')} (default {shown}{formerly})"
        if tp is bool:
            kwargs["action"] = argparse.BooleanOptionalAction
        elif typing.get_origin(tp) is Literal:
            kwargs["choices"] = list(typing.get_args(tp))
            kwargs["type"] = type(typing.get_args(tp)[0])
        else:
            kwargs["type"] = _optional_parser(tp) if optional else tp
            if item is None and field.metadata.get("choices") is not None:
                kwargs["choices"] = list(field.metadata["choices"])
        add_deprecated(parser, deprecated, parser.add_argument(*names, **kwargs))


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
    return [(field_flag(f) if f in cli_fields(cls) else f.name, repr(getattr(defaults, f.name)),
             f.metadata.get("help", "")) for f in dataclasses.fields(cls)]
