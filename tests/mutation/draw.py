"""Mutants drawn by a mutation tool: every mutation cosmic-ray's operators can make in the package,
and a seeded random sample of them in proportion to each module's lines.

Enumeration is cosmic-ray's (its ``core/`` operators, each at each of its positions, exactly as
``cosmic-ray init`` lists them; the two operators that need a configured variable name are left
out). Positions inside type annotations are left out: with ``from __future__ import annotations``
an annotation is never evaluated, so its mutants are equivalent by construction.

Sampling is stratified by module, with probability proportional to size: the modules' statement
lines are laid end to end, ``size`` points are taken at a fixed step from a seeded random start
(systematic sampling), and each point falls in one module. A module with L of the package's W
statement lines therefore receives ``size * L / W`` mutants rounded up or down, never more; in
each module the mutants are drawn without replacement, first a mutation *site* (a position) at
random, then one of the operators that apply there at random, so that an operator with many
variants (eleven replacements of ``+``) weighs no more than one with a single variant.
"""

from __future__ import annotations

import ast
import difflib
import json
import hashlib
import random
from bisect import bisect_right
from dataclasses import asdict, dataclass
from pathlib import Path

from tests.mutation.workspace import CACHE, ROOT

PACKAGE = ROOT / "gpfverify"
#: operators that need configuration (a cause and an effect variable name) are not enumerated
NEEDS_ARGUMENTS = ("core/VariableReplacer", "core/VariableInserter")

#: the areas of the report, by path prefix (first match wins)
AREAS: tuple[tuple[str, str], ...] = (
    ("gpfverify/symbolic/", "proof engine"),
    ("gpfverify/kernel/", "proof engine"),
    ("gpfverify/contract/", "claims and experiments"),
    ("gpfverify/experiments/", "claims and experiments"),
    ("gpfverify/papers/", "papers"),
    ("gpfverify/gp/", "GP moments"),
    ("gpfverify/filters/", "filters"),
    ("gpfverify/consistency.py", "filters"),
    ("gpfverify/fusion/", "fusion rules"),
    ("gpfverify/model_fusion.py", "fusion rules"),
    ("gpfverify/audit/", "audit"),
    ("gpfverify/models/", "models"),
    ("gpfverify/scenarios/", "models"),
    ("gpfverify/systems.py", "models"),
    ("gpfverify/adapters/", "adapters"),
    ("gpfverify/strategies/", "strategies and testing"),
    ("gpfverify/testing.py", "strategies and testing"),
    ("gpfverify/pytest_plugin.py", "strategies and testing"),
    ("gpfverify/report/", "reports"),
    ("gpfverify/full_report.py", "reports"),
    ("gpfverify/notebook.py", "reports"),
    ("gpfverify/reference_pages.py", "reports"),
    ("gpfverify/views.py", "reports"),
    ("gpfverify/health.py", "reports"),
    ("gpfverify/commands/", "command line"),
    ("gpfverify/cli.py", "command line"),
    ("gpfverify/entry.py", "command line"),
    ("gpfverify/__main__.py", "command line"),
    ("gpfverify/outputs.py", "outputs and processes"),
    ("gpfverify/userfiles.py", "outputs and processes"),
    ("gpfverify/streams.py", "outputs and processes"),
    ("gpfverify/supervise.py", "outputs and processes"),
    ("gpfverify/runtime.py", "outputs and processes"),
    ("gpfverify/memory.py", "outputs and processes"),
    ("gpfverify/usercode.py", "outputs and processes"),
    ("gpfverify/provenance.py", "outputs and processes"),
    ("gpfverify/", "ground floor"),  # errors, tolerances, angles, rng, linalg, validate, ...
)


def area_of(path: str) -> str:
    return next(area for prefix, area in AREAS if path.startswith(prefix))


@dataclass(frozen=True)
class Drawn:
    """One sampled mutant: cosmic-ray's (module, operator, occurrence) and what it changes."""

    path: str
    operator: str
    occurrence: int
    line: int
    column: int
    area: str
    before: str  #: the line as written
    after: str  #: the line as mutated (the first changed line of the mutated module)
    module_digest: str  #: sha256 of the unmutated module: a stored result is for these contents only

    @property
    def key(self) -> str:
        return f"{self.path}:{self.line}:{self.column}:{self.operator}:{self.occurrence}:{self.module_digest[:12]}"

    @property
    def name(self) -> str:
        """What a reader recognises: module, line and the change, stable while the line's text is."""
        return f"{self.path}:{self.line} {self.operator.removeprefix('core/')}"

    def record(self) -> dict:
        return {**asdict(self), "key": self.key}


def statement_lines(tree: ast.Module) -> set[int]:
    """Lines on which a statement starts, docstrings left out: the module's size for sampling."""
    lines = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.stmt):
            docstring = isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) \
                and isinstance(node.value.value, str)
            if not docstring:
                lines.add(node.lineno)
    return lines


def annotation_spans(tree: ast.Module, source_lines: list[str]) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """(start, end) positions, as (line, character column), of every annotation of the module."""
    def char(line: int, byte_col: int) -> int:
        return len(source_lines[line - 1].encode("utf-8")[:byte_col].decode("utf-8", errors="ignore"))

    spans = []
    for node in ast.walk(tree):
        found = []
        if isinstance(node, ast.arg) and node.annotation is not None:
            found.append(node.annotation)
        elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and node.returns is not None:
            found.append(node.returns)
        elif isinstance(node, ast.AnnAssign):
            found.append(node.annotation)
        for a in found:
            assert a.end_lineno is not None and a.end_col_offset is not None
            start = (a.lineno, char(a.lineno, a.col_offset))
            spans.append((start, (a.end_lineno, char(a.end_lineno, a.end_col_offset))))
    return spans


