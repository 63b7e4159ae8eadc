"""The names of the multipath geometries, in a module light enough for the command line.

``"triangle"``: one leg of the multipath is reflected, the other direct (the paper's
finding); ``"double"``: both legs are reflected (:mod:`.geometry` has the formulas).
``"auto"`` asks :func:`~bayes_mpem.lbl.em.path_choice.choose_path` to pick, per beacon, the
likelier of the two. This module imports nothing, so ``bayes-mpem --help`` can list the
choices without loading numpy.
"""

PATHS: tuple[str, ...] = ("triangle", "double")
AUTO = "auto"
PATH_CHOICES: tuple[str, ...] = (AUTO, *PATHS)
