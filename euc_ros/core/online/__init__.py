"""The frame-by-frame estimators and monitors behind the nodes.

Rider states and torques (:mod:`.estimators`), the sliding RMSE and online h (:mod:`.window`), the residual
alarm's threshold (:mod:`.alarm`) and the health rules of the monitor (:mod:`.monitoring`).
"""
