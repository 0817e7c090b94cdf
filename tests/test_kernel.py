"""The kernel on its own: its rules accept what they should and nothing else, every hand edit of
a certificate file is rejected, ``gpfverify prove --check`` needs nothing but the kernel, and
the trust base stated in docs/proofs.md is the kernel's real size."""

from __future__ import annotations

import ast
import copy
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
import sympy as sp

from gpfverify.cli import main
from gpfverify.kernel.instances import Instance
from gpfverify.kernel.normal import Context
from gpfverify.kernel.rules import check_proof
from gpfverify.kernel.terms import KernelError, frozen, read_statement
from gpfverify.kernel.verdict import check_record, derive
from gpfverify.symbolic import fusion_claims as fc
from gpfverify.symbolic.formal import Declare, I, Sum, eq, every, spd
from tests.kernel_helpers import instance, is_refuted, matrix, outcome, roundtrip

ROOT = Path(__file__).resolve().parent.parent
KERNEL = ROOT / "gpfverify" / "kernel"


@pytest.fixture(scope="module")
def records() -> dict:
    """Certificates of the claims the edits below start from, as read back from a file."""
    return {c.claim: roundtrip(c.to_json()) for c in (fc.prove_prop1("small"), fc.prove_kernel_inclusion("small"),
                                                       fc.prove_full_rank_needs_l_le_d("small"),
                                                       fc.refute_exact_without_condition("small"))}


# ---- normal forms ----------------------------------------------------------------------------------------

def _context(**letters):
    d = Declare()
    d.sizes("n", "l", "N")
    d.index_set("J", "N")
    d.family_size("k", "J")
    d.partition("S", "J", "l", "k[#]")
    for name, (rows, cols) in letters.items():
        d.matrix(name, rows, cols)
    d.conclude(eq(I("n"), I("n")))
    st = read_statement(frozen(d.json()))
    return Context(st), st


def test_the_normal_form_identifies_exactly_the_ring_and_transpose_laws():
    ctx, _ = _context(A=("n", "l"), B=("l", "n"), x=("n", 1), y=("n", 1))
    scope = ctx.scope()
    nf = lambda t: ctx.nf(frozen(t), scope)  # noqa: E731
    a, b, x, y = (("var", v) for v in ("A", "B", "x", "y"))
    assert nf(("T", ("*", a, b))) == nf(("*", ("T", b), ("T", a)))
    assert nf(("*", ("T", x), a, b, y)) == nf(("*", ("T", y), ("T", b), ("T", a), x))  # a 1 × 1 word is a number
    assert nf(("*", a, b)) != nf(("T", ("*", a, b)))  # no letter is its own transpose unless declared so
    assert nf(("T", ("pinv", a))) == nf(("pinv", ("T", a)))
    assert nf(("*", a, ("pinv", a), a)) != nf(a)  # Penrose is a generator, not built in
    with pytest.raises(KernelError, match="ill-typed"):
        nf(("*", a, a))


def test_sums_move_constant_factors_count_and_sift_selectors():
    ctx, _ = _context(G=("n", "l"))
    scope = ctx.scope()
    nf = lambda t: ctx.nf(frozen(t), scope)  # noqa: E731
    g = ("var", "G")
    s_i, s_j = ("sel", "S", "i"), ("sel", "S", "j")
    assert nf(("sum", "i", "J", ("*", g, s_i, ("T", s_i), ("T", g)))) == nf(("sum", "j", "J", ("*", g, s_j, ("T", s_j),
                                                                                                  ("T", g))))
    assert nf(("sum", "i", "J", ("I", "n"))) == nf(("*", ("size", "N"), ("I", "n")))  # Σ_i c = N c
    sifted = ("sum", "i", "J", ("sum", "j", "J", ("*", g, s_i, ("T", s_i), s_j, ("T", s_j), ("T", g))))
    assert nf(sifted) == nf(("sum", "i", "J", ("*", g, s_i, ("T", s_i), ("T", g))))  # S_iᵀS_j = δ_ij I
    with pytest.raises(KernelError, match="change size"):
        nf(("sum", "i", "J", ("I", "k[i]")))
    with pytest.raises(KernelError, match="already in use"):
        nf(("sum", "i", "J", ("sum", "i", "J", ("I", "n"))))
    with pytest.raises(KernelError, match="det of a sum"):  # as docs/proofs.md says: not supported
        nf(("*", ("det", ("sum", "i", "J", ("*", s_i, ("T", s_i)))), ("sum", "j", "J", ("*", g, s_j, ("T", s_j)))))


