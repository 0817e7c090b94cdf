"""What runs filtered together (``reproduce --batch B``) share: how their CPU times are reported,
and the part of a run record that must not depend on the batch."""

from __future__ import annotations

BATCH_TIMING = ("runs filtered together (reproduce --batch B) each carry their batch's CPU time for the filter divided "
                "by B, so the runs of one batch share one value and a paired ratio compares the filters on the "
                "same runs at the same batch size; its standard error counts those runs as independent, and the "
                "interpreter's per-step overhead, which batching divides by B, weighs less than at B = 1")

def without_seconds(value):
    """A run record in JSON form (``contract.serial.to_json``) with every ``seconds`` field set to
    None: what must not depend on how the runs were batched."""
    if isinstance(value, dict):
        return {k: None if k == "seconds" else without_seconds(v) for k, v in value.items()}
    if isinstance(value, list):
        return [without_seconds(v) for v in value]
    return value
