"""Run a gpfverify command's Monte Carlo runs on a dask LocalCluster: worker processes on this
machine, one thread each (as the local pool's), the dashboard off.

    python examples/local_cluster.py OUT [gpfverify reproduce options ...]

starts the cluster, runs ``gpfverify reproduce ... --scheduler ADDRESS --out OUT`` on it (by default a
small ungm1d) and stops the cluster. The results are the bytes ``--workers 2`` gives (docs/cluster.md).
"""

import sys

from dask.distributed import LocalCluster

from gpfverify.cli import main

SMALL_UNGM1D = ["ungm1d", "--train-points", "15", "--test-steps", "3", "--sweep", "2", "--runs", "3", "--seed", "11"]

if __name__ == "__main__":  # the workers are processes that import this file again
    out, options = sys.argv[1], sys.argv[2:] or SMALL_UNGM1D
    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None) as cluster:
        print(f"a LocalCluster at {cluster.scheduler_address}")
        status = main(["reproduce", *options, "--scheduler", cluster.scheduler_address, "--out", out])
    sys.exit(status)
