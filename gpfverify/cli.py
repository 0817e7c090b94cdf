"""Command line: parse, call, print. User errors exit with status 2 and one line on stderr.

One error boundary (:func:`main`) for every command: a :class:`~gpfverify.errors.GpfverifyError`
(the user's code failing included, :mod:`gpfverify.usercode`), an operating-system error (a
missing or unwritable file, ``--out`` naming a file, a full disk), undecodable text and input
nested too deeply each end as exit status 2 and exactly one line ``gpfverify COMMAND: error: ...``
on stderr; the notes an exception gathered on its way (what was kept of an interrupted command's
runs) end that same line. A closed output pipe (``gpfverify audit RUN | head -3``) ends as exit
status 2 too (the output is incomplete, as ``set -o pipefail`` should see) but quietly: the reader
closed it on purpose, like ``head`` does, and an error line would only interrupt what it printed.
Numeric options must be finite (``inf``/``nan`` are refused by the parser). Warnings raised while a
command runs (numpy's floating-point RuntimeWarnings, for instance) are collected instead of
printed: dropped when the command fails (its one line says what went wrong), summarised in one
line when it succeeds. Anything else is a bug: one line asking for a report, exit status 1, and
the traceback only with ``GPFVERIFY_DEBUG=1``. Run as a program (:func:`program`), the command
runs in a child process that reports its exit status to gpfverify's (:mod:`gpfverify.supervise`).

Each subcommand lives in its own module under :mod:`gpfverify.commands` with
``add_arguments(parser)`` and ``run(args) -> int``; modules are imported only when their command
runs, so ``gpfverify --help`` stays fast.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import math
import os
import re
import shutil
import signal
import sys
import warnings
from typing import NoReturn

from gpfverify import __version__, provenance, streams, supervise
from gpfverify.errors import GpfverifyError, OutOfMemory
from gpfverify.runtime import default_single_blas_thread
from gpfverify.usercode import Interrupted, forget_interrupts, interrupt_received, marks_interrupts, note_interrupt

#: command name -> (module, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "report": ("gpfverify.commands.report", "build the verification report (quick profile by default)"),
    "reproduce": ("gpfverify.commands.reproduce", "run one of the papers' experiments"),
    "props": ("gpfverify.commands.props", "run the property-based test suite and write a summary"),
    "check": ("gpfverify.commands.check", "check DMF against CMF at every step of your own system (SYSTEM.py:NAME)"),
    "audit": ("gpfverify.commands.audit", "rank-condition audit of a fusion-case file"),
    "fuse": ("gpfverify.commands.fuse", "fuse a fusion-case file with one method (cmf, dmf, cc, ci, rcc-ci, ...)"),
    "prove": ("gpfverify.commands.prove", "run the symbolic proofs and casadi cross-checks, write certificates"),
}


class OneLineParser(argparse.ArgumentParser):
    """argparse that reports a usage error as one line and exit status 2, and takes every option
    by its full name only (``allow_abbrev=False``: ``--train`` is not silently ``--training-start-var``)."""

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def error(self, message: str):  # noqa: D401 - argparse API
        self.exit(2, f"{self.prog}: error: {one_line(message)}\n")

    def _print_message(self, message: str, file=None) -> None:
        """argparse's messages to stderr (usage errors) are gpfverify's diagnostics
        (:func:`gpfverify.streams.diagnostics`), not other code's held output; --help and --version
        go to standard output as argparse prints them."""
        if message:
            (streams.diagnostics() if file is None or file is sys.stderr else file).write(message)

    def parse_args(self, args=None, namespace=None):
        """Parse, then refuse non-finite numbers (argparse's ``float`` accepts inf and nan)."""
        parsed = super().parse_args(args, namespace)
        for action in self._actions:
            value = getattr(parsed, action.dest, None)
            values = value if isinstance(value, list) else [value]
            for v in values:
                if isinstance(v, float) and not math.isfinite(v):
                    flag = action.option_strings[-1] if action.option_strings else action.dest
                    self.error(f"{flag} must be a finite number, got {v}")
        return parsed


_SPHINX_ROLE = re.compile(r":[a-z]+:`~?([^`]+)`")


def plain_help(doc: str | None) -> str | None:
    """A docstring as --help shows it: Sphinx roles (``:mod:`x```) and literals (````x````) as
    their plain text."""
    if doc is None:
        return None
    return _SPHINX_ROLE.sub(r"\1", doc).replace("``", "")


def one_line(text) -> str:
    """``text`` with its line breaks folded, for the single stderr line of an error."""
    return " ".join(str(text).split()) or "(no message)"


def non_negative_int(text: str) -> int:
    """argparse type: an integer >= 0 (seeds)."""
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0, got {value}")
    return value


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1 (run and worker counts)."""
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1, got {value}")
    return value


def fusion_rule(text: str) -> str:
    """argparse type: one fusion rule by any accepted name, as its canonical name
    (:mod:`gpfverify.fusion.names`: ``cw`` -> ``cc``)."""
    from gpfverify.fusion.names import canonical_rule

    try:
        return canonical_rule(text)
    except GpfverifyError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def fusion_rules(text: str) -> tuple[str, ...]:
    """argparse type: comma-separated fusion rules (:func:`fusion_rule` each), each once."""
    return tuple(dict.fromkeys(fusion_rule(name) for name in text.split(",") if name.strip()))


#: the one description of ``--batch`` (check, reproduce)
BATCH_HELP = ("Monte Carlo runs advanced together as arrays, B at a time (default: as many as the memory available "
              "holds, at most 64); each batch is one task for a worker process or a dask cluster, and each run is "
              "saved as it ends (--resume continues run by run). Results are the same bits for every B, --workers "
              "and --scheduler.")


#: the one description of ``--rank-rule`` (check, audit, reproduce)
RANK_RULE_HELP = ("How the rank of each C_xy^m in eq. 35 is decided: canonical[:TAU] (canonical correlations "
                  "of state and sensor output above TAU, default sqrt(eps); unit-free), absolute:TOL "
                  "(singular values above TOL) or numpy (singular values above sigma_max * max(D, l) * eps, "
                  "numpy's and MATLAB's rank()).")


def rank_rule_text(text: str) -> str:
    """argparse type: a rank rule ``canonical[:TAU]``, ``absolute:TOL`` or ``numpy``, checked and
    kept as typed (:func:`gpfverify.fusion.exactness.parse_rank_rule`)."""
    from gpfverify.fusion.exactness import parse_rank_rule

    try:
        parse_rank_rule(text)
    except GpfverifyError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def positive_seconds(text: str) -> float:
    """argparse type: a duration in seconds, > 0 (``--timeout``)."""
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be a number of seconds > 0, got {text}")
    return value


positive_seconds.__name__ = "number of seconds"
non_negative_int.__name__ = "integer >= 0"  # argparse names the type in "invalid ... value"
positive_int.__name__ = "integer >= 1"


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(prog="gpfverify", description="Gaussian-process filters and multisensor fusion: "
                                                         "implemented, verified, reproduced.")
    parser.add_argument("--version", action="version", version=f"gpfverify {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=OneLineParser)
    for name, (_module, help_text) in COMMANDS.items():
        sub.add_parser(name, help=help_text, add_help=False)
    return parser


def command_parser(command: str) -> OneLineParser:
    """The parser of one subcommand (``gpfverify COMMAND ...``), its options added by its module."""
    module = importlib.import_module(COMMANDS[command][0])
    parser = OneLineParser(prog=f"gpfverify {command}", description=COMMANDS[command][1])
    module.add_arguments(parser)
    return parser


@marks_interrupts
def _interrupt(signum, frame):
    """Ctrl-C (SIGINT) and SIGTERM stop the command (:class:`~gpfverify.usercode.Interrupted`);
    from the first one on, further ones are ignored, so that a second Ctrl-C cannot cut short the
    clean-up the first started (stopping the workers, keeping the saved runs, the one
    "interrupted" line). It is recorded too (:func:`~gpfverify.usercode.note_interrupt`): one that
    other code swallows still ends the command as interrupted."""
    note_interrupt()
    _ignore_further_interrupts()
    raise Interrupted


def _user_error(exc: BaseException) -> str | None:
    """The one-line message for an error the user (or the machine) caused, or None for a bug."""
    from gpfverify.memory import advice, out_of_memory

    if isinstance(exc, GpfverifyError) and not isinstance(exc, OutOfMemory):
        return str(exc)
    memory = out_of_memory(exc, near=False)
    if memory is not None:
        return f"out of memory ({memory}); {advice()}"
    if isinstance(exc, shutil.Error) and exc.args and isinstance(exc.args[0], list) and exc.args[0]:
        return _copy_error(exc.args[0])  # copytree's list of (source, destination, why)
    if isinstance(exc, OSError):
        where = " ".join(f"{name}" for name in (exc.filename, exc.filename2) if name is not None)
        return f"{exc.strerror or exc}" + (f": {where}" if where else "")
    if isinstance(exc, UnicodeError):
        return f"not valid UTF-8 text ({exc})"
    if isinstance(exc, RecursionError):
        return "input nested too deeply"
    if isinstance(exc, FloatingPointError):
        return (f"numerical overflow ({exc}): the input's numbers are too large or too small in "
                "combination")
    memory = out_of_memory(exc)  # a bug, unless the process came near its memory limit
    return None if memory is None else f"out of memory ({memory}); {advice()}"


def _copy_error(failures: list) -> str:
    """The first failure of a folder copy (``shutil.Error``: (source, destination, reason) each, the
    reason an OSError as text) and how many files failed."""
    source, _, reason = failures[0] if isinstance(failures[0], tuple) and len(failures[0]) == 3 \
        else (None, None, failures[0])
    code = re.match(r"\[Errno (\d+)\] ", str(reason))
    what = os.strerror(int(code.group(1))) if code else str(reason)
    more = f" (and {len(failures) - 1} more files)" if len(failures) > 1 else ""
    return f"{what}: {source} could not be copied{more}" if source else f"{what}{more}"


def _with_notes(message: str, exc: BaseException) -> str:
    """``message`` followed by the notes ``exc`` gathered (:meth:`BaseException.add_note`)."""
    return "; ".join([message, *getattr(exc, "__notes__", ())])


#: commands that read one user case: a floating-point overflow there is the input's fault
OVERFLOW_IS_INPUT_ERROR = ("audit", "fuse")


def _float_errors(command: str):
    if command not in OVERFLOW_IS_INPUT_ERROR:
        return contextlib.nullcontext()
    import numpy as np

    return np.errstate(over="raise")


def _silence_stdout() -> None:
    """After a broken pipe: point stdout at /dev/null so the interpreter's final flush does not
    print a second error."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):  # no real file descriptor (captured in tests)
        pass


def _occupy_closed_standard_fds() -> None:
    """Point a closed descriptor 0, 1 or 2 (``2>&-``) at /dev/null, so that no file gpfverify opens
    gets its number (a library writing to descriptor 2 would write into that file)."""
    for fd in (0, 1, 2):
        try:
            os.fstat(fd)
        except OSError:
            null = os.open(os.devnull, os.O_RDWR)
            if null != fd:
                os.dup2(null, fd)
                os.close(null)


def _refuse_closed_stdout() -> None:
    """A closed stdout (``>&-``) is refused before anything runs: the result would be lost."""
    if sys.stdout is None:
        raise GpfverifyError("standard output is closed: give the command somewhere to print "
                             "(e.g. >/dev/null)")


#: warning categories handed back to the warnings machinery (hidden by default outside tests)
DEVELOPER_WARNINGS = (DeprecationWarning, PendingDeprecationWarning, ImportWarning)


def _summarise_warnings(command: str, caught: list) -> None:
    """One line for the warnings a successful command raised (numpy's floating-point
    RuntimeWarnings, a solver's accuracy warning); developer warnings are handed back unchanged."""
    shown = [w for w in caught if not issubclass(w.category, DEVELOPER_WARNINGS)]
    for w in caught:
        if issubclass(w.category, DEVELOPER_WARNINGS):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    if shown:
        first = shown[0]
        print(f"gpfverify {command}: note: {len(shown)} warning(s) while running, first: "
              f"{first.category.__name__}: {one_line(first.message)}", file=streams.diagnostics())


def _ignore_further_interrupts() -> None:
    """After the first Ctrl-C or SIGTERM the command is ending (workers stopped, saved runs kept):
    a second one would only interrupt that clean-up with a traceback, so it is ignored."""
    with contextlib.suppress(ValueError):  # not the main thread
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)


