"""Results in a notebook (``_repr_html_``) say what the pages say, because the pages' renderers make them:

* a run_fusion result shows the check page of the same run, compact: the verdict sentence and the
  summary that ``gpfverify check --measurements`` writes for the same system and measurements, the gap
  figure alone, styled as the pages, light (a 25-step run's view within 100 KB), pointing at nothing a
  notebook does not have; ``write_page`` writes the whole page with every figure;
* a RunAudit shows the page ``gpfverify audit RUN --out`` writes for the same steps;
* a CaseAudit shows what ``gpfverify audit CASE.json`` prints; a claim record the report's claims table;
* progress bars are drawn on a terminal and in a Jupyter kernel, not in a log file.
"""

from __future__ import annotations

import builtins
import html
import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from gpfverify.audit.case import audit_to_dict
from gpfverify.model_fusion import run_fusion
from gpfverify.audit.runfile import write_run
from gpfverify.runtime import progress_shown

sys.path.insert(0, str(Path(__file__).parent))  # the suite imports in importlib mode: the helper beside it
from audit_routes import assert_same_audit  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TRACKER = f"{ROOT / 'examples' / 'three_sensor_system.py'}:tracker"


@pytest.fixture(scope="module")
def tracker_run():
    from gpfverify.systems import load_system

    model = load_system(TRACKER)
    _, ys = model.simulate(6, np.random.default_rng(3))
    return model, ys, run_fusion(model, ys, family="ukf", methods=("cmf", "dmf", "cc", "ci"), rank_rule="canonical")


def _numbers_read(text: str) -> str:
    """``text`` with every number in scientific notation read as <number>."""
    return re.sub(r"\d+(?:\.\d+)?e[+-]\d+", "<number>", text)


def _largest_at_read(text: str) -> str:
    """``text`` with the step of the largest gap read as <k> (where every gap is rounding noise)."""
    return re.sub(r"(largest observed gap <number>) at k = \d+", r"\1 at k = <k>", text)


def _words(text: str) -> str:
    """A paragraph as the pages render it (the one renderer, given this paragraph alone)."""
    from gpfverify.report.document import Paragraph, Section
    from gpfverify.report.render import to_fragment

    alone = to_fragment([Section("p", "p").add(Paragraph(text))])
    return alone[alone.index("<p>"):alone.rindex("</p>") + 4]


def test_a_fusion_run_shows_the_check_page_of_the_same_run(tracker_run, tmp_path, capsys):
    from gpfverify.cli import main
    from gpfverify.contract.check import verdict_sentence
    from gpfverify.report.equivalence import summary_paragraphs

    model, ys, fused = tracker_run
    np.savez(tmp_path / "m.npz", y=ys)
    assert main(["check", TRACKER, "--measurements", str(tmp_path / "m.npz"), "--json"]) == 0
    results = json.loads(capsys.readouterr().out)
    # the command runs its runs batched (run_fusion_batch): the same verdicts, and gaps that are
    # rounding noise of another route, so the numbers are read as numbers
    page = _largest_at_read(_numbers_read(fused._repr_html_()))
    assert _largest_at_read(_numbers_read(_words(verdict_sentence(results)))) in page
    for paragraph in summary_paragraphs(results)[1:]:
        assert _largest_at_read(_numbers_read(_words(paragraph))) in page
    assert page.count("<img") == 1  # the gap per step; the whole page is write_page's
    from gpfverify.notebook import write_page

    whole = write_page(fused, tmp_path / "page").read_text(encoding="utf-8")
    assert whole.count("<img") >= 4
    assert _largest_at_read(_numbers_read(_words(verdict_sentence(results)))) in _largest_at_read(_numbers_read(whole))


def _classes(fragment: str) -> set[str]:
    return {c for value in re.findall(r'class="([^"]*)"', fragment) for c in value.split()}


