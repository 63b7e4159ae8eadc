"""Travel times through a sound-speed profile as equivalent straight-line ranges, for navigation.

The method and why: ``docs/navigate.md`` (*Ranges through the sound-speed profile*).

Examples
--------
In a homogeneous medium the equivalent range is speed times time:

>>> from bayes_mpem.acoustics.profile import SoundSpeedProfile
>>> r, ok = equivalent_ranges([2.0], [10.0], [2000.0], SoundSpeedProfile.constant(1500.0))
>>> round(float(r[0]), 6), bool(ok[0])
(3000.0, True)
"""

from __future__ import annotations

import os

import numpy as np
import pandas as pd

from ...acoustics.profile import SoundSpeedProfile
from ...acoustics.profile_checks import check_profile
from ...acoustics.turning import direct_times
from ...exceptions import InputError
from ...io.cells import as_beacon_id
from ...io.tables import Problems, load_table, numeric_column

__all__ = ["TRAVEL_TIMES", "RangeModel", "equivalent_ranges", "prepare", "travel_time_pings"]

#: What the pings' ``range`` column holds when it holds travel times.
TRAVEL_TIMES = ("one-way", "two-way")

#: A transducer more than this far above the profile's sea surface (m) is refused: the
#: tables' depths are then not the profile's (ellipsoidal heights: set ``surface_depth``).
ABOVE_SURFACE = 1.0

#: Newton stops once its step in the horizontal distance is below this (m).
STEP_TOL = 1e-4


def _profile(profile) -> SoundSpeedProfile:
    if isinstance(profile, SoundSpeedProfile):
        return profile
    if isinstance(profile, str | os.PathLike):
        return SoundSpeedProfile.from_file(profile)
    if isinstance(profile, int | float) and not isinstance(profile, bool):
        if not 1300.0 <= float(profile) <= 1800.0:
            raise ValueError(f"profile: a constant sound speed must be in [1300, 1800] m/s, "
                             f"got {profile!r}")
        return SoundSpeedProfile.constant(float(profile))
    raise TypeError("profile: expected a SoundSpeedProfile, a profile file (depth m, speed "
                    f"m/s) or a constant sound speed in m/s, got {type(profile).__name__}")


def equivalent_ranges(time, z_vehicle, z_beacon, profile: SoundSpeedProfile, *,
                      max_iter: int = 30) -> tuple[np.ndarray, np.ndarray]:
    """Equivalent straight-line ranges of one-way travel times through a profile.

    Parameters
    ----------
    time : array_like
        One-way travel times (s), positive.
    z_vehicle, z_beacon : array_like
        Depths of the two ends in the profile's frame (m, positive down). All three
        broadcast.
    max_iter : int, default 30
        Newton steps at most.

    Returns
    -------
    ranges : numpy.ndarray
        ``sqrt(h^2 + dz^2)``, ``h`` the horizontal distance whose direct eigenray
        takes ``time``. A time shorter than the vertical ray's gives the vertical
        distance scaled by the ratio of the times; a time no direct eigenray takes
        (not even a turning one) is converted with the harmonic-mean speed between
        the two depths.
    valid : numpy.ndarray of bool
        Where the eigenray was found and Newton's last step was below ``STEP_TOL``.

    Examples
    --------
    >>> prof = SoundSpeedProfile([0.0, 3000.0], [1480.0, 1520.0])
    >>> t = direct_times(prof, 10.0, 2500.0, 1200.0).time
    >>> r, ok = equivalent_ranges(t, 10.0, 2500.0, prof)
    >>> bool(abs(r[0] - np.hypot(1200.0, 2490.0)) < 1e-6), bool(ok[0])
    (True, True)
    """
    t, za, zb = (np.array(v, float) for v in np.broadcast_arrays(time, z_vehicle, z_beacon))
    t, za, zb = t.ravel(), za.ravel(), zb.ravel()
    dz = np.abs(zb - za)
    top, bot = np.minimum(za, zb), np.maximum(za, zb)
    t_vert = np.asarray(profile.vertical_time(top, bot), float)
    c_max = float(np.max(profile.speeds))
    hm = np.asarray(profile.harmonic_mean(top, bot), float) if dz.size else np.zeros(0)
    hm = np.where(dz > 0, hm, profile.speed(za))
    h = np.sqrt(np.maximum((hm * t) ** 2 - dz ** 2, 0.0))  # the straight ray's, a start
    h_max = c_max * t  # no ray runs farther than the fastest speed for the time
    short = t <= t_vert
    h[short] = 0.0
    todo = np.flatnonzero(~short)
    valid = short.copy()
    for _ in range(max_iter):
        if not todo.size:
            break
        ray = direct_times(profile, za[todo], zb[todo], h[todo])
        lost = ~ray.valid
        step = np.where(lost, 0.0, (t[todo] - ray.time) / np.maximum(ray.p, 1e-9))
        h[todo] = np.clip(h[todo] + step, 0.0, h_max[todo])
        ok = ~lost & (np.abs(step) < STEP_TOL)
        valid[todo[ok]] = True
        todo = todo[~ok & ~lost]
    out = np.hypot(h, dz)
    out[short] = dz[short] * t[short] / np.maximum(t_vert[short], 1e-300)
    bad = ~valid
    out[bad] = np.sqrt(np.maximum((hm[bad] * t[bad]) ** 2, 0.0))
    return out, valid


