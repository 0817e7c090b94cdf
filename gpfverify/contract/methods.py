"""Method names as values: ``Method(rule, family, sensor)`` instead of strings built with
f-strings and split apart again.

A method is a fusion rule or filter (``rule``: ``"CMF"``, ``"DMF"``, ``"RCC-CI"``, ``"CW"``,
``"Sensor"``, ``"PF"``, ``"IE-PFF"`` ...), the Gaussian filter family it runs on (``family``:
``"GP-ADF"``, ``"GP-UKF"``, ``"UKF"`` ... or None) and, for a single sensor's filter, the sensor's
number from 1 (``sensor``). Its :attr:`Method.key` is the name used in ``results.json`` and in the
papers' figures (CONTRACT.md): ``"CMF-GP-ADF"``, ``"Sensor2-GP-UKF"``, ``"PF"``;
:meth:`Method.parse` reads it back. Family names are spelled one way, upper case as in the
papers; :func:`gpfverify.filters.families.gaussian_family` accepts them as they are.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from gpfverify.errors import InputError

#: the Gaussian filter families, spelled as in the papers and in results.json
FAMILIES: tuple[str, ...] = ("KF", "EKF", "UKF", "SR-UKF", "GP-ADF", "GP-UKF")
SENSOR_RULE = "Sensor"


@dataclass(frozen=True, order=True)
class Method:
    """A method of an experiment (see the module docstring)."""

    rule: str
    family: str | None = None
    sensor: int | None = None

    def __post_init__(self) -> None:
        if self.family is not None and self.family not in FAMILIES:
            raise InputError(f"unknown filter family {self.family!r}; choose from {list(FAMILIES)}")
        if (self.rule == SENSOR_RULE) != (self.sensor is not None):
            raise InputError(f"a method has a sensor number exactly when its rule is {SENSOR_RULE!r}: {self!r}")
        if self.sensor is not None and self.sensor < 1:
            raise InputError(f"sensor numbers start at 1, got {self.sensor}")
        if not self.rule or self.rule.endswith("-") or re.fullmatch(r"Sensor\d+", self.rule):
            raise InputError(f"malformed rule {self.rule!r}")

    @property
    def key(self) -> str:
        """The name in ``results.json``: rule (with the sensor number) and family, joined by '-'."""
        head = f"{self.rule}{self.sensor}" if self.sensor is not None else self.rule
        return head if self.family is None else f"{head}-{self.family}"

    def __str__(self) -> str:
        return self.key

    @property
    def is_sensor(self) -> bool:
        return self.sensor is not None

    @classmethod
    def parse(cls, key: str) -> Method:
        """The method named ``key`` (the inverse of :attr:`key`)."""
        family = next((f for f in sorted(FAMILIES, key=len, reverse=True) if key.endswith("-" + f)), None)
        head = key[: -len(family) - 1] if family else key
        match = re.fullmatch(rf"{SENSOR_RULE}(\d+)", head)
        if match:
            return cls(SENSOR_RULE, family, int(match.group(1)))
        if not head:
            raise InputError(f"malformed method name {key!r}")
        return cls(head, family)

    @classmethod
    def sensor_filter(cls, sensor: int, family: str | None) -> Method:
        """Sensor ``sensor``'s own filter (numbered from 1)."""
        return cls(SENSOR_RULE, family, sensor)
