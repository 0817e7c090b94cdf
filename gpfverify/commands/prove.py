"""``gpfverify prove --out DIR``: run the symbolic proofs and casadi cross-checks, write
``DIR/certificates.json`` (CONTRACT.md) and a readable ``DIR/README.md``."""

from __future__ import annotations

import argparse
import json

from gpfverify.cli import non_negative_int
from gpfverify.outputs import add_wait_argument, out_path, output_folder
from gpfverify.streams import diagnostics


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from gpfverify.symbolic.claims import CLAIMS

    parser.add_argument("--out", type=out_path, required=True, help="output folder")
    add_wait_argument(parser)
    parser.add_argument("--size", choices=("small", "large"), default="large",
                        help="problem sizes: small (seconds, as in the test suite) or large (minutes; default)")
    parser.add_argument("--only", nargs="+", metavar="CLAIM", choices=list(CLAIMS),
                        help=f"run only these sympy claims (no casadi cross-checks): {', '.join(CLAIMS)}")
    parser.add_argument("--no-casadi", action="store_true", help="skip the casadi cross-checks")
    parser.add_argument("--seed", type=non_negative_int, default=1, help="root seed of the cross-checks' random inputs")


def run(args: argparse.Namespace) -> int:
    from gpfverify.report.render import to_markdown
    from gpfverify.report.sections.proofs import render
    from gpfverify.symbolic.claims import run_claims
    from gpfverify.symbolic.crosscheck import run_crosschecks

    progress = lambda text: print(text, file=diagnostics())  # noqa: E731
    with output_folder(args.out, keep=False, wait=args.wait) as stage:
        certificates = run_claims(args.size, args.only, progress)
        if not args.no_casadi and not args.only:
            certificates += run_crosschecks(args.size, seed=args.seed, progress=progress)
        from gpfverify.provenance import current

        provenance = current()  # certificates.json is a list (CONTRACT.md): every record carries it
        records = [{**c.to_json(), "provenance": provenance} for c in certificates]
        (stage / "certificates.json").write_text(json.dumps(records, indent=2), encoding="utf-8")
        (stage / "README.md").write_text(to_markdown(render(records), stage), encoding="utf-8")
    summary = ", ".join(f"{c.claim}: {c.status}" for c in certificates)
    print(f"{len(certificates)} certificates -> {args.out / 'certificates.json'} ({summary})")
    accepted = [(c.claim, m["mutant"]) for c in certificates for m in c.negative_controls if not m["rejected"]]
    if accepted:  # CONTRACT.md: a negative control that is not rejected fails the run
        for claim, mutant in accepted:
            print(f"NOT A PROOF: {claim} accepted the mutated statement {mutant!r}", file=diagnostics())
        return 1
    return 0
