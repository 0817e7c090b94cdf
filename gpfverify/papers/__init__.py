"""The source papers, one package each: what this toolkit runs to reproduce them.

Each package holds a paper's scenario (the model and data generator), contract (parameters, run
record, claims), experiment (``run_one`` and ``summarize``, run by
:func:`gpfverify.experiments.runner.run_experiment`), report section (``render_section``) and
reference-page script (``page.py``, run as ``python -m gpfverify.papers.<paper>.page``). A paper
with several experiments names each file by its experiment (``ct2d_experiment.py``). Papers
consume the shared engines below them (filters, fusion, the audit, the experiment machinery, the
report's document builders) and never import each other (docs/architecture.md).

* :mod:`~gpfverify.papers.fusion` — Liao et al. 2019 (seed 000): GP moment matching (``moments``),
  the 1-D two-sensor example (``ungm1d``) and the 2-D constant turn (``ct2d``);
* :mod:`~gpfverify.papers.gpsr_upf` — Meng et al. 2015 (seed 001): SINS/GPS (``sins-gps``);
* :mod:`~gpfverify.papers.particle_flow` — Zhou et al. 2020 (seed 003): ``pff1d`` and ``bearing``;
* :mod:`~gpfverify.papers.tbd` — Chen et al. 2015 (seed 004): ``tbd``;
* :mod:`~gpfverify.papers.gpadf_scalar` — Deisenroth et al. 2009, the scalar benchmark (``gpadf-scalar``).

What an experiment module defines is specified in :mod:`gpfverify.contract.experiment`.
"""

#: experiment name (as on the command line) -> module
EXPERIMENTS: dict[str, str] = {
    "pff1d": "gpfverify.papers.particle_flow.pff1d_experiment",
    "bearing": "gpfverify.papers.particle_flow.bearing_experiment",
    "gpadf-scalar": "gpfverify.papers.gpadf_scalar.experiment",
    "ct2d": "gpfverify.papers.fusion.ct2d_experiment",
    "ungm1d": "gpfverify.papers.fusion.ungm1d_experiment",
    "tbd": "gpfverify.papers.tbd.experiment",
    "sins-gps": "gpfverify.papers.gpsr_upf.experiment",
    "moments": "gpfverify.papers.fusion.moments_experiment",
}
