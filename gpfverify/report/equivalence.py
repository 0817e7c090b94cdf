"""The equivalence report of ``gpfverify check`` (and of ``gpfverify audit RUN --out``): does the
distributed rule DMF (Liao et al. 2019, eq. 35) reproduce centralized fusion CMF (Proposition 1) on the
user's system, at every step, and if not, which sensor's report makes the difference and what
repairs it.

A pure renderer: everything comes from the results dict (``results.json`` of ``check``, see
:func:`gpfverify.experiments.check.summarize`; the ``{"steps", "summary"}`` object of ``audit``);
nothing is filtered or simulated here. Output: ``DIR/README.md`` (Markdown), ``DIR/report.html``
(one self-contained page, figures embedded) and ``DIR/figures/*.png``; every file is built in a
temporary folder inside DIR and moved into place, so a crash never leaves a half-written report.

Entry points: :func:`write_equivalence_report`, :func:`write_run_audit_report`;
:func:`equivalence_sections` / :func:`summary_paragraphs` build the page without writing it.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from gpfverify.contract.check import verdict_sentence
from gpfverify.report.document import Code, Figure, Paragraph, Section, Table, integer_ranges
from gpfverify.report.render import md_escaped, provenance_section, to_html, to_markdown

FIGURES = "figures"
#: inexact steps listed one per row up to this many (the rest counted)
MAX_STEP_ROWS = 300
RANK_RULE_WORDS = {
    "numpy matrix_rank rule": "numpy matrix_rank rule (a singular value of C_xy^m counts when it exceeds "
                              "σ_max · max(D, l_m) · eps, per matrix)",
    "absolute tolerance": "absolute singular-value tolerance",
}


# -- small helpers ---------------------------------------------------------------------------------

def _g(x: float, digits: int = 2) -> str:
    return f"{x:.{digits}g}"


def _plural(n: int, word: str, plural: str | None = None) -> str:
    return f"{n} {word if n == 1 else (plural or word + 's')}"


def rank_rule_text(rule, rank_tol=None) -> str:
    """The rank rule in words, whatever its form: a string, or a rule object (dict) such as
    ``{"name": "canonical", "tol": 1e-6, ...}``."""
    if rule is None:
        text = "the rank rule recorded with the run"
    elif isinstance(rule, dict):
        name = rule.get("name") or rule.get("kind") or rule.get("rule") or "rank rule"
        described = ("name", "kind", "rule", "description") + (("tol",) if rule.get("description") else ())
        rest = [f"{k} = {v:.3g}" if isinstance(v, float) else f"{k} = {v}" for k, v in rule.items()
                if k not in described and v is not None]  # a description states its tolerance
        extras = f" ({', '.join(rest)})" if rest else ""
        text = (f"{name} rank rule{extras}" if not rule.get("description")
                else f"{name} rank rule — {rule['description']}{extras}")
    elif isinstance(rule, (list, tuple)):
        text = "; ".join(rank_rule_text(r) for r in rule) + " (differed between steps)"
    else:
        text = RANK_RULE_WORDS.get(str(rule), str(rule))
    if rank_tol is not None:
        text += f", tolerance {rank_tol:g}"
    return text


def _rule_threshold(rule):
    """The threshold τ of a canonical-correlation rule object, if it names one."""
    if isinstance(rule, dict) and "canonical" in str(rule.get("name", "canonical")):
        for key in ("tol", "tau", "threshold", "rtol"):
            value = rule.get(key)
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                return float(value)
    return None


def _min_ragged(values) -> np.ndarray:
    """Smallest entry of each innermost list of an (R, T, N, ·) ragged nesting -> (R, T, N); NaN for an
    empty list (no canonical correlation: a sensor without outputs)."""
    def reduce(v):
        if isinstance(v, (list, tuple)) and v and isinstance(v[0], (list, tuple)):
            return [reduce(x) for x in v]
        return float(np.min(v)) if len(v) else np.nan
    return np.array([[reduce(s) for s in step] for step in values], dtype=float) \
        if values and isinstance(values[0][0][0], (list, tuple)) else np.array(values, dtype=float)


# -- the check results, as arrays ------------------------------------------------------------------

class CheckData:
    """Arrays of a ``check`` results dict: runs R (those that finished), steps T, sensors N."""

    def __init__(self, results: dict):
        self.r = results
        # the gap and its rounding bound in prior standard deviations (docs/fusion-definitions.md)
        self.gap = np.asarray(results["gap_size"], dtype=float)              # (R, T)
        self.bound = np.asarray(results["gap_bound"], dtype=float)
        # the drift of the recursive filters beside the one-step gap, in one unit: prior standard
        # deviations (recursive_gap_size), or state units for results written before it
        self.drift_in_prior_sd = "recursive_gap_size" in results
        self.recursive = np.asarray(results["recursive_gap_size" if self.drift_in_prior_sd else "recursive_gap_norm"],
                                    dtype=float)
        self.one_step = self.gap if self.drift_in_prior_sd else np.asarray(results["gap_norm"], dtype=float)
        self.full = np.asarray(results["full_column_rank"], dtype=bool)       # (R, T, N)
        self.exact = np.asarray(results["exact"], dtype=bool)
        self.rank = np.asarray(results["rank"], dtype=int)
        self.repair = np.asarray(results["repair_dim"], dtype=int)
        # each sensor's share of the gap in prior standard deviations, the unit of the gap itself
        # (results.json's gap_share is in state units; older results have only that)
        self.share_in_prior_sd = "gap_share_size" in results
        self.share = np.asarray(results["gap_share_size" if self.share_in_prior_sd else "gap_share"], dtype=float)
        self.tol = np.asarray(results["tol"], dtype=float)
        offsets = results.get("branch_offset_count")
        self.branch = (np.asarray(offsets, dtype=int) if offsets is not None
                       else np.zeros(np.shape(results["full_column_rank"]), dtype=int))   # (R, T, N)
        self.runs_ok: int
        self.steps: int
        self.n: int
        self.runs_ok, self.steps, self.n = self.full.shape
        self.total = self.runs_ok * self.steps
        self.ks = list(results.get("k") or range(1, self.steps + 1))
        self.D = int(results["state_dim"])
        self.sensors = results["sensors"]
        # asarray: numpy's stubs cannot tell that all(axis=2) of (R, T, N) is an array, not a scalar
        self.step_exact = np.asarray(self.exact.all(axis=2))                  # (R, T)
        self.step_held = np.asarray(self.full.all(axis=2))
        failed = {f.get("index") for f in results.get("failed_runs") or []}
        runs = int(results.get("runs", self.runs_ok))
        labels = [i for i in range(runs) if i not in failed]
        self.run_labels = labels if len(labels) == self.runs_ok else list(range(self.runs_ok))
        self.canonical = None
        if results.get("min_canonical_correlation") is not None:
            try:
                self.canonical = np.array([[[np.nan if v is None else v for v in step] for step in run]
                                           for run in results["min_canonical_correlation"]], dtype=float)
                if self.canonical.shape != self.full.shape or np.isnan(self.canonical).all():
                    self.canonical = None
            except (TypeError, ValueError):
                self.canonical = None
        if self.canonical is None and results.get("canonical_correlations") is not None:
            try:
                self.canonical = _min_ragged(results["canonical_correlations"])  # (R, T, N)
                if self.canonical.shape != self.full.shape:
                    self.canonical = None
            except (TypeError, ValueError, IndexError):
                self.canonical = None

    def sensor_label(self, m: int) -> str:
        name = self.sensors[m].get("name") or f"sensor {m}"
        return f"sensor {m}" if name == f"sensor {m}" else f"sensor {m} ({name})"

    def where(self, runs_and_steps) -> str:
        """'run 0 k = 3' style locations of (r, t) pairs."""
        return "; ".join(f"run {self.run_labels[r]} k = {self.ks[t]}" for r, t in runs_and_steps)

    @property
    def of_runs(self) -> str:
        return f" of {self.runs_ok} runs" if self.runs_ok > 1 else ""


# -- the plain-words summary -----------------------------------------------------------------------

def _repair_words(sizes: np.ndarray) -> str:
    sizes = np.unique(sizes[sizes > 0])
    if not sizes.size:
        return "0 numbers"
    if sizes.size == 1:
        return _plural(int(sizes[0]), "number")
    return f"{sizes.min()}–{sizes.max()} numbers"


def _exact_anyway_words(exact: int, lost: int) -> str:
    """How many of the ``lost`` steps where a sensor lost rank it was exact at, from the counts."""
    if exact == lost:
        return f"exact anyway at all {_plural(lost, 'step')} (the lost directions carried no gain)"
    if exact:
        return (f"exact anyway at {exact} of those {lost} steps (the lost directions carried no gain there) and "
                f"not at {lost - exact}")
    return "not exact at any of them"


def _share_unit(d: CheckData) -> str:
    return " prior standard deviations" if d.share_in_prior_sd else " (state units)"


def _sensor_sentence(d: CheckData, m: int) -> str | None:
    lost = ~d.full[:, :, m]
    n_lost = int(lost.sum())
    s = d.sensors[m]
    outputs = int(s["outputs"])
    too_many = outputs > d.D
    if not n_lost and not too_many:
        return None
    label = d.sensor_label(m)
    if not n_lost:   # l_m > D cannot keep full column rank; say so if the data disagree
        return (f"{label[0].upper()}{label[1:]} has {outputs} outputs and the state {d.D} "
                f"(l_m > D: the rank condition can never hold for this sensor), yet no step recorded a rank loss "
                f"for it — check the rank rule.")
    when = "at every step" if n_lost == d.total else f"at {n_lost} of {d.total} steps"
    text = f"{label[0].upper()}{label[1:]} lost full column rank {when}"
    if too_many:
        text += (f": it has {outputs} outputs and the state {d.D} — l_m > D: the rank condition can never hold "
                 "for this sensor")
    exact_anyway = int((lost & d.exact[:, :, m]).sum())
    inexact = lost & ~d.exact[:, :, m]
    n_inexact = int(inexact.sum())
    text += "; its report was " + _exact_anyway_words(exact_anyway, n_lost)
    if n_inexact:
        share = d.share[:, :, m][inexact]
        text += (f" (its share of the gap up to {_g(share.max())}{_share_unit(d)}); sending its repair "
                 f"message — {_repair_words(d.repair[:, :, m][inexact])} per step, the part of its whitened "
                 "innovation in the lost directions — restores CMF")
    return text + "."


def summary_paragraphs(results: dict) -> list[str]:
    """The plain-words verdict of a check, computed from its arrays: headline, one sentence per
    sensor that lost rank, the explanation of every inexact step, the rule that decided."""
    d = CheckData(results)
    exact_steps = int(d.step_exact.sum())
    held_steps = int(d.step_held.sum())
    within = np.less_equal(d.gap, d.bound)
    n_within = int(within.sum())
    out = [verdict_sentence(results)]
    if exact_steps < d.total:
        worst = np.unravel_index(np.argmax(d.gap), d.gap.shape)
        out.append(f"The exactness condition (ker C_xy^m ⊆ ker G_m C_y^m) failed at {d.total - exact_steps} of "
                   f"{d.total} steps; the largest gap was at {d.where([worst])}; "
                   + ("the rank condition of Proposition 1 never held." if held_steps == 0 else
                      f"the rank condition of Proposition 1 held at {held_steps} of the {d.total} steps."))
    elif n_within < d.total:
        out.append(f"Every sensor was judged exact at every step, yet at {d.total - n_within} step(s) the gap "
                   "exceeded the rounding bound (explained below).")
    out += [s for s in (_sensor_sentence(d, m) for m in range(d.n)) if s]
    inexact = ~d.step_exact
    if inexact.any():
        groups: dict[tuple, list] = {}
        for r, t in zip(*np.nonzero(inexact)):
            culprits = tuple(int(m) for m in np.flatnonzero(~d.exact[r, t]))
            groups.setdefault(culprits, []).append((r, t))
        parts = []
        for culprits, where in sorted(groups.items(), key=lambda kv: -len(kv[1])):
            rs, ts = np.array(where).T
            # a share over the gap, both in prior standard deviations (older results: no fraction)
            fraction = np.array([d.share[r, t, list(culprits)].max() / d.gap[r, t]
                                 if d.gap[r, t] > 0 and d.share_in_prior_sd else np.nan for r, t in where])
            who = " and ".join(d.sensor_label(m) for m in culprits)
            part = f"at {_plural(len(where), 'step')} {who} {'was' if len(culprits) == 1 else 'were'} judged not exact"
            if np.isfinite(fraction).any():
                low, high = (f"{100 * v:.0f} %" for v in (np.nanmin(fraction), np.nanmax(fraction)))
                span = low if low == high else f"{low} to {high}"
                part += (f" (its share of the gap: {span} of the gap's norm)" if len(culprits) == 1 else
                         f" (the largest single-sensor share of the gap: {span} of the gap's norm)")
            parts.append(part)
        out.append("Every inexact step is explained by the sensors judged not exact there: " + "; ".join(parts)
                   + ". The table of inexact steps lists each one.")
        quiet = inexact & within
        if quiet.any():
            out.append(f"At {_plural(int(quiet.sum()), 'step')} judged not exact the observed gap still stayed "
                       "within the rounding bound: the innovation happened to have little component in the lost "
                       "directions.")
    wrapped = d.step_exact & ~within & d.branch.any(axis=2)
    if wrapped.any():
        where = list(zip(*np.nonzero(wrapped)))
        offset_sensors = sorted({int(m) for r, t in where for m in np.nonzero(d.branch[r, t])[0]})
        listed = "; ".join(f"run {d.run_labels[r]} k = {d.ks[t]}: gap {_g(d.gap[r, t])}" for r, t in where[:10])
        out.append(f"At {_plural(len(where), 'step')} every sensor was exact but an angle output of "
                   + " and ".join(d.sensor_label(m) for m in offset_sensors)
                   + " had a branch offset: its eq. 35 terms μ_y^m − μ_y(m) and y^m − μ_y^m, each wrapped to "
                     "(−π, π], summed outside (−π, π], so DMF's innovation differs from CMF's by 2π and the gap is "
                     f"2π G_m e_j, as the audit predicts ({listed}).")
    odd = d.step_exact & ~within & ~d.branch.any(axis=2)
    if odd.any():
        where = list(zip(*np.nonzero(odd)))
        def top(r, t):
            m = int(np.argmax(d.share[r, t]))
            return (f", largest share {d.sensor_label(m)} {_g(d.share[r, t, m])}" if d.share[r, t, m] > 0 else "")
        listed = "; ".join(f"run {d.run_labels[r]} k = {d.ks[t]}: gap {_g(d.gap[r, t])} vs bound "
                           f"{_g(d.bound[r, t])}{top(r, t)}" for r, t in where[:10])
        listed += "; …" if len(where) > 10 else ""
        lost = [(r, t) for r, t in where if not d.step_held[r, t]]
        angles = any(s.get("circular") for s in d.sensors)
        out.append(f"At {_plural(len(where), 'step')} every sensor was judged exact but the observed gap exceeded "
                   f"the rounding bound ({listed}). The rank and exactness verdicts do not account for this"
                   + ("" if lost else ": every sensor kept full column rank there, so Proposition 1's condition held "
                      "and the difference is not a rank failure but "
                      + ("either a branch offset of an angle output (the separately wrapped eq. 35 terms left "
                         "(−π, π], so DMF's innovation differs from CMF's by 2π) or " if angles else "")
                      + "rounding amplified by ill-conditioned moments")
                   + " — audit that step (gpfverify audit) to see the singular values.")
    out.append(_rule_sentence(d))
    out += _unit_sentences(d)
    if d.canonical is not None:
        mins = np.nanmin(d.canonical, axis=(0, 1))
        out.append("Smallest canonical correlation of state and sensor output over all steps: "
                   + ", ".join(f"{d.sensor_label(m)} {_g(v, 3)}" for m, v in enumerate(mins)) + ".")
    failed = results.get("failed_runs") or []
    if failed:
        out.append(f"{_plural(len(failed), 'run')} of {results.get('runs', d.runs_ok + len(failed))} failed and "
                   f"{'is' if len(failed) == 1 else 'are'} left out (first error: {failed[0].get('error')}).")
    return out


def _rule_sentence(d: CheckData) -> str:
    params = d.r.get("params") or {}
    rule = rank_rule_text(d.r.get("rank_rule"), params.get("rank_tol"))
    tols = d.tol[np.isfinite(d.tol)]
    rule_obj = d.r.get("rank_rule")
    stated = isinstance(rule_obj, dict) and isinstance(rule_obj.get("tol"), (int, float))
    span = (f"the tolerances it gave ranged from {_g(tols.min())} to {_g(tols.max())}" if tols.size
            and tols.min() != tols.max() else f"tolerance {_g(tols.max())}" if tols.size and not stated else "")
    return (f"Every rank verdict was decided by the {rule}" + (f"; {span}" if span else "") +
            ". A sensor is exact when the directions its rank decision drops carry no gain (its gap gain "
            "‖L_p⁻¹ G_m C_y^m Π_m L_y⁻ᵀ‖₂, prior standard deviations per unit whitened innovation, at the "
            "rounding level of the fused estimate), a step when every sensor is. The rounding bound is the "
            "first-order bound on the DMF − CMF gap, in prior standard deviations, that rounding in the "
            "step's own CMF and DMF arithmetic can produce when DMF is exact; a gap within it counts as DMF "
            "reproducing CMF (derivation: docs/fusion-definitions.md, 'Rounding bound and \"reproduced\"').")


def _unit_sentences(d: CheckData) -> list[str]:
    """What on this page depends on the units of the state and output components, and by how much
    where results.json measured it: eq. 35's Moore–Penrose inverse where a sensor lost rank, a rank
    rule on singular values, CI's trace criterion, RCC-CI (docs/fusion-definitions.md, "Units")."""
    out = []
    rule = d.r.get("rank_rule") or {}
    if isinstance(rule, dict) and rule.get("name") in ("numpy", "absolute"):
        out.append(f"The {rule['name']} rank rule decides on the singular values of C_xy^m, which change with "
                   "the units of the state and output components: the rank verdicts above hold in these units "
                   "(--rank-rule canonical decides without them).")
    dependence = [v for run in d.r.get("unit_dependence") or [] for v in run if v is not None]
    if dependence:
        out.append(f"At {_plural(len(dependence), 'step')} a sensor lost rank, and there eq. 35's Moore–Penrose "
                   "inverse depends on the units of the state and output components: in these units DMF was up to "
                   f"{_g(max(dependence))} prior standard deviations (median {_g(float(np.median(dependence)))}) "
                   "from the unit-free variant of DMF (truncated in whitened coordinates), the estimate no change "
                   "of units moves. In other units DMF lies at its own distance from that variant, which this one "
                   "does not bound: a change of units moves DMF by at most the sum of the two distances.")
    methods = list((d.r.get("params") or {}).get("methods") or [])
    criterion = (d.r.get("params") or {}).get("ci_criterion", "trace")
    weighted = [m.upper() for m in ("ci", "ici") if m in methods]
    if weighted and criterion == "trace":
        verb, their = ("weighs", "its estimate changes") if len(weighted) == 1 else ("weigh", "their estimates change")
        out.append(f"{' and '.join(weighted)} {verb} the local estimates by the trace criterion, which adds the "
                   f"variances of state components in different units: {their} with the units "
                   "(--ci-criterion det, the determinant criterion, does not).")
    elif weighted:
        verb = "weighs" if len(weighted) == 1 else "weigh"
        out.append(f"{' and '.join(weighted)} {verb} the local estimates by the determinant criterion, which does "
                   "not depend on units.")
    if "rcc-ci" in methods:
        out.append("RCC-CI's Chebyshev centre measures distances with the Euclidean norm of the state, so its "
                   "estimate changes with the units of the state components.")
    return out


