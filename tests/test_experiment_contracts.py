"""Every experiment honours the contract of gpfverify.contract.experiment: its Params round-trip
through JSON text, every profile setting is valid and distinct, and its command-line options are
generated from the Params."""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import json

import pytest

from gpfverify.contract import PAPERS, Params, Profile
from gpfverify.contract.params import add_arguments, cli_fields, from_arguments
from gpfverify.papers import EXPERIMENTS


def _module(name: str):
    return importlib.import_module(EXPERIMENTS[name])


@pytest.mark.parametrize("name", sorted(EXPERIMENTS))
def test_params_profiles_and_options_follow_the_contract(name):
    module = _module(name)
    assert module.NAME == name and module.PAPER in PAPERS
    assert issubclass(module.Params, Params) and dataclasses.is_dataclass(module.RunRecord)
    default = module.Params()
    assert module.Params.from_json(json.loads(json.dumps(default.to_json()))) == default
    assert set(module.PROFILES) == {"quick", "full"}
    for profile in module.PROFILES.values():
        assert isinstance(profile, Profile) and profile.runs >= 1 and profile.settings
        tags = [s.tag for s in profile.settings]
        assert len(set(tags)) == len(tags)  # one folder per setting
        for setting in profile.settings:
            again = module.Params.from_json(json.loads(json.dumps(setting.params.to_json())))
            assert again == setting.params and isinstance(setting.params, module.Params)
    parser = argparse.ArgumentParser()
    add_arguments(parser, module.Params)
    assert from_arguments(module.Params, parser.parse_args([])) == default
    assert all(f.metadata.get("help") for f in dataclasses.fields(module.Params)), "every field documented"
    assert cli_fields(module.Params)


@pytest.mark.parametrize("name", sorted(EXPERIMENTS))
def test_declared_interpretations_are_valid_parameter_changes(name):
    module = _module(name)
    for spec in getattr(module, "INTERPRETATIONS", ()):
        changed = module.Params().replace(**spec.changes)
        assert changed != module.Params() and spec.why
