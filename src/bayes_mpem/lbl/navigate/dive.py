"""A dive as the navigation sees it: epochs (distinct ping times), dead reckoning, ranges."""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass, field

import numpy as np

from ...exceptions import InputError
from ...io.dead_reckoning import read_dead_reckoning
from ...io.survey import Survey
from ...io.tables import row_name
from ...mixture.densities import uniform_logpdf

#: Pings of one epoch whose dead-reckoned positions differ by more than this (m) are refused.
SAME_EPOCH_TOLERANCE = 0.01
#: A beacon with fewer replies takes the outlier window of all replies (its own few ranges
#: would make a window too narrow, and every reply an outlier).
MIN_WINDOW_REPLIES = 10
#: An interval of a dead-reckoning table longer than this many times the table's local
#: spacing (the median of :data:`LOCAL_INTERVALS` intervals either side) is a gap (a row or
#: more missing): the motion across it is taken as unknown. Local, so that a logger that
#: changes its rate (every 4 s, then every 12 s) has no gap.
GAP_FACTOR = 2.5
#: Intervals either side of one that give the local spacing :data:`GAP_FACTOR` is against.
LOCAL_INTERVALS = 5
#: A gap across which the vehicle cannot stray this far (m) from the straight line (half its
#: fastest speed times the gap) is left as it is: a 1 Hz log's dropout of a few seconds.
MIN_GAP_M = 1.0
#: A gap in a table of velocities whose worst offset (the fastest speed times the gap) is
#: larger than this (m) is refused: every later position carries the offset, and from a
#: start that far off the track's fit was not found again (3.3 km off after a 300-s gap).
MAX_VELOCITY_GAP_M = 50.0
#: An interval of a table of positions whose chord is slower than this share of the local
#: fastest speed (the fastest chord of :data:`LOCAL_INTERVALS` intervals either side), and
#: slower than it by :data:`TURN_MADS` of the chords' local spread too, holds a turn (or a
#: slowing): a straight line between its rows is not trusted where epochs fall inside it and
#: the vehicle could stray :data:`MIN_GAP_M` from the chord.
TURN_SPEED_RATIO = 0.995
#: See :data:`TURN_SPEED_RATIO`: the chords' own jitter (a logger's noise, the dead
#: reckoning's random walk) is not a turn. Without it, a 5-s table of a vehicle at 1.7 m/s
#: had 280-644 "turns" and up to a third of its epochs flagged (a review).
TURN_MADS = 10.0
#: Intervals either side whose chords give the local spread :data:`TURN_MADS` is counted in.
SPREAD_INTERVALS = 25
#: A chord whose heading differs from both neighbours' by more than this (degrees) bends: a
#: vehicle turning at a steady rate has chords of one speed (no deficit), each the chord of
#: an arc whose sagitta is ``(c dt / 2) tan(theta / 4)`` (a circle of 50 m radius logged every
#: 60 s: 18.9 m off the straight lines, unflagged).
TURN_HEADING_DEG = 20.0