# -- tables ----------------------------------------------------------------------------------------

def sensor_table(d: CheckData) -> Table:
    headers = ["sensor", "name", "outputs l_m", "angle outputs (indices from 0)", "l_m > D", "steps full rank",
               "steps exact", "largest share of gap" + (" (prior sd)" if d.share_in_prior_sd else " (state units)"),
               "repair size (numbers per step)", "rank tolerance"]
    if d.canonical is not None:
        headers.append("smallest canonical correlation")
    rows = []
    for m, s in enumerate(d.sensors):
        repair = d.repair[:, :, m]
        tol = d.tol[:, :, m]
        row = [m, s.get("name", ""), s["outputs"], ", ".join(f"#{i}" for i in s.get("circular") or []) or "none",
               "yes" if int(s["outputs"]) > d.D else "no", f"{int(d.full[:, :, m].sum())} of {d.total}",
               f"{int(d.exact[:, :, m].sum())} of {d.total}", _g(float(d.share[:, :, m].max())),
               "0" if not repair.any() else f"{repair.max()} (at {int((repair > 0).sum())} steps)",
               _g(float(tol.min())) if tol.min() == tol.max() else f"{_g(float(tol.min()))} – {_g(float(tol.max()))}"]
        if d.canonical is not None:
            row.append(_g(float(np.nanmin(d.canonical[:, :, m])), 3))
        rows.append(row)
    return Table(headers, rows, f"Sensors (state dimension D = {d.D}; counts over {d.total} steps{d.of_runs})")


