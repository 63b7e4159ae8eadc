"""Readers of OBSrange EdgeTech deck-box logs (SIO text and WHOI CSV).

Each returns a :class:`~bayes_mpem.io.raw.RawSurvey` that accounts for every
line of the file (see :mod:`bayes_mpem.io.raw` for the formats).
"""

from __future__ import annotations

import re
from datetime import UTC, datetime, timedelta

import numpy as np

from ..exceptions import InputError
from .raw import RawSurvey, bad, finish, read_lines


def _dm(deg, minutes, hemi):
    """Degrees and decimal minutes with a hemisphere letter to signed degrees."""
    v = float(deg) + float(minutes) / 60.0
    return -v if hemi.upper() in ("S", "W") else v


# --------------------------------------------------------------------------- OBSrange SIO

_SIO_PING = re.compile(
    r"^\s*(?P<ms>\d+(?:\.\d*)?)\s*msec\.\s+Lat:\s*(?P<latd>\d+)\s+(?P<latm>\d+(?:\.\d*)?)\s*"
    r"(?P<lath>[NS])\s+Lon:\s*(?P<lond>\d+)\s+(?P<lonm>\d+(?:\.\d*)?)\s*(?P<lonh>[EW])\s+"
    r"Alt:\s*(?P<alt>[-+]?\d+(?:\.\d*)?)\s+Time\(UTC\):\s*(?P<year>\d{4}):(?P<doy>\d{1,3}):"
    r"(?P<hh>\d{2}):(?P<mm>\d{2}):(?P<ss>\d{2}(?:\.\d*)?)\s*$")
_SIO_HEADER = {"drop point (latitude)": "lat", "drop point (longitude)": "lon",
               "depth (meters)": "depth", "site": "site"}


def read_obsrange_sio(path, *, strict=False) -> RawSurvey:
    """Read an SIO EdgeTech deck-box log (OBSrange sample format).

    Parameters
    ----------
    path : str or pathlib.Path
    strict : bool, default False
        Raise on a line that does not parse, instead of skipping it with a reason.

    Returns
    -------
    RawSurvey

    Raises
    ------
    FileNotFoundError, InputError
    """
    source = str(path)
    rows, skipped, header = [], [], {}
    in_header = True
    for i, text in enumerate(read_lines(path), start=1):
        s = text.strip()
        if not s:
            continue
        if in_header:
            if set(s) == {"="}:
                in_header = False
                continue
            key, sep, value = s.partition(":")
            if sep:
                k = _SIO_HEADER.get(key.strip().lower())
                if k in ("lat", "lon", "depth"):
                    try:
                        header[k] = float(value)
                    except ValueError:
                        raise InputError(f"{source} line {i}: header {key.strip()!r}: "
                                         f"expected a number, got {value.strip()!r}") from None
                elif k:
                    header[k] = value.strip()
                continue
            in_header = False  # no separator line: data starts here
        if s.startswith("Event skipped"):
            skipped.append((i, text, "deck box: " + s.partition(" - ")[2] or s))
            continue
        m = _SIO_PING.match(s)
        if m is None:
            bad(strict, source, i, text, "not a ping line of the SIO deck-box format", skipped)
            continue
        g = m.groupdict()
        try:
            year, doy = int(g["year"]), int(g["doy"])
            days = 366 if (year % 4 == 0 and year % 100 != 0) or year % 400 == 0 else 365
            if not 1 <= doy <= days:
                raise ValueError(f"day of year {doy} outside 1-{days}")
            t = (datetime(year, 1, 1, tzinfo=UTC)
                 + timedelta(days=int(g["doy"]) - 1, hours=int(g["hh"]), minutes=int(g["mm"]),
                             seconds=float(g["ss"])))
        except ValueError as exc:
            bad(strict, source, i, text, f"invalid time ({exc})", skipped)
            continue
        rows.append({"line": i, "_epoch": t.timestamp(), "twtt": float(g["ms"]) / 1000.0,
                     "lat": _dm(g["latd"], g["latm"], g["lath"]),
                     "lon": _dm(g["lond"], g["lonm"], g["lonh"]), "alt": float(g["alt"])})
    return finish("obsrange-sio", source, rows, header, skipped, header.get("site", "1"))


# --------------------------------------------------------------------------- OBSrange WHOI

_WHOI_DM = re.compile(r"^\s*(\d+)\s+(\d+(?:\.\d*)?)\s*([NSEW])\s*$")


def read_obsrange_whoi(path, *, strict=False) -> RawSurvey:
    """Read a WHOI EdgeTech CSV log (OBSrange sample format).

    Parameters
    ----------
    path : str or pathlib.Path
    strict : bool, default False

    Returns
    -------
    RawSurvey
        ``header`` has the drop point, ``tat`` (s) and ``sound_speed`` (m/s, the
        deck box's) when present; ``pings`` keep ``rng_m`` (the deck box's
        range, computed with its sound speed) beside ``twtt``.

    Raises
    ------
    FileNotFoundError, InputError
    """
    source = str(path)
    rows, skipped, header = [], [], {}
    for i, text in enumerate(read_lines(path), start=1):
        s = text.strip()
        if not s:
            continue
        if s.startswith("#"):
            key, sep, value = s.lstrip("#").partition(":")
            key, value = key.strip().lower(), value.strip()
            try:
                if key == "drop-point latitude" or key == "drop-point longitude":
                    m = _WHOI_DM.match(value)
                    if m:
                        header["lat" if "latitude" in key else "lon"] = _dm(*m.groups())
                elif key == "drop-point depth (m)":
                    header["depth"] = float(value)
                elif key == "tat":
                    header["tat"] = float(value.split()[0]) / 1000.0
                elif key == "speed of sound":
                    header["sound_speed"] = float(value.split()[0])
                elif key == "instrument":
                    header["site"] = value
            except (ValueError, IndexError):
                raise InputError(f"{source} line {i}: header {key!r}: could not read "
                                 f"{value!r}") from None
            continue
        parts = [p.strip() for p in s.split(",")]
        if len(parts) != 7:
            bad(strict, source, i, text, f"expected 7 comma-separated fields, got {len(parts)}",
                 skipped)
            continue
        try:
            t = datetime.strptime(parts[0], "%Y-%m-%d %H:%M:%S").replace(tzinfo=UTC)
            lat, lon = _WHOI_DM.match(parts[3]), _WHOI_DM.match(parts[4])
            if lat is None or lon is None:
                raise ValueError("latitude/longitude not as 'DD MM.MMMM H'")
            twtt = float(parts[2]) / 1000.0
            if not np.isfinite(twtt) or twtt <= 0:
                raise ValueError(f"travel time {parts[2]!r} ms is not positive")
            rows.append({"line": i, "_epoch": t.timestamp(), "twtt": twtt,
                         "rng_m": float(parts[1]), "lat": _dm(*lat.groups()),
                         "lon": _dm(*lon.groups()), "heading": float(parts[6])})
        except ValueError as exc:
            bad(strict, source, i, text, str(exc), skipped)
    return finish("obsrange-whoi", source, rows, header, skipped, header.get("site", "1"))
