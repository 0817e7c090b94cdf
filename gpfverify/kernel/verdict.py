"""Statuses and every word of a certificate record, derived from its formal content alone.

A record (one claim of ``certificates.json``) carries ``formal``: a list of parts, each
``{"statement": S, "proof": P, "witness": W}`` or ``{"statement": S, "refutation": C}``;
``negative_controls``: mutated statements ``{"mutant", "statement", "proof" (an attempt),
"instance", "rejected", "false_on_instance"}``; and ``checks``: identities verified by another
route at listed sizes ``{"what", "sizes", "domain", "holds"}``.

* **proved** — every part is a statement whose proof the kernel accepts and whose witness
  satisfies every hypothesis exactly (otherwise it is reported *vacuous*, not proved); its
  conclusion, where it can be evaluated exactly, must hold on the witness too;
* **refuted** — one part, whose counterexample satisfies every hypothesis and falsifies the
  conclusion, evaluated exactly by the kernel;
* **checked** — anything else: identities at listed sizes (never counted as proved), numerical
  agreement, or a proof the kernel did not accept (the detail says why).

:func:`derive` computes status, statement, hypotheses, scope, method and detail; ``gpfverify
prove`` writes them and ``gpfverify prove --check`` recomputes and compares them.
"""

from __future__ import annotations

from dataclasses import dataclass

from gpfverify.kernel.instances import Instance, conclusion_fails, degenerate, refutes, satisfies
from gpfverify.kernel.render import ANY_DIMENSION, hypotheses, instance_text, scope, statement_text
from gpfverify.kernel.rules import check_proof, generator_kind, statement_needs
from gpfverify.kernel.terms import KernelError, Statement, frozen, read_statement

DERIVED = ("status", "statement", "hypotheses", "scope", "method", "detail")


@dataclass(frozen=True)
class Part:
    """The kernel's verdict on one part: "proved", "vacuous", "refuted" or "not proved"."""

    outcome: str
    why: str
    statement: Statement | None  # None when unreadable
    generators: tuple = ()
    steps: int = 0


def judge(part) -> Part:
    """The kernel's verdict on one formal part (never raises on malformed content: it is not proved)."""
    if not isinstance(part, dict) or "statement" not in part or not set(part) <= {"statement", "proof", "witness",
                                                                                  "refutation"}:
        return Part("not proved", "a part is {'statement', 'proof', 'witness'} or {'statement', 'refutation'}", None)
    try:
        st = read_statement(part["statement"])
    except KernelError as e:
        return Part("not proved", f"the statement is malformed: {e}", None)
    try:
        if "refutation" in part:  # a well-formed statement: typed as a proof's is (its side conditions aside)
            statement_needs(st)
            why = refutes(st, Instance(st, part["refutation"]))
            return Part("refuted" if not why else "not proved", why or "", st)
        proof = frozen(part.get("proof"))
        checker = check_proof(st, proof)
        witness = Instance(st, part.get("witness") or {}, proof.get("bases"))
        why = degenerate(witness) or satisfies(st, witness)
        if why:
            return Part("vacuous", f"no witness of the hypotheses: {why}", st)
        if conclusion_fails(st, witness):
            return Part("not proved", "the conclusion fails at the witness (a kernel error: refused)", st)
        used = sorted({str(generator_kind(e.get("gen"))) for step in proof["steps"] for part in ("by", "then")
                       if isinstance(step.get(part), tuple) for e in step[part]}
                      | {f"{k} substitution" for step in proof["steps"] for sub in step.get("subst", ())
                         for k in ("det", "exp") if k in sub})
        return Part("proved", "", st, tuple(used), len(checker.steps))
    except KernelError as e:
        return Part("not proved", str(e), st)
    except (TypeError, KeyError, AttributeError, IndexError, ValueError, RecursionError) as e:
        return Part("not proved", f"malformed: {type(e).__name__}: {e}", st)


def _control(control) -> tuple[bool, bool]:
    """(the kernel rejects the attempt, the instance refutes the mutant)."""
    part = judge({"statement": control.get("statement"), "proof": control.get("proof") or {"steps": []},
                  "witness": control.get("instance")})
    refuted = judge({"statement": control.get("statement"), "refutation": control.get("instance")})
    return part.outcome != "proved", refuted.outcome == "refuted"


def control_outcomes(record: dict) -> list[tuple[str, bool, bool]]:
    return [(str(c.get("mutant")), *_control(c)) for c in record.get("negative_controls", ())
            if isinstance(c, dict) and "statement" in c]