def inexact_table(d: CheckData) -> Table | None:
    """One row per step judged not exact or whose gap exceeds the rounding bound."""
    flagged = ~d.step_exact | (d.gap > d.bound)
    where = list(zip(*np.nonzero(flagged)))
    if not where:
        return None
    rows = []
    for r, t in where[:MAX_STEP_ROWS]:
        culprits = np.flatnonzero(~d.exact[r, t])
        lost = np.flatnonzero(~d.full[r, t])
        rows.append([d.run_labels[r], d.ks[t], _g(d.gap[r, t], 3), _g(d.bound[r, t], 2),
                     "no" if culprits.size else "yes",
                     ", ".join(str(m) for m in lost) or "none",
                     "; ".join(f"sensor {m}: {_g(d.share[r, t, m], 3)}"
                               + (f" ({100 * d.share[r, t, m] / d.gap[r, t]:.0f} %)"
                                  if d.gap[r, t] > 0 and d.share_in_prior_sd else "")
                               for m in culprits) or "— (every sensor exact)",
                     ", ".join(f"{d.repair[r, t, m]}" for m in culprits) or "0"])
    caption = (f"Steps judged not exact, or with a gap above the rounding bound ({len(where)} of {d.total})"
               + (f"; the first {MAX_STEP_ROWS} listed" if len(where) > MAX_STEP_ROWS else ""))
    return Table(["run", "k", "gap (prior sd)", "rounding bound (prior sd)", "exact", "sensors without full rank",
                  "share of the gap (sensors not exact" + (", prior sd)" if d.share_in_prior_sd else ", state units)"),
                  "repair numbers"], rows, caption)