class RangeModel:
    """How the pings' ``range`` column becomes ranges: the options and what they did.

    Parameters
    ----------
    profile : SoundSpeedProfile, str, os.PathLike or float
        A profile, a profile file (depth m, speed m/s) or a constant sound speed (m/s).
    turnaround : float, default 0
        The beacons' turn-around time (s), subtracted from every travel time.
    transducer_offset : float, default 0
        Depth of the acoustic transducer below the pings' ``depth`` (m, positive down).
    surface_depth : float, default 0
        Depth, in the tables' frame, of the profile's 0 m (the sea surface): non-zero
        where the tables' depths are minus ellipsoidal heights (GNSS-A).

    Raises
    ------
    ValueError
        An option out of its range, naming it.
    InputError
        A bad profile file (naming its line).

    Examples
    --------
    >>> m = RangeModel("two-way", 1500.0, turnaround=0.013)
    >>> m.describe()["profile"]
    'constant 1500.0 m/s'
    """

    def __init__(self, travel_times, profile, *, turnaround=0.0, transducer_offset=0.0,
                 surface_depth=0.0):
        if travel_times not in TRAVEL_TIMES:
            raise ValueError(f"travel_times (--travel-time with --ranges): expected one of "
                             f"{', '.join(TRAVEL_TIMES)}, got {travel_times!r}")
        if profile is None:
            raise ValueError("travel times need a sound-speed profile (profile=, --ssp FILE) "
                             "or a constant speed (--sound-speed C)")
        self.travel_times = travel_times
        self.profile = _profile(profile)
        self.turnaround = _number("turnaround (--turnaround)", turnaround, 0.0, 10.0, "s")
        self.transducer_offset = _number("transducer_offset (--transducer-offset)",
                                         transducer_offset, -100.0, 100.0, "m")
        self.surface_depth = _number("surface_depth (--surface-depth)", surface_depth,
                                     -1000.0, 1000.0, "m")

    def describe(self) -> dict:
        """Return the options as a JSON-ready dict (for ``summary.json``)."""
        return {"travel_times": self.travel_times,
                "profile": self.profile.source or f"{len(self.profile)} knots",
                "turnaround": self.turnaround, "transducer_offset": self.transducer_offset,
                "surface_depth": self.surface_depth}


def _number(name, value, lo, hi, unit):
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = float("nan")
    if not lo <= v <= hi:
        raise ValueError(f"{name}: expected a number in [{lo:g}, {hi:g}] {unit}, got {value!r}")
    return v


def travel_time_pings(pings, beacons, model: RangeModel) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Return the pings with travel times replaced by equivalent straight-line ranges.

    Parameters
    ----------
    pings, beacons : str, os.PathLike or pandas.DataFrame
        The tables of :func:`~bayes_mpem.lbl.navigate.navigate`, the pings' ``range``
        holding travel times (s).

    Returns
    -------
    pings, beacons : pandas.DataFrame
        ``range`` the one-way equivalent range (m), the input kept as
        ``range_input``; ``depth`` the transducer's (the input kept as
        ``depth_input`` when ``transducer_offset`` is not 0); ``ray_traced``
        false where no eigenray takes the time (converted with the harmonic-mean
        speed instead).

    Raises
    ------
    InputError
        A bad cell, a travel time not longer than the turn-around time, a
        transducer above the profile's sea surface (naming the file, line and
        column), a profile that ends above the deepest beacon.

    Examples
    --------
    >>> p = pd.DataFrame({"time": [0.0], "beacon": ["1"], "range": [4.013], "x": [0.0],
    ...                   "y": [0.0], "depth": [10.0]})
    >>> b = pd.DataFrame({"beacon": ["1"], "x": [0.0], "y": [0.0], "depth": [3010.0]})
    >>> out, _ = travel_time_pings(p, b, RangeModel("two-way", 1500.0, turnaround=0.013))
    >>> round(float(out["range"][0]), 6), float(out["range_input"][0])
    (3000.0, 4.013)
    """
    p = load_table(pings, None, "pings")
    b = load_table(beacons, None, "beacons")
    for table, cols in ((p, ("range", "beacon", "depth")), (b, ("beacon", "depth"))):
        missing = [c for c in cols if c not in table.frame.columns]
        if missing:
            raise InputError(f"{table.source}: missing required column {missing[0]!r}")
    problems, bp = Problems(p.source), Problems(b.source)
    raw = numeric_column(p, "range", problems, allow_missing=True, positive=True)
    z_v = numeric_column(p, "depth", problems)
    z_b = numeric_column(b, "depth", bp)
    bp.raise_if_any()
    tat = model.turnaround
    with np.errstate(invalid="ignore"):
        short = ~np.isnan(raw) & (raw <= tat)
    problems.add_mask(short, lambda i: f"{p.where(i, 'range')}: expected a travel time longer "
                                       f"than the turn-around time {tat:g} s, got {raw[i]:g} s")
    depth_of = {as_beacon_id(v): float(z) for v, z in zip(b.frame["beacon"], z_b, strict=True)}
    zb = np.array([depth_of.get(as_beacon_id(v), np.nan) for v in p.frame["beacon"]])
    zt = np.nan_to_num(z_v) + model.transducer_offset  # the transducer, tables' frame
    above = zt - model.surface_depth < -ABOVE_SURFACE
    problems.add_mask(above, lambda i: (
        f"{p.where(i, 'depth')}: the transducer is {model.surface_depth - zt[i]:.3g} m above "
        f"the profile's sea surface (depth {z_v[i]:g} + transducer_offset "
        f"{model.transducer_offset:g} - surface_depth {model.surface_depth:g}); if the depths "
        "are minus ellipsoidal heights, set surface_depth (--surface-depth) to the sea "
        "surface's depth in the tables' frame"))
    problems.raise_if_any()
    deepest = float(max(np.nanmax(zb, initial=0.0), np.max(zt, initial=0.0))
                    - model.surface_depth)
    try:
        check_profile(model.profile, deepest, name="profile (--ssp)")
    except ValueError as err:
        raise InputError(str(err)) from None
    one_way = (raw - tat) / (2.0 if model.travel_times == "two-way" else 1.0)
    reply = np.isfinite(one_way) & np.isfinite(zb)
    rng = np.full(raw.shape, np.nan)
    traced = np.zeros(raw.shape, bool)
    rng[reply], traced[reply] = equivalent_ranges(
        one_way[reply], zt[reply] - model.surface_depth, zb[reply] - model.surface_depth,
        model.profile)
    out = p.frame.copy()
    out["range_input"] = p.frame["range"]
    out["range"] = rng
    out["ray_traced"] = traced | ~reply
    if model.transducer_offset:
        out["depth_input"] = p.frame["depth"]
        out["depth"] = zt
    return _with_lines(out, p), _with_lines(b.frame.copy(), b)


def _with_lines(frame, table):
    """Return ``frame`` carrying ``table``'s source and line numbers (for later messages)."""
    if table.lines is not None:
        frame.attrs.update(source=table.source, lines=tuple(map(int, table.lines)))
    return frame


