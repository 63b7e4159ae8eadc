"""Where the ranges did not correct the navigation.

The flags: ``docs/navigate.md`` (*Where it cannot correct*).

Examples
--------
>>> import numpy as np
>>> major_sd(np.array([[[4.0, 0.0], [0.0, 1.0]]])).tolist()
[2.0]
"""

from __future__ import annotations

import numpy as np

#: A nuisance is "not identified" when its posterior sd exceeds this fraction of the prior's.
PRIOR_FRACTION = 0.5


def major_sd(cov) -> np.ndarray:
    """Return the standard deviation along the major axis of each 2x2 covariance.

    Parameters
    ----------
    cov : numpy.ndarray
        ``(K, 2, 2)``.

    Returns
    -------
    numpy.ndarray
        ``(K,)`` square root of the largest eigenvalue.
    """
    a, b, c = cov[:, 0, 0], cov[:, 0, 1], cov[:, 1, 1]
    lam = 0.5 * (a + c) + np.sqrt(0.25 * (a - c) ** 2 + b * b)
    return np.sqrt(np.maximum(lam, 0.0))


def _stretches(mask):
    """``(start, stop)`` index pairs (stop exclusive) of the runs of True in ``mask``."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1), strict=True))


def _reason(dive, resp, i0, i1) -> str:
    inside = (dive.epoch >= i0) & (dive.epoch < i1)
    useful = inside & (resp[:, 0] + resp[:, 1] >= 0.5)
    seen = sorted({dive.beacon_ids[j] for j in np.unique(dive.beacon[useful])})
    if not seen:
        return "no direct-path or multipath reply"
    if len(seen) == 1:
        return f"replies from beacon {seen[0]} only"
    return (f"replies from beacons {', '.join(seen)}, whose geometry leaves a direction "
            "unresolved")


def _loose(dive) -> np.ndarray:
    """``(K,)`` epochs whose every step to a neighbour crosses a gap or a turn.

    The epochs inside one, and an epoch at a row between two: the motion model does not
    hold them.
    """
    var = dive.dr_gap_var
    if var is None or var.size == 0:
        return np.zeros(dive.n_epochs, bool)
    loose = var > 0
    return np.r_[loose[:1], loose[1:] & loose[:-1], loose[-1:]]


#: Inside a gap or a turn, the replies of an epoch left without one leave a direction open
#: where their bearings' information is this flat (its smallest over its largest eigenvalue:
#: ``tan^2 15°``, two bearings within 30 degrees of parallel).
OPEN_RATIO = float(np.tan(np.deg2rad(15.0)) ** 2)


def _ambiguous_in_gaps(dive, resp, loose, track=None) -> np.ndarray:
    """``(K,)`` epochs inside a gap or a turn of the dead reckoning that their replies do not fix.

    There (:func:`_loose`) the motion model no longer holds the position: an epoch with
    useful replies from fewer than three beacons fits two positions (two circles cross
    twice). With ``track``, also an epoch whose useful replies, any one beacon's left out, leave a
    direction open (:data:`OPEN_RATIO`): that one reply alone places the vehicle across
    it, and a spurious one is not told from a true one (simulated: two beacons on either
    side of the vehicle and an outlier of a third taken as true, 176 m off at a 4 m sd).
    """
    out = np.zeros(dive.n_epochs, bool)
    gaps = getattr(dive, "dr_gaps", ())
    if not gaps:
        return out
    useful = resp[:, 0] + resp[:, 1] >= 0.5
    pairs = np.unique(np.column_stack([dive.epoch[useful], dive.beacon[useful]]), axis=0)
    n_beacons = np.bincount(pairs[:, 0], minlength=dive.n_epochs)
    out = loose & (n_beacons < 3)
    if track is None:
        return out
    for k in np.flatnonzero(loose & (n_beacons >= 3)):
        b = pairs[pairs[:, 0] == k, 1]
        d = track[k] - dive.beacon_xyz[b, :2]
        slant = np.sqrt((d**2).sum(axis=1) + (dive.depth[k] - dive.beacon_xyz[b, 2]) ** 2)
        g = d / slant[:, None]  # a range's gradient in the horizontal
        for i in range(b.size):
            rest = np.delete(g, i, axis=0)
            vals = np.linalg.eigvalsh(rest.T @ rest)
            if vals[0] <= OPEN_RATIO * vals[1]:
                out[k] = True
                break
    return out


#: An epoch inside a gap or a turn of the dead reckoning is out of the vehicle's reach where
#: its fitted position is farther from the fitted epochs either side of the interval than this
#: many times the table's fastest speed times the time between them, plus three sds.
REACH_MARGIN = 1.05


def _out_of_reach(dive, track, sd, loose) -> np.ndarray:
    """``(K,)`` epochs inside a gap or a turn whose fitted position the vehicle cannot reach.

    Across a gap or a turn of the table the steps are loose (the vehicle anywhere it could
    go), so an epoch's own replies place it; where they are half spurious, the fit can sit
    where a spurious reply agrees with the two crossings of two true ones (simulated: 110 to
    200 m off at a 4 m sd). No vehicle at most the table's fastest speed (times
    :data:`REACH_MARGIN`, for the speed scale's error) gets there from the epochs either
    side of the interval and back, or from the loose epoch before it: those epochs are not
    corrected.
    """
    out = np.zeros(dive.n_epochs, bool)
    gaps = getattr(dive, "dr_gaps", ())
    if track is None or not gaps:
        return out
    t = dive.times
    for g in gaps:
        inside = np.flatnonzero((t > g["start"]) & (t < g["end"]))
        for end in (np.flatnonzero(t <= g["start"])[-1:], np.flatnonzero(t >= g["end"])[:1]):
            if not (inside.size and end.size):
                continue
            j = int(end[0])
            far = np.hypot(*(track[inside] - track[j]).T)
            reach = (REACH_MARGIN * g["speed"] * np.abs(t[inside] - t[j])
                     + 3.0 * np.hypot(sd[inside], sd[j]))
            out[inside[far > reach]] = True
    # and each step between two loose epochs (a review: 149 m in 12 s, at 8.6 m/s, 72 m off
    # at a 7.5 m sd, the interval's ends 48 s away and within reach)
    both = np.flatnonzero(loose[:-1] & loose[1:])
    fastest = max(g["speed"] for g in gaps)
    step = np.hypot(*(track[both + 1] - track[both]).T)
    reach = (REACH_MARGIN * fastest * np.diff(t)[both]
             + 3.0 * np.hypot(sd[both], sd[both + 1]))
    bad = both[step > reach]
    out[bad] = out[bad + 1] = True
    return out


def _gap_flag(dive, sd, gap: dict) -> dict:
    """Return the flag of a gap or a turn of the dead-reckoning table (``dive.dr_gaps``)."""
    near = (dive.times >= gap["start"]) & (dive.times <= gap["end"])
    worst = float(sd[near].max()) if near.any() else None
    told = ("the ranges position the vehicle there" if worst is None
            else f"the ranges position the vehicle there (position sd up to {worst:.3g} m)")
    where = (f"dead reckoning {gap['file']}", f"t = {gap['start']:g} and {gap['end']:g} s",
             f"{gap['lines'][0]} and {gap['lines'][1]}")
    if gap.get("kind") == "turn":
        kind, reason = "dead_reckoning_turn", (
            f"{where[0]} between {where[1]} ({where[2]}, {gap['end'] - gap['start']:g} s "
            f"apart, {gap['n_epochs']} epoch(s) between them): the vehicle turned or slowed "
            f"between the rows (their chord at {gap['chord_speed']:.3g} m/s, the table's "
            f"fastest nearby {gap['speed']:.3g} m/s): not interpolated as a straight line; "
            f"the position there is taken as unknown within {gap['deviation']:.3g} m of it, "
            f"and {told}")
    else:
        kind, reason = "dead_reckoning_gap", (
            f"{where[0]} has no row between {where[1]} ({where[2]}: a gap of "
            f"{gap['end'] - gap['start']:g} s where its rows are {gap['interval']:g} s "
            f"apart, {gap['n_epochs']} epoch(s) inside): not interpolated across; the "
            f"motion there is taken as unknown (up to {gap['speed']:.3g} m/s, the "
            f"table's fastest) and {told}")
    return {"kind": kind, "file": gap["file"], "lines": list(gap["lines"]),
            "start": gap["start"], "end": gap["end"], "n_epochs": gap["n_epochs"],
            "max_sd": worst, "reason": reason}


#: The flags of :func:`_gap_flag`.
TABLE_KINDS = ("dead_reckoning_gap", "dead_reckoning_turn")


def assess(dive, cov, resp, nuisances: dict, *, max_sd: float, track=None) -> list:
    """Flag where the ranges did not correct the navigation.

    Parameters
    ----------
    cov : numpy.ndarray
        ``(K, 2, 2)`` covariance of every epoch.
    resp : numpy.ndarray
        ``(n, 3)`` class probabilities of the replies.
    nuisances : dict
        ``{name: (posterior sd, prior sd, unit)}`` of the dead-reckoning nuisances.
    max_sd : float
        An epoch whose major-axis position sd exceeds this (m) is not corrected.
    track : numpy.ndarray, optional
        ``(K, 2)`` the fitted track: an epoch inside a gap or a turn of the dead reckoning
        whose position the vehicle cannot reach from the epochs either side is not
        corrected (:func:`_out_of_reach`).

    Returns
    -------
    list of dict
        ``kind`` (``"track"``, ``"dead_reckoning_gap"``, ``"dead_reckoning_turn"`` or the
        nuisance's name),
        ``reason`` and, for the track, ``start``, ``end`` (s), ``n_epochs`` and
        ``max_sd`` (m); for a gap or a turn of the dead-reckoning table, its ``file``, the
        ``lines`` either side, ``start``, ``end``, ``n_epochs`` and ``max_sd``
        (the track's largest sd from one side of the gap to the other).
    """
    sd = major_sd(cov)
    flags = []
    loose = _loose(dive)  # the epochs the motion model does not hold
    ambiguous = _ambiguous_in_gaps(dive, resp, loose, track)
    unreachable = _out_of_reach(dive, track, sd, loose)
    for i0, i1 in _stretches((sd > max_sd) | ambiguous | unreachable):
        why = _reason(dive, resp, i0, i1)
        if unreachable[i0:i1].any():
            why = ("inside a gap (or a turn) of the dead reckoning, the fitted position is "
                   "farther from the epochs either side than the vehicle can go at the "
                   "table's fastest speed (replies spurious taken as true); " + why)
        elif ambiguous[i0:i1].any():
            why = ("inside a gap (or a turn) of the dead reckoning, where an epoch with "
                   "replies from fewer than three beacons fits two positions, or one whose "
                   "replies, any one left out, leave a direction open (a spurious reply "
                   "among them is not told from a true one); " + why)
        flags.append({"kind": "track", "start": float(dive.times[i0]),
                      "end": float(dive.times[i1 - 1]), "n_epochs": int(i1 - i0),
                      "max_sd": float(sd[i0:i1].max()), "reason": why})
    for g in getattr(dive, "dr_gaps", ()):
        flags.append(_gap_flag(dive, sd, g))
    for name, (post, prior, unit) in nuisances.items():
        if post > PRIOR_FRACTION * prior:
            flags.append({"kind": name, "reason": (
                f"the ranges do not identify the {name.replace('_', ' ')}: posterior sd "
                f"{post:.3g} {unit} against the prior's {prior:.3g} {unit}")})
    return flags


def describe(flags: list) -> str:
    """One sentence per flag (at most three track stretches listed), for a warning.

    Parameters
    ----------
    flags : list of dict
        From :func:`assess`.

    Examples
    --------
    >>> print(describe([{"kind": "track", "start": 0.0, "end": 60.0, "n_epochs": 6,
    ...                  "max_sd": 250.0, "reason": "replies from beacon 1 only"}]))
    ... # doctest: +NORMALIZE_WHITESPACE
    navigation not corrected for t = 0-60 s (6 epochs, position sd up to 250 m): replies from
    beacon 1 only
    """
    track = [f for f in flags if f["kind"] == "track"]
    parts = [f"navigation not corrected for t = {f['start']:.0f}-{f['end']:.0f} s "
             f"({f['n_epochs']} epochs, position sd up to {f['max_sd']:.3g} m): {f['reason']}"
             for f in track[:3]]
    if len(track) > 3:
        parts.append(f"and {len(track) - 3} more stretches")
    for kind, what in zip(TABLE_KINDS, ("gaps", "turns between rows"), strict=True):
        found = [f["reason"] for f in flags if f["kind"] == kind]
        parts += found[:3] + ([f"and {len(found) - 3} more {what} of the dead reckoning"]
                              if len(found) > 3 else [])
    parts += [f["reason"] for f in flags if f["kind"] not in ("track", *TABLE_KINDS)]
    return "; ".join(parts)
