"""The per-survey commands.

One loop over beacons (:mod:`.survey`) behind ``fit`` (:mod:`.fitting`), ``sample``
(:mod:`.sampling`) and ``compare`` (:mod:`.comparison`), and the model checks of every fit
(:mod:`.model_checks`).
"""
