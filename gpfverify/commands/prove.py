"""``gpfverify prove --out DIR``: run the proofs and casadi cross-checks, write
``DIR/certificates.json`` (CONTRACT.md) and a readable ``DIR/README.md``.

``gpfverify prove --check CERT.json`` re-checks a certificate file with the kernel alone
(:mod:`gpfverify.kernel`, nothing of the proof search): exit 0 when the kernel derives every
status, statement, scope and negative control the file records, 1 with one line per problem
otherwise, 2 with one line for a file that is not a certificate file."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from gpfverify.cli import non_negative_int
from gpfverify.errors import InputError
from gpfverify.outputs import add_wait_argument, out_path, output_folder
from gpfverify.streams import diagnostics


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=out_path, help="output folder (required unless --check)")
    parser.add_argument("--check", type=Path, metavar="CERT.json",
                        help="re-check a certificate file with the kernel alone (no proof search)")
    add_wait_argument(parser)
    parser.add_argument("--size", choices=("small", "large"), default="large",
                        help="listed sizes of the checks by another route: small (seconds, as in the test suite) or "
                             "large (minutes; default)")
    parser.add_argument("--only", nargs="+", metavar="CLAIM",
                        help="run only these claims (no casadi cross-checks); an unknown name lists the claims")
    parser.add_argument("--no-casadi", action="store_true", help="skip the casadi cross-checks")
    parser.add_argument("--seed", type=non_negative_int, default=1, help="root seed of the cross-checks' random inputs")


def run(args: argparse.Namespace) -> int:
    if args.check is not None:
        return check(args.check)
    if args.out is None:
        raise InputError("--out is required (or --check CERT.json)")
    from gpfverify.report.render import to_markdown
    from gpfverify.report.proofs import render
    from gpfverify.symbolic.claims import run_claims
    from gpfverify.symbolic.crosscheck import run_crosschecks

    progress = lambda text: print(text, file=diagnostics())  # noqa: E731
    with output_folder(args.out, keep=False, wait=args.wait) as stage:
        certificates: list = run_claims(args.size, args.only, progress)
        if not args.no_casadi and not args.only:
            certificates += run_crosschecks(args.size, seed=args.seed, progress=progress)
        from gpfverify.provenance import current

        provenance = current()  # certificates.json is a list (CONTRACT.md): every record carries it
        records = [{**c.to_json(), "provenance": provenance} for c in certificates]
        (stage / "certificates.json").write_text(json.dumps(records, indent=1, ensure_ascii=False), encoding="utf-8")
        (stage / "README.md").write_text(to_markdown(render(records), stage), encoding="utf-8")
    summary = ", ".join(f"{c.claim}: {c.status}" for c in certificates)
    print(f"{len(certificates)} certificates -> {args.out / 'certificates.json'} ({summary})")
    failures = [(c.claim, f) for c in certificates for f in c.failures]
    for claim, failure in failures:  # CONTRACT.md: a negative control that is not rejected fails the run
        print(f"NOT A PROOF: {claim}: {failure}", file=diagnostics())
    return 1 if failures else 0


def check(path: Path) -> int:
    """The kernel's re-check of a certificate file."""
    from gpfverify.kernel.terms import read_json
    from gpfverify.kernel.verdict import check_record

    try:
        records = read_json(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as e:
        raise InputError(f"{path} is not JSON: {e}") from None
    if not isinstance(records, list) or not records or not all(
            isinstance(r, dict) and isinstance(r.get("claim"), str) and isinstance(r.get("status"), str)
            for r in records):
        raise InputError(f"{path} is not a certificate file (a list of records with 'claim' and 'status')")
    problems = [p for r in records for p in check_record(r)]
    for p in problems:
        print(f"REJECTED: {p}", file=diagnostics())
    kernel = sum(1 for r in records if "formal" in r or "checks" in r)
    print(f"{path}: {len(records)} records, {kernel} derived by the kernel: "
          + ("every status, statement and scope confirmed" if not problems else f"{len(problems)} problems"))
    return 1 if problems else 0

