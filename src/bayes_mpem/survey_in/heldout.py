"""Held-out (K-fold cross-validated) log predictive density of a transponder's pings."""

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


#: A lag is recommended when it predicts held-out pings better by at least this many nats ...
LAG_MIN_GAIN = 10.0
#: ... and by at least this many standard errors of the paired sum.
LAG_MIN_Z = 4.0


def lag_check(pings: pd.DataFrame, beacons: pd.DataFrame, transponder=None, *, n_folds=5,
              rng=0, **kwargs) -> dict:
    """Is the acoustic position behind the logged one? The held-out gain of a fitted lag.

    Parameters
    ----------
    pings, beacons, transponder
        As for :func:`locate` (``time``, ``x``, ``y`` for the ship's velocity).
    n_folds : int, default 5
    rng : None, int or numpy.random.Generator
        Assigns the pings to folds.
    **kwargs
        Passed to :func:`locate` (``tat``, ``ssp``, ...; not ``fit_lag``).

    Returns
    -------
    dict
        ``lag`` and ``lag_sd`` (s), ``gain`` and ``gain_se`` (nats, lag minus no
        lag, summed over pings), ``rms_ms_without`` and ``rms_ms_with`` (the
        scatter of true arrivals, ms), ``recommended`` (a gain of at least :data:`LAG_MIN_GAIN`
        nats and :data:`LAG_MIN_Z` standard errors) and ``rule``; only ``skipped`` (why)
        where the folds, or the fit with a lag, have too few pings.
    """
    kwargs.pop("fit_lag", None)
    seed = as_generator(rng).integers(2**63)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LocateWarning)
        try:
            fits = [locate(pings, beacons, transponder, fit_lag=lag, **kwargs)
                    for lag in (False, True)]
            held = [heldout_logpdf(pings, beacons, transponder, fit_lag=lag, n_folds=n_folds,
                                   rng=seed, **kwargs) for lag in (False, True)]
        except InputError as exc:  # the survey's own fit ran: its folds are too small
            return {"skipped": f"too few pings for a {n_folds}-fold held-out check with a "
                               f"fitted lag ({exc})"}
    d = held[1] - held[0]
    gain, se = float(d.sum()), float(np.sqrt(d.size * d.var()))
    return {"lag": float(fits[1].model["lag"]), "lag_sd": float(fits[1].sd.get("lag", 0.0)),
            "gain": gain, "gain_se": se, "rms_ms_without": 1e3 * fits[0].sigma,
            "rms_ms_with": 1e3 * fits[1].sigma,
            "recommended": bool(gain >= LAG_MIN_GAIN and gain >= LAG_MIN_Z * se),
            "rule": f"recommended when the {n_folds}-fold held-out gain is >= "
                    f"{LAG_MIN_GAIN:g} nats and >= {LAG_MIN_Z:g} standard errors"}