@dataclass(frozen=True, eq=False)
class Dive:
    """The navigation problem's data, computed once.

    Attributes
    ----------
    survey : Survey
    times : numpy.ndarray
        ``(K,)`` epoch times (s), increasing.
    dr : numpy.ndarray
        ``(K, 2)`` dead-reckoned position at each epoch (m).
    depth : numpy.ndarray
        ``(K,)`` mean pressure depth of each epoch's pings (m).
    epoch_of_row : numpy.ndarray
        ``(N,)`` epoch of every input row.
    rows, epoch, beacon : numpy.ndarray
        ``(n,)`` per reply: its position in the input table, its epoch and the
        index of its beacon in :attr:`beacon_ids`.
    z, zdepth : numpy.ndarray
        ``(n,)`` the measured range and the vehicle depth of every reply (m).
    beacon_ids : list of str
    beacon_xyz : numpy.ndarray
        ``(B, 3)`` beacon x, y, depth.
    window : numpy.ndarray
        ``(B, 2)`` outlier window of each beacon: its smallest and largest range
        (of all replies below :data:`MIN_WINDOW_REPLIES`).
    d0_min : numpy.ndarray
        ``(B,)`` lowest physical plane height (above every vehicle position).
    dr_source : str
        ``"pings"`` or the dead-reckoning table's label and form.
    dr_gap_var : numpy.ndarray or None
        ``(K - 1,)`` variance (m^2 per axis) added to each step's random walk where the
        dead-reckoning table has a gap (:func:`dead_reckoning_gaps`); None without gaps.
    dr_gaps : tuple of dict
        The table's gaps the epochs meet, as :func:`dead_reckoning_gaps` describes them.
    """

    survey: Survey = field(repr=False)
    times: np.ndarray = field(repr=False)
    dr: np.ndarray = field(repr=False)
    depth: np.ndarray = field(repr=False)
    epoch_of_row: np.ndarray = field(repr=False)
    rows: np.ndarray = field(repr=False)
    epoch: np.ndarray = field(repr=False)
    beacon: np.ndarray = field(repr=False)
    z: np.ndarray = field(repr=False)
    zdepth: np.ndarray = field(repr=False)
    beacon_ids: list
    beacon_xyz: np.ndarray = field(repr=False)
    window: np.ndarray = field(repr=False)
    d0_min: np.ndarray = field(repr=False)
    dr_source: str = "pings"
    dr_gap_var: np.ndarray | None = field(default=None, repr=False)
    dr_gaps: tuple = ()

    @property
    def n_epochs(self) -> int:
        """Number of epochs ``K``."""
        return int(self.times.size)

    @property
    def n(self) -> int:
        """Number of replies."""
        return int(self.z.size)

    @property
    def dt(self) -> np.ndarray:
        """``(K - 1,)`` time between consecutive epochs (s)."""
        return np.diff(self.times)

    @property
    def delta(self) -> np.ndarray:
        """``(K - 1, 2)`` dead-reckoned displacement between consecutive epochs (m)."""
        return np.diff(self.dr, axis=0)

    @property
    def log_ol(self) -> np.ndarray:
        """``(n,)`` log-density of an outlier for every reply (uniform over its beacon's window)."""
        w = self.window[self.beacon]
        return uniform_logpdf(w[:, 0], w[:, 1])

    def replies_per_beacon(self) -> np.ndarray:
        """``(B,)`` number of replies of each beacon."""
        return np.bincount(self.beacon, minlength=len(self.beacon_ids))


def _epoch_dr(survey: Survey, inverse: np.ndarray, k: int) -> np.ndarray:
    """Dead-reckoned position of each epoch from the pings (which must agree)."""
    xy = np.column_stack([survey.x, survey.y])
    sums = np.zeros((k, 2))
    np.add.at(sums, inverse, xy)
    mean = sums / np.bincount(inverse, minlength=k)[:, None]
    off = np.hypot(*(xy - mean[inverse]).T)
    bad = np.flatnonzero(off > SAME_EPOCH_TOLERANCE)
    if bad.size:
        e = inverse[bad[0]]
        rows = np.flatnonzero(inverse == e)
        where = ", ".join(survey.row_name(int(r)) for r in rows[:6])
        more = f" and {rows.size - 6} more" if rows.size > 6 else ""
        raise InputError(
            f"{survey.pings_source}: the pings at time {float(survey.time[bad[0]])!r} s "
            f"({where}{more}) give dead-reckoned positions up to "
            f"{2 * off[inverse == e].max():.3g} m apart; expected one position per ping time "
            "(columns 'x', 'y')")
    return mean


