"""Where the transponder settled against where it was dropped: drift, azimuth, depth change.

The depth change is the located depth minus the drop point's (OBSrange's ``dz`` is its
negative); the azimuth is degrees clockwise from north.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import norm

from ..mcmc.summaries import draw_summary


def _wald(mean, sd, ci):
    half = float(norm.ppf(0.5 + ci / 2)) * float(sd)
    return {"mean": float(mean), "sd": float(sd),
            "interval": [float(mean) - half, float(mean) + half]}


def drift_from_fit(east, north, depth, cov, drop_depth=None, *, ci=0.95) -> dict:
    """Drift, azimuth and depth change of a located transponder, with Wald intervals.

    Parameters
    ----------
    east, north, depth : float
        The located transponder in the drop point's frame (m; depth positive down).
    cov : array_like
        ``(3, 3)`` covariance of east, north, depth.
    drop_depth : float, optional
        The drop point's depth (m); without it there is no ``depth_change``.
    ci : float, default 0.95

    Returns
    -------
    dict
        ``drift`` (m), ``azimuth`` (degrees clockwise from north, in [0, 360);
        its interval may cross 0 or 360), ``depth_change`` (m, positive when
        deeper than the drop point), each ``{"mean", "sd", "interval"}``; the
        interval of the drift is clipped at 0.

    Examples
    --------
    >>> d = drift_from_fit(3.0, 4.0, 1000.0, [[1, 0, 0], [0, 1, 0], [0, 0, 4]], 990.0)
    >>> d["drift"]["mean"], round(d["azimuth"]["mean"], 2), d["depth_change"]["sd"]
    (5.0, 36.87, 2.0)
    """
    C = np.asarray(cov, float)
    r = float(np.hypot(east, north))
    if r > 0:
        g = np.array([east / r, north / r])
        a = np.array([north / r**2, -east / r**2])
    else:
        g = a = np.zeros(2)
    out = {"drift": _wald(r, np.sqrt(max(g @ C[:2, :2] @ g, 0.0)), ci),
           "azimuth": _wald(np.degrees(np.arctan2(east, north)) % 360.0,
                            np.degrees(np.sqrt(max(a @ C[:2, :2] @ a, 0.0))), ci)}
    out["drift"]["interval"][0] = max(out["drift"]["interval"][0], 0.0)
    if drop_depth is not None:
        out["depth_change"] = _wald(depth - float(drop_depth), np.sqrt(max(C[2, 2], 0.0)), ci)
    return out


def drift_from_draws(east, north, depth, drop_depth=None, *, ci=0.95) -> dict:
    """Drift, azimuth and depth change from posterior draws, with equal-tailed intervals.

    Parameters
    ----------
    east, north, depth : array_like
        Draws (any shape, the same for the three).
    drop_depth : float, optional
    ci : float, default 0.95

    Returns
    -------
    dict
        As :func:`drift_from_fit`; the azimuth's draws are unwrapped around
        their circular mean before the interval is taken.
    """
    e, n, d = (np.asarray(v, float).ravel() for v in (east, north, depth))
    r = np.hypot(e, n)
    az = np.degrees(np.arctan2(e, n))
    centre = np.degrees(np.arctan2(np.mean(np.sin(np.radians(az))),
                                   np.mean(np.cos(np.radians(az)))))
    az = centre + (az - centre + 180.0) % 360.0 - 180.0

    out = {"drift": draw_summary(r, ci), "azimuth": draw_summary(az, ci)}
    shift = out["azimuth"]["mean"] % 360.0 - out["azimuth"]["mean"]
    out["azimuth"]["mean"] += shift
    out["azimuth"]["interval"] = [v + shift for v in out["azimuth"]["interval"]]
    if drop_depth is not None:
        out["depth_change"] = draw_summary(d - float(drop_depth), ci)
    return out
