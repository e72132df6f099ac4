"""ROS 2 nodes of euc_ros (thin: parameters, messages, the core).

A live node does small numerical work per message; BLAS thread pools only add spinning threads that
compete with the pipeline's other processes for the machine's cores. Node processes therefore run
BLAS single-threaded unless the environment says otherwise (set before numpy is first imported,
which happens after this package is, for every node console script and ``pipeline_container``).
"""
import os as _os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")