def dead_reckoning_gaps(t, pos, times, form: str):
    """Find where a dead-reckoning table's straight lines are not trusted, and the variance.

    **Gaps.** An interval of the table longer than :data:`GAP_FACTOR` times its local
    spacing (:func:`local_spacing`) is a gap, unless the vehicle cannot stray
    :data:`MIN_GAP_M` from the chord across it. Across a gap the table says nothing of the
    path: interpolating positions draws a chord (wrong by up to half the gap times the speed
    where the vehicle turned), and integrating velocities assumes the speed changed linearly
    (wrong by up to the gap times the speed, for good; :func:`build_dive` refuses such a gap
    beyond :data:`MAX_VELOCITY_GAP_M`, and the offset of a shorter one is a random-walk step
    like the others). So each step between epochs that meets a gap gets the variance
    ``v^2 u G`` per axis (``u`` the seconds of the step inside the gap of length ``G``,
    ``v`` the table's fastest speed outside its gaps): ``(v G)^2`` summed over the gap, the
    vehicle anywhere it could have reached.

    **Turns between rows** (positions only). A regular interval ``dt`` whose chord speed
    ``c`` is below :data:`TURN_SPEED_RATIO` of the local fastest ``v`` (the fastest chord
    of :data:`LOCAL_INTERVALS` intervals either side, itself included), and below it by
    more than :data:`TURN_MADS` of the chords' local spread (that of the faster half),
    holds a turn or a slowing: a vehicle at most that fast, between the two rows, lies
    within the ellipse whose half minor axis is ``b = (dt / 2) sqrt(v^2 - c^2)`` (the
    chord's foci; 0 on a straight leg, ``v dt / 2`` where it turned back). A chord whose
    heading turns from both its neighbours' by ``theta`` above :data:`TURN_HEADING_DEG`
    bends at least as the arc of that chord, ``b = (c dt / 2) tan(theta / 4)`` (a steady
    turn: chords of one speed). Where epochs
    fall inside such an interval and ``b`` exceeds :data:`MIN_GAP_M`, its steps get
    ``(2 b / dt)^2 u dt`` per axis: ``(2 b)^2`` summed over the interval, an epoch in its
    middle ``b`` from either row (a gap is the case ``c = 0``). A table every 60 s of a
    vehicle making U-turns was otherwise 209 m off at a 1 m sd (docs/navigate.md).

    For positions, a step whose two epochs are outside the interval keeps its exact
    displacement and gets nothing.

    Parameters
    ----------
    t : numpy.ndarray
        ``(M,)`` the table's times (s), strictly increasing.
    pos : numpy.ndarray
        ``(M, 2)`` its positions (m), or its velocities (m/s) for ``form="velocity"``.
    times : numpy.ndarray
        ``(K,)`` the epochs (s), within ``[t[0], t[-1]]``.
    form : {"position", "velocity"}

    Returns
    -------
    var : numpy.ndarray or None
        ``(K - 1,)`` added variance of each step (m^2), or None when no interval meets a
        step.
    gaps : list of dict
        Per interval met, in time order: ``kind`` (``"gap"`` or ``"turn"``), ``index`` (the
        table row before it), ``start``, ``end`` (s), ``interval`` (the local spacing, s),
        ``speed`` (m/s), ``n_epochs`` (epochs inside it); a turn also ``chord_speed``
        (m/s) and ``deviation`` (``b``, m).

    Examples
    --------
    >>> t = np.array([0.0, 10.0, 20.0, 60.0, 70.0])
    >>> pos = np.column_stack([t, np.zeros(5)])       # 1 m/s east
    >>> var, gaps = dead_reckoning_gaps(t, pos, np.array([0.0, 15.0, 30.0, 45.0, 70.0]),
    ...                                 "position")
    >>> var.tolist(), [(g["kind"], g["start"], g["end"], g["n_epochs"]) for g in gaps]
    ([0.0, 400.0, 600.0, 600.0], [('gap', 20.0, 60.0, 2)])
    >>> t = np.arange(0.0, 61.0, 10.0)                # east, then back west from t = 35 s
    >>> pos = np.column_stack([np.where(t < 35, t, 70 - t), np.zeros(t.size)])
    >>> var, gaps = dead_reckoning_gaps(t, pos, np.arange(0.0, 61.0, 5.0), "position")
    >>> [(g["kind"], g["start"], g["end"], round(g["deviation"], 2)) for g in gaps]
    [('turn', 30.0, 40.0, 5.0)]
    """
    dt = np.diff(t)
    if times.size < 2 or dt.size == 0:
        return None, []
    spacing = local_spacing(dt)
    long = dt > GAP_FACTOR * spacing
    chord = np.hypot(*np.diff(pos, axis=0).T) / dt if form == "position" else None
    speed = chord[~long] if form == "position" else np.hypot(pos[:, 0], pos[:, 1])
    v = float(speed.max()) if speed.size else 0.0
    var, found = np.zeros(times.size - 1), []

    def add(j, rate):  # the steps meeting interval j: ``rate u dt`` each; None if none
        a, b = t[j], t[j + 1]
        first, stop = np.searchsorted(times, a, "right"), np.searchsorted(times, b, "left")
        k = np.arange(max(first - 1, 0), min(stop, times.size - 1))  # steps that may meet it
        u = np.clip(np.minimum(times[k + 1], b) - np.maximum(times[k], a), 0.0, None)
        if form == "position":  # a step between epochs outside the interval is exact
            u = np.where((k >= first) | (k + 1 < stop), u, 0.0)
        if not u.any():
            return None
        var[k] += rate * u * (b - a)
        return {"index": int(j), "start": float(a), "end": float(b),
                "interval": float(spacing[j]), "n_epochs": int(stop - first)}

    for j in np.flatnonzero(long & (0.5 * v * dt > MIN_GAP_M)):
        entry = add(j, v * v)
        if entry is not None:
            found.append({"kind": "gap", **entry, "speed": v})
    if form == "position":
        dev, reach = _turn_deviation(pos, dt, chord, long)
        for j in np.flatnonzero(dev > MIN_GAP_M):
            entry = add(j, (2.0 * dev[j] / dt[j]) ** 2)  # (2 b)^2 over the interval
            if entry is not None:
                found.append({"kind": "turn", **entry, "speed": float(reach[j]),
                              "chord_speed": float(chord[j]), "deviation": float(dev[j])})
    found.sort(key=lambda g: g["start"])
    return (var if found else None), found


