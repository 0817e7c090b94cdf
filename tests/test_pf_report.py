"""The particle-flow report page rendered from committed results.json fixtures (tiny pff1d and
bearing runs; no experiment runs here). Regenerate the fixtures with
``python tests/test_pf_report.py`` after a change of the experiments' summaries."""

import json
import shutil
import sys
from pathlib import Path

from gpfverify.contract.claims import read_claims
from gpfverify.contract.experiment import RunEntry, SectionRuns
from gpfverify.report.document import Figure, Table
from gpfverify.report.inputs import SectionInput
from gpfverify.papers.particle_flow import section

FIXTURES = Path(__file__).parent / "fixtures"
PFF1D = FIXTURES / "pff1d" / "results.json"
BEARING = FIXTURES / "bearing" / "results.json"


def _section_input(folder: Path, pff: dict | None, brg: dict | None) -> SectionInput:
    entries, results = [], []
    if pff is not None:
        entries.append(RunEntry("pff1d", "tiny grid", "tiny", "pff1d-tiny/run/results.json"))
        results.append(pff)
    if brg is not None:
        entries.append(RunEntry("bearing", "", "tiny", "bearing-tiny/run/results.json"))
        results.append(brg)
    return SectionInput(section.SLUG, folder, SectionRuns(section.SLUG, "quick", 1, tuple(entries)), tuple(results))


def _texts(page) -> str:
    return " ".join(getattr(b, "text", "") or getattr(b, "caption", "") for b in page.blocks)


def test_render_from_the_stored_results(tmp_path):
    pff, brg = json.loads(PFF1D.read_text()), json.loads(BEARING.read_text())
    page = section.render_section(_section_input(tmp_path, pff, brg))
    figures = [b for b in page.blocks if isinstance(b, Figure)]
    assert len(figures) == 3 and all(f.path.exists() and f.path.parent == tmp_path for f in figures)
    tables = {b.caption.split(":")[0]: b for b in page.blocks if isinstance(b, Table)}
    assert len(tables["Table 1 (UNGM, N = 20, T = 6, 3 runs)"].rows) == len(pff["table1"])
    assert [row[0] for row in tables["Table 2"].rows] == ["PF-N50", "PF-N200", "IE-PFF-N50", "IE-PFF-N200"]
    assert [row[0] for row in tables["Table 2 at larger process noise (r1 and r2 × 10"].rows] == \
        ["PF-N50", "PF-N200", "IE-PFF-N50"]
    claims = [b for b in page.blocks if isinstance(b, Table) and b.css == "claims"]
    records = read_claims(pff) + read_claims(brg)
    # the accuracy claims, the timing claims, those true by construction, each in a table of its own
    groups = [r.group for r in records]
    assert [len(t.rows) for t in claims] == [groups.count(g) for g in ("accuracy", "timing", "by construction")]
    rows = [row for t in claims for row in t.rows]
    assert [row[2].verdict for row in rows] == [r.verdict for g in ("accuracy", "timing", "by construction")
                                                for r in records if r.group == g]
    # every claim rests on 3 runs where the paper used 30 or 200; the run-time claim on CPU times
    assert all(row[2].cautions for row in rows)
    assert any("CPU times" in c for c in claims[1].rows[0][2].cautions)
    text = _texts(page)
    assert "Zhou et al. 2020" in page.title and all(r.source.startswith("§3.") and r.quote for r in records)
    assert "the paper used 30" in text and "the paper used 200" in text
    divergences = ", ".join(f"{d['method']} Δλ = {d['dlambda']:g} {d['spacing']}: {d['diverged']}/{d['total']}"
                            for d in pff["divergences"])
    assert divergences.split(", ")[0] in text
    assert "_{" not in text and "x_k" not in text  # Unicode maths, no pseudo-LaTeX


def test_render_states_a_missing_run(tmp_path):
    page = section.render_section(_section_input(tmp_path, None, json.loads(BEARING.read_text())))
    assert "No pff1d run" in _texts(page)
    assert sum(isinstance(b, Figure) for b in page.blocks) == 1


def test_report_section_imports_no_experiment():
    source = Path(section.__file__).read_text(encoding="utf-8")
    assert "gpfverify.experiments" not in source and "run_for_report" not in source
    assert not hasattr(section, "build")


def test_render_shows_health_checks_and_the_verdict_under_each_interpretation(tmp_path):
    pff, brg = json.loads(PFF1D.read_text()), json.loads(BEARING.read_text())
    page = section.render_section(_section_input(tmp_path, pff, brg))
    text = _texts(page)
    assert "pff1d health checks:" in text and "bearing health checks:" in text
    failed = [c for c in pff["health"] if not c["passed"]]
    tables = {b.caption: b for b in page.blocks if isinstance(b, Table)}
    if failed:
        assert len(tables["pff1d: the health checks that failed"].rows) == len(failed)
    sensitivity = next(b for caption, b in tables.items() if caption.startswith("Sensitivity"))
    records = [r for r in read_claims(pff) + read_claims(brg) if r.interpretations]
    assert records and len(sensitivity.rows) == len(records)
    names = sensitivity.headers[2:-2]  # claim, as run, one column per interpretation, robustness, runs to decide
    for row, record in zip(sensitivity.rows, records):
        assert row[1] == record.verdict and all(i.name in names for i in record.interpretations)
        assert row[-2].startswith(("depends on the interpretation", f"{record.verdict} under all"))
    declared = tables["Interpretations tried"]
    assert {row[1] for row in declared.rows} >= {"exponential-1.2", "li-coates-29", "noise-as-std"}
    assert all(row[3] for row in declared.rows)  # every interpretation says why


def test_render_of_results_without_health_or_interpretations(tmp_path):
    pff = {k: v for k, v in json.loads(PFF1D.read_text()).items() if k != "health"}
    pff["claims"] = [{**c, "interpretations": []} for c in pff["claims"]]
    page = section.render_section(_section_input(tmp_path, pff, None))
    assert "pff1d: this run recorded no health checks." in _texts(page)


def regenerate(work: Path) -> None:
    """Write the fixtures from tiny runs (3 runs each; two gamma R so every claim is decided),
    with every declared interpretation tried."""
    from gpfverify.papers.particle_flow import bearing_experiment as bearing
    from gpfverify.papers.particle_flow import pff1d_experiment as pff1d
    from gpfverify.experiments.runner import make_executor, run_experiment
    from gpfverify.experiments.sensitivity import run_interpretations

    pff = pff1d.Params(steps=6, particles=20, table_q=(0.1, 10.0), table_r=(1.0,), dlambda=(0.1,),
                       gamma_r=(0.1, 1.0), gamma_dlambda=0.1)
    for name, module, params in (("pff1d", pff1d, pff), ("bearing", bearing, bearing.Params(duration=10))):
        shutil.rmtree(work / name, ignore_errors=True)
        run_experiment(module, params, 3, 1, work / name, show_progress=False)
        with make_executor(1) as executor:
            run_interpretations(module, params, module.INTERPRETATIONS, 3, 1, work / name, executor)
        (FIXTURES / name).mkdir(parents=True, exist_ok=True)
        shutil.copyfile(work / name / "results.json", FIXTURES / name / "results.json")


if __name__ == "__main__":
    regenerate(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("/tmp/gpfverify-pf-fixtures"))
