"""Monte Carlo experiments. Each experiment is a module listed in :data:`EXPERIMENTS` that defines

* ``DEFAULT_RUNS`` — the paper's run count;
* ``add_arguments(parser)`` — its own options (defaults are the paper's settings);
* ``params_from_args(args) -> dict`` — every parameter, JSON-able, recorded in ``results.json``;
* ``run_one(params, seed_sequence) -> dict`` — one independent run (a picklable top-level function);
* ``summarize(params, results) -> dict`` — the ``results.json`` body from the successful runs,
  in run order.

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
