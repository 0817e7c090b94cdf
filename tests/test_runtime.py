"""The command line and the test suite run BLAS single-threaded unless the user says otherwise."""

import os
import subprocess
import sys

from gpfverify import runtime


def test_cli_defaults_blas_threads_to_one_but_respects_the_user():
    code = ("import os, sys; from gpfverify import cli; sys.argv=['gpfverify','--version'];\n"
            "try: cli.main()\nexcept SystemExit: pass\n"
            "print(os.environ['OPENBLAS_NUM_THREADS'], os.environ['OMP_NUM_THREADS'])")
    env = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS")}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True).stdout
    assert out.split()[-2:] == ["1", "1"]
    env["OMP_NUM_THREADS"] = "2"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True).stdout
    assert out.split()[-2:] == ["1", "2"]


def test_suite_itself_runs_single_threaded():
    assert os.environ.get("OPENBLAS_NUM_THREADS") == "1"


def test_api_calls_limit_blas_to_one_thread_only_while_they_run():
    """In a process without the thread variables (a user's own script): inside a decorated call
    BLAS runs one thread, nested calls too; outside, the user's setting (2 threads here) holds;
    a user who set a thread variable is obeyed."""
    code = """
import numpy, scipy.linalg
from threadpoolctl import threadpool_info, threadpool_limits
from gpfverify.runtime import one_blas_thread
from gpfverify.filters import ukf_step, run_filter
from gpfverify.models import learn_gp_model
from gpfverify.gp import GaussianProcess

def blas_threads():
    return sorted({lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"})

@one_blas_thread
def outer():
    return blas_threads(), inner()

@one_blas_thread
def inner():
    return blas_threads()

with threadpool_limits(2, user_api="blas"):
    print(outer(), blas_threads())
print(all(hasattr(f, "__wrapped__") for f in (ukf_step, run_filter, learn_gp_model, GaussianProcess.fit)))
"""
    env = {k: v for k, v in os.environ.items() if k not in runtime.BLAS_THREAD_VARS}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout
    assert out.split("\n")[:2] == ["([1], [1]) [2]", "True"]
    env["OPENBLAS_NUM_THREADS"] = "2"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout
    assert out.split("\n")[0] == "([2], [2]) [2]"


def test_cycle_collection_is_paused_inside_and_restored_as_it_was_even_on_error():
    import gc

    import pytest

    from gpfverify.runtime import no_cycle_collection

    assert gc.isenabled()
    with pytest.raises(ValueError), no_cycle_collection():
        assert not gc.isenabled()
        raise ValueError
    assert gc.isenabled()
    gc.disable()
    try:
        with no_cycle_collection():
            assert not gc.isenabled()
        assert not gc.isenabled()  # a caller's own pause is kept
    finally:
        gc.enable()
