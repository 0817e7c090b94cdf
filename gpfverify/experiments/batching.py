"""What runs filtered together (``reproduce --batch B``) share: how their CPU times are reported,
and the part of a run record that must not depend on the batch."""

from __future__ import annotations

BATCH_TIMING = ("runs filtered together (reproduce --batch B) each carry their batch's CPU time for the filter divided "
                "by B, so the runs of one batch share one value and a paired ratio compares the filters on the "
                "same runs at the same batch size; its standard error counts those runs as independent, and the "
                "interpreter's per-step overhead, which batching divides by B, weighs less than at B = 1")


def batching_caveat(module) -> str:
    """The words an experiment module gives for its timing claims when runs were filtered together:
    its ``BATCH_TIMING_CAVEAT`` when it states one (what its batching times differently), else
    :data:`BATCH_TIMING`."""
    return getattr(module, "BATCH_TIMING_CAVEAT", BATCH_TIMING)


def runs_batched(results: dict) -> bool:
    """Whether the record says some of its runs were filtered together (``machine_load.runs_batched``
    > 0, counted from the saved runs' ``batch_size``): their CPU times are then the batch's."""
    return bool((results.get("machine_load") or {}).get("runs_batched"))


def batch_option(results: dict) -> str:
    """The ``--batch`` option of the command that remakes ``results`` as it was run: ``--batch 1 `` when
    the record does not say that runs shared batches (every run filtered alone, or runs saved before
    batch sizes were recorded, by a runner that ran them one at a time): its timing claims pair per-run
    CPU times, and a remake with the default batch would time batches instead; nothing when runs
    shared batches (the runner's default then remakes them, the same bits)."""
    return "" if runs_batched(results) else "--batch 1 "


def with_batching_caveat(results: dict, caveat: str = BATCH_TIMING) -> dict:
    """``results`` (a ``results.json`` body) with ``caveat`` added to every claim on computation time
    when the record says some of its runs were filtered together (``machine_load.runs_batched`` > 0,
    counted from the saved runs' ``batch_size``); unchanged when every run was timed alone (B = 1) or
    the runs did not record it. The words follow the runs, not the experiment's code."""
    if not runs_batched(results) or "timing_claims" not in results:
        return results
    claims = [{**c, "caveats": [*c.get("caveats", []), caveat]} if caveat not in c.get("caveats", []) else c
              for c in results["timing_claims"]]
    return {**results, "timing_claims": claims}


def without_seconds(value):
    """A run record in JSON form (``contract.serial.to_json``) with every ``seconds`` field set to
    None: what must not depend on how the runs were batched."""
    if isinstance(value, dict):
        return {k: None if k == "seconds" else without_seconds(v) for k, v in value.items()}
    if isinstance(value, list):
        return [without_seconds(v) for v in value]
    return value