def method_table(d: CheckData) -> Table:
    r = d.r
    times = r.get("time_per_step") or {}
    methods = list((r.get("params") or {}).get("methods") or r.get("rmse", {}).keys() or times.keys())
    methods = [m for m in methods if m != "local"]
    truth = bool(r.get("truth_known")) and "rmse" in r
    headers = ["estimate"] + (["RMSE over the run", "ANEES (mean over steps)", "steps with ANEES inside band"]
                              if truth else []) + ["time per step (ms)"]
    rows = []
    for m in methods:
        row = [m.upper()]
        if truth and m not in r["rmse"]:
            row += ["failed at some steps (see the verdict)", "—", "—"]
        elif truth:
            rmse = np.asarray(r["rmse"][m], float)
            nees = r["nees"][m]
            row += [_g(float(np.sqrt(np.mean(rmse ** 2))), 4), _g(float(np.mean(nees["average"])), 3),
                    f"{100 * nees['fraction_inside']:.0f} %"]
        row.append(_g(1e3 * times[m], 3) if m in times else "—")
        rows.append(row)
    for i in range(d.n):
        row = [f"local filter, {d.sensor_label(i)}"]
        if truth:
            rmse = np.asarray(r["local_rmse"][i], float)
            nees = r["local_nees"][i]
            row += [_g(float(np.sqrt(np.mean(rmse ** 2))), 4), _g(float(np.mean(nees["average"])), 3),
                    f"{100 * nees['fraction_inside']:.0f} %"]
        row.append(_g(1e3 * times["local"], 3) + " (all local filters)" if i == 0 and "local" in times else "")
        rows.append(row)
    band = ""
    if truth:
        first = next(iter(r["nees"].values()))
        band = (f"; ANEES band: the {100 * first['level']:.0f} % two-sided χ² band of the average of "
                f"{first['runs']} χ²_{first['dof']} values, [{_g(first['band'][0], 3)}, {_g(first['band'][1], 3)}]")
    return Table(headers, rows, "Estimates of the recursive filters (each method from its own previous posterior): "
                 "RMSE = sqrt of the mean squared error over all steps and runs" + band
                 + "; times are wall-clock on the machine that made the run")


