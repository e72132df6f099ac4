"""From rigid-body poses to the planar model's states (EUC paper, Section 2).

The per-frame geometry (:mod:`.geometry`), the skeleton-constrained rider CoG (:mod:`.skeleton`), the offline
reconstruction (:mod:`.kinematics`), the low-lag split states (:mod:`.split_lag`), the floor under the wheel
measured from the contact path (:mod:`.floor`) and reconstructed runs as the model's evaluation contexts
(:mod:`.contexts`).
"""