def program() -> NoReturn:
    """``gpfverify`` run as a program (the console script, ``python -m gpfverify``): the command runs
    in a child process that reports its exit status as its last act (:mod:`gpfverify.supervise`),
    and this process ends with that status. gpfverify prints through private duplicates of
    descriptors 1 and 2 (:mod:`gpfverify.streams`). Once the command has returned, its status is
    final: Ctrl-C and SIGTERM are held (one that came meanwhile makes it 130), and the ``atexit``
    handlers of other code (a system file's) run after the status is sent, their output dropped and
    unable to end the process with another status. Ends the process."""
    command = "gpfverify"
    try:
        _occupy_closed_standard_fds()  # before the pipe to the child takes a free descriptor
        args = sys.argv[1:]
        command = args[0] if args and args[0] in COMMANDS else "gpfverify"
        supervise.start(command, _keep_abandoned)  # from here on: the process running the command
        held = sys.stderr  # descriptor 2: held by the parent (gpfverify.supervise)
        sys.stdout, sys.stderr = streams.private_streams(supervise.standard_fds())
    except KeyboardInterrupt:  # before the command started (gpfverify.entry's handler)
        with contextlib.suppress(BaseException):
            _say(f"gpfverify {command}: interrupted")
        supervise.HARD_EXIT(130)
    code, returned = 1, False
    try:
        try:
            try:
                code = main(held=held)
                returned = True
            finally:
                signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
        except SystemExit as exc:  # argparse: --help, --version, a usage error (printed already)
            code = exc.code if isinstance(exc.code, int) else int(exc.code is not None)
        except KeyboardInterrupt:  # before the command's own handler, or between its end and the line above
            if returned:
                code = _interrupted_as_it_ended(command)
            else:
                _say(f"gpfverify {command}: interrupted")
                code = 130
        if code == 0 and {signal.SIGINT, signal.SIGTERM} & signal.sigpending():  # a failure's line stands
            code = _interrupted_as_it_ended(command)
    except BaseException as exc:  # noqa: BLE001 - GPFVERIFY_DEBUG=1's traceback, or gpfverify failing outside main
        code = _outside_the_command(command, exc)
    with contextlib.suppress(BaseException):
        code = supervise.finish(command, code)
    with contextlib.suppress(BaseException):
        _run_exit_handlers()
    supervise.HARD_EXIT(code)


