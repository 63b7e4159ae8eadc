"""Readers of OBSrange EdgeTech deck-box logs (SIO text and WHOI CSV).

Details: ``docs/measured-data.md``.
"""

from __future__ import annotations

import re
from datetime import UTC, datetime, timedelta

from ..exceptions import InputError
from .boundary import COMMENT, LIMITS, Shape, classify, limit_problem, read_text_lines
from .raw import RawSurvey, bad, finish


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


_SIO_SHAPES = (Shape("ping", _SIO_PING.pattern[1:-1]), Shape("separator", r"=+"),
               Shape("event", r"Event skipped\b.*"),
               Shape("header", r"(?P<key>[A-Za-z][A-Za-z ()/_.-]*?)\s*:\s*(?P<value>.*)"))


def _sio_header(source, i, key, value, header):
    k = _SIO_HEADER.get(key.strip().lower())
    if k in ("lat", "lon", "depth"):
        try:
            v = float(value)
        except ValueError:
            v = None
        why = (f"expected a number, got {value.strip()!r}" if v is None
               else limit_problem(k, v))
        if why:
            raise InputError(f"{source} line {i}: header {key.strip()!r}: {why}")
        header[k] = v
    elif k:
        header[k] = value.strip()


def _sio_ping(g):
    """Return a ping line's values, or the reason it cannot be used."""
    for part, kind in (("latm", "minutes"), ("lonm", "minutes")):
        why = limit_problem(kind, float(g[part]))
        if why or float(g[part]) >= 60.0:
            return why or f"arc-minutes {g[part]} outside [0, 60)"
    year, doy = int(g["year"]), int(g["doy"])
    days = 366 if (year % 4 == 0 and year % 100 != 0) or year % 400 == 0 else 365
    if not 1 <= doy <= days:
        return f"invalid time (day of year {doy} outside 1-{days})"
    if int(g["hh"]) > 23 or int(g["mm"]) > 59 or float(g["ss"]) >= 61:
        return f"invalid time ({g['hh']}:{g['mm']}:{g['ss']})"
    t = (datetime(year, 1, 1, tzinfo=UTC)
         + timedelta(days=doy - 1, hours=int(g["hh"]), minutes=int(g["mm"]),
                     seconds=float(g["ss"])))
    row = {"_epoch": t.timestamp(), "twtt": float(g["ms"]) / 1000.0,
           "lat": _dm(g["latd"], g["latm"], g["lath"]),
           "lon": _dm(g["lond"], g["lonm"], g["lonh"]), "alt": float(g["alt"])}
    for kind in ("twtt", "lat", "lon"):
        why = limit_problem(kind, row[kind])
        if why:
            return why
    return row


def read_obsrange_sio(path, *, strict=False) -> RawSurvey:
    """Read an SIO EdgeTech deck-box log (OBSrange sample format).

    Each line is classified by its shape; a line that is not a ping or header, or a ping
    whose values are not physically possible, is skipped with its reason.

    Parameters
    ----------
    path : str or pathlib.Path
    strict : bool, default False
        Raise on a line that does not parse instead of skipping it.

    Returns
    -------
    RawSurvey

    Raises
    ------
    FileNotFoundError, InputError
    """
    source = str(path)
    rows, skipped, header = [], [], {}
    lines = read_text_lines(path)
    for i, kind, m in classify(lines, _SIO_SHAPES):
        text = lines[i - 1]
        if kind in ("blank", "separator"):
            continue
        if kind == "header" and not rows:
            _sio_header(source, i, m["key"], m["value"], header)
        elif kind == "event":
            skipped.append((i, text, "deck box: " + (text.strip().partition(" - ")[2]
                                                     or text.strip())))
        elif kind == "ping":
            row = _sio_ping(m.groupdict())
            if isinstance(row, str):
                bad(strict, source, i, text, row, skipped)
            else:
                rows.append({"line": i, **row})
        else:
            why = ("a header line among the pings" if kind == "header"
                   else "not a ping line of the SIO deck-box format")
            bad(strict, source, i, text, why, skipped)
    return finish("obsrange-sio", source, rows, header, skipped, header.get("site") or "1")


