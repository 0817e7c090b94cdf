"""The experiment machinery every paper shares: the Monte Carlo runner
(:func:`gpfverify.experiments.runner.run_experiment`: seeding, parallelism, saving and resuming),
the interpretations' sensitivity runs (:mod:`.sensitivity`) and the check of a user's own system
(:mod:`.check`, run by the same runner). The papers' experiments are in :mod:`gpfverify.papers`
(listed in :data:`gpfverify.papers.EXPERIMENTS`); what an experiment module defines is specified in
:mod:`gpfverify.contract.experiment`.
"""
