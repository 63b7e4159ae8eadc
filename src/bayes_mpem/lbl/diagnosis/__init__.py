"""Which assumption of the paper do the data break (``bayes-mpem diagnose``)."""