def _turn_deviation(pos, dt, chord, long):
    """Return each interval's bound ``b`` off its chord (0: trusted) and the local fastest speed.

    A chord slower than the local fastest ``v`` (:data:`TURN_SPEED_RATIO`, :data:`TURN_MADS`)
    gets the ellipse's ``(dt / 2) sqrt(v^2 - c^2)``; one whose heading turns from both its
    neighbours' by more than :data:`TURN_HEADING_DEG` at least the sagitta of its arc,
    ``(c dt / 2) tan(theta / 4)``. Gaps (``long``) get 0: their own rule covers them.
    """
    c = np.where(long, np.nan, chord)
    reach = local_fastest(np.where(long, 0.0, chord))
    spread = _local_upper_spread(c)
    slow = ~long & (chord < TURN_SPEED_RATIO * reach) & (reach - chord > TURN_MADS * spread)
    dev = np.where(slow, 0.5 * dt * np.sqrt(np.clip(reach**2 - chord**2, 0.0, None)), 0.0)
    step = np.diff(pos, axis=0)
    heading = np.arctan2(step[:, 1], step[:, 0])
    turn = np.abs(np.angle(np.exp(1j * np.diff(heading))))  # between chords j and j + 1
    length = chord * dt  # a chord under a metre has no heading to speak of
    turn[(length[1:] <= MIN_GAP_M) | (length[:-1] <= MIN_GAP_M)] = 0.0
    theta = np.minimum(np.r_[0.0, turn], np.r_[turn, 0.0])  # bent from both: a steady turn
    bent = ~long & (theta > np.deg2rad(TURN_HEADING_DEG))
    arc = np.where(bent, 0.5 * chord * dt * np.tan(np.minimum(theta, np.pi) / 4.0), 0.0)
    return np.maximum(dev, arc), reach