def prepare(pings, beacons, *, travel_times=None, profile=None, turnaround=0.0,
            transducer_offset=0.0, surface_depth=0.0):
    """Apply :func:`navigate`'s range-model options to its input tables.

    Parameters
    ----------
    travel_times : {"one-way", "two-way"}, optional
        The pings' ``range`` holds travel times (s); default: one-way ranges (m).
    profile, turnaround, surface_depth
        See :class:`RangeModel`; they apply to travel times only.
    transducer_offset : float, default 0
        Depth of the transducer below the pings' ``depth`` (m); with ranges as well as
        with travel times.

    Returns
    -------
    pings, beacons
        Unchanged without options, else the converted tables.
    description : dict or None
        For ``summary.json``.

    Raises
    ------
    ValueError
        Options that do not go together, or out of range.
    InputError
        As :func:`travel_time_pings`.

    Examples
    --------
    >>> p = pd.DataFrame({"time": [0.0], "beacon": ["1"], "range": [2000.0], "x": [0.0],
    ...                   "y": [0.0], "depth": [10.0]})
    >>> b = pd.DataFrame({"beacon": ["1"], "x": [0.0], "y": [0.0], "depth": [2000.0]})
    >>> out, _, info = prepare(p, b, transducer_offset=2.5)
    >>> float(out["depth"][0]), info
    (12.5, {'transducer_offset': 2.5})
    """
    if travel_times is None:
        given = [n for n, v in (("profile (--ssp)", profile is not None),
                                ("turnaround (--turnaround)", bool(turnaround)),
                                ("surface_depth (--surface-depth)", bool(surface_depth))) if v]
        if given:
            raise ValueError(f"{given[0]} applies to travel times only (travel_times='one-way' "
                             "or 'two-way'; --travel-time)")
        offset = _number("transducer_offset (--transducer-offset)", transducer_offset,
                         -100.0, 100.0, "m")
        if not offset:
            return pings, beacons, None
        _not_a_survey(pings, "transducer_offset")
        p = load_table(pings, None, "pings")
        problems = Problems(p.source)
        z = numeric_column(p, "depth", problems)
        problems.raise_if_any()
        out = p.frame.copy()
        out["depth_input"], out["depth"] = p.frame["depth"], z + offset
        return _with_lines(out, p), beacons, {"transducer_offset": offset}
    _not_a_survey(pings, "travel_times")
    model = RangeModel(travel_times, profile, turnaround=turnaround,
                       transducer_offset=transducer_offset, surface_depth=surface_depth)
    p, b = travel_time_pings(pings, beacons, model)
    return p, b, model.describe()


def _not_a_survey(pings, name):
    if not isinstance(pings, str | os.PathLike | pd.DataFrame):
        raise ValueError(f"{name}: give the pings as a file or a DataFrame, not a "
                         f"{type(pings).__name__} (its ranges are already converted)")