def test_an_indexed_size_is_not_a_number_and_sizes_are_never_negative():
    ctx, _ = _context()
    with pytest.raises(KernelError):
        ctx.nf(("sum", "i", "J", ("tr", ("I", "k[i]"))), ctx.scope())
    d = Declare()
    d.sizes("n")
    d.param("ρ")
    d.index_set("J", "ρ")  # counted by a parameter: Σ_i I would be ρ I
    d.conclude(eq(Sum("i", "J", I("n")), I("n")))
    st = read_statement(frozen(d.json()))
    with pytest.raises(KernelError, match="unknown size symbol"):
        Context(st).nf(st.conclusion[0][1], {})
    for bad in ("n - 1", "-1", -2, "n + -l"):
        d = Declare()
        d.sizes("n")
        d.matrix("A", bad, 1)
        d.conclude(eq(I("n"), I("n")))
        with pytest.raises(KernelError):
            read_statement(frozen(d.json()))


def test_an_index_is_renamed_in_every_size_however_it_is_written():
    from gpfverify.kernel.rules import substitute_pred
    from gpfverify.kernel.terms import substitute

    assert substitute(("I", "l[ m ] + 2*l[m]"), index=("m", "j")) == ("I", "3*l[j]")
    assert substitute(("I", "l[k]"), index=("m", "j")) == ("I", "l[k]")
    renamed = substitute_pred(("forall", (("y", "l[m]", 1),), ("=", ("var", "y"), ("var", "y"))), index=("m", "j"))
    assert renamed[1] == (("y", "l[j]", 1),)
    assert substitute_pred(("<=", "l[m]", "D"), index=("m", "j")) == ("<=", "l[j]", "D")


# ---- instances -------------------------------------------------------------------------------------------

def test_instances_decide_spd_rank_and_every_measurement_exactly():
    d = Declare()
    d.sizes("n")
    c = d.matrix("C", "n", "n")
    d.assume(spd(c))
    d.conclude(eq(c, c.T))
    st = read_statement(frozen(d.json()))
    holds = lambda m: Instance(st, frozen(instance({"n": 2}, {"C": matrix(m)}))).holds(st.hypotheses[0])  # noqa: E731
    assert holds([[2, 1], [1, 1]]) and not holds([[1, 2], [2, 1]]) and not holds([[1, 1], [0, 1]])
    # "for every y": the kernel substitutes symbols for y, and DMF − CMF must cancel identically
    statement = fc.necessity_of_full_rank_statement()
    st = read_statement(frozen(statement))
    exact = fc._one_sensor(fc._RANK_ONE * fc._CY.inv(), measurement=False, free={"j": 1})
    broken = fc._one_sensor(sp.eye(2), measurement=False, free={"j": 1})
    assert Instance(st, frozen(exact)).holds(st.hypotheses[1])
    assert not Instance(st, frozen(broken)).holds(st.hypotheses[1])


def test_a_matrix_with_no_rows_has_its_declared_width():
    d = Declare()
    d.sizes("N")
    d.index_set("J", "N")
    d.family_size("l", "J")
    z = d.matrix("z", "l[#]", 1, over="J")
    d.conclude(eq(z["j"].T * z["j"], z["j"].T * z["j"]))
    d.free_index("j", "J")
    st = read_statement(frozen(d.json()))
    inst = Instance(st, frozen({"sizes": {"N": 2}, "indexed_sizes": {"l": [0, 1]}, "free_indices": {"j": 1},
                                "values": {"z": [[], [[1]]]}}))
    assert inst.values[("z", 1)].shape == (0, 1) and inst.values[("z", 2)].shape == (1, 1)
    assert inst.holds(st.conclusion[0])


