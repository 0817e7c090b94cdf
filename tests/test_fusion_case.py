"""Fusion-case files: round trip, and every malformed or inconsistent file -> CaseFileError
naming the entry."""

import json

import numpy as np
import pytest

from gpfverify.errors import CaseFileError
from gpfverify.fusion.case import case_to_dict
from gpfverify.fusion.caseblock import case_from_dict, load_case
from gpfverify.fusion.synthetic import random_case


def _case_dict(seed=0):
    return case_to_dict(random_case(np.random.default_rng(seed), 2, (1, 2)))


def test_round_trip(tmp_path):
    data = _case_dict()
    data["rank_tol"] = 1e-9
    path = tmp_path / "case.json"
    path.write_text(json.dumps(data))
    assert case_to_dict(load_case(path)) == data


def _mutations():
    def set_(path, value):
        def apply(d):
            target = d
            for key in path[:-1]:
                target = target[key]
            target[path[-1]] = value
        return apply

    def delete(path):
        def apply(d):
            target = d
            for key in path[:-1]:
                target = target[key]
            del target[path[-1]]
        return apply

    return {
        "missing central": (delete(["central"]), "central"),
        "missing local key": (delete(["locals", 1, "mu_e"]), "mu_e"),
        "wrong sizes sum": (set_(["central", "sizes"], [1, 1]), "central.mu_y"),
        "sizes not ints": (set_(["central", "sizes"], [1.5, 1.5]), "sizes"),
        "too few locals": (lambda d: d["locals"].pop(), "locals"),
        "non-PSD C_p": (set_(["central", "C_p"], [[1.0, 0.0], [0.0, -1.0]]), "central.C_p"),
        "singular local C_y": (set_(["locals", 0, "C_y"], [[0.0]]), "locals[0].C_y"),
        "asymmetric C_y": (set_(["central", "C_y"], [[1, 2, 0], [0, 1, 0], [0, 0, 1]]), "central.C_y"),
        "NaN": (set_(["locals", 1, "mu_p"], [0.0, float("nan")]), "locals[1].mu_p"),
        "wrong C_xy shape": (set_(["locals", 1, "C_xy"], [[1.0], [2.0]]), "locals[1].C_xy"),
        "string entry": (set_(["central", "mu_p"], ["a", 1]), "central.mu_p"),
        "wrong y length": (set_(["y"], [1.0]), "y"),
        "negative rank_tol": (set_(["rank_tol"], -1), "rank_tol"),
        "locals not a list": (set_(["locals"], {"a": 1}), "locals"),
        "local not object": (set_(["locals", 0], [1, 2]), "locals[0]"),
        "non-PSD C_e": (set_(["locals", 0, "C_e"], [[-1.0, 0.0], [0.0, 1.0]]), "locals[0].C_e"),
    }


@pytest.mark.parametrize("name", list(_mutations()))
def test_malformed_case_names_the_problem(name):
    mutate, needle = _mutations()[name]
    data = _case_dict()
    mutate(data)
    with pytest.raises(CaseFileError, match=needle.replace("[", r"\[").replace("]", r"\]")):
        case_from_dict(data)


def test_unreadable_and_invalid_json(tmp_path):
    with pytest.raises(CaseFileError, match="cannot read"):
        load_case(tmp_path / "absent.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(CaseFileError, match="not valid JSON"):
        load_case(bad)
    top = tmp_path / "top.json"
    top.write_text("[1, 2]")
    with pytest.raises(CaseFileError, match="JSON object"):
        load_case(top)


def test_optional_fields_may_be_absent():
    data = _case_dict()
    del data["y"]
    for local in data["locals"]:
        del local["C_e"]
    case = case_from_dict(data)
    assert case.y is None and all(r.C_e is None for r in case.locals)