def _keep_abandoned(stage: str, out: str, made: list[str]) -> str:
    """For :mod:`gpfverify.supervise`: the saved runs of a staging folder that a killed command
    process left, kept at once (:func:`gpfverify.outputs.keep_abandoned`); what was kept, for the
    end of the one line."""
    from pathlib import Path

    from gpfverify.outputs import keep_abandoned, kept_note

    finished = keep_abandoned(Path(stage), Path(out), [Path(m) for m in made])
    if finished is None:
        return "the runs it had saved are kept for the next command on --out"
    return kept_note(Path(out), finished)


def _outside_the_command(command: str, exc: BaseException) -> int:
    """The exit status, and its one line, of an exception that reached :func:`program`: the
    traceback that ``GPFVERIFY_DEBUG=1`` asked for, or memory running out after the command
    ended (2); anything else is a bug (1)."""
    from gpfverify.memory import advice, out_of_memory

    with contextlib.suppress(BaseException):
        if os.environ.get("GPFVERIFY_DEBUG"):
            import traceback

            streams.diagnostics().write("".join(traceback.format_exception(exc)))
            return 1
        memory = out_of_memory(exc)
        if memory is not None:
            _say(f"gpfverify {command}: error: out of memory ({memory}); {advice()}")
            return 2
        _say(f"gpfverify {command}: internal error: {type(exc).__name__}: {one_line(exc)} (a bug: please report "
             "it; GPFVERIFY_DEBUG=1 shows the traceback)")
    return 1


