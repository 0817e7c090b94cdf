"""One module per command-line subcommand (see :mod:`gpfverify.cli`)."""
