"""The audit of a run file as a stream (docs/run-file-format.md, "Output"): blocks of steps are
read and checked (:func:`~gpfverify.audit.runfile.open_run`), audited — in this process or
spread over an executor (``--workers``, ``--scheduler``), always in the same fixed blocks so the
bytes do not depend on the workers — and written in order, while the summary is kept as running
aggregates (:class:`RunSummary`). Nothing held in memory grows with the run's length: the
summary's lists of step indices where a sensor lost rank are spooled like the output
(:class:`StepIndices`) and written to the JSON a chunk at a time.

The output is assembled in a spooled temporary file (in memory while small, on disk beyond
:data:`SPOOL_BYTES`) and copied out only when the whole run has been audited, so a file that is
refused at its last line, or an interruption, leaves nothing half-written.
"""

from __future__ import annotations

import codecs
import contextlib
import shutil
import sys
import tempfile
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import Executor, Future
from dataclasses import dataclass, field
from typing import IO

import msgspec
import numpy as np

from gpfverify.audit.case import CaseAudit, RunAudit, audit_case, audit_to_dict
from gpfverify.audit.block import block_audits
from gpfverify.fusion.caseblock import CaseBlock
from gpfverify.fusion.exactness import DEFAULT_RANK_RULE, RankRule, resolve_rank_rule
from gpfverify.audit.runfile import BLOCK_STEPS, RunBlock, open_run

#: output kept in memory before the spool moves to a temporary file
SPOOL_BYTES = 32 << 20
#: bytes of one list of step indices kept in memory before it moves to a temporary file
INDEX_SPOOL_BYTES = 1 << 20
#: step indices read back at a time from a spooled list
INDEX_CHUNK = 1 << 16

_ENCODER = msgspec.json.Encoder()


@dataclass(frozen=True)
class BlockAudit:
    """What one block contributes: the encoded per-step JSON objects (``json``, joined by ", ")
    or the text table's rows (``text``), optionally the per-step dicts (``steps``, for callers
    that render them), and the per-step facts the summary aggregates."""

    ks: np.ndarray
    condition_holds: np.ndarray
    exact: np.ndarray
    full_column_rank: np.ndarray
    sensor_exact: np.ndarray
    gap_norm: np.ndarray
    gap_size: np.ndarray
    rank_rules: list
    reported: np.ndarray | None = None
    reproduced: np.ndarray | None = None
    json: bytes = b""
    text: str = ""
    steps: list[dict] | None = None
    audits: list[CaseAudit] | None = None


def audit_block(run_block: RunBlock, rank_rule=None, rank_tol: float | None = None, sensitivity: bool = False,
                form: str = "json", keep: bool = False) -> BlockAudit:
    """Audit every step of a block — all at once (:func:`gpfverify.audit.block.block_audits`) when
    one rank rule decides the whole block and no sensitivities are asked for, else one by one
    (:func:`gpfverify.audit.case.audit_case`; also a block the batched route leaves) — (``form``: "json"
    encodes the step objects, "text" the table rows, "none" neither); ``keep`` also returns the step
    dicts and CaseAudit records."""
    rule = None if sensitivity else block_rule(run_block.block, rank_rule, rank_tol)
    batched: list[CaseAudit | None] = [None] * len(run_block)
    complete = np.flatnonzero(run_block.block.complete)  # steps where every sensor reported: all at once
    if rule is not None and complete.size:
        together = block_audits(run_block.block.take(complete), rule)
        for t, audit in zip(complete.tolist(), together):
            batched[t] = audit
    audits = [audit if audit is not None else
              audit_case(run_block.block.case(t), rank_tol, sensitivity=sensitivity, rank_rule=rank_rule)
              for t, audit in enumerate(batched)]
    return audits_block(run_block.ks, audits, form, keep)


