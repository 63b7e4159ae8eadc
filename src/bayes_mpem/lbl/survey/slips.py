"""The slips a new user makes with a survey's two tables, named once with the likely cause."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd

from ...exceptions import FitQualityWarning, InputError
from ...io.boundary import LIMITS
from ...io.survey import Survey, load_survey
from ...io.tables import as_beacon_id, load_table

__all__ = ["MAX_EXAMPLES", "MAX_MESSAGE", "SlipError", "check_geometry", "explain_read_error",
           "flag_impossible", "impossible_rows", "load_checked"]

#: Example lines in a slip's message.
MAX_EXAMPLES = 10
#: The longest message (characters).
MAX_MESSAGE = 4000
#: Sound speeds tried for ranges given as travel times (m/s).
SOUND_SPEEDS = np.arange(1400.0, 1601.0, 2.0)
#: A range matches the direct path within this many metres plus :data:`MATCH_FRACTION` of it.
MATCH_METRES = 20.0
MATCH_FRACTION = 0.01
#: The ranges as given "fit no direct path" when fewer than this share matches it ...
NO_FIT = 0.15
#: ... and a slip is named when its transformed ranges match at least this share.
SLIP_FIT = 0.3
#: A range shorter than the vertical distance to its beacon by more than this many metres
#: plus :data:`MATCH_FRACTION` of it is impossible.
IMPOSSIBLE_METRES = 10.0
#: The most replies looked at (evenly spaced) by :func:`check_geometry`.
MAX_REPLIES = 20000


class SlipError(InputError):
    """A survey refused for a slip of its input: :attr:`slip` names which.

    Parameters
    ----------
    slip : str
        ``"seconds"``, ``"two_way_seconds"``, ``"km"``, ``"two_way"``, ``"depth_sign"``,
        ``"xy_swapped"``, ``"axis_sign"``, ``"beacon_ids"`` or ``"swapped"``.
    """

    def __init__(self, slip: str, message: str):
        super().__init__(_cap(message))
        self.slip = slip


def _cap(message: str) -> str:
    if len(message) <= MAX_MESSAGE:
        return message
    return message[:MAX_MESSAGE - 20].rsplit("\n", 1)[0] + "\n  ..."


def load_checked(pings, beacons=None) -> Survey:
    """Read a survey as :func:`~bayes_mpem.io.survey.load_survey`, naming the usual slips.

    Parameters
    ----------
    pings, beacons
        As :func:`~bayes_mpem.io.survey.load_survey`.

    Raises
    ------
    SlipError
        The tables are refused, or fit no direct path, and a slip explains it.
    InputError, FileNotFoundError
        As :func:`~bayes_mpem.io.survey.load_survey` when no slip does.
    """
    try:
        survey = load_survey(pings, beacons)
    except InputError as err:
        slip = explain_read_error(pings, beacons)
        if slip is not None:
            raise SlipError(*slip) from None
        raise err from None
    slip = check_geometry(survey)
    if slip is not None:
        raise SlipError(*slip)
    _warn_small(survey)
    return survey


#: Every length of a survey below this (m): kilometres, perhaps (:func:`_warn_small`).
SMALL_METRES = 20.0


def _warn_small(survey: Survey) -> None:
    """Warn where every range and beacon depth is under :data:`SMALL_METRES`.

    Lengths all in kilometres fit the direct path as well as metres (the geometry check
    cannot tell), and the fit ran with d0 of 2.39 for 2,392 m, warned only that sigma_MP
    sat at its floor (a hunt, session 48): the floors are in metres. A tank is as small.
    """
    r = survey.range[np.isfinite(survey.range)]
    depth = survey.beacons["depth"].to_numpy(float)
    if r.size and r.max() < SMALL_METRES and np.abs(depth).max() < SMALL_METRES:
        warnings.warn(f"{survey.pings_source}: every range (up to {r.max():g}) and beacon depth "
                      f"(up to {np.abs(depth).max():g}) is under {SMALL_METRES:g} m: if these "
                      "are kilometres, give metres (the fit's floors of sigma_DP and sigma_MP "
                      "are in metres); a tank survey can ignore this", FitQualityWarning,
                      stacklevel=3)


# --------------------------------------------------------------------------- read time


def _table(source, kind):
    try:
        return load_table(source, None, kind)
    except (InputError, OSError, TypeError, ValueError):
        return None


def _numbers(frame: pd.DataFrame, column: str) -> np.ndarray:
    if column not in frame.columns:
        return np.array([])
    return pd.to_numeric(frame[column], errors="coerce").to_numpy(dtype=float)


def explain_read_error(pings, beacons):
    """Name the slip that makes a survey's tables unreadable, if one does.

    Returns
    -------
    tuple of (str, str) or None
        ``(slip, message)``.
    """
    if isinstance(pings, Survey) or beacons is None:
        return None
    p, b = _table(pings, "pings"), _table(beacons, "beacons")
    if p is None or b is None:
        return None
    for check in (_swapped, _depth_sign, _beacon_ids):
        slip = check(p, b)
        if slip is not None:
            return slip
    return None


def _swapped(p, b):
    pc, bc = set(map(str, p.frame.columns)), set(map(str, b.frame.columns))
    ping_cols = {"time", "range"}
    if not ping_cols <= bc:
        return None
    if ping_cols <= pc:
        return ("swapped", f"the beacons file {b.source} looks like a pings table: it has the "
                           f"columns time and range, and {len(b.frame)} rows; expected one row "
                           "per beacon with the columns beacon, x, y, depth (give the beacons "
                           "table with --beacons)")
    return ("swapped", f"the two files look swapped: {p.source} has the columns of a beacons "
                       f"table ({', '.join(sorted(map(str, p.frame.columns))[:8])}; "
                       f"{len(p.frame)} rows) and {b.source} those of a pings table (time, "
                       f"range; {len(b.frame)} rows); give the pings first and the beacons "
                       "with --beacons")


def _depth_sign(p, b):
    lim = LIMITS["depth"]
    parts = []
    for t, what in ((p, "vehicle depths"), (b, "beacon depths")):
        d = _numbers(t.frame, "depth")
        d = d[np.isfinite(d)]
        if d.size == 0:
            continue
        bad = (d < lim.low) | (d > lim.high)
        flipped_ok = ((-d >= lim.low) & (-d <= lim.high)).all()
        if bad.any() and flipped_ok and (d[bad] < 0).all() and np.median(d) < 0:
            parts.append((t, what, int(bad.sum()), d.size))
    if not parts:
        return None
    t, *_ = parts[0]
    col = t.frame["depth"]
    vals = pd.to_numeric(col, errors="coerce").to_numpy(dtype=float)
    rows = np.flatnonzero(vals < lim.low)[:MAX_EXAMPLES]
    examples = [f"  {t.where(int(i), 'depth')}: {col.iloc[int(i)]} -> "
                f"{-vals[int(i)]:g}" for i in rows]
    counts = "; ".join(f"{n} of {m} {what} in {tt.source} are below {lim.low:g} m"
                       for tt, what, n, m in parts)
    return ("depth_sign", "the depths look positive up (negative below the surface): "
                          f"{counts}, and every one of them is a possible depth with the other "
                          "sign; give depths in metres, positive down (depth = -value). For "
                          "example:\n" + "\n".join(examples))


def _ids(t) -> list:
    if "beacon" not in t.frame.columns:
        return []
    return [as_beacon_id(v) for v in t.frame["beacon"]]


_SPELLINGS = (("letters and punctuation dropped", lambda s: "".join(c for c in s if c.isdigit())),
              ("leading zeros dropped", lambda s: s.lstrip("0") or "0"),
              ("case", str.lower))


def _beacon_ids(p, b):
    ids_p, ids_b = _ids(p), _ids(b)
    known = {i for i in ids_b if i}
    strangers = [i for i in ids_p if i and i not in known]
    if not strangers or not known:
        return None
    n_rows = len(strangers)
    unknown = sorted(set(strangers))
    show_p = ", ".join(map(repr, unknown[:MAX_EXAMPLES])) + (" ..." if len(unknown) > 10 else "")
    show_b = ", ".join(map(repr, sorted(known)[:MAX_EXAMPLES])) + (
        " ..." if len(known) > 10 else "")
    for how, f in _SPELLINGS:
        mapped = {f(k): k for k in known}
        if len(mapped) == len(known) and all(f(s) in mapped for s in unknown):
            pairs = ", ".join(f"{s!r} = {mapped[f(s)]!r}" for s in unknown[:MAX_EXAMPLES])
            return ("beacon_ids", f"the beacon ids of {p.source} and {b.source} are spelled "
                                  f"differently ({how}, they agree): {pairs}; {n_rows} rows of "
                                  f"{p.source} name a beacon the beacons table does not; use "
                                  "one spelling in both files")
    if not set(ids_p) & known:
        return ("beacon_ids", f"none of the beacon ids of {p.source} ({show_p}) is in "
                              f"{b.source} ({show_b}): the two files may belong to different "
                              f"surveys ({n_rows} rows)")
    return None


# --------------------------------------------------------------------------- geometry


def _replies(survey: Survey):
    rep = np.flatnonzero(np.isfinite(survey.range))
    if rep.size > MAX_REPLIES:
        rep = rep[np.linspace(0, rep.size - 1, MAX_REPLIES).astype(int)]
    pos = survey.beacons.loc[survey.beacon[rep], ["x", "y", "depth"]].to_numpy(float)
    return rep, pos


def _direct(survey, rep, pos, flip_vehicle=False, flip_beacon=False, plane=None):
    """Return the direct paths' lengths, the depths' signs or the pings' x and y changed.

    ``plane``: the pings' x and y ``"swap"``-ped, or ``"-x"`` or ``"-y"`` flipped.
    """
    dz = pos[:, 2] * (-1.0 if flip_beacon else 1.0) - survey.depth[rep] * (
        -1.0 if flip_vehicle else 1.0)
    x, y = survey.x[rep], survey.y[rep]
    x, y = {None: (x, y), "swap": (y, x), "-x": (-x, y), "-y": (x, -y)}[plane]
    return np.sqrt((pos[:, 0] - x) ** 2 + (pos[:, 1] - y) ** 2 + dz * dz)


def _matches(t, g):
    return np.abs(t - g) <= MATCH_METRES + MATCH_FRACTION * g


def _best_speed(r, g, factor):
    """Return the sound speed that makes ``r * c * factor`` match ``g`` most, and the share."""
    hits = np.array([_matches(r * c * factor, g).mean() for c in SOUND_SPEEDS])
    c = float(SOUND_SPEEDS[int(np.argmax(hits))])
    hit = _matches(r * c * factor, g)
    if hit.any():  # the speed the matching replies agree on
        c = float(np.clip(np.median(g[hit] / (r[hit] * factor)), SOUND_SPEEDS[0],
                          SOUND_SPEEDS[-1]))
    return c, float(_matches(r * c * factor, g).mean())


def check_geometry(survey: Survey):
    """Name the slip that makes a survey's ranges fit no direct path, if one does."""
    rep, pos = _replies(survey)
    if rep.size < 10:
        return None
    r, g = survey.range[rep], _direct(survey, rep, pos)
    raw = float(_matches(r, g).mean())
    if raw >= NO_FIT:
        return None
    tried = []
    for name, what, factor in (("seconds", "one-way travel times in seconds", 1.0),
                               ("two_way_seconds", "two-way travel times in seconds", 0.5),
                               ("milliseconds", "one-way travel times in milliseconds", 1e-3),
                               ("two_way_milliseconds", "two-way travel times in milliseconds",
                                5e-4)):
        c, share = _best_speed(r, g, factor)
        tried.append((share, name, what, r * c * factor, g, c * factor))
    for name, what, scale in (("km", "ranges in kilometres", 1000.0),
                              ("two_way", "two-way ranges in metres (there and back)", 0.5)):
        tried.append((float(_matches(r * scale, g).mean()), name, what, r * scale, g, scale))
    for flip_v, flip_b, what in ((True, False, "the vehicle's depths with the wrong sign "
                                               "(positive up)"),
                                 (False, True, "the beacons' depths with the wrong sign "
                                               "(positive up)")):
        g2 = _direct(survey, rep, pos, flip_v, flip_b)
        tried.append((float(_matches(r, g2).mean()), "depth_sign", what, r, g2, None))
    for plane, name, what in (("swap", "xy_swapped", "the pings' x and y swapped"),
                              ("-x", "axis_sign", "the pings' x with the wrong sign"),
                              ("-y", "axis_sign", "the pings' y with the wrong sign")):
        g2 = _direct(survey, rep, pos, plane=plane)
        tried.append((float(_matches(r, g2).mean()), name, what, r, g2, None))
    share, name, what, t, g_used, k = max(tried, key=lambda x: x[0])
    if share < SLIP_FIT or share < 2 * raw + 0.1:
        return None
    hit = np.flatnonzero(_matches(t, g_used))
    examples = []
    for i in hit[:MAX_EXAMPLES]:
        row = int(rep[i])
        given = f"range {survey.range[row]:g}"
        turned = f" -> {t[i]:.1f} m" if k is not None else ""
        examples.append(f"  {survey.pings_source} {survey.row_name(row)} (beacon "
                        f"{survey.beacon[row]}): {given}{turned}; the direct path is "
                        f"{g_used[i]:.1f} m")
    fix = _fix(name, k, survey.pings_source)
    slip = name
    text = (f"the ranges look like {what}: {share:.0%} of {rep.size} replies match the direct "
            f"path so read, {raw:.0%} as given; {fix}. For example:\n" + "\n".join(examples))
    if hit.size > MAX_EXAMPLES:
        text += f"\n  ... and {hit.size - MAX_EXAMPLES} more replies"
    if name in ("depth_sign", "xy_swapped", "axis_sign"):
        text = text.replace(f"the ranges look like {what}", f"the survey looks like {what}")
    return slip, text


