"""A survey file as read (:class:`RawSurvey`), its conversion to pings, and reader helpers.

Details: ``docs/measured-data.md``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ..exceptions import InputError
from .boundary import read_text_lines
from .geodesy import antenna_to_transducer, atd_offset_enu, geodetic_to_enu

#: Formats of GNSS-acoustic array surveys (several transponders, antenna or transducer
#: positions at transmit and receive): located jointly by ``bayes-mpem locate``.
ARRAY_FORMATS = ("garpos", "gnatss")


@dataclass(frozen=True)
class RawSurvey:
    """A survey file as read: pings, header, and every line that was not a ping.

    Attributes
    ----------
    format, source : str
    pings : pandas.DataFrame
        One row per ping: ``line`` (1-based), ``transponder``, ``twtt`` (s), ``time`` (s since
        the first ping), ``lat``, ``lon`` or ``east``, ``north``, ``up``, and the format's columns.
    header : dict
        Drop point (``lat``, ``lon``, ``depth``), ``tat`` (s) and ``sound_speed`` where given.
    skipped : pandas.DataFrame
        ``line``, ``text``, ``reason`` of every line that is neither a ping nor header.
    """

    format: str
    source: str
    pings: pd.DataFrame = field(repr=False)
    header: dict
    skipped: pd.DataFrame = field(repr=False)

    def to_pings(self, *, sound_speed=None, tat=None, origin=None, transducer_depth=0.0):
        """Convert to the package's pings and beacons tables (one-way ranges, local metres).

        ``range = sound_speed * (twtt - tat) / 2``; GNSS-A surveys are in local metres already
        (their vehicle position the transducer's mean at transmit and receive; ``docs/gnssa.md``).

        Parameters
        ----------
        sound_speed : float, optional
            Mean sound speed (m/s); default the file's, else the profile's harmonic mean, else 1500.
        tat : float, optional
            Turn-around time (s); default the file's, else 0.
        origin : tuple of float, optional
            ``(lat, lon)`` of the local frame; default the drop point.
        transducer_depth : float, default 0
            Depth of the ship's transducer (m, positive down).

        Returns
        -------
        pings, beacons : pandas.DataFrame

        Raises
        ------
        InputError
            For a deck-box survey without a drop point and no ``origin``.
        """
        if self.format in ("seagap", *ARRAY_FORMATS):
            return self._to_pings_seagap(sound_speed)
        c = float(sound_speed or self.header.get("sound_speed") or 1500.0)
        t0 = float(self.header.get("tat", 0.0) if tat is None else tat)
        if origin is None:
            if "lat" in self.header and "lon" in self.header:
                origin = (self.header["lat"], self.header["lon"])
            elif len(self.pings):  # no drop point: start from the middle of the ship's track
                origin = (float(self.pings["lat"].mean()), float(self.pings["lon"].mean()))
            else:
                raise InputError(f"{self.source}: no drop point in the header; pass origin=")
        e, n, _ = geodetic_to_enu(self.pings["lat"], self.pings["lon"], 0.0, *origin)
        p = pd.DataFrame({
            "time": self.pings["time"].to_numpy(), "beacon": self.pings["transponder"],
            "range": c * (self.pings["twtt"].to_numpy() - t0) / 2.0, "x": e, "y": n,
            "depth": float(transducer_depth), "line": self.pings["line"].to_numpy(),
            "twtt": self.pings["twtt"].to_numpy()})
        de, dn, _ = geodetic_to_enu(self.header.get("lat", origin[0]),
                                    self.header.get("lon", origin[1]), 0.0, *origin)
        # no drop-point depth: start at the median one-way range (the slant range bounds it)
        depth = self.header.get("depth", float(np.median(p["range"])) if len(p) else np.nan)
        b = pd.DataFrame([{"beacon": str(self.pings["transponder"].iloc[0]) if len(self.pings)
                           else "1", "x": float(de), "y": float(dn), "depth": float(depth)}])
        return p, b


    def transducer_positions(self) -> dict:
        """East, north, up (m) of the ship's transducer at transmit and at receive, per ping.

        The GNSS antenna's positions are turned by each format's lever-arm convention
        (``docs/gnssa.md``); GNATSS's are the transducer's already.

        Returns
        -------
        dict
            ``{"tx": (east, north, up), "rx": (east, north, up)}`` of numpy arrays.

        Raises
        ------
        InputError
            For a survey without antenna positions (a deck-box log).
        """
        p, h = self.pings, self.header
        if self.format not in ("seagap", *ARRAY_FORMATS):
            raise InputError(f"{self.source}: a {self.format} survey has no antenna positions")
        pos = {}
        for end in ("tx", "rx"):
            enu = [p[f"{c}_{end}"].to_numpy(float) for c in "enu"]
            att = [p[f"{a}_{end}"] for a in ("head", "pitch", "roll")] \
                if f"head_{end}" in p.columns else None
            if "tr_ant" in h and att is not None:
                enu = antenna_to_transducer(*enu, *att, h["tr_ant"])
            elif h.get("atd_offset") is not None and att is not None:
                d = atd_offset_enu(*h["atd_offset"], *att)
                enu = [v + dv for v, dv in zip(enu, d, strict=True)]
            pos[end] = tuple(np.asarray(v, float) for v in enu)
        return pos

    def _to_pings_seagap(self, sound_speed):
        p, h = self.pings, self.header
        if "transponders" not in h:
            raise InputError(f"{self.source}: no pxp-ini.inp was read; the transponder "
                             "positions are needed")
        tp = h["transponders"]
        if sound_speed is None and "ss_prof" in h:
            prof = h["ss_prof"]
            keep = prof["depth"] <= float(-tp["up"].mean())
            sound_speed = float(1.0 / np.mean(1.0 / prof.loc[keep, "sound_speed"]))
        c = float(sound_speed or 1500.0)
        pos = self.transducer_positions()
        pings = pd.DataFrame({
            "time": p["time"].to_numpy(), "beacon": p["transponder"].to_numpy(),
            "range": c * p["twtt"].to_numpy() / 2.0,
            "x": 0.5 * (pos["tx"][0] + pos["rx"][0]),
            "y": 0.5 * (pos["tx"][1] + pos["rx"][1]),
            "depth": -0.5 * (pos["tx"][2] + pos["rx"][2]),
            "line": p["line"].to_numpy(), "twtt": p["twtt"].to_numpy()})
        beacons = pd.DataFrame({"beacon": tp.index, "x": tp["east"].to_numpy(),
                                "y": tp["north"].to_numpy(), "depth": -tp["up"].to_numpy()})
        return pings, beacons


def read_lines(path):
    r"""Read a survey file as text lines (UTF-8), ending at ``\n`` only as ``grep -n`` counts them.

    Parameters
    ----------
    path : str or pathlib.Path

    Returns
    -------
    list of str

    Raises
    ------
    FileNotFoundError, InputError
        No such file; a folder, a binary file, or not UTF-8 text (naming the line).
    """
    return read_text_lines(path, "survey file")


def finish(fmt, source, rows, header, skipped, transponder):
    """Assemble a reader's parsed lines into a :class:`RawSurvey`.

    Parameters
    ----------
    fmt, source, transponder : str
        The format, the file and the transponder's name.
    rows : list of dict
        One per ping, with an ``_epoch`` (s) that becomes ``time`` from the first ping.
    header : dict
    skipped : list of tuple
        ``(line, text, reason)`` of every skipped line.

    Returns
    -------
    RawSurvey

    Raises
    ------
    InputError
        No ping line in the file; a ping line repeated (:func:`check_repeated_pings`).
    """
    pings = pd.DataFrame(rows)
    if pings.empty:
        raise InputError(f"{source}: no ping lines found (expected the {fmt} format; "
                         f"{len(skipped)} lines skipped"
                         + (f": {skip_reasons(skipped)})" if skipped else ")"))
    check_repeated_pings(source, pings)
    pings.insert(1, "transponder", transponder)
    epoch = pings.pop("_epoch")
    pings.insert(2, "time", epoch - epoch.iloc[0])
    skipped = pd.DataFrame(skipped, columns=["line", "text", "reason"])
    return RawSurvey(fmt, source, pings, header, skipped)


#: The repeated lines a refusal of :func:`check_repeated_pings` lists.
MAX_REPEATS_SHOWN = 5


def check_repeated_pings(source, pings):
    """Refuse a log in which a ping line is repeated: the same time and travel time twice.

    A deck-box log pasted together from overlapping captures repeats its ping lines; each
    repeat would count as a second reply and narrow the intervals (by up to sqrt 2). Which
    copy to keep is the user's choice, so none is dropped here.

    Parameters
    ----------
    source : str
        The file, for the message.
    pings : pandas.DataFrame
        One row per ping line: ``line``, ``_epoch`` (s) and ``twtt`` (s); one transponder.

    Raises
    ------
    InputError
        Naming the file, the first repeats with the lines they repeat, and how many.
    """
    key = ["_epoch", "twtt"]
    again = pings.duplicated(key, keep="first").to_numpy()
    if not again.any():
        return
    first = pings.drop_duplicates(key).set_index(key)["line"]
    pairs = [(int(first[(e, t)]), int(n))
             for e, t, n in pings.loc[again, ["_epoch", "twtt", "line"]].itertuples(index=False)]
    shown = "; ".join(f"line {n} repeats line {f}" for f, n in pairs[:MAX_REPEATS_SHOWN])
    more = len(pairs) - MAX_REPEATS_SHOWN
    count = f"{len(pairs)} ping lines repeat" if len(pairs) > 1 else "1 ping line repeats"
    raise InputError(
        f"{source}: {count} an earlier one (the same time and travel time): {shown}"
        + (f"; and {more} more" if more > 0 else "")
        + "; expected each ping once (a repeat would count as a second reply and narrow "
          "the intervals); remove the repeated lines")


def skip_reasons(skipped, limit: int = 3) -> str:
    """Say why lines were skipped: the commonest reasons, each with its count and first line.

    For a refusal that leaves nothing to fit: it names why, not only how many. Reasons that
    differ only in their numbers count as one.

    Parameters
    ----------
    skipped : list of tuple
        ``(line, text, reason)`` or ``(line, text, reason, file)`` (:func:`bad`).
    limit : int, default 3
        Reasons shown; the others are counted.

    Returns
    -------
    str

    Examples
    --------
    >>> skip_reasons([(2, "a", "column 2: got 'x'"), (3, "b", "column 2: got 'y'"),
    ...               (4, "c", "time 12.5 not found"), (5, "d", "time 13.5 not found")])
    "2 lines: time 12.5 not found (first line 4); 1 line: column 2: got 'x' (line 2); 1 line: \
column 2: got 'y' (line 3)"
    """
    groups = {}
    for line, _, reason, *rest in skipped:
        key = re.sub(r"[-+]?\d[\d.eE+-]*", "#", str(reason))
        g = groups.setdefault(key, {"n": 0, "line": line, "reason": str(reason),
                                    "file": rest[0] if rest else None})
        g["n"] += 1
    top = sorted(groups.values(), key=lambda g: -g["n"])
    parts = [f"{g['n']} line{'s' if g['n'] > 1 else ''}: {g['reason']} ("
             + ("first " if g["n"] > 1 else "")
             + (f"{Path(g['file']).name} " if g["file"] else "") + f"line {g['line']})"
             for g in top[:limit]]
    rest = len(top) - limit
    return "; ".join(parts) + (f"; and {rest} other reason{'s' if rest > 1 else ''}"
                               if rest > 0 else "")


def bad(strict, source, line, text, reason, skipped):
    """Record a line that does not parse in ``skipped``, or raise if ``strict``.

    Parameters
    ----------
    strict : bool
    source, text, reason : str
    line : int
    skipped : list

    Raises
    ------
    InputError
        With ``strict``, naming the file and line.
    """
    if strict:
        raise InputError(f"{source} line {line}: {reason}: {text.strip()[:80]!r}")
    skipped.append((line, text, reason))