def _say(line: str) -> None:
    """One line of gpfverify's on its diagnostics, written whole (one write: memory running out
    cannot leave it without its end)."""
    stream = streams.diagnostics()
    stream.write(line + "\n")
    stream.flush()


def _interrupted_as_it_ended(command: str) -> int:
    """A Ctrl-C or SIGTERM that came when the command had completed (or that other code swallowed
    while it ran): exit status 130, never 0, and a line saying the output is complete."""
    _say(f"gpfverify {command}: interrupted as it ended; the command had completed and its output is complete")
    return 130


def _run_exit_handlers() -> None:
    """The ``atexit`` handlers of other code, run once gpfverify's status is sent and its output
    flushed (:func:`program`): what they print is dropped, their exceptions are not shown, and an
    ``os._exit`` among them ends only themselves."""
    import atexit

    def refuse_exit(code: int = 0) -> None:
        raise SystemExit(code)

    sys.stdout = sys.stderr = streams.Diagnostics(None)
    sys.unraisablehook = lambda unraisable: None
    os._exit = refuse_exit  # type: ignore[assignment]
    atexit._run_exitfuncs()


def _unraisable_hook(previous):
    """``sys.unraisablehook`` while a command runs: a Ctrl-C that lands in a weak-reference
    callback or a ``__del__`` is recorded by gpfverify's handler and ends the command as
    interrupted, so it is not printed; anything else goes to ``previous``."""
    def hook(unraisable) -> None:
        if isinstance(unraisable.exc_value, KeyboardInterrupt) and interrupt_received():
            return
        previous(unraisable)

    return hook


