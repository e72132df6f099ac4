"""Tracing the residual M_d1 - M_d2 to a missing physical effect: candidates fitted on held-out folds,
selected by significance, discovery of what no named effect explains, the floor under the wheel and
the residual's noise floor.
"""
