"""The paper's problem: one-way LBL ranges to beacons at known positions.

Classify every range (direct path, multipath, outlier) and identify each beacon's
reflector. Grouped by concept: the range model (``model/``), the two EMs (``em/``),
the posterior (``bayes/``), the per-survey commands (``survey/``), the simulator
(``simulation/``), the diagnosis of hidden effects (``diagnosis/``) and navigation
(:mod:`.navigate`, with the same model one ping at a time in :mod:`.navigate.online`).
Never imports :mod:`bayes_mpem.survey_in`.
"""
