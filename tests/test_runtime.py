"""The command line and the test suite run BLAS single-threaded unless the user says otherwise."""

import os
import subprocess
import sys


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