def audits_block(ks, audits: list[CaseAudit], form: str = "none", keep: bool = False) -> BlockAudit:
    """The :class:`BlockAudit` of the audits of steps ``ks`` (``form`` and ``keep`` as in
    :func:`audit_block`)."""
    steps = [{"k": int(k), **audit_to_dict(a)} for k, a in zip(ks, audits)]
    rules: list = []
    for s in steps:
        if s["rank_rule"] not in rules:
            rules.append(s["rank_rule"])
    run = RunAudit(tuple(audits))
    return BlockAudit(
        ks=np.asarray(ks, dtype=np.int64),
        condition_holds=np.array([a.condition_holds for a in audits], dtype=bool),
        exact=np.array([a.exact for a in audits], dtype=bool),
        full_column_rank=run.full_column_rank,   # True where a sensor did not report: nothing was lost
        sensor_exact=run.exact,
        gap_norm=np.array([np.nan if a.gap is None else np.linalg.norm(a.gap) for a in audits]),
        gap_size=np.array([np.nan if a.gap_size is None else a.gap_size for a in audits]),
        rank_rules=rules,
        reproduced=np.array([a.reproduced is True for a in audits], dtype=bool),
        json=b", ".join(_ENCODER.encode(s) for s in steps) if form == "json" else b"",
        text="".join(table_row(s) + "\n" for s in steps) if form == "text" else "",
        steps=steps if keep else None, audits=audits if keep else None,
        reported=None if not any(a.missing for a in audits) else run.reported)


def block_rule(block: CaseBlock, rank_rule=None, rank_tol: float | None = None) -> RankRule | None:
    """The rank rule that decides every step of ``block`` (:func:`~gpfverify.fusion.exactness.resolve_rank_rule`
    of each step), or None when the steps' own ``rank_tol`` make it differ between steps."""
    if rank_rule is not None or rank_tol is not None:
        return resolve_rank_rule(None, rank_rule, rank_tol)
    tols = block.rank_tol
    if np.all(np.isnan(tols)):
        return DEFAULT_RANK_RULE
    if np.all(tols == tols[0]):
        return RankRule("absolute", float(tols[0]))
    return None


def table_row(step: dict) -> str:
    """One step of the text table (:func:`table_header`)."""
    cells = {x["index"]: f"{x['rank']}/{x['cols']}" + ("" if x["exact"] else "!") for x in step["sensors"]}
    cells.update({m: "-" for m in step.get("missing_sensors", [])})  # did not report
    ranks = " ".join(cells[m] for m in sorted(cells))
    gap = f"{step['gap_norm']:.3g}" if "gap_norm" in step else "-"
    pred = f"{float(np.linalg.norm(step['predicted_gap'])):.3g}" if "predicted_gap" in step else "-"
    return (f"{step['k']:>6} {str(step['condition_holds']):>9} {str(step['exact']):>5}  {ranks:<24} "
            f"{gap:>10} {pred:>11}")


def table_header() -> str:
    return (f"{'k':>6} {'condition':>9} {'exact':>5}  {'rank/cols per sensor':<24} {'|gap|':>10} "
            f"{'|predicted|':>11}")


def run_rank_rule(rules: list):
    """The run's ``rank_rule`` from the steps' distinct top-level objects (in order of first
    appearance): the common one; with ``"covariance": "mixed"`` when only the whitening
    covariance differs; else the list of distinct objects."""
    if len(rules) == 1:
        return rules[0]
    if all(isinstance(r, dict) for r in rules):
        bare = [{k: v for k, v in r.items() if k != "covariance"} for r in rules]
        if all(b == bare[0] for b in bare):
            return {**rules[0], "covariance": "mixed"}
    return list(rules)


class StepIndices(Sequence):
    """Step indices appended in increasing order while a run is audited, as 8-byte integers in a
    spooled temporary file (memory up to :data:`INDEX_SPOOL_BYTES`, then disk): a read-only
    sequence of ints whose size in memory does not grow with the run. :meth:`chunks` reads it
    back as arrays; :meth:`write_json` writes it as a JSON array without building the list."""

    def __init__(self) -> None:
        self._file = tempfile.SpooledTemporaryFile(max_size=INDEX_SPOOL_BYTES, mode="w+b",
                                                   prefix="gpfverify-steps-")
        self._count = 0

    def append(self, ks: np.ndarray) -> None:
        if ks.size:
            self._file.seek(0, 2)
            self._file.write(np.ascontiguousarray(ks, dtype=np.int64).tobytes())
            self._count += int(ks.size)

    def __len__(self) -> int:
        return self._count

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(self._count))]
        if index < 0:
            index += self._count
        if not 0 <= index < self._count:
            raise IndexError("step index out of range")
        self._file.seek(8 * index)
        return int(np.frombuffer(self._file.read(8), np.int64)[0])

    def chunks(self) -> Iterator[np.ndarray]:
        """The indices as int64 arrays of up to :data:`INDEX_CHUNK` each, in order."""
        for start in range(0, self._count, INDEX_CHUNK):
            self._file.seek(8 * start)
            yield np.frombuffer(self._file.read(8 * min(INDEX_CHUNK, self._count - start)), np.int64)

    def __iter__(self) -> Iterator[int]:
        for chunk in self.chunks():
            yield from chunk.tolist()

    def tolist(self) -> list[int]:
        return [k for chunk in self.chunks() for k in chunk.tolist()]

    def write_json(self, out: IO[bytes]) -> None:
        out.write(b"[")
        for n, chunk in enumerate(self.chunks()):
            out.write((b"," if n else b"") + ",".join(map(str, chunk.tolist())).encode())
        out.write(b"]")


