"""Files in, validated objects out; files out. No science here.

The input boundary (:mod:`~bayes_mpem.io.boundary`), the LBL tables
(:mod:`~bayes_mpem.io.tables`, :mod:`~bayes_mpem.io.survey`), the measured survey-in and
GNSS-A files (:mod:`~bayes_mpem.io.raw` and its readers), geodesy
(:mod:`~bayes_mpem.io.geodesy`) and the one writer of every output folder
(:mod:`~bayes_mpem.io.results`).
"""
