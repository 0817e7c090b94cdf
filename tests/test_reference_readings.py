"""The committed reference pages of the particle filters keep the readings their verdicts rest on.

A verdict that goes against a paper is only as good as the readings of its unstated choices that
were tried and the filters it compares: on the SINS/GPS page every claim that is not held was tried
under at least two interpretations, the mis-specified Q among them for the paper's own claims; on
the particle-flow page the Table-1 grid ran on the second 1-D model at the paper's run count, every
Table-1 / Fig. 1 claim carries its verdict under that model, and a NOT held states that the filters
it compares records their health checks; on the TBD page the SNR-gain claim was read under both
other birth proposals with every detection definition. These read the committed ``results.json``
files, so a page made again without those readings fails here.
"""

from __future__ import annotations

import json
from pathlib import Path

from gpfverify.contract.claims import AS_RUN, ClaimRecord, read_claims
from gpfverify.papers.gpsr_upf.contract import Q_MISSPECIFIED
from gpfverify.papers.tbd.contract import BIRTH_INTERPRETATIONS, DETECTION_INTERPRETATIONS
from gpfverify.papers.particle_flow import pff1d_experiment as pff1d

REFERENCE = Path(__file__).resolve().parents[1] / "reports" / "reference"


def _claims(relative: str) -> list[ClaimRecord]:
    return read_claims(json.loads((REFERENCE / relative).read_text(encoding="utf-8")))


def _tried(claim: ClaimRecord) -> dict[str, dict]:
    return {i.name: i.params for i in claim.interpretations if i.name != AS_RUN}


def test_sins_gps_claims_not_held_were_tried_under_two_readings_the_misspecified_q_among_them():
    claims = _claims("sins-gps/run/results.json")
    assert claims
    for claim in claims:
        if claim.verdict != "held" and not claim.needs:  # a claim not judged for want of data says what it needs
            assert len(_tried(claim)) >= 2, f"{claim.id} ({claim.verdict}) was tried under {list(_tried(claim))}"
    papers = [c for c in claims if c.id.startswith("sins-gps/reduction-")]
    assert len(papers) == 3
    for claim in papers:
        assert any(params.items() >= Q_MISSPECIFIED.items() for params in _tried(claim).values()), claim.id


def test_particle_flow_page_decides_the_table1_claims_on_both_models_at_the_papers_runs():
    claims = _claims("particle-flow/pff1d/results.json")
    second = json.loads((REFERENCE / "particle-flow/pff1d/vdm-gaussian/results.json").read_text(encoding="utf-8"))
    assert second["params"]["table_model"] == "vdm" and second["runs_ok"] >= pff1d.PAPER_RUNS
    table1 = [c for c in claims if c.id.startswith("pff1d/ie-pff-beats-pf-and-edh")]
    assert table1 and all(c.n >= pff1d.PAPER_RUNS for c in claims)
    for claim in table1:
        entry = next(i for i in claim.interpretations if i.name == "vdm-gaussian")
        assert entry.n is None or entry.n >= pff1d.PAPER_RUNS
    for claim in (c for c in claims if c.verdict == "NOT held"):  # every pff1d claim compares flows and PFs
        assert claim.health and all(h.gates for h in claim.health), claim.id  # the checks of every filter compared
        assert claim.parts_gated or not claim.failed_filters, claim.id


def test_tbd_page_reads_the_gain_claim_under_every_birth_proposal_and_detection_definition():
    gain = next(c for c in _claims("tbd/run/results.json") if c.id == "tbd/snr-gain-equal-n")
    tried = _tried(gain)
    for birth in BIRTH_INTERPRETATIONS:
        assert birth.name in tried
        for detection in DETECTION_INTERPRETATIONS:
            assert f"{birth.name}-{detection}" in tried
    runs = {i.n or gain.n for i in gain.interpretations if i.name.startswith("birth-")}
    assert len(runs) == 1  # the birth readings rest on equal run counts


def test_fusion_pages_give_the_batch_their_runs_were_timed_at():
    """The command a fusion page prints remakes its runs as they were timed: ``--batch 1`` when the
    record says no run shared a batch (its timing claims pair per-run CPU times), no option when
    runs were batched (the runner's default batches them)."""
    from gpfverify.papers.fusion.page import command

    alone = {"runs": 1000, "claims": [], "machine_load": {"runs_batched": 0, "largest_batch": 1}}
    batched = {"runs": 1000, "claims": [], "machine_load": {"runs_batched": 1000, "largest_batch": 64}}
    assert " --batch 1 " in command("ct2d-k300-w0.5", alone)
    assert "--batch" not in command("ct2d-k300-w0.5", batched)
    for name in ("ct2d-k300-w0.0698", "ct2d-k300-w0.5", "ct2d-k30-w0.0698", "ct2d-k60-w0.0698", "ungm1d-sweep"):
        folder = REFERENCE / "ct2d" / name.removeprefix("ct2d-") if name.startswith("ct2d") else REFERENCE / "ungm1d"
        results = json.loads((folder / "results.json").read_text(encoding="utf-8"))
        page = (REFERENCE / name.split("-")[0] / "README.md").read_text(encoding="utf-8")
        assert command(name, results) in page, name


def test_particle_flow_page_gives_the_batch_its_runs_were_timed_at():
    """The particle-flow page's commands carry ``--batch 1`` exactly where the committed record says
    its runs were filtered one at a time (or predates batches), and the page prints them."""
    from gpfverify.papers.particle_flow.page import COMMANDS, HERE, made_by

    page = (HERE / "README.md").read_text(encoding="utf-8")
    for name in COMMANDS:
        results = json.loads((HERE / name / "results.json").read_text(encoding="utf-8"))
        made = made_by(name, results)
        assert made in page and f"--runs {results['runs']} " in made, name
        assert ("--batch 1" in made) == (not (results.get("machine_load") or {}).get("runs_batched")), name
    batched = {"runs": 30, "machine_load": {"runs_batched": 30, "largest_batch": 15}}
    assert "--batch" not in made_by("pff1d", batched)
