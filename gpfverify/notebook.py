"""gpfverify's results in a Jupyter notebook: the HTML that ``_repr_html_`` shows, made by the same
page renderers as the reports (:mod:`gpfverify.report`), so a notebook says what the pages say.

* :func:`fusion_run_html` — a :func:`~gpfverify.model_fusion.run_fusion` result on a
  :class:`~gpfverify.models.StateSpaceModel` with CMF, DMF and the audit: the page of
  ``gpfverify check`` for that one run, compact (verdict, sensors, the gap per step against its
  rounding bound, each method's RMSE, NEES and NIS when the truth is given, settings; a few tens of
  kilobytes, drawn in well under a second); :func:`write_page` writes the whole page with every
  figure. A run without them: its fused means.
* :func:`run_audit_html` — a :class:`~gpfverify.audit.case.RunAudit`: the page of ``gpfverify audit
  RUN --out DIR`` (steps numbered from 0).
* :func:`case_audit_html` — a :class:`~gpfverify.audit.case.CaseAudit`: what ``gpfverify audit CASE.json``
  prints.
* :func:`claims_html` — claim records: the report's claims table.

Figures are drawn with matplotlib (Agg) into a temporary folder and embedded in the HTML, styled as
the pages are (:func:`gpfverify.report.render.to_fragment`).
The records do not import this module: it registers each function above for its record type in
:mod:`gpfverify.views`, the registry their ``_repr_html_`` asks, so the display sits on top of the
objects it shows (docs/architecture.md). Progress bars, on a terminal and in a notebook:
:func:`gpfverify.runtime.progress_shown`.
"""

from __future__ import annotations

import html
import tempfile
from collections.abc import Iterable
from pathlib import Path

from gpfverify import views
from gpfverify.audit.case import CaseAudit, RunAudit
from gpfverify.contract.claims import ClaimRecord
from gpfverify.model_fusion import FusionRun


def _fragment(sections) -> str:
    from gpfverify.report.render import to_fragment

    return to_fragment(sections)


#: where the compact view says the whole page is
WHOLE_PAGE = ("The check page of this run with every figure — the rank verdicts per step and sensor, the recursive "
              "drift, the trajectory, RMSE and the χ² bands of NEES and NIS — is written by "
              "`gpfverify.notebook.write_page(run, \"DIR\")`.")


def _checkable(fused) -> bool:
    from gpfverify.models.system import StateSpaceModel

    return (isinstance(fused.model, StateSpaceModel) and fused.ys is not None and fused.steps[0].audit is not None
            and "cmf" in fused.methods)


def fusion_run_html(fused, truth=None, system: str = "run_fusion") -> str:
    """The compact check page of one :func:`~gpfverify.model_fusion.run_fusion` result (module docstring)."""
    from gpfverify.experiments.check import results_of_run

    if _checkable(fused):
        from gpfverify.report.equivalence import equivalence_sections

        results = results_of_run(fused, truth, system)
        with tempfile.TemporaryDirectory(prefix="gpfverify-notebook-") as folder:
            return _fragment(equivalence_sections(results, Path(folder), compact=WHOLE_PAGE,
                                                  estimates="`run.means(method)`"))
    from gpfverify.report.document import Paragraph, Section, Table

    last = fused.steps[-1]
    section = Section("run", f"run_fusion: {fused.family}, {len(fused.steps)} steps")
    section.add(Paragraph("The check's page needs CMF, DMF and the audit on a StateSpaceModel; this run shows "
                          "its fused means at the last step."),
                Table(["method", f"mean at k = {last.k}"],
                      [[m, "—" if m in last.failed else ", ".join(f"{v:.4g}" for v in last.estimate(m).mean)]
                       for m in fused.methods], "Fused means"))
    return _fragment([section])


def write_page(fused, out_dir, truth=None, system: str = "run_fusion") -> Path:
    """The whole check page of one :func:`~gpfverify.model_fusion.run_fusion` result, with every figure,
    as ``gpfverify check --out DIR`` writes it: ``DIR/report.html``, ``DIR/README.md`` and the
    figures; returns the HTML page's path. ``truth`` (T, D) adds RMSE and NEES."""
    from gpfverify.errors import InputError
    from gpfverify.experiments.check import results_of_run
    from gpfverify.report.equivalence import write_equivalence_report

    if not _checkable(fused):
        raise InputError("write_page needs a run_fusion result on a StateSpaceModel with its measurements, CMF "
                         "and the audit")
    return write_equivalence_report(results_of_run(fused, truth, system), Path(out_dir))


def run_audit_html(run_audit) -> str:
    """The page of a run audit (module docstring)."""
    from gpfverify.report.equivalence import run_audit_sections
    from gpfverify.audit.run import RunSummary, audits_block

    block = audits_block(range(len(run_audit.steps)), list(run_audit.steps), keep=True)
    summary = RunSummary()
    summary.add(block)
    result = summary.result()
    with tempfile.TemporaryDirectory(prefix="gpfverify-notebook-") as folder:
        return _fragment(run_audit_sections({"steps": block.steps, "summary": result,
                                             "rank_rule": result["rank_rule"]}, Path(folder)))


def case_audit_html(audit) -> str:
    """What ``gpfverify audit CASE.json`` prints for this audit (module docstring)."""
    from gpfverify.audit.case import format_audit

    return f'<div class="gpfverify-report"><pre>{html.escape(format_audit(audit))}</pre></div>'


def claims_html(records: Iterable) -> str:
    """The report's tables of claim records (verdict, statistic, threshold, evidence, caveats), one per
    group as on the pages (accuracy, a theorem checked on the runs, timing)."""
    from gpfverify.report.document import Section, claim_tables

    return _fragment([Section("claims", "Claims").add(*claim_tables(list(records), "Claims"))])


views.register(FusionRun, fusion_run_html)
views.register(RunAudit, run_audit_html)
views.register(CaseAudit, case_audit_html)
views.register(ClaimRecord, lambda record: claims_html([record]))
