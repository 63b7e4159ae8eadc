"""Survey-in: locate a transponder from two-way travel times measured from a ship.

The travel-time model (:mod:`.travel_times`), the EM location with
true/spurious classification (:mod:`.location`), its posterior
(:mod:`.posterior`, :mod:`.location_sampling`), a whole measured survey
(:mod:`.survey`), and measured against simulated residuals
(:mod:`.simcheck`, :mod:`.gap_statistics`, :mod:`.unabsorbed`). Never imports
:mod:`bayes_mpem.lbl`.
"""
