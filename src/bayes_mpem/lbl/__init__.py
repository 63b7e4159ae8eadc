"""The paper's problem: one-way LBL ranges to beacons at known positions.

Classify every range (direct path, multipath, outlier) and identify each
beacon's reflector. Per beacon: the geometry (:mod:`.geometry`,
:mod:`.beacon_geometry`, :mod:`.refracted`), the likelihood
(:mod:`.likelihood`), the two EMs (:mod:`.em_paper`, :mod:`.em_mixture`), the
posterior (:mod:`.posterior`, :mod:`.beacon_sampling`) and the prior comparison
(:mod:`.loo`). Over a survey: :mod:`.fitting`, :mod:`.sampling`,
:mod:`.comparison` (one loop, :mod:`.survey`), the simulator
(:mod:`.simulate`, :mod:`.presets`) and the diagnosis of hidden effects
(:mod:`.diagnosis`). Never imports :mod:`bayes_mpem.survey_in`.
"""
