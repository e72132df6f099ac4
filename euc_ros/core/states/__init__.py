"""From rigid-body poses to the planar model's states (EUC paper, Section 2): the per-frame geometry
(:mod:`.geometry`), the skeleton-constrained rider CoG (:mod:`.skeleton`), the offline reconstruction
(:mod:`.kinematics`) and the low-lag split states (:mod:`.split_lag`).
"""
