"""The EUC-rider model (EUC paper, Section 3): parameters, torques, state reconstruction, identification.

ROS-free. Modules: :mod:`.model` (eqs (5)-(8)), :mod:`.torque` (eqs (9), (10), (13)),
:mod:`.kinematics` (frame geometry and rider states, eqs (1)-(3)), :mod:`.identify` (RMSE(h) and
the optimal h, Section 4) and :mod:`.online` (sliding RMSE and the online h estimate).
"""