def test_for_every_x_is_decided_only_over_the_rationals():
    from gpfverify.kernel.instances import NotEvaluable, _exactly_zero

    x = sp.Symbol("x")
    assert _exactly_zero((x + 1) ** 2 - x ** 2 - 2 * x - 1) and not _exactly_zero(x / 2)
    with pytest.raises(NotEvaluable):  # zero (3 + 2√2 = (1 + √2)²), which cancel does not see
        _exactly_zero((sp.sqrt(3 + 2 * sp.sqrt(2)) - 1 - sp.sqrt(2)) * x)


def test_a_proved_statement_needs_a_witness_and_its_conclusion_must_hold_there():
    statement = fc.prop1_statement()
    proof = fc.attempt(statement, fc._templates(full_rank_hyp=1))
    assert outcome(statement, proof, fc.instance(1)) == "proved"
    assert outcome(statement, proof, fc.instance(1, deficient=True)) == "vacuous"
    assert outcome(statement, proof, None) != "proved"


def test_the_side_steps_and_substitutions_accept_only_what_they_state():
    checker = check_proof(read_statement(frozen(fc.prop1_statement())),
                          frozen(fc.attempt(fc.prop1_statement(), fc._templates(full_rank_hyp=1))))
    assert set(checker.steps) == {"s1"}


# ---- hand-edited certificate files ---------------------------------------------------------------------------

def _edit(record, change):
    edited = copy.deepcopy(record)
    change(edited)
    return edited


def _first_step(record):
    return record["formal"][0]["proof"]["steps"][0]


EDITS = {
    "a step removed": ("prop1-full-column-rank", lambda r: r["formal"][0]["proof"]["steps"].clear()),
    "an entry removed": ("prop1-full-column-rank", lambda r: _first_step(r)["by"].pop(0)),
    "a rule renamed": ("prop1-full-column-rank", lambda r: _first_step(r)["by"][0].__setitem__(
        "gen", {"rank": _first_step(r)["by"][0]["gen"].get("fcr"), "hyp": 1, "index": "i0"})),
    "a generator's hypothesis number changed": ("prop1-full-column-rank", lambda r: [
        e["gen"].__setitem__("hyp", 0) for e in _first_step(r)["by"] if "fcr" in e["gen"]]),
    "a hypothesis swapped": ("prop1-full-column-rank", lambda r: r["formal"][0]["statement"]["hypotheses"].__setitem__(
        1, ["every", "m", "sensor", ["fcr", ["var", "C_y", "m"]]])),
    "a hypothesis removed": ("prop1-full-column-rank", lambda r: r["formal"][0]["statement"]["hypotheses"].pop()),
    "a size made negative": ("prop1-full-column-rank", lambda r: r["formal"][0]["statement"]["variables"]["G"]
                             .__setitem__("rows", "D - 1")),
    "a letter redefined": ("prop1-full-column-rank", lambda r: r["formal"][0]["statement"]["definitions"]
                           .__setitem__("G", {"body": ["0", "D", "L"]})),
    "a definition changed": ("prop1-full-column-rank", lambda r: r["formal"][0]["statement"]["definitions"]["μ_CMF"]
                             .__setitem__("body", ["var", "μ_p"])),
    "the status changed": ("prop1-full-column-rank", lambda r: r.__setitem__("status", "checked")),
    "the statement text changed": ("prop1-full-column-rank", lambda r: r.__setitem__(
        "statement", r["statement"].replace("full column rank", "any rank"))),
    "the scope changed": ("full-rank-needs-l-le-D", lambda r: r.__setitem__("scope", "D ≤ 3")),
    "the conclusion changed": ("full-rank-needs-l-le-D", lambda r: r["formal"][0]["statement"]["conclusion"][0]
                               .__setitem__(1, "l + 1")),
    "a square's weight made negative": ("full-rank-needs-l-le-D", lambda r: _first_step(r)["squares"][0]
                                        .__setitem__(0, -1)),
    "the witness edited off the hypotheses": ("full-rank-needs-l-le-D", lambda r: r["formal"][0]["witness"]["values"]
                                              .__setitem__("A", [[1, 2], [2, 4], [0, 0]])),
    "a generic index removed": ("dmf-exact-iff-kernel-inclusion", lambda r: r["formal"][1]["proof"]["steps"][0]
                                .pop("index")),
    "the counterexample edited": ("dmf-exact-without-condition", lambda r: r["formal"][0]["refutation"]["values"]
                                  .__setitem__("G", [[0, 0], [0, 0]])),
    "a negative control marked accepted": ("prop1-full-column-rank", lambda r: r["negative_controls"][0]
                                           .__setitem__("rejected", False)),
    "a negative control's instance replaced": ("prop1-full-column-rank", lambda r: r["negative_controls"][0]
                                               .__setitem__("instance", fc.instance(1, deficient=True))),
}


