"""Tracing the residual M_d1 - M_d2 to a missing physical effect.

Candidates fitted on held-out folds (:mod:`.folds`, :mod:`.selection`), selected by significance (:mod:`.significance`),
discovery of what no named effect explains (:mod:`.discovery`) and the residual's noise floor (:mod:`.noise`);
:mod:`.analysis` runs the steps, :mod:`.result` holds what they find.
"""