def derive(record: dict) -> dict:
    """Every derived field of a record with formal parts, or of a listed-size check record."""
    parts = [judge(p) for p in record.get("formal", ())]
    checks = [c for c in record.get("checks", ()) if isinstance(c, dict)]
    statements = [p.statement for p in parts if p.statement is not None]
    label = (lambda k: f"({k + 1}) ") if len(statements) > 1 else (lambda k: "")
    statement = " ".join(label(k) + statement_text(s) for k, s in enumerate(statements))
    hyps = [h for s in statements for h in hypotheses(s) if h]
    lines, status, scope_text = [], "checked", ""
    if parts and all(p.outcome == "proved" for p in parts):
        status = "proved"
        scopes = {scope(s) for s in statements}
        scope_text = scopes.pop() if len(scopes) == 1 else "; ".join(sorted(scopes))
        for k, (p, raw) in enumerate(zip(parts, record["formal"])):
            lines.append(f"{label(k)}Kernel-checked: {p.steps} step{'s' if p.steps != 1 else ''} from the generators "
                         f"{', '.join(p.generators)}; witness at {instance_text(raw.get('witness') or {})} "
                         "satisfies every hypothesis exactly.")
        method = "kernel-checked certificate (ideal membership in the declared theory)"
    elif len(parts) == 1 and parts[0].outcome == "refuted":
        status = "refuted"
        at = instance_text(record["formal"][0]["refutation"])
        scope_text = f"counterexample at {at}"
        lines.append(f"Counterexample at {at}: every hypothesis holds exactly and the conclusion fails (evaluated by "
                     "the kernel).")
        method = "exact counterexample evaluated by the kernel"
    else:
        failing = [f"{label(k)}{p.outcome}: {p.why}" for k, p in enumerate(parts) if p.outcome != "proved"]
        if failing:
            lines.append("NOT PROVED: " + "; ".join(failing))
        sizes = sorted({s for c in checks for s in c.get("sizes", ())})
        scope_text = "checked at " + ", ".join(sizes) + " (not proved)" if sizes else "not proved"
        method = "identities at listed sizes (not a proof)" if checks else "not proved"
        if not statements:
            statement = "; ".join(str(c.get("what")) for c in checks)
            hyps = sorted({d for c in checks for d in c.get("domain", ())})
    for c in checks:
        lines.append(f"{'Also checked' if status == 'proved' else 'Checked'} at {', '.join(c.get('sizes', ()))} "
                     f"(exact, another route, not a proof): {c.get('what')} — {'holds' if c.get('holds') else 'FAILS'}"
                     + (f"; domain: {'; '.join(c.get('domain', ()))}" if c.get("domain") else "") + ".")
    outcomes = control_outcomes(record)
    if outcomes:
        lines.append(f"Negative controls: {sum(r and f for _, r, f in outcomes)} of {len(outcomes)} mutated statements "
                     "refused by the kernel and refuted by it on an exact instance.")
    return {"status": status, "statement": statement, "hypotheses": hyps, "scope": scope_text or ANY_DIMENSION,
            "method": method, "detail": " ".join(lines)}


def check_record(record) -> list[str]:
    """What the kernel finds wrong with a record of a certificate file ([] when it accepts it)."""
    if not isinstance(record, dict) or not isinstance(record.get("claim"), str):
        return ["not a certificate record"]
    claim = record["claim"]
    if "formal" not in record and "checks" not in record:
        return [] if record.get("status") == "checked" else [
            f"{claim}: status {record.get('status')!r} without formal content (only 'checked' needs no kernel)"]
    derived = derive(record)
    problems = [f"{claim}: '{k}' is {str(record.get(k))[:60]!r}, the kernel derives {str(derived[k])[:60]!r}"
                for k in DERIVED if record.get(k) != derived[k]]
    if "expected" in record and record["expected"] != derived["status"]:
        problems.append(f"{claim}: meant to be {record['expected']!r}, the kernel derives {derived['status']!r}")
    for c in record.get("negative_controls", ()):
        if not isinstance(c, dict) or "statement" not in c:
            problems.append(f"{claim}: a negative control without a formal statement")
            continue
        rejected, false = _control(c)
        if (c.get("rejected"), c.get("false_on_instance")) != (rejected, false):
            problems.append(f"{claim}: negative control {c.get('mutant')!r}: recorded rejected={c.get('rejected')}, "
                            f"false_on_instance={c.get('false_on_instance')}; the kernel finds {rejected}, {false}")
    return problems


__all__ = ["DERIVED", "Part", "check_record", "control_outcomes", "derive", "judge"]
