"""The planar 3-DoF model of the EUC with a human rider (EUC paper, Section 3).

Its terms (:mod:`.terms`, eqs (5)-(8)), the driving torques (:mod:`.torque`, eqs (9), (10), (13)), the library
of physical effects that may extend it (:mod:`.effects`) and the model extended with some of them
(:mod:`.extended`).
"""
