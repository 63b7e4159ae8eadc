"""The two EMs of one beacon: the paper's and the mixture EM.

:mod:`.em_paper`, :mod:`.em_mixture`, their shared result (:mod:`.em_result`), the choice
between the triangle and the double bounce (:mod:`.path_choice`) and the paper's Pol
sensitivity (:mod:`.pol_sensitivity`).
"""
