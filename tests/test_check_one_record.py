"""check's console line, report page and README are renderings of one record, results.json: the
verdict sentence made from results.json's counts appears, word for word, in all three, and its
counts are results.json's."""

import html
import json
from pathlib import Path

from gpfverify.cli import main
from gpfverify.contract.check import verdict_sentence

ROOT = Path(__file__).resolve().parents[1]
TRACKER = f"{ROOT / 'examples' / 'three_sensor_system.py'}:tracker"


def test_console_page_and_readme_render_results_json(tmp_path, capsys):
    out = tmp_path / "check"
    assert main(["check", TRACKER, "--steps", "3", "--methods", "cmf,dmf,cc", "--out", str(out)]) == 0
    console = capsys.readouterr().out
    results = json.loads((out / "results.json").read_text())
    sentence = verdict_sentence(results)
    assert results["total_steps"] == 3 and f"all {results['total_steps']} steps" in sentence
    assert sentence in console
    assert sentence in html.unescape((out / "report.html").read_text())
    assert sentence in (out / "README.md").read_text()