@dataclass
class RunSummary:
    """Running aggregates of a run audit; :meth:`result` is the ``summary`` object."""

    steps: int = 0
    condition_held: int = 0
    exact: int = 0
    with_y: int = 0
    reproduced: int = 0
    max_gap: float | None = None
    max_gap_k: int | None = None
    max_gap_size: float | None = None
    max_gap_size_k: int | None = None
    rules: list = field(default_factory=list)
    lost: list[StepIndices] = field(default_factory=list)
    lost_not_exact: list[StepIndices] = field(default_factory=list)
    missing: list[StepIndices] = field(default_factory=list)

    def add(self, block: BlockAudit) -> None:
        self.steps += len(block.ks)
        self.condition_held += int(block.condition_holds.sum())
        self.exact += int(block.exact.sum())
        measured = ~np.isnan(block.gap_norm)
        self.with_y += int(measured.sum())
        if block.reproduced is not None:
            self.reproduced += int(block.reproduced.sum())
        if measured.any():
            i = int(np.nanargmax(block.gap_norm))
            if self.max_gap is None or block.gap_norm[i] > self.max_gap:
                self.max_gap, self.max_gap_k = float(block.gap_norm[i]), int(block.ks[i])
            j = int(np.nanargmax(block.gap_size))
            if self.max_gap_size is None or block.gap_size[j] > self.max_gap_size:
                self.max_gap_size, self.max_gap_size_k = float(block.gap_size[j]), int(block.ks[j])
        for r in block.rank_rules:
            if r not in self.rules:
                self.rules.append(r)
        if not self.lost:
            n = block.full_column_rank.shape[1]
            self.lost, self.lost_not_exact = [StepIndices() for _ in range(n)], [StepIndices() for _ in range(n)]
            self.missing = [StepIndices() for _ in range(n)]
        for m in range(len(self.lost)):
            lost = ~block.full_column_rank[:, m]
            self.lost[m].append(block.ks[lost])
            self.lost_not_exact[m].append(block.ks[lost & ~block.sensor_exact[:, m]])
            if block.reported is not None:
                self.missing[m].append(block.ks[~block.reported[:, m]])

    def result(self, spooled: bool = False) -> dict:
        """The ``summary`` object; its step-index lists as :class:`StepIndices` (``spooled``, for a
        run of any length) or as lists of ints."""
        def ks(indices: StepIndices):
            return indices if spooled else indices.tolist()

        return {
            "steps": self.steps, "condition_held_steps": self.condition_held, "exact_steps": self.exact,
            "steps_with_y": self.with_y, "reproduced_steps": self.reproduced,
            "max_gap_norm": self.max_gap, "max_gap_k": self.max_gap_k,
            "max_gap_size": self.max_gap_size, "max_gap_size_k": self.max_gap_size_k,
            "sensors": [{"index": m, "rank_lost_steps": ks(self.lost[m]),
                         "rank_lost_not_exact_steps": ks(self.lost_not_exact[m]),
                         "not_reported_steps": ks(self.missing[m])} for m in range(len(self.lost))],
            "rank_rule": run_rank_rule(self.rules),
        }


def write_summary_json(out: IO[bytes], summary: dict) -> None:
    """``summary`` (from :meth:`RunSummary.result`) as JSON, its step-index lists written a chunk at
    a time: the bytes ``msgspec`` writes for the same object with lists."""
    def write_object(obj: dict) -> None:
        out.write(b"{")
        for n, (key, value) in enumerate(obj.items()):
            out.write((b"," if n else b"") + _ENCODER.encode(key) + b":")
            if isinstance(value, StepIndices):
                value.write_json(out)
            elif key == "sensors":
                out.write(b"[")
                for i, sensor in enumerate(value):
                    out.write(b"," if i else b"")
                    write_object(sensor)
                out.write(b"]")
            else:
                out.write(_ENCODER.encode(value))
        out.write(b"}")

    write_object(summary)


