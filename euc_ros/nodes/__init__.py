"""ROS 2 nodes of euc_ros: one node per module, wiring only (parameters, messages, the core).

A live node does small numerical work per message; BLAS thread pools only add spinning threads that
compete with the pipeline's other processes for the machine's cores. Node processes therefore run
BLAS single-threaded unless the environment says otherwise (set before numpy is first imported,
which happens after this package is, for every node console script and ``pipeline_container``).

The console scripts import this package before the node's module and its heavy imports: a node
executable stopped by SIGINT or SIGTERM while it starts ends quietly with code 0
(:mod:`euc_ros.ros.startup`).
"""
import os as _os
import sys as _sys

from euc_ros.ros import startup as _startup

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")

_startup.install_for(_sys.argv)
