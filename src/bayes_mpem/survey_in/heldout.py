"""Held-out (K-fold cross-validated) log predictive density of a transponder's pings.

How much a travel-time extension (refraction, a time-varying sound speed, a
lag, the first-arrival outlier model) gains on pings the fit has not seen:
``benchmarks/measured_gain.py`` sums the paired differences per survey
(``docs/measured-data.md``).
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd

from .._rng import as_generator
from .._validate import check_choice
from ..exceptions import InputError, LocateWarning
from .location import locate
from .travel_times import ship_velocity


def heldout_logpdf(pings: pd.DataFrame, beacons: pd.DataFrame, transponder=None, *,
                   outliers="uniform", n_folds=5, folds="random", rng=0,
                   **kwargs) -> np.ndarray:
    """K-fold cross-validated log predictive density of every ping of one transponder.

    Each fold is located from the other pings (same listening window: the
    whole file's) and scores its own pings with :meth:`LocateResult.logpdf`.

    Parameters
    ----------
    pings, beacons, transponder
        As for :func:`locate`.
    outliers : {"uniform", "first_arrival"}
    n_folds : int, default 5
    folds : {"random", "blocked"}
        Pings assigned to folds at random, or in contiguous blocks of time (a
        harder test for anything that varies in time: each block is predicted
        from the others, not from its neighbours).
    rng : None, int or numpy.random.Generator
        Assigns the pings to random folds.
    **kwargs
        Passed to :func:`locate` (``tat``, ``sound_speed``, ...).

    Returns
    -------
    numpy.ndarray
        One value (log 1/s) per ping of the transponder, in table order.
    """
    check_choice("folds", folds, ("random", "blocked"), words=True)
    full = locate(pings, beacons, transponder, outliers=outliers, **kwargs)
    sub = pings.iloc[full.rows]
    if kwargs.get("fit_lag"):  # each fold's velocities from the whole track, not its own pings
        vx, vy = ship_velocity(sub)
        sub = sub.assign(vx=vx, vy=vy)
    if folds == "random":
        fold = as_generator(rng).permutation(np.arange(full.rows.size) % int(n_folds))
    else:
        if "time" not in sub.columns:
            raise InputError("folds='blocked' needs a 'time' column in pings")
        order = np.argsort(sub["time"].to_numpy(float), kind="stable")
        fold = np.empty(full.rows.size, int)
        fold[order] = np.arange(full.rows.size) * int(n_folds) // full.rows.size
    out = np.empty(full.rows.size)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LocateWarning)
        for k in range(int(n_folds)):
            test = fold == k
            fit_k = locate(sub[~test], beacons, full.transponder, outliers=outliers,
                           window=full.window, time_range=full.model["time_range"], **kwargs)
            out[test] = fit_k.logpdf(sub[test])
    return out
