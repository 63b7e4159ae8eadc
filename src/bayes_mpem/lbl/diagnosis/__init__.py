"""Which assumption of the paper do the data break (``bayes-mpem diagnose``).

A joint model over every beacon (:mod:`.model`) with shared effect
extensions, fitted by ECM (:mod:`.ecm`), kept by held-out gain
(:mod:`.evidence`), with residual checks (:mod:`.residuals`); the driver is
:func:`.driver.diagnose` and the result :class:`.result.Diagnosis`.
"""
