"""Seeds of the open-world study, fixed before any tuning.

The study (``euc-ros campaign open-world``) runs one ride per seed and family. A ride's seed draws
its rider, EUC, controllers and excitation (:func:`euc_ros.core.worldsim.simulate.draw_spec`), and,
together with the family, the hidden force law, the artefact level and the target residual ratio.
The same seed in two families is the same rider on the same EUC with a different hidden law.

* :data:`TUNING_SEEDS` may be used while developing the analysis and the study (pilots, checks);
* :data:`REPORT_SEEDS` are the published table's; methods were chosen with their numbers in view, so they
  are a development set (named ``report`` so that the published table can be reproduced);
* :data:`HELD_OUT_SEEDS` are for the next reported table only (perturbed sessions, both artefact
  models): fixed here before any run of that study, to be run once, at the end, and published as they
  come. Nothing may be tuned or chosen on them.
"""
from __future__ import annotations

#: The hidden-law families: ``none`` are the no-effect controls.
FAMILIES = ("none", "lab_field", "wheel", "speed", "drift", "dynamic")
#: Seeds for development and pilots.
TUNING_SEEDS = tuple(range(0, 100))
#: Seeds of the reported study, per family (the first ``N`` are used).
REPORT_SEEDS = tuple(range(1000, 2000))
#: Seeds of the next reported table (perturbed sessions, both artefact models), per family: fixed before any run.
HELD_OUT_SEEDS = tuple(range(20_000, 21_000))
#: Seed sets by name (the command's ``--seeds``).
SEED_SETS = {"tuning": TUNING_SEEDS, "report": REPORT_SEEDS, "held-out": HELD_OUT_SEEDS}