def settings_table(results: dict, d: CheckData) -> Table:
    p = results.get("params") or {}
    rows = [["system", p.get("system", results.get("system", "—"))],
            ["filter family", p.get("filter", results.get("filter", "—"))],
            ["runs", f"{d.runs_ok} finished of {results.get('runs', d.runs_ok)}"],
            ["steps per run", d.steps],
            ["seed", results.get("seed", "—")],
            ["methods", ", ".join(p.get("methods") or [])],
            ["rank rule", rank_rule_text(results.get("rank_rule"), p.get("rank_tol"))],
            ["CI weight criterion", p.get("ci_criterion", "trace")],
            ["measurements", p.get("measurements") or "simulated from the system"],
            ["truth known", "yes" if results.get("truth_known") else "no"]]
    if str(p.get("filter", "")).startswith("gp"):
        rows += [["GP training", p.get("training") or f"{p.get('train')} samples drawn from the system"],
                 ["GP fit points / restarts", f"{p.get('fit_points')} / {p.get('restarts')}"]]
    return Table(["setting", "value"], rows, "Settings")


def failed_table(results: dict) -> Table | None:
    failed = results.get("failed_runs") or []
    if not failed:
        return None
    return Table(["run", "seed spawn key", "error"],
                 [[f.get("index"), f.get("spawn_key"), f.get("error")] for f in failed], "Failed runs (left out)")


# -- the page --------------------------------------------------------------------------------------

#: where the check page says each method's estimates are (its run files)
ESTIMATES_IN_RUN_FILES = 'runs/run-NNNNNN.json ("means")'


def equivalence_sections(results: dict, fig_dir: Path, fig_prefix: str = FIGURES, compact: str = "",
                         estimates: str = ESTIMATES_IN_RUN_FILES) -> list[Section]:
    """The report's sections, figures drawn into ``fig_dir`` (Figure paths point there). ``compact``
    (a sentence saying where the whole page is) draws the gap figure alone, small, and says that
    sentence in place of the other figures (a notebook's view); ``estimates`` says where each
    method's estimates are."""
    from gpfverify.report import equivalence_figures as ef

    d = CheckData(results)
    labels = [d.sensor_label(m) for m in range(d.n)]
    system = (results.get("params") or {}).get("system", results.get("system", ""))
    head = Section("summary", "Does DMF reproduce CMF?")
    head.add(*[Paragraph(p) for p in summary_paragraphs(results)])
    head.add(Paragraph(f"System `{system}`, filter family {results.get('filter', '?')}, {d.runs_ok} "
                       f"run(s) × {d.steps} steps. DMF is the distributed rule of Liao et al. 2019, eq. 35 "
                       "(each sensor sends its local posterior); CMF fuses the stacked measurements at the centre. "
                       "One-step numbers — the gap, its rounding bound, the rank and exactness verdicts, the shares "
                       "and the repair sizes — compare both rules from the same central prediction, DMF's (the "
                       "centre predicts from DMF's previous posterior; the audit applies CMF's update to it). "
                       f"Recursive numbers — the drift, RMSE, NEES and the estimates in {estimates} — come from "
                       "each method's own filter, run from its own previous posterior."))
    head.add(sensor_table(d))

    gap = Section("gap", "The gap per step")
    path, floor = ef.plot_gap(d.ks, d.gap, d.bound, ~d.step_exact, fig_dir / "gap.png", d.run_labels,
                              dpi=ef.COMPACT_DPI if compact else None)
    gap.add(Figure(path, "‖L_p⁻¹(μ_DMF − μ_CMF)‖ per step, in prior standard deviations, from the same central "
                         "prediction (solid) against the rounding bound of that step (dashed, "
                         "docs/fusion-definitions.md), log scale; circles: steps judged not exact"
                   + (f"; zero gaps drawn at {_g(floor)}" if (d.gap <= 0).any() else "")
                   + (" (median and range over runs)" if d.runs_ok > ef.MAX_RUN_LINES else "")))
    if compact:
        return _compact_sections(results, d, head, gap, compact)
    gap.add(Figure(ef.plot_verdict_strip(d.ks, d.full, d.exact, labels, fig_dir / "verdicts.png",
                                         f"run {d.run_labels[0]}"),
                   "Rank verdict and exactness per step and sensor: green full column rank, amber rank lost but "
                   "exact anyway, red not exact" + ("; below, the fraction of runs with full column rank and "
                                                    "the fraction exact" if d.runs_ok > 1 else "")))
    if d.canonical is not None:
        threshold = _rule_threshold(results.get("rank_rule"))
        gap.add(Figure(ef.plot_min_per_sensor(d.ks, d.canonical[0], labels, fig_dir / "canonical.png",
                                              "smallest canonical correlation",
                                              "smallest canonical correlation of state and output, "
                                              f"run {d.run_labels[0]}",
                                              threshold, "rank rule threshold"),
                       "Smallest canonical correlation per step and sensor (unit-free: a correlation near 0 means "
                       "an output direction carries almost no information about the state)"))
    quantity = ef.GAP_IN_PRIOR_SD if d.drift_in_prior_sd else ef.GAP_IN_STATE_UNITS
    unit = "prior standard deviations" if d.drift_in_prior_sd else "state units"
    path, floor = ef.plot_drift(d.ks, d.recursive, d.one_step, fig_dir / "drift.png", d.run_labels, quantity)
    gap.add(Figure(path, f"Recursive drift: {quantity[0]} of the two filters, each from its own previous posterior "
                         f"(solid), against the one-step gap (dashed), both in {unit} of the step's central "
                         "prediction, log scale"
                   + (f"; zeros drawn at {_g(floor)}" if (d.one_step <= 0).any() or (d.recursive <= 0).any()
                      else "")))
    gap.add(Paragraph(_drift_sentence(d)))

    acc = Section("accuracy", "Accuracy and consistency")
    if results.get("trajectory"):  # results written before it was recorded have none
        from gpfverify.report.check_trajectory import plot_trajectory, trajectory_caption

        acc.add(Figure(plot_trajectory(results["trajectory"], fig_dir / "trajectory.png"),
                       trajectory_caption(results["trajectory"])))
    if results.get("truth_known") and "rmse" in results:
        acc.add(Figure(ef.plot_rmse(d.ks, results["rmse"], results["local_rmse"],
                                    [f"local, {lab}" for lab in labels], fig_dir / "rmse.png"),
                       "RMSE per step (over runs) of every fusion method and every local filter (dotted)"))
    else:
        acc.add(Paragraph("The truth is not known (logged measurements without x): no RMSE or NEES."))
    nees = results.get("nees") if results.get("truth_known") else None
    acc.add(Figure(ef.plot_consistency(d.ks, nees, results["nis"]["cmf"], results["nis"]["local"],
                                       [f"local {lab}" for lab in labels], fig_dir / "consistency.png"),
                   ("ANEES of every method (shaded: its χ² band) and " if nees else "") +
                   "ANIS of CMF and of every local filter, each against its χ² band"))
    acc.add(method_table(d))

    sections = [head, gap, acc]
    table = inexact_table(d)
    if table is not None:
        sections.append(Section("inexact-steps", "Inexact steps").add(
            Paragraph("Each step judged not exact, or whose gap exceeds the rounding bound: the sensors that lost "
                      "full column rank, the share of the gap of each sensor judged not exact (the norm of its "
                      "term −G_m C_y^m N_m r_m, and its ratio to the gap's norm) and the size of its repair message "
                      "r_m."), table))
    settings = Section("settings", "Settings")
    settings.add(settings_table(results, d))
    failed = failed_table(results)
    if failed is not None:
        settings.add(failed)
    return sections + [settings]


