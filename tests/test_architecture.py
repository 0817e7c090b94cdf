"""The house's plan holds: no two files import each other (through any chain, function-level and
TYPE_CHECKING imports included), docs/architecture.md draws the layers the import-linter contract in
pyproject.toml states (``make test`` runs ``lint-imports`` on that contract), the names the package
resolves at run time (experiment and section registries, the notebook's display module, the
commands) point into the layers the contract gives them, every paper has its rooms, and the moved
names still answer, with a warning, for one release.
"""

from __future__ import annotations

import importlib
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import grimp
import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

ROOT = Path(__file__).resolve().parents[1]
#: where docs/architecture.md's diagram starts; the fenced block after it is the diagram
DIAGRAM_MARK = "<!-- the layers, top first: generated from pyproject.toml by tests/test_architecture.py -->"
#: the rooms of a paper package: each module's name is a room or ends in "_<room>" (ct2d_experiment)
ROOMS = ("scenario", "contract", "claims", "experiment", "section", "page")


def _contracts() -> dict[str, dict]:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["importlinter"]
    return {c["id"]: c for c in config["contracts"]}


def _layers() -> list[str]:
    return _contracts()["layers"]["layers"]


def layer_diagram(layers: list[str]) -> str:
    """The diagram of docs/architecture.md: one line per layer, top first, arrows pointing down (the
    direction imports may go)."""
    return "\n    ↓\n".join(layers)


def _layer_of(module: str) -> int:
    """The index (0 = top) of the layer holding ``module`` (a full dotted name)."""
    top = module.split(".")[1]
    for i, layer in enumerate(_layers()):
        if top in re.split(r"\s*[|:]\s*", layer):
            return i
    raise AssertionError(f"{module} is in no layer of the contract")


def test_no_two_files_import_each_other():
    """Strongly connected components of the file-level import graph, every import counted."""
    graph = grimp.build_graph("gpfverify", cache_dir=None)
    modules = sorted(graph.modules)
    index = {m: i for i, m in enumerate(modules)}
    edges = [(index[m], index[i]) for m in modules for i in graph.find_modules_directly_imported_by(m) if i != m]
    rows, cols = zip(*edges)
    adjacency = csr_matrix((np.ones(len(edges)), (rows, cols)), shape=(len(modules),) * 2)
    count, labels = connected_components(adjacency, directed=True, connection="strong")
    circles = [sorted(m for m, label in zip(modules, labels) if label == c) for c in range(count)]
    circles = [c for c in circles if len(c) > 1]
    assert not circles, "files importing each other: " + "; ".join(" <-> ".join(c) for c in circles)
    assert len(modules) > 150  # the graph is the package's, not an empty one


def test_the_documented_layers_are_the_contracts():
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    assert DIAGRAM_MARK in text, f"docs/architecture.md lacks the line {DIAGRAM_MARK!r}"
    block = re.search(r"```text\n(.*?)\n```", text[text.index(DIAGRAM_MARK):], re.S)
    assert block is not None
    expected = layer_diagram(_layers())
    assert block.group(1) == expected, f"docs/architecture.md's diagram should read:\n{expected}"


def test_the_papers_contract_names_every_paper_package():
    papers = importlib.import_module("gpfverify.papers")
    packages = {p.name for p in Path(papers.__file__).parent.iterdir() if (p / "__init__.py").is_file()}
    assert set(_contracts()["papers"]["modules"]) == {f"gpfverify.papers.{p}" for p in packages}


@pytest.mark.parametrize("paper", ["fusion", "gpsr_upf", "particle_flow", "tbd", "gpadf_scalar"])
def test_every_paper_has_its_rooms(paper):
    folder = ROOT / "gpfverify" / "papers" / paper
    names = {p.stem for p in folder.glob("*.py")} - {"__init__"}
    for room in ROOMS:
        assert any(n == room or n.endswith(f"_{room}") for n in names), f"papers/{paper} has no {room}"


def test_names_resolved_at_run_time_point_into_their_layers():
    """The registries name modules by string (imported on demand); each must exist and sit where
    the contract says: experiments and sections in the papers (or the report's own proofs page)
    below the assembly that lists them, the display module beside the assembly, the commands in
    the top layer with the command line."""
    from gpfverify import cli, full_report, views
    from gpfverify.papers import EXPERIMENTS

    papers = _layer_of("gpfverify.papers")
    for name, module in EXPERIMENTS.items():
        assert module.startswith("gpfverify.papers."), name
        assert importlib.import_module(module).NAME == name
    for slug, module in full_report.SECTIONS.items():
        assert _layer_of(module) > _layer_of(full_report.__name__), slug
        assert hasattr(importlib.import_module(module), "render_section"), slug
    assert _layer_of(views.DISPLAY_MODULE) < papers
    for command, (module, _) in cli.COMMANDS.items():
        assert _layer_of(module) == _layer_of(cli.__name__), command
        importlib.import_module(module)


def test_records_do_not_load_their_display_until_shown():
    """Importing the records leaves the notebook module unloaded; the first view loads it through
    the registry and renders the record."""
    code = ("import sys\n"
            "from gpfverify.contract.claims import ClaimRecord\n"
            "assert 'gpfverify.notebook' not in sys.modules\n"
            "html = ClaimRecord('c', 'seed 000, eq. 35', 'held', 1.0, 2.0, 10, 'e')._repr_html_()\n"
            "assert 'gpfverify.notebook' in sys.modules and '<table' in html, html[:200]\n")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)


@pytest.mark.parametrize("name, home", [("run_fusion", "gpfverify.model_fusion"),
                                        ("FusionRun", "gpfverify.model_fusion"),
                                        ("runfile", "gpfverify.audit")])
def test_moved_names_answer_with_a_deprecation_warning(name, home):
    import gpfverify.fusion

    with pytest.warns(DeprecationWarning, match=f"gpfverify.fusion.{name} moved to") as caught:
        old = getattr(gpfverify.fusion, name)
    assert old is getattr(importlib.import_module(home), name)
    # the warning names the line that used the old name (the user's), not the package's own
    assert [Path(w.filename).resolve() for w in caught] == [Path(__file__).resolve()]
