"""Deterministic randomness: one root seed, independent child streams per run, so results do not
depend on how runs are spread over workers."""

from __future__ import annotations

import numpy as np


def run_seeds(seed: int, runs: int) -> list[np.random.SeedSequence]:
    """``SeedSequence(seed).spawn(runs)``: the seed of run i is the same whatever the worker count."""
    return np.random.SeedSequence(seed).spawn(runs)


def generator(seed) -> np.random.Generator:
    """A PCG64 generator from an int, a SeedSequence or an existing Generator (returned as is)."""
    if isinstance(seed, np.random.Generator):
        return seed
    return np.random.default_rng(seed)


def child_seed(seed_seq: np.random.SeedSequence, *key: int) -> np.random.SeedSequence:
    """The seed of sub-stream ``key`` of a run: the same however often it is asked for (unlike
    ``SeedSequence.spawn``, which advances a counter)."""
    return np.random.SeedSequence(seed_seq.entropy, spawn_key=(*seed_seq.spawn_key, *key))


def child_rng(seed_seq: np.random.SeedSequence, *key: int) -> np.random.Generator:
    """A generator for sub-stream ``key`` of a run (:func:`child_seed`)."""
    return np.random.default_rng(child_seed(seed_seq, *key))
