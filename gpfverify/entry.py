"""The command line's entry point (the ``gpfverify`` console script and ``python -m gpfverify``).

A Ctrl-C or SIGTERM that comes while Python loads gpfverify, before :func:`gpfverify.cli.program`
takes signals over, ends it with exit status 130 and one line, not a traceback (Python's default
for SIGINT) nor death by the signal (its default for SIGTERM). This module imports nothing of
gpfverify's before it has set its handlers.
"""

from __future__ import annotations

import os
import signal


def _interrupt(signum, frame) -> None:
    raise KeyboardInterrupt


def program() -> None:
    """Set the early handlers, load the command line and run it (:func:`gpfverify.cli.program`)."""
    try:
        signal.signal(signal.SIGINT, _interrupt)
        signal.signal(signal.SIGTERM, _interrupt)
        from gpfverify.cli import program as run
    except KeyboardInterrupt:
        try:
            os.write(2, b"gpfverify: interrupted\n")
        finally:
            os._exit(130)
    run()
