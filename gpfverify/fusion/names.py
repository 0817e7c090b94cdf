"""The fusion rules' command-line names: one list for every subcommand and for
:func:`gpfverify.model_fusion.run_fusion`.

``cmf`` centralized fusion with the stacked measurement; ``dmf`` distributed fusion, Proposition
1 (eq. 35); ``cc`` convex combination (labelled CW, "convex weights", in the papers' figures, so
``cw`` is accepted as another name for it); ``ci`` covariance intersection; ``rcc-ci`` relaxed
Chebyshev centre CI; ``ici`` inverse covariance intersection; ``ei`` ellipsoidal intersection.
Results record the canonical name (``cc``), whichever spelling was given.
"""

from __future__ import annotations

from collections.abc import Iterable

from gpfverify.errors import InputError

#: every fusion rule, by its one canonical name
FUSION_RULES: tuple[str, ...] = ("cmf", "dmf", "cc", "ci", "rcc-ci", "ici", "ei")
#: the baselines: rules that use only the sensors' own estimates (mu_e, C_e)
BASELINES: tuple[str, ...] = ("cc", "ci", "rcc-ci", "ici", "ei")
#: other accepted spellings -> canonical name
ALIASES: dict[str, str] = {"cw": "cc"}
#: the list as help texts show it
CHOICES_TEXT = ", ".join(FUSION_RULES) + " (cw = cc)"


def canonical_rule(name: str) -> str:
    """The canonical name of the fusion rule ``name`` (an alias such as ``cw`` -> ``cc``);
    :class:`InputError` naming the choices for anything else."""
    key = name.strip().lower()
    key = ALIASES.get(key, key)
    if key not in FUSION_RULES:
        raise InputError(f"unknown fusion rule {name!r}; choose from {CHOICES_TEXT}")
    return key


def canonical_rules(names: Iterable[str]) -> tuple[str, ...]:
    """:func:`canonical_rule` of each name, in order, each once."""
    return tuple(dict.fromkeys(canonical_rule(n) for n in names))
