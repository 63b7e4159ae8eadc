"""Pol sensitivity (moved from ``plots``)."""

from __future__ import annotations

import numpy as np


def pol_sensitivity(data, pols, **kwargs):
    """Run the paper's EM for each ``Pol`` (the data of the paper's Fig. 12).

    Parameters
    ----------
    data : BeaconData
    pols : sequence of float
    **kwargs
        Passed to :func:`~bayes_mpem.em.fit_paper_em` (``alpha``, ``sigma_dp``, ...).

    Returns
    -------
    dict of numpy.ndarray
        ``pol``, ``d0``, ``sigma_mp``, ``p_dp``, ``p_mp``, ``p_ol`` (mean class
        probabilities), ``converged`` and ``flags`` (the fit-quality flags of each
        run, collected instead of warned about).
    """
    import warnings

    from ..exceptions import ConvergenceWarning, FitQualityWarning
    from .em_paper import fit_paper_em

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
