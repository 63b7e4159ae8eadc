"""The posterior of one beacon.

The log-posterior (:mod:`.posterior`), its sampling (:mod:`.beacon_sampling`,
:mod:`.beacon_chains`), equal against learned priors by PSIS-LOO (:mod:`.loo`) and
simulation-based calibration (:mod:`.sbc`).
"""