def _operators():
    import cosmic_ray.plugins

    for name in cosmic_ray.plugins.operator_names():
        if name not in NEEDS_ARGUMENTS:
            yield name, cosmic_ray.plugins.get_operator(name)()


@dataclass(frozen=True)
class ModuleMutations:
    path: str
    weight: int  #: statement lines
    digest: str
    #: (line, column) -> [(operator, occurrence)]
    sites: dict[tuple[int, int], list[tuple[str, int]]]


def enumerate_module(path: Path) -> ModuleMutations:
    """Every mutation cosmic-ray makes in one module, grouped by site, annotations left out (stored in
    the cache by the module's digest: enumerating the package takes minutes)."""
    source = path.read_text(encoding="utf-8")
    digest = hashlib.sha256(source.encode()).hexdigest()
    stored = CACHE / "enumeration" / f"{digest}.json"
    if stored.exists():
        data = json.loads(stored.read_text(encoding="utf-8"))
        sites = {(line, column): [(op, occ) for op, occ in ops] for line, column, ops in data["sites"]}
        return ModuleMutations(data["path"], data["weight"], digest, sites)
    found = _enumerate(path, source, digest)
    stored.parent.mkdir(parents=True, exist_ok=True)
    stored.write_text(json.dumps({"path": found.path, "weight": found.weight,
                                  "sites": [[*site, ops] for site, ops in found.sites.items()]}), encoding="utf-8")
    return found


def _enumerate(path: Path, source: str, digest: str) -> ModuleMutations:
    from cosmic_ray.ast import ast_nodes, get_ast_from_path

    tree = ast.parse(source)
    spans = annotation_spans(tree, source.splitlines())
    nodes = list(ast_nodes(get_ast_from_path(path)))
    sites: dict[tuple[int, int], list[tuple[str, int]]] = {}
    for name, operator in _operators():
        positions = (pos for node in nodes for pos in operator.mutation_positions(node))
        for occurrence, (start, _end) in enumerate(positions):
            if any(lo <= tuple(start) < hi for lo, hi in spans):
                continue
            sites.setdefault(tuple(start), []).append((name, occurrence))
    rel = str(path.relative_to(ROOT)) if path.is_relative_to(ROOT) else str(path)
    return ModuleMutations(rel, len(statement_lines(tree)), digest, dict(sorted(sites.items())))


def mutated_source(path: Path, operator: str, occurrence: int) -> str:
    """The module's text with one mutation applied (cosmic-ray's ``mutate_code``); raises if the
    operator has no such occurrence."""
    import cosmic_ray.plugins
    from cosmic_ray.mutating import mutate_code

    code = mutate_code(path.read_text(encoding="utf-8"), cosmic_ray.plugins.get_operator(operator)(), occurrence)
    if code is None:
        raise ValueError(f"{operator} has no occurrence {occurrence} in {path}")
    return code


def changed_line(before: str, after: str) -> tuple[str, str]:
    """What a mutation changed: the lines it removed and the lines it added, each joined by `` / ``."""
    removed, added = [], []
    for line in difflib.unified_diff(before.splitlines(), after.splitlines(), lineterm="", n=0):
        if line.startswith(("---", "+++", "@@")):
            continue
        (removed if line.startswith("-") else added).append(line[1:].strip())
    return " / ".join(removed), " / ".join(added)


def modules() -> list[Path]:
    return sorted(PACKAGE.rglob("*.py"))


def draw(size: int, seed: int, log=print) -> list[Drawn]:
    """The seeded sample of ``size`` mutants (see the module's docstring for the design)."""
    enumerated = [m for m in (enumerate_module(p) for p in modules()) if m.sites and m.weight]
    log(f"draw: {sum(len(v) for m in enumerated for v in m.sites.values())} mutants at "
        f"{sum(len(m.sites) for m in enumerated)} sites in {len(enumerated)} modules")
    rng = random.Random(seed)
    cumulative, total = [], 0
    for m in enumerated:
        total += m.weight
        cumulative.append(total)
    step = total / size
    start = rng.uniform(0, step)
    counts = [0] * len(enumerated)
    for k in range(size):
        counts[bisect_right(cumulative, start + k * step)] += 1
    drawn: list[Drawn] = []
    for m, count in zip(enumerated, counts):
        if not count:
            continue
        sites = list(m.sites)
        order = rng.sample(sites, len(sites))  # the sites in random order: the first ones are drawn
        picks = [(site, rng.choice(m.sites[site])) for site in order]
        # a module with fewer sites than its share: further mutants at its sites, without repeats
        rest = [(s, op) for s in sites for op in m.sites[s] if (s, op) not in picks]
        picks += rng.sample(rest, min(len(rest), max(0, count - len(sites))))
        path = ROOT / m.path
        original = path.read_text(encoding="utf-8")
        taken = 0
        for (line, column), (operator, occurrence) in picks:
            if taken == count:
                break
            try:
                mutated = mutated_source(path, operator, occurrence)
            except Exception as exc:  # the tool cannot make this one (its ExceptionReplacer on `except a.B`)
                log(f"draw: {m.path}:{line} {operator} cannot be made ({type(exc).__name__}); the next site is drawn")
                continue
            before, after = changed_line(original, mutated)
            drawn.append(Drawn(m.path, operator, occurrence, line, column, area_of(m.path), before, after,
                               m.digest))
            taken += 1
    return drawn
