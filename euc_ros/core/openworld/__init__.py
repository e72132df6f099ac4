"""The open-world study: hidden random laws in rides of the independent generator, traced and judged.

Each ride of :mod:`euc_ros.core.worldsim` carries a random force law of one family
(:mod:`euc_ros.core.worldsim.forces`) with soft-tissue sliding and the paper's pose noise; ``euc-ros
residual`` (:func:`euc_ros.core.residual.pipeline.trace_residual`) runs on it, and what it says is judged
against the law and the true h.

* :mod:`.study`: drawing, simulating and writing a ride, and a ride's row (:func:`.study.run_task`);
  the study's list of rides and its results.csv;
* :mod:`.judge`: the verdicts of one analysis (right and false names, explained, h coverage) and the
  per-family table of a run with its goals.

The command ``euc-ros campaign open-world`` runs the rides on a cluster and writes the report and its figure.
It sits above both simulators (it writes the generator's rides with the ride simulator's soft-tissue
artefacts), which share no code with each other.
"""
