"""Autonomous unicycle (steering paper): model, steady states, linearisation, steering control.

ROS-free. Modules: :mod:`.dynamics` (closed-form eqs (6), (36)), :mod:`.derivation` (Kane and
Lagrange derivations used to check them), :mod:`.linearize`, :mod:`.steady`, :mod:`.steering`,
:mod:`.simulate`.
"""