# --------------------------------------------------------------------------- OBSrange WHOI

_WHOI_DM = re.compile(r"^\s*(\d+)\s+(\d+(?:\.\d*)?)\s*([NSEW])\s*$")


def _whoi_dm(text, kind):
    """Signed degrees from 'DD MM.MMMM H', or the reason they are not usable."""
    m = _WHOI_DM.match(text)
    if m is None:
        return f"{LIMITS[kind].what} {text.strip()!r} not as 'DD MM.MMMM H'"
    if float(m.group(2)) >= 60.0:
        return f"arc-minutes {m.group(2)} outside [0, 60)"
    if (m.group(3) in "NS") != (kind == "lat"):
        return f"{LIMITS[kind].what} {text.strip()!r} has the hemisphere of the other axis"
    v = _dm(*m.groups())
    return limit_problem(kind, v) or v


def _whoi_header(source, i, text, header):
    key, _, value = text.strip().lstrip("#").partition(":")
    key, value = key.strip().lower(), value.strip()
    try:
        if key in ("drop-point latitude", "drop-point longitude"):
            kind = "lat" if "latitude" in key else "lon"
            v = _whoi_dm(value, kind)
            if isinstance(v, str):
                raise ValueError(v)
            header[kind] = v
        elif key in ("drop-point depth (m)", "tat", "speed of sound"):
            kind = {"drop-point depth (m)": "depth", "tat": "tat",
                    "speed of sound": "sound_speed"}[key]
            v = float(value.split()[0]) / (1000.0 if kind == "tat" else 1.0)
            why = limit_problem(kind, v)
            if why:
                raise ValueError(why)
            header[kind] = v
        elif key == "instrument":
            header["site"] = value
    except (ValueError, IndexError) as exc:
        raise InputError(f"{source} line {i}: header {key!r}: could not read {value!r}"
                         + (f" ({exc})" if str(exc) else "")) from None


def _whoi_ping(parts):
    """Return a WHOI ping line's values, or the reason it cannot be used."""
    try:
        t = datetime.strptime(parts[0], "%Y-%m-%d %H:%M:%S").replace(tzinfo=UTC)
    except ValueError as exc:
        return f"invalid time ({exc})"
    row = {"_epoch": t.timestamp()}
    for key, text, kind in (("twtt", parts[2], "twtt"), ("rng_m", parts[1], "range"),
                            ("heading", parts[6], "heading")):
        try:
            v = float(text) / (1000.0 if key == "twtt" else 1.0)
        except ValueError:
            return f"{LIMITS[kind].what} {text!r} is not a number"
        why = limit_problem(kind, v)
        if why:
            return why
        row[key] = v
    for key, text in (("lat", parts[3]), ("lon", parts[4])):
        v = _whoi_dm(text, key)
        if isinstance(v, str):
            return v
        row[key] = v
    return row


def read_obsrange_whoi(path, *, strict=False) -> RawSurvey:
    """Read a WHOI EdgeTech CSV log (OBSrange sample format; ``#`` lines are the header).

    Parameters
    ----------
    path : str or pathlib.Path
    strict : bool, default False

    Returns
    -------
    RawSurvey

    Raises
    ------
    FileNotFoundError, InputError
    """
    source = str(path)
    rows, skipped, header = [], [], {}
    lines = read_text_lines(path)
    for i, kind, _ in classify(lines, (COMMENT,)):
        text = lines[i - 1]
        if kind == "blank":
            continue
        if kind == "comment":
            _whoi_header(source, i, text, header)
            continue
        parts = [p.strip() for p in text.strip().split(",")]
        row = (f"expected 7 comma-separated fields, got {len(parts)}" if len(parts) != 7
               else _whoi_ping(parts))
        if isinstance(row, str):
            bad(strict, source, i, text, row, skipped)
        else:
            rows.append({"line": i, **row})
    return finish("obsrange-whoi", source, rows, header, skipped, header.get("site") or "1")