def _drift_sentence(d: CheckData) -> str:
    """How far apart the two recursive filters ended, and what that drift is."""
    unit = "prior standard deviations" if d.drift_in_prior_sd else "state units"
    return (f"The recursive filters ended at most {_g(float(d.recursive.max()))} {unit} apart (largest over steps "
            f"and runs; {_g(float(np.median(d.recursive[:, -1])))} at the last step, median of runs). Where every "
            "step is exact this drift is rounding carried through the recursion; where steps are inexact it "
            "accumulates their gaps.")


def _compact_sections(results: dict, d: CheckData, head: Section, gap: Section, whole_page: str) -> list[Section]:
    """The summary, the gap figure, the methods' table and the settings, with where the other figures are."""
    gap.add(Paragraph(f"{_drift_sentence(d)} {whole_page}"))
    settings = Section("settings", "Settings").add(settings_table(results, d))
    return [head, gap, Section("accuracy", "Accuracy and consistency").add(method_table(d)), settings]


def _markdown(sections: list[Section], page_dir: Path) -> str:
    return "\n".join(to_markdown(section, page_dir) for section in sections)


def _publish(out_dir: Path, build) -> Path:
    """Build the report into a temporary folder inside ``out_dir`` with ``build(tmp) -> {name: text}``
    (figures drawn into ``tmp/figures``), then move it into place: the figures folder swapped whole,
    every other file replaced atomically (README.md and report.html last). Returns report.html."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".report-", dir=out_dir))
    try:
        (tmp / FIGURES).mkdir()
        files = build(tmp)
        for name, text in files.items():
            (tmp / name).write_text(text, encoding="utf-8")
        figures, old = out_dir / FIGURES, None
        if figures.exists():
            old = out_dir / f".{FIGURES}-old-{os.getpid()}"
            os.replace(figures, old)
        os.replace(tmp / FIGURES, figures)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
        for name in sorted(files, key=lambda n: (n in ("README.md", "report.html"), n)):
            os.replace(tmp / name, out_dir / name)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return out_dir / "report.html"


def write_equivalence_report(results: dict, out_dir: Path) -> Path:
    """``out_dir/README.md``, ``out_dir/report.html`` and ``out_dir/figures/*.png`` from the results
    of ``gpfverify check``; returns the HTML path."""
    out_dir = Path(out_dir)
    system = (results.get("params") or {}).get("system", results.get("system", "system"))
    title = f"DMF vs CMF on {Path(str(system).split(':')[0]).name}:{str(system).split(':')[-1]}"

    def build(tmp: Path) -> dict[str, str]:
        sections = equivalence_sections(results, tmp / FIGURES) + [provenance_section()]
        markdown = _markdown(sections, tmp)
        return {"README.md": _with_title(title, markdown), "report.html": to_html(sections, title)}

    return _publish(out_dir, build)


def _with_title(title: str, markdown: str) -> str:
    """The page title on top; every section heading one level below it."""
    lines = [("#" + line) if line.startswith("#") and line.lstrip("#").startswith(" ") else line
             for line in markdown.splitlines()]
    return f"# {md_escaped(title)}\n\n" + "\n".join(lines) + "\n"


# -- the run audit (gpfverify audit RUN --out DIR) ------------------------------------------------

class AuditData:
    """Arrays of a run audit ``{"steps": [...], "summary": {...}}``: steps T, sensors N."""

    def __init__(self, run_audit: dict):
        self.steps = run_audit["steps"]
        self.summary = run_audit.get("summary") or {}
        self.T = len(self.steps)
        self.ks = [s.get("k", t) for t, s in enumerate(self.steps)]
        self.n = len(self.steps[0]["sensors"]) if self.steps else 0

        def per_sensor(key, dtype, default=np.nan):
            return np.array([[s.get(key, default) for s in step["sensors"]] for step in self.steps], dtype=dtype)

        self.full = per_sensor("full_column_rank", bool)
        self.exact = per_sensor("exact", bool)
        self.repair = per_sensor("repair_dim", int, 0)
        self.rows = per_sensor("rows", float)
        self.cols = per_sensor("cols", float)
        self.tol = per_sensor("tol", float)
        self.sigma_min = np.array([[min(s["singular_values"]) if s.get("singular_values") else np.nan
                                    for s in step["sensors"]] for step in self.steps], dtype=float)
        self.canonical = None
        if any("canonical_correlations" in s for step in self.steps for s in step["sensors"]):
            self.canonical = np.array([[min(s["canonical_correlations"]) if s.get("canonical_correlations")
                                        else np.nan for s in step["sensors"]] for step in self.steps], dtype=float)
        self.gap = np.array([s.get("gap_norm", np.nan) if s.get("gap_norm") is not None else np.nan
                             for s in self.steps], dtype=float)
        self.predicted = np.array([np.linalg.norm(s["predicted_gap"]) if s.get("predicted_gap") is not None
                                   else np.nan for s in self.steps], dtype=float)
        self.step_exact = np.array([bool(s["exact"]) for s in self.steps])
        self.step_held = np.array([bool(s["condition_holds"]) for s in self.steps])
        # each sensor's share of the gap in prior standard deviations (gap_contribution_size; a run audit
        # written before it had only the share in state units)
        self.share_in_prior_sd = any("gap_contribution_size" in x for step in self.steps for x in step["sensors"])
        key = "gap_contribution_size" if self.share_in_prior_sd else "gap_contribution"
        self.share = np.array([[np.nan if x.get(key) is None else float(np.linalg.norm(x[key]))
                                for x in step["sensors"]] for step in self.steps], dtype=float)
        self.gap_size = np.array([np.nan if s.get("gap_size") is None else s["gap_size"] for s in self.steps],
                                 dtype=float)
        self.reproduced = [s.get("reproduced") for s in self.steps]             # True, False or None (no y)
        rule = self.summary.get("rank_rule", self.steps[0].get("rank_rule") if self.steps else None)
        self.rule_name = rule.get("name") if isinstance(rule, dict) else None


def audit_summary_paragraphs(run_audit: dict) -> list[str]:
    """The plain-words verdict of a run audit, computed from its steps."""
    a = AuditData(run_audit)
    out = []
    with_y = np.isfinite(a.gap)
    exact, held = int(a.step_exact.sum()), int(a.step_held.sum())
    measured = int(with_y.sum())
    reproduced = int(sum(r is True for r in a.reproduced))
    if measured:
        head = (f"DMF reproduced CMF at all {_plural(measured, 'step')} with y" if reproduced == measured else
                f"DMF differed from CMF beyond rounding at {measured - reproduced} of the {_plural(measured, 'step')} "
                "with y")
        head += f" (of {_plural(a.T, 'step')} in the run)" if measured < a.T else ""
        head += (f"; DMF was exact at {exact} of the {a.T} steps and the rank condition held at {held}"
                 if exact < a.T or held < a.T else "; every step exact, the rank condition held at every one")
    else:
        head = (f"DMF is exact at {exact} of {_plural(a.T, 'step')} of the run and the rank condition held at {held}"
                if exact < a.T else f"DMF is exact at all {_plural(a.T, 'step')} of the run"
                + ("" if held == a.T else f" (the rank condition failed at {a.T - held}, exact anyway)"))
    if with_y.any():
        t = int(np.nanargmax(a.gap))
        head += f"; largest observed gap {_g(a.gap[t])} at k = {a.ks[t]}" + (
            f" ({_g(a.gap_size[t])} prior standard deviations)" if np.isfinite(a.gap_size[t]) else "")
    else:
        head += "; no step carries y, so the gap itself cannot be evaluated (only how large it can be)"
    out.append(head + ".")
    for m in range(a.n):
        lost = ~a.full[:, m]
        too_many = bool(np.all(a.cols[:, m] > a.rows[:, m]))
        if not lost.any() and not too_many:
            continue
        l, D = int(a.cols[0, m]), int(a.rows[0, m])
        when = "at every step" if lost.all() else f"at k = {integer_ranges(np.asarray(a.ks)[lost])}"
        text = f"Sensor {m} lost full column rank {when}" if lost.any() else f"Sensor {m}"
        if too_many:
            text += (f"{':' if lost.any() else ''} it has {l} outputs and the state {D} — l_m > D: the rank condition "
                     "can never hold for this sensor")
        bad = lost & ~a.exact[:, m]
        if lost.any():
            text += "; " + _exact_anyway_words(int((lost & a.exact[:, m]).sum()), int(lost.sum()))
        if bad.any():
            shares = a.share[bad, m]
            if np.isfinite(shares).any():
                unit = " prior standard deviations" if a.share_in_prior_sd else " (state units)"
                text += f" (its share of the gap up to {_g(np.nanmax(shares))}{unit})"
            text += f"; its repair message, {_repair_words(a.repair[bad, m])} per step, restores CMF"
        out.append(text + ".")
    rule = a.summary.get("rank_rule", a.steps[0].get("rank_rule") if a.steps else None)
    out.append(f"Rank verdicts decided by the {rank_rule_text(rule)}.")
    return out


def run_audit_sections(run_audit: dict, fig_dir: Path) -> list[Section]:
    from gpfverify.report import equivalence_figures as ef

    a = AuditData(run_audit)
    labels = [f"sensor {m}" for m in range(a.n)]
    head = Section("summary", "Run audit: does DMF reproduce CMF?")
    head.add(*[Paragraph(p) for p in audit_summary_paragraphs(run_audit)])
    rows = []
    for m in range(a.n):
        rows.append([m, int(a.cols[0, m]), "yes" if a.cols[0, m] > a.rows[0, m] else "no",
                     f"{int(a.full[:, m].sum())} of {a.T}", f"{int(a.exact[:, m].sum())} of {a.T}",
                     _g(float(np.nanmax(a.share[:, m]))) if np.isfinite(a.share[:, m]).any() else "—",
                     int(a.repair[:, m].max()) if a.T else 0,
                     _g(float(np.nanmin(a.sigma_min[:, m])), 3)]
                    + ([_g(float(np.nanmin(a.canonical[:, m])), 3)] if a.canonical is not None else []))
    head.add(Table(["sensor", "outputs l_m", "l_m > D", "steps full rank", "steps exact",
                    "largest share of gap" + (" (prior sd)" if a.share_in_prior_sd else " (state units)"),
                    "largest repair size", "smallest singular value of C_xy^m"]
                   + (["smallest canonical correlation"] if a.canonical is not None else []), rows,
                   f"Sensors (state dimension D = {int(a.rows[0, 0]) if a.n else '?'})"))
    figs = Section("figures", "Per step")
    inexact = ~a.step_exact
    if np.isfinite(a.gap).any():
        gap = np.where(np.isfinite(a.gap), a.gap, 0.0)[None, :]
        pred = np.where(np.isfinite(a.predicted), a.predicted, 0.0)[None, :]
        path, _ = ef.plot_gap(a.ks, gap, None, inexact[None, :], fig_dir / "gap.png", predicted=pred,
                              quantity=ef.GAP_IN_STATE_UNITS)
        figs.add(Figure(path, "‖μ_DMF − μ_CMF‖ per step (solid) against the closed-form predicted gap "
                              "−Σ_m G_m C_y^m N_m r_m (dotted; hidden under the solid line where it explains the gap), "
                              "log scale; "
                              "circles: steps judged not exact"))
    figs.add(Figure(ef.plot_verdict_strip(a.ks, a.full[None], a.exact[None], labels, fig_dir / "verdicts.png",
                                          "this run"),
                    "Rank verdict and exactness per step and sensor: green full column rank, amber rank lost but "
                    "exact anyway, red not exact"))
    if a.repair.any():
        figs.add(Figure(ef.plot_repair(a.ks, a.repair, labels, fig_dir / "repair.png"),
                        "Repair message size per step and sensor (numbers the sensor would add to restore CMF)"))
    canonical_rule = a.rule_name == "canonical"
    if a.canonical is not None:
        threshold = _rule_threshold(a.summary.get("rank_rule")) if canonical_rule else None
        figs.add(Figure(ef.plot_min_per_sensor(a.ks, a.canonical, labels, fig_dir / "canonical.png",
                                               "smallest canonical correlation",
                                               "smallest canonical correlation"
                                               + (" and the rank rule's threshold τ (dashed)" if canonical_rule
                                                  else ""),
                                               threshold, "threshold τ"),
                        "Smallest canonical correlation of state and output per step and sensor (unit-free)"
                        + (": the canonical rank rule in force decides on these — a direction whose correlation is "
                           "at or below τ (dashed) is dropped" if canonical_rule else
                           ": what the canonical rule would decide on; the rule in force decides on the singular "
                           "values below")))
    if np.isfinite(a.sigma_min).any():
        figs.add(Figure(ef.plot_min_per_sensor(a.ks, a.sigma_min, labels, fig_dir / "singular-values.png",
                                               "σ_min(C_xy^m)", "smallest singular value of C_xy^m"
                                               + ("" if canonical_rule else " and its rank tolerance (dashed)"),
                                               None if canonical_rule else a.tol, "tolerance"),
                        "Smallest singular value of each sensor's cross covariance C_xy^m per step"
                        + (" (in the case's units; the canonical rule in force does not decide on it: see the "
                           "canonical correlations above)" if canonical_rule else
                           ", and the rank tolerance of the rule in force (dashed): below it the rank verdict drops "
                           "that direction")))
    step_rows = [[s.get("k"), "yes" if s["condition_holds"] else "no", "yes" if s["exact"] else "no",
                  _g(s["gap_norm"], 3) if s.get("gap_norm") is not None else "—",
                  _g(s["gap_size"], 3) if s.get("gap_size") is not None else "—",
                  _g(s["gap_bound"], 2) if s.get("gap_bound") is not None else "—",
                  ", ".join(str(x["index"]) for x in s["sensors"] if not x["full_column_rank"]) or "none",
                  "; ".join(s.get("notes") or [])] for s in a.steps if not (s["exact"] and s["condition_holds"])]
    if step_rows:
        figs.add(Table(["k", "rank condition", "exact", "‖gap‖ (state units)", "gap (prior sd)",
                        "rounding bound (prior sd)", "sensors without full rank", "notes"],
                       step_rows[:MAX_STEP_ROWS], f"Steps where the rank condition failed or DMF is not exact "
                       f"({len(step_rows)} of {a.T})"))
    summary = a.summary
    if summary:
        figs.add(Code(json.dumps({k: v for k, v in summary.items() if k != "sensors"}, indent=1, default=str)))
    return [head, figs]


def write_run_audit_report(run_audit: dict, out_dir: Path) -> Path:
    """``out_dir/audit.json`` (the run audit as given), ``README.md``, ``report.html`` and
    ``figures/*.png`` for ``gpfverify audit RUN --out DIR``; returns the HTML path."""
    title = "Run audit: DMF vs CMF per step"

    def build(tmp: Path) -> dict[str, str]:
        sections = run_audit_sections(run_audit, tmp / FIGURES) + [provenance_section()]
        return {"audit.json": json.dumps(run_audit, indent=1, default=_json_default),
                "README.md": _with_title(title, _markdown(sections, tmp)), "report.html": to_html(sections, title)}

    return _publish(Path(out_dir), build)


def _json_default(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")