def test_a_25_step_runs_view_is_light_styled_as_the_pages_and_points_at_nothing_a_notebook_lacks():
    """The view of a 25-step run with its truth: at most 100 KB; each class it uses is styled by the
    page's rules scoped to the view (tables, verdicts, captions alike); no page-only path (runs/), no
    in-page link; its figure's text at least 9 px at the figure's own size (a notebook shows it so)."""
    import base64

    from gpfverify.notebook import fusion_run_html
    from gpfverify.report.figures import MIN_TEXT_PX, measured
    from gpfverify.systems import load_system

    model = load_system(TRACKER)
    truth, ys = model.simulate(25, np.random.default_rng(3))
    fused = run_fusion(model, ys, family="ukf", methods=("cmf", "dmf", "cc", "ci"))
    view = fusion_run_html(fused, truth)
    assert len(view.encode("utf-8")) <= 100_000
    style = re.search(r"<style>(.*?)</style>", view, re.S).group(1)
    body = view.replace(style, "")
    for name in ("table", "td", "th", "caption", "figure", "img"):
        assert re.search(rf"\.gpfverify-report {name}[{{,:\[. ]", style), name
    unstyled = {c for c in _classes(body) if f".{c}" not in style} - {"gpfverify-report", "verdict-text"}
    assert not unstyled, unstyled
    assert "runs/" not in body and 'href="#' not in body and " id=" not in body
    assert "write_page" in body and "RMSE" in body  # where the whole page is; the methods' table
    (png,) = [base64.b64decode(d) for d in re.findall(r'src="data:image/png;base64,([^"]+)"', body)]
    record = measured(png)
    assert record["min_font_px"] >= MIN_TEXT_PX and record["legends_over_data"] == 0


def test_a_run_audit_shows_the_audit_page_of_the_same_steps(tracker_run, tmp_path):
    from gpfverify.commands.audit import audit_run_file
    from gpfverify.report.equivalence import audit_summary_paragraphs

    _, _, fused = tracker_run
    cases = [s.dmf.case for s in fused.steps]
    path = write_run(tmp_path / "run.jsonl", cases)  # steps k = 0, 1, ...
    _, steps, summary = audit_run_file(path, rank_rule="canonical")
    # the run file's audit (its blocks with stacked linear algebra) and the run's own (step by step)
    # round differently: each step's numbers agree to their rounding, and the page says the same
    # words, with numbers that are rounding noise (a gap of 1e-15) in the one or the other rounding
    for k, (step, case, audit) in enumerate(zip(steps, cases, fused.audit.steps)):
        assert_same_audit({"k": k, **json.loads(json.dumps(audit_to_dict(audit)))}, step, case)
    # every gap is within its step's rounding bound, so which step's is the largest is rounding noise too
    assert summary["reproduced_steps"] == summary["steps_with_y"] == len(cases)
    page = _largest_at_read(_numbers_read(fused.audit._repr_html_()))
    for paragraph in audit_summary_paragraphs({"steps": steps, "summary": summary}):
        assert _largest_at_read(_numbers_read(_words(paragraph))) in page


def test_a_case_audit_and_a_claim_show_what_the_command_and_the_report_show(tracker_run):
    from gpfverify.audit.case import format_audit
    from gpfverify.contract.claims import ClaimRecord

    _, _, fused = tracker_run
    audit = fused.steps[0].audit
    assert html.escape(format_audit(audit)) in audit._repr_html_()
    claim = ClaimRecord("DMF reproduces CMF", "Liao et al. 2019, Proposition 1", "NOT held", 0.3, 0.0, 10,
                        "largest gap 0.3")
    shown = claim._repr_html_()
    assert "v-not-held" in shown and "DMF reproduces CMF" in shown and "largest gap 0.3" in shown


def test_a_run_without_the_audit_shows_its_fused_means(tracker_run):
    model, ys, _ = tracker_run
    fused = run_fusion(model, ys, family="ukf", methods=("cc",), audit=False)
    page = fused._repr_html_()
    assert "Fused means" in page and ", ".join(f"{v:.4g}" for v in fused.means("cc")[-1]) in page


class _Stream:
    def __init__(self, tty: bool):
        self.tty = tty

    def isatty(self) -> bool:
        return self.tty


class ZMQInteractiveShell:
    """The class name by which rich recognises a Jupyter kernel's shell."""


def test_progress_is_drawn_on_a_terminal_and_in_a_notebook_only(monkeypatch):
    monkeypatch.delitem(sys.modules, "ipykernel", raising=False)
    assert progress_shown(_Stream(True)) and not progress_shown(_Stream(False))
    monkeypatch.setitem(sys.modules, "ipykernel", type(sys)("ipykernel"))
    monkeypatch.setattr(builtins, "get_ipython", lambda: ZMQInteractiveShell(), raising=False)
    assert progress_shown(_Stream(False))  # a notebook: rich draws the bar as a live output