def main(argv: list[str] | None = None, held=None) -> int:
    """Run one command (see the module docstring) in this process, with gpfverify's own streams
    (:func:`gpfverify.streams.owned`: stderr drops what it cannot write, ``sys.stdout`` carries the
    command's result only; ``held``, where other code's writes to ``sys.stderr`` go, the program's
    descriptor 2). Called with ``argv`` None (the program, :func:`program`), the signal handlers it
    sets stay until the process ends; called from Python with ``argv``, they are restored on
    return."""
    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    hook = sys.unraisablehook
    _occupy_closed_standard_fds()
    sys.unraisablehook = _unraisable_hook(hook)
    try:
        with streams.owned(sys.stdout, sys.stderr, held):
            return _main(argv)
    finally:
        sys.unraisablehook = hook
        if argv is not None:
            with contextlib.suppress(ValueError, TypeError):
                for number, handler in handlers.items():
                    signal.signal(number, handler)


def _main(argv: list[str] | None) -> int:
    from gpfverify.memory import advise, hold_reserve, release_reserve, reserve_blas_buffers
    from gpfverify.usercode import set_time_limit

    default_single_blas_thread()  # before any command imports numpy (see gpfverify.runtime)
    forget_interrupts()
    try:
        signal.signal(signal.SIGTERM, _interrupt)  # `kill` stops cleanly, like Ctrl-C
        signal.signal(signal.SIGINT, _interrupt)
    except ValueError:  # not the main thread (an embedding application): leave signals alone
        pass
    argv = list(sys.argv[1:] if argv is None else argv)
    provenance.set_command(argv)
    parser = build_parser()
    known, rest = parser.parse_known_args(argv[:1] if argv and argv[0] in COMMANDS else argv)
    command = known.command
    if command is None:
        parser.error(f"name a command, one of {', '.join(COMMANDS)} (gpfverify COMMAND --help for its options)")
    with warnings.catch_warnings(record=True) as caught:
        try:
            _refuse_closed_stdout()
            reserve_blas_buffers()  # before the command's modules load them
            hold_reserve()  # for the clean-up, should memory run out
            module = importlib.import_module(COMMANDS[command][0])
            command_args = command_parser(command)
            args = command_args.parse_args(argv[1:])
            advise(command_args._option_string_actions)
            set_time_limit(getattr(args, "timeout", None))
            with _float_errors(command):
                code = int(module.run(args) or 0)
            sys.stdout.flush()  # a closed pipe shows here, inside the boundary
            if interrupt_received():  # swallowed by other code on its way: the command is still interrupted
                return _interrupted_as_it_ended(command)
        except KeyboardInterrupt as exc:
            _ignore_further_interrupts()
            _say(f"gpfverify {command}: {one_line(_with_notes('interrupted', exc))}")
            return 130
        except SystemExit:  # argparse: usage error (one line) or --help
            raise
        except BaseException as exc:  # noqa: BLE001 - the one error boundary of the command line
            release_reserve()  # room to say what happened, should memory have run out
            streams.reinstate()  # whatever other code did to sys.stdout and sys.stderr
            if interrupt_received():  # a Ctrl-C that reached compiled code became another error there
                _ignore_further_interrupts()
                _say(f"gpfverify {command}: {one_line(_with_notes('interrupted', exc))}")
                return 130
            if isinstance(exc, BrokenPipeError):  # the reader stopped reading (| head): it knows, so no line
                _silence_stdout()
                return 2
            message = _user_error(exc)
            if message is not None:
                _say(f"gpfverify {command}: error: {one_line(_with_notes(message, exc))}")
                return 2
            if os.environ.get("GPFVERIFY_DEBUG"):
                raise
            _say(f"gpfverify {command}: internal error: {type(exc).__name__}: {one_line(exc)} "
                 "(a bug: please report it; GPFVERIFY_DEBUG=1 shows the traceback)")
            return 1
    _summarise_warnings(command, caught)
    return code


if __name__ == "__main__":  # pragma: no cover
    program()