def _fix(name: str, k, source) -> str:
    """Return what to do about the slip ``name`` (``k``: its speed or scale; None: geometry)."""
    if name == "seconds":
        return (f"multiply by the sound speed (about {k:.0f} m/s) to give one-way ranges in "
                f"metres (fit: --travel-time --sound-speed {k:.0f})")
    if name == "two_way_seconds":
        return (f"give one-way ranges in metres: range = c * t / 2 (c about {2 * k:.0f} m/s; "
                f"fit: --ranges two-way --travel-time --sound-speed {2 * k:.0f} --turnaround S)")
    if name == "milliseconds":
        return f"give one-way ranges in metres: range = c * t / 1000 (c about {k * 1000:g} m/s)"
    if name == "two_way_milliseconds":
        return f"give one-way ranges in metres: range = c * t / 2000 (c about {k * 2000:g} m/s)"
    return {"km": "give ranges in metres (range * 1000)",
            "two_way": "give one-way ranges (range / 2; fit: --ranges two-way)",
            "depth_sign": "give depths in metres, positive down",
            "xy_swapped": f"give x (east) and y (north) in their own columns of {source} (or "
                          "swap the beacons' the same way: both tables in one frame)",
            "axis_sign": "give both tables in one frame, x east and y north (an axis of the "
                         "pings flipped, or the beacons')"}[name]


