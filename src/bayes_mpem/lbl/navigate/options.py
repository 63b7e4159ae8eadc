"""The names of :func:`~bayes_mpem.lbl.navigate.navigate`'s choices, light enough for the CLI.

This module imports nothing, so ``bayes-mpem --help`` can list the choices of
``navigate`` without loading numpy (as :mod:`bayes_mpem.lbl.model.paths` does for the
multipath geometries).

Examples
--------
>>> MODELS[0], MULTIPATH
('mixture', ('signal', 'outlier'))
"""

#: What stands for the ranges' likelihood: the mixture, or a baseline's weights.
MODELS: tuple[str, ...] = ("mixture", "huber", "gate", "gaussian")
#: What the multipath replies are for the mixture: position information, or outliers.
MULTIPATH: tuple[str, ...] = ("signal", "outlier")
