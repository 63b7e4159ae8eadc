"""Readers for real acoustic ranging surveys, and conversion to the project's input.

Formats (see ``data/README.md`` for the sample files and their sources):

* ``obsrange-sio``: EdgeTech deck-box text as logged by SIO (OBSrange sample
  surveys): a ``Key: value`` header up to a line of ``=``, then ping lines such
  as ``6306 msec. Lat: 4 52.9270 S  Lon: 132 41.4272 W  Alt: 29.42
  Time(UTC): 2018:114:06:04:30`` (two-way travel time in ms, ship GPS in degrees
  and decimal minutes, day-of-year time) and ``Event skipped - ...`` lines;
* ``obsrange-whoi``: the WHOI EdgeTech CSV: ``#`` comment header (drop point,
  ``TAT``, deck-box sound speed), then ``date time, rng m, rng ms, lat, lon, GPS
  time, heading``; ``rng ms`` is the two-way travel time;
* ``seagap``: SeaGap GNSS-acoustic ``obsdata.inp`` (18 columns, local E/N/U in m),
  with ``pxp-ini.inp`` (transponder positions), ``tr-ant.inp`` and ``ss_prof.inp``.

Every line of a file is accounted for: a ping, a header or comment line, or a
*skipped* line with its reason (``Event skipped`` in the deck-box log, or a line
that does not parse). ``strict=True`` turns a line that does not parse into an
:class:`~bayes_mpem.data.InputError` naming the file and line.

Latitude/longitude go to a local metric frame with the exact WGS84
geodetic -> ECEF -> local east-north-up transform (:func:`geodetic_to_enu`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pandas as pd

from .data import InputError

FORMATS = ("obsrange-sio", "obsrange-whoi", "seagap")

# WGS84
_A = 6378137.0
_F = 1.0 / 298.257223563
_E2 = _F * (2.0 - _F)


def _ecef(lat, lon, height):
    """WGS84 geodetic (degrees, m) to Earth-centred Earth-fixed (m)."""
    la, lo = np.radians(lat), np.radians(lon)
    nu = _A / np.sqrt(1.0 - _E2 * np.sin(la) ** 2)
    return np.array([(nu + height) * np.cos(la) * np.cos(lo),
                     (nu + height) * np.cos(la) * np.sin(lo),
                     (nu * (1.0 - _E2) + height) * np.sin(la)], dtype=float)


def _enu_rotation(lat0, lon0):
    """Rows: the local east, north and up unit vectors at the origin, in ECEF."""
    la, lo = np.radians(lat0), np.radians(lon0)
    return np.array([[-np.sin(lo), np.cos(lo), 0.0],
                     [-np.sin(la) * np.cos(lo), -np.sin(la) * np.sin(lo), np.cos(la)],
                     [np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)]])


def geodetic_to_enu(lat, lon, height, lat0, lon0, height0=0.0):
    """Local east, north, up (m) of WGS84 points relative to an origin.

    Exact: geodetic -> Earth-centred Earth-fixed -> rotation to the local
    tangent plane at the origin.

    Parameters
    ----------
    lat, lon : array_like
        Degrees.
    height : array_like
        Height above the ellipsoid (m).
    lat0, lon0, height0 : float
        The origin.

    Returns
    -------
    e, n, u : numpy.ndarray

    Examples
    --------
    >>> e, n, u = geodetic_to_enu(0.0, 0.001, 0.0, 0.0, 0.0)
    >>> round(float(e), 3), round(float(n), 6)
    (111.319, 0.0)
    """
    lat, lon, height = np.broadcast_arrays(*(np.asarray(v, float) for v in (lat, lon, height)))
    d = _ecef(lat, lon, height) - _ecef(float(lat0), float(lon0), float(height0)).reshape(
        (3,) + (1,) * lat.ndim)
    e, n, u = np.tensordot(_enu_rotation(lat0, lon0), d, axes=1)
    return e, n, u


def enu_to_geodetic(east, north, up, lat0, lon0, height0=0.0):
    """Inverse of :func:`geodetic_to_enu` (WGS84, exact to < 1 mm).

    Parameters
    ----------
    east, north, up : float
        Local coordinates (m).
    lat0, lon0, height0 : float
        The origin.

    Returns
    -------
    lat, lon, height : float
    """
    x, y, z = _ecef(float(lat0), float(lon0), float(height0)) + _enu_rotation(lat0, lon0).T @ \
        np.array([east, north, up], dtype=float)
    lon = np.arctan2(y, x)
    p = np.hypot(x, y)
    lat = np.arctan2(z, p * (1 - _E2))
    for _ in range(10):
        nu = _A / np.sqrt(1 - _E2 * np.sin(lat) ** 2)
        h = p / np.cos(lat) - nu
        lat = np.arctan2(z, p * (1 - _E2 * nu / (nu + h)))
    return float(np.degrees(lat)), float(np.degrees(lon)), float(h)


def antenna_to_transducer(east, north, up, heading, pitch, roll, offset):
    """Transducer positions from antenna positions, attitude and the lever arm.

    SeaGap's convention (its ``anttena2tr``): the offset ``(x, y, z)`` is in the
    local frame at zero attitude; it is rotated by ``-heading`` about the
    vertical, then by ``pitch`` about the horizontal axis at azimuth
    ``-heading``, then by ``roll`` about the axis at azimuth ``90 - heading``
    tilted up by ``pitch``, and added to the antenna position.

    Parameters
    ----------
    east, north, up : array_like
        Antenna positions (m).
    heading, pitch, roll : array_like
        Degrees.
    offset : array_like
        The three components of ``tr-ant.inp`` (m).

    Returns
    -------
    east, north, up : numpy.ndarray
    """
    from scipy.spatial.transform import Rotation

    h, p, r = (np.radians(np.asarray(v, float)) for v in (heading, pitch, roll))
    zero = np.zeros_like(h)
    steps = [np.stack([zero, zero, -h], axis=-1),
             p[:, None] * np.stack([np.cos(-h), np.sin(-h), zero], axis=-1),
             r[:, None] * np.stack([np.cos(p) * np.cos(np.pi / 2 - h),
                                    np.cos(p) * np.sin(np.pi / 2 - h), np.sin(p)], axis=-1)]
    v = np.tile(np.asarray(offset, float), (h.size, 1))
    for rotvec in steps:
        v = Rotation.from_rotvec(rotvec).apply(v)
    return (np.asarray(east, float) + v[:, 0], np.asarray(north, float) + v[:, 1],
            np.asarray(up, float) + v[:, 2])


def _dm(deg, minutes, hemi):
    """Degrees and decimal minutes with a hemisphere letter to signed degrees."""
    v = float(deg) + float(minutes) / 60.0
    return -v if hemi.upper() in ("S", "W") else v


@dataclass(frozen=True)
class RawSurvey:
    """A survey file as read: pings, header, and every line that was not a ping.

    Attributes
    ----------
    format : str
    source : str
    pings : pandas.DataFrame
        One row per ping: ``line`` (1-based file line), ``transponder``,
        ``twtt`` (two-way travel time, s), ``time`` (s since the first ping),
        ``lat``, ``lon`` (degrees) or ``east``, ``north``, ``up`` (m, SeaGap),
        plus format-specific columns.
    header : dict
        Drop point (``lat``, ``lon``, ``depth``), ``tat`` (turn-around time, s)
        and ``sound_speed`` (m/s) where the file gives them.
    skipped : pandas.DataFrame
        ``line``, ``text``, ``reason`` of every line that is neither a ping nor header.
    """

    format: str
    source: str
    pings: pd.DataFrame = field(repr=False)
    header: dict
    skipped: pd.DataFrame = field(repr=False)

    def to_pings(self, *, sound_speed=None, tat=None, origin=None, transducer_depth=0.0):
        """Convert to the project's pings and beacons tables (one-way ranges, local metres).

        ``range = sound_speed * (twtt - tat) / 2``. Pings are kept in file order;
        skipped lines are not pings and are not included (see :attr:`skipped`).

        Parameters
        ----------
        sound_speed : float, optional
            Mean sound speed (m/s); default: the file's deck-box value, else 1500.
        tat : float, optional
            Turn-around time (s); default: the file's, else 0.
        origin : tuple of float, optional
            ``(lat, lon)`` of the local frame; default: the drop point.
        transducer_depth : float, default 0
            Depth of the ship's transducer (m, positive down).

        Returns
        -------
        pings, beacons : pandas.DataFrame
            Ready for :func:`bayes_mpem.load_survey`; the beacon is the
            transponder at its drop point (the position a survey-in refines).

        Raises
        ------
        InputError
            For a deck-box survey without a drop point and no ``origin``.

        Notes
        -----
        SeaGap surveys are already in local metres: the vehicle position is the
        mean of the transducer at transmit and at receive (the antenna position
        moved by the ``tr-ant.inp`` lever arm, rotated by the attitude:
        :func:`antenna_to_transducer`), its depth is minus ``up``, the
        beacons are the transponders of ``pxp-ini.inp``, and the default sound
        speed is the harmonic mean of ``ss_prof.inp`` from the surface to the mean
        transponder depth (the straight-ray equivalent for vertical paths).
        """
        if self.format == "seagap":
            return self._to_pings_seagap(sound_speed)
        c = float(sound_speed or self.header.get("sound_speed") or 1500.0)
        t0 = float(self.header.get("tat", 0.0) if tat is None else tat)
        if origin is None:
            if "lat" not in self.header:
                raise InputError(f"{self.source}: no drop point in the header; pass origin=")
            origin = (self.header["lat"], self.header["lon"])
        e, n, _ = geodetic_to_enu(self.pings["lat"], self.pings["lon"], 0.0, *origin)
        p = pd.DataFrame({
            "time": self.pings["time"].to_numpy(), "beacon": self.pings["transponder"],
            "range": c * (self.pings["twtt"].to_numpy() - t0) / 2.0, "x": e, "y": n,
            "depth": float(transducer_depth), "line": self.pings["line"].to_numpy(),
            "twtt": self.pings["twtt"].to_numpy()})
        de, dn, _ = geodetic_to_enu(self.header.get("lat", origin[0]),
                                    self.header.get("lon", origin[1]), 0.0, *origin)
        b = pd.DataFrame([{"beacon": str(self.pings["transponder"].iloc[0]) if len(self.pings)
                           else "1", "x": float(de), "y": float(dn),
                           "depth": float(self.header.get("depth", np.nan))}])
        return p, b


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
        pos = {}
        for end in ("tx", "rx"):
            enu = (p[f"e_{end}"], p[f"n_{end}"], p[f"u_{end}"])
            if "tr_ant" in h:  # the transducer, not the antenna
                enu = antenna_to_transducer(*enu, p[f"head_{end}"], p[f"pitch_{end}"],
                                            p[f"roll_{end}"], h["tr_ant"])
            pos[end] = [np.asarray(v, float) for v in enu]
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


# --------------------------------------------------------------------------- OBSrange SIO

_SIO_PING = re.compile(
    r"^\s*(?P<ms>\d+(?:\.\d*)?)\s*msec\.\s+Lat:\s*(?P<latd>\d+)\s+(?P<latm>\d+(?:\.\d*)?)\s*"
    r"(?P<lath>[NS])\s+Lon:\s*(?P<lond>\d+)\s+(?P<lonm>\d+(?:\.\d*)?)\s*(?P<lonh>[EW])\s+"
    r"Alt:\s*(?P<alt>[-+]?\d+(?:\.\d*)?)\s+Time\(UTC\):\s*(?P<year>\d{4}):(?P<doy>\d{1,3}):"
    r"(?P<hh>\d{2}):(?P<mm>\d{2}):(?P<ss>\d{2}(?:\.\d*)?)\s*$")
_SIO_HEADER = {"drop point (latitude)": "lat", "drop point (longitude)": "lon",
               "depth (meters)": "depth", "site": "site"}


def _read_lines(path):
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"survey file not found: {str(path)!r}")
    try:
        return path.read_text(encoding="utf-8-sig", errors="strict").splitlines()
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not UTF-8 text ({exc.reason})") from None


def _finish(fmt, source, rows, header, skipped, transponder):
    pings = pd.DataFrame(rows)
    if pings.empty:
        raise InputError(f"{source}: no ping lines found (expected the {fmt} format; "
                         f"{len(skipped)} lines skipped)")
    pings.insert(1, "transponder", transponder)
    epoch = pings.pop("_epoch")
    pings.insert(2, "time", epoch - epoch.iloc[0])
    skipped = pd.DataFrame(skipped, columns=["line", "text", "reason"])
    return RawSurvey(fmt, source, pings, header, skipped)


def _bad(strict, source, line, text, reason, skipped):
    if strict:
        raise InputError(f"{source} line {line}: {reason}: {text.strip()[:80]!r}")
    skipped.append((line, text, reason))


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
    for i, text in enumerate(_read_lines(path), start=1):
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
            _bad(strict, source, i, text, "not a ping line of the SIO deck-box format", skipped)
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
            _bad(strict, source, i, text, f"invalid time ({exc})", skipped)
            continue
        rows.append({"line": i, "_epoch": t.timestamp(), "twtt": float(g["ms"]) / 1000.0,
                     "lat": _dm(g["latd"], g["latm"], g["lath"]),
                     "lon": _dm(g["lond"], g["lonm"], g["lonh"]), "alt": float(g["alt"])})
    return _finish("obsrange-sio", source, rows, header, skipped, header.get("site", "1"))


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
    for i, text in enumerate(_read_lines(path), start=1):
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
            _bad(strict, source, i, text, f"expected 7 comma-separated fields, got {len(parts)}",
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
            _bad(strict, source, i, text, str(exc), skipped)
    return _finish("obsrange-whoi", source, rows, header, skipped, header.get("site", "1"))


# --------------------------------------------------------------------------- SeaGap

_SEAGAP_COLS = ("transponder", "twtt", "t_tx", "e_tx", "n_tx", "u_tx", "head_tx", "pitch_tx",
                "roll_tx", "t_rx", "e_rx", "n_rx", "u_rx", "head_rx", "pitch_rx", "roll_rx",
                "shot", "flag")


def _numeric_table(path, ncols, what, strict, skipped):
    rows = []
    for i, text in enumerate(_read_lines(path), start=1):
        s = text.strip()
        if not s or s.startswith("#"):
            continue
        parts = s.split()
        try:
            if len(parts) != ncols:
                raise ValueError(f"expected {ncols} numbers ({what}), got {len(parts)} fields")
            vals = [float(v) for v in parts]
            if not np.all(np.isfinite(vals)):
                raise ValueError("non-finite number")
        except ValueError as exc:
            if skipped is None:
                raise InputError(f"{path} line {i}: {exc}") from None
            _bad(strict, str(path), i, text, str(exc), skipped)
            continue
        rows.append([i, *vals])
    return rows


def read_seagap(obsdata, *, pxp=None, tr_ant=None, ss_prof=None, strict=False) -> RawSurvey:
    """Read SeaGap GNSS-acoustic data (``obsdata.inp`` and its companion files).

    Parameters
    ----------
    obsdata : str or pathlib.Path
        ``obsdata.inp``: transponder, two-way travel time (s), transmit time,
        antenna E N U (m) and heading pitch roll at transmit, the same at
        receive, shot number, flag.
    pxp, tr_ant, ss_prof : str or pathlib.Path, optional
        ``pxp-ini.inp`` (transponder E N U and 3 more columns), ``tr-ant.inp``
        (transducer offset from the antenna, vessel frame, m), ``ss_prof.inp``
        (depth m, sound speed m/s). Default: beside ``obsdata``, when present.
    strict : bool, default False

    Returns
    -------
    RawSurvey
        ``pings`` has the 18 columns (``twtt`` in s, ``time`` from ``t_tx``);
        ``header`` has ``transponders`` (DataFrame of E N U), ``tr_ant`` and
        ``ss_prof`` (DataFrame) when read.

    Raises
    ------
    FileNotFoundError, InputError
        Companion files must parse completely (they are small and authoritative).
    """
    obsdata = Path(obsdata)
    skipped = []
    rows = _numeric_table(obsdata, 18, "obsdata.inp columns", strict, skipped)
    if not rows:
        raise InputError(f"{obsdata}: no data lines found (expected 18 columns)")
    pings = pd.DataFrame(rows, columns=["line", *_SEAGAP_COLS])
    for c in ("transponder", "shot", "flag"):
        pings[c] = pings[c].astype(int)
    pings["transponder"] = pings["transponder"].astype(str)
    pings.insert(2, "time", pings["t_tx"] - pings["t_tx"].iloc[0])
    header = {}
    here = obsdata.parent
    for key, arg, name, ncols in (("transponders", pxp, "pxp-ini.inp", 6),
                                  ("tr_ant", tr_ant, "tr-ant.inp", 3),
                                  ("ss_prof", ss_prof, "ss_prof.inp", 2)):
        path = Path(arg) if arg is not None else here / name
        if arg is None and not path.exists():
            continue
        vals = _numeric_table(path, ncols, name, strict=True, skipped=None)
        if key == "transponders":
            t = pd.DataFrame([r[1:4] for r in vals], columns=["east", "north", "up"])
            t.index = [str(k + 1) for k in range(len(t))]
            header[key] = t
        elif key == "tr_ant":
            header[key] = np.asarray(vals[0][1:], float)
        else:
            header[key] = pd.DataFrame([r[1:] for r in vals], columns=["depth", "sound_speed"])
    skipped_df = pd.DataFrame(skipped, columns=["line", "text", "reason"])
    return RawSurvey("seagap", str(obsdata), pings, header, skipped_df)


def sample_file(name: str) -> Path:
    """Path of a measured sample survey shipped with the package.

    The OBSrange samples (``"obsrange/SIO_CC03.txt"``, ``SIO_EC03.txt``,
    ``SIO_WC03.txt``, ``WHOI_S05.txt``, ``CC03_ssp.txt``,
    ``CC03_obsrange_solution.txt``) and the SeaGap example (``"seagap/obsdata.inp"``
    with its companion files); their sources and licences are in the ``README.md``
    beside them (``data/README.md`` in the source repository).

    Parameters
    ----------
    name : str
        Path relative to the sample folder.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    FileNotFoundError
        If there is no such sample.

    Examples
    --------
    >>> sample_file("obsrange/SIO_CC03.txt").name
    'SIO_CC03.txt'
    """
    here = Path(__file__).resolve().parent
    for root in (here / "_samples", here.parents[1] / "data"):
        if (root / name).is_file():
            return root / name
    raise FileNotFoundError(f"no sample file {name!r} (expected e.g. 'obsrange/SIO_CC03.txt' or "
                            "'seagap/obsdata.inp')")


def read_survey(path, format: str, **kwargs) -> RawSurvey:
    """Read a survey file of the given ``format`` (one of :data:`FORMATS`).

    Parameters
    ----------
    path : str or pathlib.Path
    format : {"obsrange-sio", "obsrange-whoi", "seagap"}
    **kwargs
        Passed to the reader (``strict``; SeaGap companion paths).

    Returns
    -------
    RawSurvey
    """
    readers = {"obsrange-sio": read_obsrange_sio, "obsrange-whoi": read_obsrange_whoi,
               "seagap": read_seagap}
    if format not in readers:
        raise ValueError(f"format: expected one of {FORMATS}, got {format!r}")
    return readers[format](path, **kwargs)


__all__ = ["FORMATS", "RawSurvey", "antenna_to_transducer", "enu_to_geodetic", "geodetic_to_enu",
           "read_obsrange_sio", "read_obsrange_whoi", "read_seagap", "read_survey", "sample_file"]
