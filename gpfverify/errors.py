"""Exception types of gpfverify. This module imports nothing from the package.

Every error a user can cause derives from :class:`GpfverifyError`; the command line turns those
into exit status 2 and one line on stderr.
"""


class GpfverifyError(Exception):
    """Base class of every error gpfverify raises on purpose."""


class InputError(GpfverifyError, ValueError):
    """An argument has the wrong shape, is not finite, or violates a documented requirement
    (a covariance that is not symmetric positive semidefinite, a non-positive hyperparameter)."""


class CaseFileError(InputError):
    """A fusion-case (or other) file is malformed or internally inconsistent."""


class NumericalError(GpfverifyError, ArithmeticError):
    """A computation could not be carried out reliably: a matrix that must be positive definite
    is not (even after the documented jitter), a factor update failed, a solver did not converge."""


class SolverError(NumericalError):
    """A convex solver returned no usable solution (infeasible, unbounded or inaccurate)."""


class WorkerLost(GpfverifyError):
    """A worker process ended abruptly (a signal, the kernel's out-of-memory killer) while runs
    were being computed: the runs already saved are kept for ``--resume``, as on an interruption."""


class OutOfMemory(GpfverifyError):
    """The machine, or the limit set on this process (``ulimit -v``), has no memory left for what the
    command needs: an error of the environment (exit status 2), never a failed run nor a bug. Raised
    by :mod:`gpfverify.memory` in place of a ``MemoryError`` or an allocation failure a library
    reported another way."""
