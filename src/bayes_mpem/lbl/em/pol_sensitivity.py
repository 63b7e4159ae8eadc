"""How the paper's EM answers to its outlier threshold ``Pol`` (the data of its Fig. 12)."""

from __future__ import annotations

import warnings

import numpy as np

from ..._validate import check_choice
from ...exceptions import ConvergenceWarning, FitQualityWarning
from .em_paper import fit_paper_em

#: Pol values of the paper's Fig. 12 as drawn by ``bayes-mpem``.
POL_GRID = (0.01, 0.02, 0.05, 0.1, 0.15, 0.2, 0.3)


def pol_sensitivity(data, pols, **kwargs):
    """Run the paper's EM for each ``Pol`` (the data of the paper's Fig. 12).

    Parameters
    ----------
    **kwargs
        Passed to :func:`~.em_paper.fit_paper_em`.

    Returns
    -------
    dict of numpy.ndarray
        ``pol``, ``d0``, ``sigma_mp``, ``p_dp``, ``p_mp``, ``p_ol``, ``converged``, ``flags``.
    """
    out = {k: [] for k in ("pol", "d0", "sigma_mp", "p_dp", "p_mp", "p_ol", "converged",
                           "flags")}
    for pol in pols:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            warnings.simplefilter("ignore", FitQualityWarning)
            r = fit_paper_em(data, pol=pol, **kwargs)
        out["flags"].append(list(r.flags))
        out["pol"].append(pol)
        out["d0"].append(r.d0)
        out["sigma_mp"].append(r.sigma_mp)
        for c in ("dp", "mp", "ol"):
            out["p_" + c].append(r.weights[c])
        out["converged"].append(r.converged)
    return {k: (v if k == "flags" else np.asarray(v)) for k, v in out.items()}


def survey_pol_sensitivity(survey_fit, beacon, *, pols=POL_GRID):
    """Run :func:`pol_sensitivity` on one fitted beacon of a survey, at its fitted sigma_DP.

    Raises
    ------
    ValueError
        When ``beacon`` was not fitted.
    """
    check_choice("beacon", beacon, sorted(survey_fit.results))
    return pol_sensitivity(survey_fit.survey.for_beacon(beacon), pols,
                           sigma_dp=survey_fit.results[beacon].sigma_dp)
