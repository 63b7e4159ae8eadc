"""What a straight-ray fit cannot absorb of another travel-time model."""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from ..acoustics.turning import direct_times
from .location import LocateResult
from .simcheck import check_straight, ping_rows


def unabsorbed(pings: pd.DataFrame, fit: LocateResult, twtt) -> tuple:
    """Find the part of noise-free travel times that a straight-ray fit cannot absorb.

    Parameters
    ----------
    pings : pandas.DataFrame
        The table the fit was located from.
    fit : LocateResult
    twtt : array_like
        Two-way travel times (s) of the fit's pings (``fit.rows`` order), from
        another model, e.g. :func:`refracted_twtt`.

    Returns
    -------
    residual : numpy.ndarray
        ``twtt`` minus the best straight-ray fit (s).
    shift : dict
        ``east``, ``north``, ``depth``, ``sound_speed`` of that fit minus the
        fit's own: how the straight-ray parameters absorb the model.

    Examples
    --------
    Straight-ray times from another position are absorbed completely:

    >>> import numpy as np, pandas as pd
    >>> from bayes_mpem.survey_in.location import locate
    >>> a = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    >>> rad = np.linspace(300.0, 3000.0, 40)
    >>> pings = pd.DataFrame({"beacon": "T", "x": rad * np.cos(a), "y": rad * np.sin(a),
    ...                       "depth": 0.0, "time": np.arange(40.0)})
    >>> noise = 1e-4 * np.sin(7.0 * np.arange(40))
    >>> pings["twtt"] = 2 * np.sqrt(pings.x**2 + pings.y**2 + 4000.0**2) / 1500.0 + noise
    >>> beacons = pd.DataFrame({"beacon": ["T"], "x": [0.0], "y": [0.0], "depth": [4000.0]})
    >>> fit = locate(pings, beacons, tat=0.0)
    >>> other = 2 * np.sqrt((pings.x - 5) ** 2 + pings.y**2 + 4002.0**2) / 1501.0
    >>> res, shift = unabsorbed(pings, fit, other)
    >>> bool(np.abs(res).max() < 1e-9)
    True
    >>> round(fit.east + shift["east"], 3), round(fit.depth + shift["depth"], 3)
    (5.0, 4002.0)
    """
    check_straight(fit)
    rows = ping_rows(pings, fit)
    target = np.asarray(twtt, float)
    if target.shape != (rows.size,):
        raise ValueError(f"twtt: expected {rows.size} values (the fit's pings), got shape "
                         f"{target.shape}")
    if not np.all(np.isfinite(target)):
        raise ValueError("twtt: non-finite values")
    sub = pings.iloc[rows]
    x, y, z = (sub[c].to_numpy(float) for c in ("x", "y", "depth"))
    th0 = np.array([fit.east, fit.north, fit.depth, fit.sound_speed])

    def resid(th):
        return target - (2.0 * np.sqrt((x - th[0]) ** 2 + (y - th[1]) ** 2 + (z - th[2]) ** 2)
                         / th[3] + fit.tat)

    sol = least_squares(resid, th0, x_scale=np.array([10.0, 10.0, 10.0, 1.0]), xtol=1e-15,
                        ftol=1e-15, gtol=1e-15)
    d = sol.x - th0
    return resid(sol.x), {"east": float(d[0]), "north": float(d[1]), "depth": float(d[2]),
                          "sound_speed": float(d[3])}


def refracted_twtt(pings: pd.DataFrame, fit: LocateResult, profile, *,
                   surface_depth: float = 0.0) -> np.ndarray:
    """Two-way travel times along refracted eigenrays, at the fit's position.

    Parameters
    ----------
    pings : pandas.DataFrame
        The table the fit was located from.
    fit : LocateResult
    profile : bayes_mpem.acoustics.SoundSpeedProfile
    surface_depth : float, default 0
        Depth, in the pings' frame, of the profile's 0 m.

    Returns
    -------
    numpy.ndarray
        ``2 T + fit.tat`` (s) for the fit's pings (``fit.rows`` order), ``T`` the
        one-way time of the direct eigenray
        (:func:`bayes_mpem.acoustics.turning.direct_times`, with a turning point
        where the straight-through ray does not reach).

    Raises
    ------
    ValueError
        Some ping is reached by no direct eigenray at all (a speed maximum
        between the ends, or a turning depth beyond the profile); the message
        gives how many and the first.
    """
    rows = ping_rows(pings, fit)
    sub = pings.iloc[rows]
    x, y, z = (sub[c].to_numpy(float) for c in ("x", "y", "depth"))
    h = np.hypot(x - fit.east, y - fit.north)
    ray = direct_times(profile, z - surface_depth, fit.depth - surface_depth, h)
    bad = np.flatnonzero(~ray.valid)
    if bad.size:
        i = bad[0]
        raise ValueError(f"transponder {fit.transponder}: {bad.size} of {rows.size} pings have "
                         f"no direct eigenray through the profile, even turning (first: row "
                         f"{rows[i]}, horizontal {h[i]:.1f} m, depth {z[i]:g} m)")
    return 2.0 * ray.time + fit.tat
