"""The paper's problem: one-way LBL ranges to beacons at known positions.

Classify every range (direct path, multipath, outlier) and identify each beacon's
reflector. Grouped by concept: the range model (:mod:`.model`), the two EMs (:mod:`.em`),
the posterior (:mod:`.bayes`), the per-survey commands (:mod:`.survey`), the simulator
(:mod:`.simulation`), the diagnosis of hidden effects (:mod:`.diagnosis`) and navigation
(:mod:`.navigate`, with the same model one ping at a time in :mod:`.navigate.online`).
Never imports :mod:`bayes_mpem.survey_in`.
"""
