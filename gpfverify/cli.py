"""Command line: parse, call, print. User errors exit with status 2 and one line on stderr.

Each subcommand lives in its own module under :mod:`gpfverify.commands` with
``add_arguments(parser)`` and ``run(args) -> int``; modules are imported only when their command
runs, so ``gpfverify --help`` stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import signal
import sys

from gpfverify import __version__
from gpfverify.errors import GpfverifyError
from gpfverify.runtime import default_single_blas_thread

#: command name -> (module, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "report": ("gpfverify.commands.report", "build the verification report (quick profile by default)"),
    "reproduce": ("gpfverify.commands.reproduce", "run one of the papers' experiments"),
    "props": ("gpfverify.commands.props", "run the property-based test suite and write a summary"),
    "audit": ("gpfverify.commands.audit", "rank-condition audit of a fusion-case file"),
    "fuse": ("gpfverify.commands.fuse", "fuse a fusion-case file with one method (cmf, dmf, cc, ci, rcc-ci, ...)"),
    "prove": ("gpfverify.commands.prove", "run the symbolic proofs and casadi cross-checks, write certificates"),
}


class OneLineParser(argparse.ArgumentParser):
    """argparse that reports a usage error as one line and exit status 2."""

    def error(self, message: str):  # noqa: D401 - argparse API
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(prog="gpfverify", description="Gaussian-process filters and multisensor fusion: implemented, verified, reproduced.")
    parser.add_argument("--version", action="version", version=f"gpfverify {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=OneLineParser)
    sub.required = True
    for name, (module, help_text) in COMMANDS.items():
        sub.add_parser(name, help=help_text, add_help=False)
    return parser


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    default_single_blas_thread()  # before any command imports numpy (see gpfverify.runtime)
    signal.signal(signal.SIGTERM, _interrupt)  # `kill` stops cleanly, like Ctrl-C
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    known, rest = parser.parse_known_args(argv[:1] if argv and argv[0] in COMMANDS else argv)
    module = importlib.import_module(COMMANDS[known.command][0])
    sub = OneLineParser(prog=f"gpfverify {known.command}", description=COMMANDS[known.command][1])
    module.add_arguments(sub)
    args = sub.parse_args(argv[1:])
    try:
        return int(module.run(args) or 0)
    except GpfverifyError as exc:
        print(f"gpfverify {known.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"gpfverify {known.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