def _local_upper_spread(x):
    """Return each interval's local spread of the chords: the scaled MAD of the faster half.

    The chords at or above the median of a window of :data:`SPREAD_INTERVALS` either side:
    a straight leg's jitter, without the turns' slower chords (on a table every 60 s of a
    vehicle turning every 150 s, a third of them). Eleven chords gave an estimate too noisy
    (a straight leg's jitter made "turns"). NaN (gaps) ignored.
    """
    w = _windows(x, SPREAD_INTERVALS, np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a window of NaN only
        upper = np.where(w >= np.nanmedian(w, axis=1)[:, None], w, np.nan)
        centre = np.nanmedian(upper, axis=1)
        mad = 1.4826 * np.nanmedian(np.abs(upper - centre[:, None]), axis=1)
    return np.nan_to_num(mad)


def local_fastest(speed):
    """Return each interval's local fastest speed: the largest of its window's, itself too.

    :data:`LOCAL_INTERVALS` intervals either side (fewer at the ends).

    Parameters
    ----------
    speed : numpy.ndarray
        ``(M - 1,)`` a table's chord speeds (m/s).

    Returns
    -------
    numpy.ndarray

    Examples
    --------
    >>> local_fastest(np.r_[[1.0] * 7, 3.0, [1.0] * 7]).tolist()
    [1.0, 1.0, 3.0, 3.0, 3.0, 3.0, 3.0, 3.0, 3.0, 3.0, 3.0, 3.0, 3.0, 1.0, 1.0]
    """
    return _windows(speed, LOCAL_INTERVALS, -np.inf).max(axis=1)


def _windows(x, half, fill):
    """Return the windows of ``half`` values either side of each of ``x`` (a read-only view).

    Past the ends the windows hold ``fill``; a day at 1 Hz needs no loop.
    """
    pad = np.full(half, fill)
    return np.lib.stride_tricks.sliding_window_view(np.r_[pad, np.asarray(x, float), pad],
                                                    2 * half + 1)


def local_spacing(dt):
    """Return each interval's local spacing: the median of its neighbours' (not its own).

    :data:`LOCAL_INTERVALS` intervals either side (fewer at the ends; the interval itself
    where it has no neighbour).

    Parameters
    ----------
    dt : numpy.ndarray
        ``(M - 1,)`` a table's intervals (s).

    Returns
    -------
    numpy.ndarray

    Examples
    --------
    >>> dt = np.r_[[4.0] * 6, [12.0] * 3, 36.0, [12.0] * 3]  # a rate change, then a gap
    >>> local_spacing(dt).tolist()
    [4.0, 4.0, 4.0, 4.0, 4.0, 8.0, 8.0, 12.0, 12.0, 12.0, 12.0, 12.0, 12.0]
    """
    dt = np.asarray(dt, float)
    if dt.size < 2:
        return dt.copy()
    windows = _windows(dt, LOCAL_INTERVALS, np.nan).copy()
    windows[:, LOCAL_INTERVALS] = np.nan  # the interval itself left out
    return np.nanmedian(windows, axis=1)


def _table_dr(survey: Survey, times: np.ndarray, first_xy, source):
    """Dead-reckoned position at ``times`` from a table (positions or velocities).

    Returns the positions, the source's description, and the gaps' added variance and
    descriptions (:func:`dead_reckoning_gaps`, each with the table's ``file`` and the
    ``lines`` either side).
    """
    table, form = read_dead_reckoning(source)
    label = source if isinstance(source, str) else "dead-reckoning DataFrame"
    t = table["time"].to_numpy()
    out = np.flatnonzero((survey.time < t[0]) | (survey.time > t[-1]))
    if out.size:
        i = out[0]
        outside = survey.time[out]
        raise InputError(
            f"{survey.pings_source} {survey.row_name(int(i))}, column 'time': "
            f"{float(survey.time[i])!r} s is outside the dead-reckoning table's span "
            f"[{float(t[0])!r}, {float(t[-1])!r}] s ({label}); {out.size} ping(s) are outside "
            f"it (times {float(outside.min())!r} to {float(outside.max())!r} s); expected a "
            "dead-reckoning table that spans every ping")
    if form == "position":
        pos = table[["x", "y"]].to_numpy()
        var, gaps = dead_reckoning_gaps(t, pos, times, form)
    else:
        v = table[["ve", "vn"]].to_numpy()
        var, gaps = dead_reckoning_gaps(t, v, times, form)
        steps = 0.5 * (v[1:] + v[:-1]) * np.diff(t)[:, None]
        pos = np.vstack([np.zeros((1, 2)), np.cumsum(steps, axis=0)])
    dr = np.column_stack([np.interp(times, t, pos[:, 0]), np.interp(times, t, pos[:, 1])])
    if form == "velocity":  # integrated from the pings' first dead-reckoned position
        dr += np.asarray(first_xy, float) - dr[0]
    for g in gaps:
        labels = source.index if hasattr(source, "columns") else None  # a DataFrame's rows
        lines = table.attrs.get("lines")
        g.update(file=label, lines=[row_name(g["index"], lines, labels),
                                    row_name(g["index"] + 1, lines, labels)], form=form)
    far = [g for g in gaps if g["speed"] * (g["end"] - g["start"]) > MAX_VELOCITY_GAP_M]
    if form == "velocity" and far:
        g = far[0]
        raise InputError(
            f"{label} {g['lines'][0]} to {g['lines'][1]}, column 'time': a gap of "
            f"{g['end'] - g['start']:g} s (t = {g['start']:g} to {g['end']:g} s) where the "
            f"rows are {g['interval']:g} s apart ({len(far)} such gap(s) among the pings); "
            "expected velocities without a gap across which the vehicle could go more than "
            f"{MAX_VELOCITY_GAP_M:g} m: integrated across this one, every later position is off "
            f"by up to {g['speed'] * (g['end'] - g['start']):.3g} m, which the ranges cannot be "
            "relied on to find; fill the gap, or navigate the parts before and after it "
            "separately")
    return dr, f"{label} ({form}s)", var, tuple(gaps)


def build_dive(survey: Survey, dead_reckoning=None) -> Dive:
    """Group the pings into epochs and attach the dead reckoning.

    Parameters
    ----------
    survey : Survey
        Pings (``x``, ``y``: dead-reckoned; ``depth``: pressure) and beacons.
    dead_reckoning : str, os.PathLike or pandas.DataFrame, optional
        A dead-reckoning table; default: the pings' own ``x``, ``y``.

    Raises
    ------
    InputError
        Pings of one time with different dead-reckoned positions; a ping outside
        the dead-reckoning table's span; a bad dead-reckoning table; a gap among the
        pings in a table of velocities (:func:`dead_reckoning_gaps`); no reply at all.

    Examples
    --------
    >>> import pandas as pd
    >>> from bayes_mpem.io.survey import load_survey
    >>> s = load_survey(pd.DataFrame({"time": [0, 0, 5], "beacon": [1, 2, 1],
    ...                               "range": [100.0, None, 101.0], "x": [0, 0, 3],
    ...                               "y": [0, 0, 0], "depth": [10, 10, 10]}),
    ...                 pd.DataFrame({"beacon": [1, 2], "x": [0, 50], "y": [0, 0],
    ...                               "depth": [100, 100]}))
    >>> d = build_dive(s)
    >>> d.n_epochs, d.n, d.epoch.tolist()
    (2, 2, [0, 1])
    """
    times, inverse = np.unique(np.asarray(survey.time), return_inverse=True)
    k = times.size
    if dead_reckoning is None:
        return _assemble(survey, times, inverse, _epoch_dr(survey, inverse, k), "pings")
    first = np.flatnonzero(inverse == 0)[0]
    dr, source, var, gaps = _table_dr(survey, times, (survey.x[first], survey.y[first]),
                                      dead_reckoning)
    dive = _assemble(survey, times, inverse, dr, source)
    if not gaps:
        return dive
    return dataclasses.replace(dive, dr_gap_var=var, dr_gaps=gaps)


def dive_with_dead_reckoning(survey: Survey, times, dr, source: str = "pings") -> Dive:
    """Rebuild the :class:`Dive` of a navigation from its pings and its epochs' dead reckoning.

    Parameters
    ----------
    times : array_like
        ``(K,)`` epoch times (s): the distinct ping times, increasing.
    dr : array_like
        ``(K, 2)`` dead-reckoned position at each epoch (m), as ``track.csv`` holds it.
    source : str, default "pings"
        :attr:`Dive.dr_source`.

    Raises
    ------
    InputError
        When ``times`` are not the pings' distinct times, or ``dr`` is not ``(K, 2)``.
    """
    own, inverse = np.unique(np.asarray(survey.time), return_inverse=True)
    times = np.asarray(times, float)
    dr = np.asarray(dr, float)
    if own.shape != times.shape or not np.array_equal(own, times):
        raise InputError(f"{survey.pings_source}: {own.size} distinct ping times, but the track "
                         f"has {times.size} epochs (or other times); expected the epochs of "
                         "these pings")
    if dr.shape != (times.size, 2):
        raise InputError(f"dead reckoning: expected shape ({times.size}, 2), got {dr.shape}")
    return _assemble(survey, times, inverse, dr, source)


def _assemble(survey: Survey, times, inverse, dr, source) -> Dive:
    """Return the :class:`Dive` of pings grouped by ``inverse`` (each row's epoch)."""
    k = times.size
    depth = np.bincount(inverse, weights=survey.depth, minlength=k) / np.bincount(
        inverse, minlength=k)
    rows = np.flatnonzero(~survey.no_reply)
    if rows.size == 0:
        raise InputError(f"{survey.pings_source}: no ping has a reply (every 'range' cell is "
                         "empty): nothing to navigate by")
    ids = survey.beacon_ids
    index = {b: i for i, b in enumerate(ids)}
    beacon = np.array([index[b] for b in survey.beacon[rows]], dtype=np.int64)
    z, zdepth = np.asarray(survey.range)[rows], np.asarray(survey.depth)[rows]
    xyz = survey.beacons[["x", "y", "depth"]].to_numpy(float)
    window = np.tile([z.min(), max(z.max(), z.min() + 1.0)], (len(ids), 1))
    d0_min = np.zeros(len(ids))
    for j in range(len(ids)):
        mine = beacon == j
        if mine.sum() >= MIN_WINDOW_REPLIES:
            window[j] = z[mine].min(), z[mine].max()
        if mine.any():
            d0_min[j] = max(0.0, float((xyz[j, 2] - zdepth[mine]).max()))
    return Dive(survey, times, dr, depth, inverse.astype(np.int64), rows, inverse[rows],
                beacon, z, zdepth, ids, xyz, window, d0_min, source)
