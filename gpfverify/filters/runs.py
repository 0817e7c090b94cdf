"""The run axis of the particle filters: many Monte Carlo runs advanced together as arrays.

A particle filter's belief holds particles (N, D) for one run, or (B, N, D) for B runs advanced
together (log weights (N,) or (B, N)); the measurement is (L,) or (B, L). Every step function takes
either: the operations act on the trailing axes, so each run's numbers come out of the same
arithmetic whatever B is (numpy's element-wise loops, its reductions along one run's axis, and one
BLAS or LAPACK call per run for a stacked product or solve), and a run's results do not depend on
the batch it was computed in.

Randomness: each run draws from its own :class:`numpy.random.Generator`. A step on one run takes a
Generator, a step on B runs a sequence of B Generators; every draw is made per run, in the order
the single-run step makes it (:func:`normal`, :func:`uniform`, :func:`random`), so a run consumes
its stream exactly as it would alone.

Failures: a run whose particles leave a model function's domain (NaN or inf) fails alone: on B
runs :func:`evaluate_runs` gives that run NaN and the others go on; on one run the error is raised
as before (:class:`~gpfverify.errors.InputError`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from gpfverify.errors import GpfverifyError, InputError
from gpfverify.validate import as_array

#: one Generator (one run) or one per run (a batch)
Streams = np.random.Generator | Sequence[np.random.Generator]


def check_streams(rng: Streams, lead: tuple[int, ...]) -> None:
    """InputError unless ``rng`` fits the leading (run) axes ``lead`` of the particles: one
    Generator for one run (``lead`` = ()), a sequence of B Generators for B runs (``lead`` = (B,))."""
    if not lead:
        if isinstance(rng, Sequence):
            raise InputError("rng: one run's particles (N, D) take one numpy Generator")
        return
    if len(lead) != 1 or not isinstance(rng, Sequence) or len(rng) != lead[0]:
        raise InputError(f"rng: particles of {lead[0] if len(lead) == 1 else lead} runs need one numpy "
                         "Generator per run (a sequence as long as the run axis)")


def particle_inputs(particles, y, model, rng: Streams | None, names: tuple[str, str] = ("belief.particles", "y")
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Particles (N, D) of one run or (B, N, D) of B runs and the measurement (L,) or (B, L),
    checked against the model's dimensions and against ``rng`` when given (:func:`check_streams`);
    InputError naming the argument (``names``). One run's particles must be finite; in a batch a
    run that failed earlier holds NaN and is carried along."""
    x = np.asarray(particles)
    if x.ndim == 3 and x.dtype.kind == "f" and x.shape[-1] == model.state_dim:
        x = x.astype(float, copy=False)
    else:
        x = as_array(x, names[0], shape=(None, model.state_dim))
    if rng is not None:
        check_streams(rng, x.shape[:-2])
    return x, as_array(y, names[1], shape=x.shape[:-2] + (model.measurement_dim,))


def normal(rng: Streams, shape: tuple[int, ...]) -> np.ndarray:
    """Standard normal draws of ``shape`` from one run's stream, or (B, *shape) from each run's
    (each run's drawn into its row of the result)."""
    if not isinstance(rng, Sequence):
        return rng.standard_normal(shape)
    out = np.empty((len(rng), *shape))
    for g, row in zip(rng, out):
        g.standard_normal(out=row)
    return out


def uniform(rng: Streams) -> np.ndarray | float:
    """One U[0, 1) draw per run (``Generator.uniform()``): a float, or (B,)."""
    if not isinstance(rng, Sequence):
        return rng.uniform()
    return np.array([g.uniform() for g in rng])


def random(rng: Streams, shape: tuple[int, ...]) -> np.ndarray:
    """U[0, 1) draws of ``shape`` (``Generator.random``) per run: ``shape`` or (B, *shape) (each
    run's drawn into its row of the result)."""
    if not isinstance(rng, Sequence):
        return rng.random(shape)
    out = np.empty((len(rng), *shape))
    for g, row in zip(rng, out):
        g.random(out=row)
    return out


def subset(rng: Streams, rows: np.ndarray) -> list[np.random.Generator]:
    """The streams of the runs ``rows`` (indices into the run axis) of a batch."""
    if not isinstance(rng, Sequence):
        raise InputError("rng: a batch of runs needs one numpy Generator per run")
    return [rng[int(i)] for i in rows]


def map_rows(fn: Callable, x: np.ndarray, k: int) -> np.ndarray:
    """A model function of rows, fn(x (M, D), k) -> (M, E), at x (..., D): the leading axes
    flattened into rows and restored, (..., E)."""
    flat = fn(x.reshape(-1, x.shape[-1]), k)
    return flat.reshape(x.shape[:-1] + flat.shape[-1:])


def evaluate_runs(fn: Callable, x: np.ndarray, k: int, width: int) -> np.ndarray:
    """:func:`map_rows` of a model function with ``width`` outputs over particles (N, D) of one
    run or (B, N, D) of B runs (:func:`isolate_runs`: a failing run gets NaN, one run alone raises)."""
    if x.ndim < 3:
        return map_rows(fn, x, k)
    return isolate_runs(lambda part: map_rows(fn, part, k), x, (x.shape[1], width))


def isolate_runs(call: Callable[[np.ndarray], np.ndarray], x: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """``call`` (a map of runs to runs: x (b, ...) -> (b, ...), each run's values its own) on the
    runs of x (B, ...) that can take it: a run whose entries are not all finite, or on which the
    call raises a :class:`~gpfverify.errors.GpfverifyError` (a model function refusing NaN or
    inf), gets NaN; the others their values. ``shape`` is one run's output shape."""
    alive = np.isfinite(x.reshape(x.shape[0], -1)).all(axis=1)
    if alive.all():
        try:
            return call(x)
        except GpfverifyError:
            pass
    out = np.full((x.shape[0], *shape), np.nan)
    rows = np.flatnonzero(alive)
    if rows.size < x.shape[0]:  # the runs still going, together
        try:
            out[rows] = call(x[rows])
            return out
        except GpfverifyError:
            pass
    for b in rows:  # a run fails in this call: find it
        value = _or_none(call, x[b:b + 1])
        if value is not None:
            out[b] = value[0]
    return out


def _or_none(call: Callable[[np.ndarray], np.ndarray], x: np.ndarray) -> np.ndarray | None:
    try:
        return call(x)
    except GpfverifyError:
        return None
