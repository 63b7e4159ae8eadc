"""The constraints of the joint model: physical planes, a second plane below the first."""

from __future__ import annotations

import numpy as np

from .params import Params

#: m: the second plane lies at least this far below the main reflector
SECOND_GAP = 50.0


def main_plane(p: Params) -> float:
    """Depth of the main reflector: the median of the beacons' planes."""
    return float(np.median(p.plane))


def is_feasible(d, p, effects):
    """Planes above the vehicle at every ping; the second plane below the main one.

    Parameters
    ----------
    effects : tuple of str
        The effects switched on.

    Returns
    -------
    bool
        Whether ``p`` satisfies the constraints (and a sound-speed scale within 50 %).
    """
    plane = p.plane[d.bi] + (p.drift * d.tau if "plane_drift" in effects else 0.0)
    ok = bool(np.all(plane <= d.vdepth))
    if "second_reflector" in effects:
        ok = ok and main_plane(p) + SECOND_GAP <= p.plane2 <= float(np.min(d.vdepth))
    if "sound_speed" in effects:
        ok = ok and abs(p.scale) < 0.5
    return ok


def repair(d, p, effects) -> Params:
    """Move an infeasible start just inside the constraints (planes 0.5 m above the vehicle).

    Parameters
    ----------
    effects : tuple of str
        The effects switched on.

    Returns
    -------
    Params
        A copy of ``p``, moved where needed.
    """
    q = p.copy()
    drift = q.drift * d.tau if "plane_drift" in effects else np.zeros(d.n)
    for j in range(d.nb):
        sel = d.bi == j
        if sel.any():
            q.plane[j] = min(q.plane[j], float(np.min(d.vdepth[sel] - drift[sel])) - 0.5)
    if "second_reflector" in effects:
        lo, hi = main_plane(q) + SECOND_GAP, float(np.min(d.vdepth)) - 0.5
        q.plane2 = float(np.clip(q.plane2, lo, max(lo, hi)))
    return q
