"""Monte Carlo experiments, one module per experiment listed in :data:`EXPERIMENTS`. What a
module defines (``Params``, ``PROFILES``, ``RunRecord``, ``run_one``, ``summarize`` with its claim
records) is specified in :mod:`gpfverify.contract.experiment`; its contract types live in
``gpfverify/contract/<name>.py``.

:func:`gpfverify.experiments.runner.run_experiment` does seeding, parallelism, saving and resuming.
"""

#: experiment name (as on the command line) -> module
EXPERIMENTS: dict[str, str] = {
    "pff1d": "gpfverify.experiments.pff1d",
    "bearing": "gpfverify.experiments.bearing",
    "gpadf-scalar": "gpfverify.experiments.gpadf_scalar",
    "ct2d": "gpfverify.experiments.ct2d",
    "ungm1d": "gpfverify.experiments.ungm1d",
    "tbd": "gpfverify.experiments.tbd",
    "sins-gps": "gpfverify.experiments.sins_gps",
    "moments": "gpfverify.experiments.moments",
}