def impossible_rows(survey: Survey) -> dict:
    """Find the replies shorter than the vertical distance to their beacon (no path is).

    Returns
    -------
    dict
        Row position in :attr:`Survey.table` -> the reason (text).
    """
    rep = np.flatnonzero(np.isfinite(survey.range))
    if rep.size == 0:
        return {}
    bz = survey.beacons.loc[survey.beacon[rep], "depth"].to_numpy(float)
    v = np.abs(bz - survey.depth[rep])
    r = survey.range[rep]
    short = r < v - (IMPOSSIBLE_METRES + MATCH_FRACTION * v)
    return {int(rep[i]): (f"range {r[i]:g} m is shorter than the {v[i]:.1f} m vertical distance "
                          f"to beacon {survey.beacon[rep[i]]}: no acoustic path is that short")
            for i in np.flatnonzero(short)}


def flag_impossible(table: pd.DataFrame, survey: Survey) -> pd.DataFrame:
    """Fill the empty ``reason`` of each impossible reply (:func:`impossible_rows`) of a table.

    Parameters
    ----------
    table : pandas.DataFrame
        One row per row of ``survey.table``, with a ``reason`` column.
    """
    short = impossible_rows(survey)
    if not short:
        return table
    rows = np.fromiter(short, dtype=np.int64, count=len(short))
    col = table.columns.get_loc("reason")
    empty = table["reason"].to_numpy()[rows] == ""
    table.iloc[rows[empty], col] = [short[int(i)] for i in rows[empty]]
    return table