@pytest.mark.parametrize("edit", list(EDITS))
def test_a_hand_edited_certificate_is_rejected(records, edit):
    claim, change = EDITS[edit]
    assert check_record(records[claim]) == []
    assert check_record(_edit(records[claim], change)), edit


def test_prove_check_accepts_a_file_and_rejects_its_edits(records, tmp_path, capsys):
    good, bad = tmp_path / "good.json", tmp_path / "bad.json"
    good.write_text(json.dumps(list(records.values()), ensure_ascii=False), encoding="utf-8")
    assert main(["prove", "--check", str(good)]) == 0
    edited = [_edit(records["prop1-full-column-rank"], EDITS["a step removed"][1])]
    bad.write_text(json.dumps(edited, ensure_ascii=False), encoding="utf-8")
    capsys.readouterr()
    assert main(["prove", "--check", str(bad)]) == 1
    assert "REJECTED: prop1-full-column-rank: 'status'" in capsys.readouterr().err


@pytest.mark.parametrize("text", ["not json", "{}", "[]", '[{"claim": "x", "status": "proved", "claim": "y"}]'])
def test_prove_check_refuses_a_malformed_file_with_one_line(tmp_path, capsys, text):
    path = tmp_path / "cert.json"
    path.write_text(text, encoding="utf-8")
    assert main(["prove", "--check", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "error" in err[0]


@pytest.mark.slow
def test_prove_check_loads_the_kernel_and_no_proof_search(records, tmp_path):
    path = tmp_path / "cert.json"
    path.write_text(json.dumps(list(records.values()), ensure_ascii=False), encoding="utf-8")
    code = ("import sys; from gpfverify.cli import main; rc = main(['prove', '--check', sys.argv[1]]); "
            "print(rc, sorted(m for m in sys.modules if m.startswith('gpfverify.symbolic')))")
    out = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "0 []"


# ---- the trust base ----------------------------------------------------------------------------------------

def _kernel_lines() -> dict:
    return {p.name: len(p.read_text(encoding="utf-8").splitlines()) for p in sorted(KERNEL.glob("*.py"))}


def test_the_trust_base_stated_in_the_docs_is_the_kernels_size():
    """docs/proofs.md states the kernel's files and lines; the numbers must be the real ones."""
    doc = (ROOT / "docs" / "proofs.md").read_text(encoding="utf-8")
    lines = _kernel_lines()
    stated = dict(re.findall(r"\| `gpfverify/kernel/(\w+\.py)` \| (\d+) \|", doc))
    assert {k: int(v) for k, v in stated.items()} == lines
    assert f"{sum(lines.values())} lines" in doc


def test_the_kernel_imports_nothing_of_gpfverify_but_its_errors():
    for path in KERNEL.glob("*.py"):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("gpfverify"):
                allowed = node.module.startswith("gpfverify.kernel") or node.module == "gpfverify.errors"
                assert allowed, (path, node.module)


# ---- what is derived ---------------------------------------------------------------------------------------

def test_every_word_of_a_record_is_derived_and_the_title_decides_nothing(records):
    record = records["prop1-full-column-rank"]
    assert derive(record)["status"] == record["status"] == "proved" and record["scope"] == "any dimension"
    retitled = dict(record, title="DMF = CMF for any rank, in any dimension, proved")
    assert check_record(retitled) == [] and derive(retitled) == derive(record)


def test_a_family_statement_over_no_members_is_not_read_as_one_over_all():
    d = Declare()
    d.sizes("n", "N")
    d.index_set("J", "N")
    c = d.matrix("C", "n", "n", over="J")
    x = d.matrix("X", "n", "n")
    d.assume(every("m", "J", spd(c["m"])))
    d.conclude(eq(Sum("m", "J", c["m"] - c["m"].T), x * 0))
    statement = d.json()
    proof = {"steps": [{"id": "s", "claim": statement["conclusion"][0], "by": []}]}
    witness = instance({"n": 2, "N": 2}, {"C": [sp.eye(2), 2 * sp.eye(2)], "X": sp.zeros(2, 2)})
    assert outcome(statement, proof, witness) == "proved"  # C_mᵀ = C_m for every member: used inside Σ_m
    assert not is_refuted(statement, witness)


def test_the_report_shows_a_record_the_kernel_rejects_as_checked(records):
    from gpfverify.report.inputs import CertificateInfo

    assert CertificateInfo.of(records["prop1-full-column-rank"]).status == "proved"
    shown = CertificateInfo.of(_edit(records["prop1-full-column-rank"], EDITS["a step removed"][1]))
    assert shown.status == "checked" and shown.detail.startswith("REJECTED by the kernel")
    assert shown.scope == "not proved" and shown.method == "not confirmed by the kernel"
    by_hand = {"claim": "x", "statement": "A⁺A = I", "status": "proved", "detail": "", "scope": "any dimension",
               "method": "kernel-checked certificate"}
    shown = CertificateInfo.of(by_hand)  # no word of the record's own reads as a proof
    assert (shown.status, shown.scope, shown.method) == ("checked", "not proved", "not confirmed by the kernel")
    retold = _edit(records["prop1-full-column-rank"], lambda r: r.update(statement="DMF = CMF for any rank"))
    assert CertificateInfo.of(retold).statement == derive(records["prop1-full-column-rank"])["statement"]


def test_hostile_sizes_and_powers_are_refused_not_computed():
    ctx, st = _context(A=("n", "n"))
    big = ("^", ("+", ("tr", ("var", "A")), ("num", 1)), "1000000")
    with pytest.raises(KernelError, match="not expanded"):
        ctx.nf(big, ctx.scope())
    with pytest.raises(KernelError, match="0..64"):
        Instance(st, frozen({"sizes": {"n": 10**6, "l": 1, "N": 0}, "indexed_sizes": {"k": []},
                             "values": {"A": []}}))
    from gpfverify.kernel.terms import number

    for text in ("1e9999999999", "0.5", "1/2/3", " 1", "٣"):  # numbers are integers or 'p/q', nothing else
        with pytest.raises(KernelError, match="a number is"):
            number(text)
    with pytest.raises(KernelError, match="not expanded"):  # 2^(10¹²) would be computed digit by digit
        ctx.nf(("^", ("num", 2), 10 ** 12), ctx.scope())
    with pytest.raises(KernelError, match="every size symbol"):  # true is not a size
        Instance(st, frozen({"sizes": {"n": True, "l": 0, "N": 0}, "indexed_sizes": {"k": []}, "values": {"A": [[1]]}}))
    inst = Instance(st, frozen({"sizes": {"n": 1, "l": 0, "N": 0}, "indexed_sizes": {"k": []}, "values": {"A": [[1]]}}))
    with pytest.raises(KernelError, match="above 256"):
        inst.value(("I", "100000000"), {})
