"""Surveys given as travel times, two-way ranges or latitude/longitude, in the package's units.

Details: ``docs/input.md``.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..exceptions import InputError
from .geodesy import geodetic_to_enu
from .tables import Problems, load_table, numeric_column

__all__ = ["RANGE_KINDS", "convert_survey"]

#: What the ``range`` column holds: one-way or two-way (ranges or travel times).
RANGE_KINDS = ("one-way", "two-way")


def _check(ranges, travel_time, sound_speed, turnaround, origin, ssp):
    if ranges not in RANGE_KINDS:
        raise InputError(f"ranges: expected one of {', '.join(RANGE_KINDS)}, got {ranges!r}")
    if travel_time:
        if sound_speed is not None and ssp is not None:
            raise InputError("travel times: give --sound-speed or --ssp, not both")
        if ssp is None and (sound_speed is None or not 1300.0 <= float(sound_speed) <= 1800.0):
            raise InputError("travel times need the sound speed (--sound-speed) in [1300, 1800] "
                             f"m/s or a profile (--ssp FILE), got {sound_speed!r}")
        if not 0.0 <= float(turnaround) <= 10.0:
            raise InputError(f"turnaround (--turnaround): expected [0, 10] s, got {turnaround!r}")
    elif sound_speed is not None or turnaround or ssp is not None:
        raise InputError("--sound-speed, --ssp and --turnaround apply to --travel-time only")
    if origin is not None:
        lat0, lon0 = (float(v) for v in origin)
        if not (-90.0 <= lat0 <= 90.0 and -180.0 <= lon0 <= 180.0):
            raise InputError(f"origin (--origin): expected LAT,LON in degrees, got {origin!r}")


def _positions(table, problems):
    cols = set(map(str, table.frame.columns))
    if {"x", "y"} <= cols:
        return None
    if {"lat", "lon"} <= cols:
        return (numeric_column(table, "lat", problems), numeric_column(table, "lon", problems))
    raise InputError(f"{table.source}: expected the columns 'x', 'y' (local metres) or 'lat', "
                     f"'lon' (degrees); found {', '.join(map(repr, table.frame.columns))}")


def _profile_speeds(ssp, p, b, problems):
    """Each ping's harmonic-mean sound speed between its vehicle's and its beacon's depths."""
    from .cells import as_beacon_id

    bp = Problems(b.source)
    z_b = numeric_column(b, "depth", bp)
    bp.raise_if_any()
    depth_of = {as_beacon_id(v): float(z) for v, z in zip(b.frame["beacon"], z_b, strict=True)}
    z_v = numeric_column(p, "depth", problems)
    # a ping of an unknown beacon gets a speed at depth 0: the survey's reader refuses it
    z_p = np.array([depth_of.get(as_beacon_id(v), 0.0) for v in p.frame["beacon"]])
    return np.asarray(ssp.harmonic_mean(np.nan_to_num(z_v), z_p), float)


def convert_survey(pings, beacons, *, ranges: str = "one-way", travel_time: bool = False,
                   sound_speed: float | None = None, turnaround: float = 0.0,
                   origin=None, ssp=None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Return the pings and beacons tables with one-way ranges (m) and local x, y (m).

    Parameters
    ----------
    pings, beacons : str, os.PathLike or pandas.DataFrame
    ranges : {"one-way", "two-way"}
        What the ``range`` column holds.
    travel_time : bool, default False
        The ``range`` column holds travel times (s).
    sound_speed : float, optional
        Mean sound speed (m/s), for travel times.
    turnaround : float, default 0
        The beacons' turn-around time (s), included in each travel time.
    origin : (float, float), optional
        Latitude, longitude of the local frame's origin (tables in ``lat``, ``lon``);
        default the beacons' mean position.
    ssp : SoundSpeedProfile, optional
        Instead of ``sound_speed``: each travel time is converted with the harmonic-mean
        speed between the vehicle's and the beacon's depths.

    Returns
    -------
    pings, beacons : pandas.DataFrame
        Every input column kept; ``range`` (input kept as ``range_input``), ``x``, ``y``.

    Raises
    ------
    InputError
        A bad option or cell (naming file, line, column), a travel time not longer than the
        turn-around time, tables with different position columns.
    """
    _check(ranges, travel_time, sound_speed, turnaround, origin, ssp)
    p = load_table(pings, None, "pings")
    b = load_table(beacons, None, "beacons")
    if "range" not in p.frame.columns:
        raise InputError(f"{p.source}: missing required column 'range'")
    problems = Problems(p.source)
    raw = numeric_column(p, "range", problems, allow_missing=True, positive=True)
    pos_p, pos_b = _positions(p, problems), _positions(b, Problems(b.source))
    if (pos_p is None) != (pos_b is None):
        raise InputError(f"{p.source} and {b.source}: give positions the same way in both "
                         "tables (x, y in local metres, or lat, lon in degrees)")
    if travel_time:
        with np.errstate(invalid="ignore"):
            short = ~np.isnan(raw) & (raw <= turnaround)
        problems.add_mask(short, lambda i: f"{p.where(i, 'range')}: expected a travel time "
                                           f"longer than the turn-around time {turnaround:g} "
                                           f"s, got {raw[i]:g} s")
    speed = (_profile_speeds(ssp, p, b, problems) if travel_time and ssp is not None
             else None if sound_speed is None else float(sound_speed))
    problems.raise_if_any()
    pings_out, beacons_out = p.frame.copy(), b.frame.copy()
    rng = raw.copy()
    if travel_time:
        rng = (rng - turnaround) * speed
    if ranges == "two-way":
        rng = rng / 2.0
    if travel_time or ranges == "two-way":
        pings_out["range_input"] = p.frame["range"]
        pings_out["range"] = rng
    if pos_p is not None:
        bp = Problems(b.source)
        lat_b, lon_b = numeric_column(b, "lat", bp), numeric_column(b, "lon", bp)
        bp.raise_if_any()
        lat0, lon0 = ((float(np.mean(lat_b)), float(np.mean(lon_b))) if origin is None
                      else (float(origin[0]), float(origin[1])))
        for frame, (lat, lon) in ((pings_out, pos_p), (beacons_out, (lat_b, lon_b))):
            e, n, _ = geodetic_to_enu(lat, lon, np.zeros_like(lat), lat0, lon0)
            frame["x"], frame["y"] = np.asarray(e, float), np.asarray(n, float)
    for frame, table in ((pings_out, p), (beacons_out, b)):  # messages name the file's lines
        if table.lines is not None:  # a tuple: pandas compares attrs when it combines frames
            frame.attrs.update(source=table.source, lines=tuple(map(int, table.lines)))
    return pings_out, beacons_out
