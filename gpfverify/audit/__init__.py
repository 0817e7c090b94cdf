"""The rank-condition audit of fusion steps (SPEC §3, use 3), behind one public face: which sensor's
cross term C_xy^m lost column rank, whether DMF is exact anyway, how large the gap is, and what
repairs it.

* :mod:`.case` — one fusion step (:func:`audit_case`, :class:`CaseAudit`, its JSON and text), and
  every step of a filter run in memory (:func:`audit_run`, :class:`RunAudit`);
* :mod:`.block` and :mod:`.blockexactness` — the same audit for a block of steps of one layout at
  once, vectorised over the steps;
* :mod:`.run` — a run file audited as a stream (:func:`stream_audit`, :class:`RunSummary`);
* :mod:`.runfile` — run files themselves (:func:`load_run`, :func:`write_run`; docs/run-file-format.md).

The exactness condition, the gap formula, the repair message, the rank rules and the rounding
bounds the audit reports are those of DMF itself (eq. 35 needs the rank rule, and its result
carries each sensor's exactness evidence), so they live with the fusion rules in
:mod:`gpfverify.fusion.exactness` and :mod:`gpfverify.fusion.rounding`; the names an audit's user
needs are served here too.
"""

from gpfverify.audit.block import block_audits
from gpfverify.audit.case import (CaseAudit, RunAudit, SensorAudit, audit_case, audit_run, audit_to_dict,
                                  cases_from_run, format_audit, rank_rule_to_dict)
from gpfverify.audit.run import RunSummary, audits_block, stream_audit
from gpfverify.audit.runfile import RunFile, load_run, open_run, write_run
from gpfverify.fusion.exactness import (DEFAULT_RANK_RULE, RankRule, branch_offsets, equivalence_tolerance, gap_size,
                                        parse_rank_rule, predicted_gap, repair_message)
from gpfverify.fusion.rounding import gap_bound

__all__ = ["CaseAudit", "RunAudit", "SensorAudit", "audit_case", "audit_run", "audit_to_dict", "cases_from_run",
           "format_audit", "rank_rule_to_dict", "block_audits", "RunSummary", "audits_block", "stream_audit",
           "RunFile", "load_run", "open_run", "write_run", "DEFAULT_RANK_RULE", "RankRule", "branch_offsets",
           "equivalence_tolerance", "gap_size", "parse_rank_rule", "predicted_gap", "repair_message", "gap_bound"]
