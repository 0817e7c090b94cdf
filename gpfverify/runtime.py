"""Process-level settings, applied before numpy is imported.

gpfverify's matrices are small (tens to a thousand rows); multithreaded BLAS on them costs more in
thread start-up and contention than it gains — measured up to 80× slower GP fitting on a loaded
2-core machine. Processes started by the command line and the Monte Carlo workers therefore use
one BLAS thread unless the user has set these variables; parallelism comes from running Monte
Carlo runs in separate processes instead.
"""

from __future__ import annotations

import os

BLAS_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                    "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")


def default_single_blas_thread() -> None:
    """Set every BLAS thread variable the user has not set to 1 (effective only before numpy
    loads its BLAS, and for child processes started afterwards)."""
    for var in BLAS_THREAD_VARS:
        os.environ.setdefault(var, "1")
