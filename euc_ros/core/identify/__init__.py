"""Identification of the rider CoG height h (EUC paper, Section 4) and how well the data determine it.

The fit (:mod:`.fit`), the block bootstrap (:mod:`.bootstrap`), the errors-in-variables bias (:mod:`.simex`,
:mod:`.sliding`), the interval and identifiability (:mod:`.interval`) and the budget over nominal values
(:mod:`.budget`).
"""