def _in_order(blocks: Iterable[RunBlock], audit: Callable[[RunBlock], BlockAudit],
              executor: Executor | None, in_flight: int) -> Iterable[BlockAudit]:
    """``audit(block)`` for every block, in order; with an executor, up to ``in_flight`` blocks
    at once (read lazily, so memory stays bounded)."""
    if executor is None:
        for block in blocks:
            yield audit(block)
        return
    pending: deque[Future] = deque()
    try:
        for block in blocks:
            pending.append(executor.submit(audit, block))
            while len(pending) >= in_flight:
                yield pending.popleft().result()
        while pending:
            yield pending.popleft().result()
    finally:
        for f in pending:
            f.cancel()


@dataclass
class _BlockAuditor:
    """A picklable ``audit_block`` with its options bound (sent to worker processes)."""

    rank_rule: object
    rank_tol: float | None
    sensitivity: bool
    form: str
    keep: bool

    def __call__(self, run_block: RunBlock) -> BlockAudit:
        return audit_block(run_block, self.rank_rule, self.rank_tol, self.sensitivity, self.form, self.keep)


def stream_audit(path, out: IO[bytes] | None, form: str = "json", rank_rule=None, rank_tol: float | None = None,
                 sensitivity: bool = False, executor: Executor | None = None, in_flight: int = 1,
                 on_block: Callable[[int, int | None], None] | None = None, keep: bool = False,
                 block_steps: int = BLOCK_STEPS):
    """Audit a run file block by block, writing ``{"steps": [...], "summary": {...},
    "rank_rule": ...}`` (``form="json"``) or the text table and summary (``"text"``) to ``out``
    as it goes. Returns ``(summary, steps, audits)`` (the last two only with ``keep``).
    ``on_block(done, total)`` reports progress (total None when the file does not declare it)."""
    summary = RunSummary()
    kept_steps: list[dict] = []
    kept_audits: list[CaseAudit] = []
    auditor = _BlockAuditor(rank_rule, rank_tol, sensitivity, form, keep)
    with open_run(path) as reader:
        if out is not None and form == "json":
            out.write(b'{"steps": [')
        if out is not None and form == "text":
            out.write((table_header() + "\n").encode())
        first = True
        for result in _in_order(reader.blocks(block_steps), auditor, executor, max(1, in_flight)):
            summary.add(result)
            if out is not None and form == "json":
                out.write(result.json if first else b", " + result.json)
            elif out is not None and form == "text":
                out.write(result.text.encode())
            first = False
            if keep and result.steps is not None and result.audits is not None:
                kept_steps += result.steps
                kept_audits += result.audits
            if on_block is not None:
                on_block(summary.steps, reader.steps)
    result_summary = summary.result(spooled=not keep)
    if out is not None and form == "json":
        out.write(b'], "summary": ')
        write_summary_json(out, result_summary)
        out.write(b', "rank_rule": ' + _ENCODER.encode(result_summary["rank_rule"]) + b"}\n")
    return result_summary, kept_steps, kept_audits


@contextlib.contextmanager
def spool():
    """A binary temporary file for output (memory up to :data:`SPOOL_BYTES`, then disk)."""
    with tempfile.SpooledTemporaryFile(max_size=SPOOL_BYTES, mode="w+b", prefix="gpfverify-audit-") as fh:
        yield fh


def copy_out(fh: IO[bytes], stream=None) -> None:
    """Copy a finished spool to a text stream (stdout by default)."""
    stream = sys.stdout if stream is None else stream
    fh.seek(0)
    buffer = getattr(stream, "buffer", None)
    if buffer is not None:
        stream.flush()
        shutil.copyfileobj(fh, buffer, 1 << 20)
        buffer.flush()
        return
    decoder = codecs.getincrementaldecoder("utf-8")()
    while chunk := fh.read(1 << 20):
        stream.write(decoder.decode(chunk))
    stream.write(decoder.decode(b"", final=True))
