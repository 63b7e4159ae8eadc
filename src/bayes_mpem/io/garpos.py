"""GARPOS GNSS-acoustic surveys: the site file, the shots and the sound-speed profile.

Details: ``docs/gnssa.md``.
"""

from __future__ import annotations

import re
import unicodedata
from pathlib import Path

import numpy as np
import pandas as pd

from ..exceptions import InputError
from .fields import flag, number, where
from .raw import RawSurvey, bad, read_lines, skip_reasons
from .results import output_folder, write_file

#: obs.csv column -> RawSurvey.pings column (the antenna and attitude at transmit and receive)
OBS_COLUMNS = {"MT": "transponder", "TT": "twtt", "ST": "t_tx",
               "ant_e0": "e_tx", "ant_n0": "n_tx", "ant_u0": "u_tx",
               "head0": "head_tx", "pitch0": "pitch_tx", "roll0": "roll_tx", "RT": "t_rx",
               "ant_e1": "e_rx", "ant_n1": "n_rx", "ant_u1": "u_rx",
               "head1": "head_rx", "pitch1": "pitch_rx", "roll1": "roll_rx"}
#: accepted range of each numeric obs.csv column: (low, high, low excluded)
OBS_RANGES = {"TT": (0.0, 60.0, True), "ST": (None, None, False), "RT": (None, None, False),
              **{f"ant_{c}{k}": (-1e5, 1e5, False) for c in "en" for k in "01"},
              **{f"ant_u{k}": (-1e3, 1e3, False) for k in "01"},
              **{f"head{k}": (-360.0, 360.0, False) for k in "01"},
              **{f"{a}{k}": (-90.0, 90.0, False) for a in ("pitch", "roll") for k in "01"}}
#: the name GARPOS gives a reply it could not assign to a transponder
UNKNOWN_STATION = "M00"


def resolve_path(text, base, source=None) -> Path:
    """Find a file a control file names: from the working folder, or from ``base``.

    A relative name is looked for in both; where both hold a file of that name, they must be
    the same file (else which campaign's data is meant is not known).

    Parameters
    ----------
    text : str
    base : str or pathlib.Path
    source : str, optional
        Where the name was read (e.g. ``"site.ini line 8 (datacsv)"``), to begin the messages.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    FileNotFoundError
        Naming every place looked at.
    InputError
        An empty name, a name that is a folder, or a relative name of two different files.
    """
    name = str(text).strip() if text is not None else ""
    lead = f"{source}: " if source else ""
    if not name:
        raise InputError(f"{lead}expected a file name, got {name!r}")
    p = Path(name)
    tried = [p] if p.is_absolute() else [Path.cwd() / p, Path(base) / p]
    found = [c for c in tried if c.is_file()]
    if len(found) == 2 and not found[0].samefile(found[1]):
        # two different files of this name: taking either silently could fit one campaign's
        # control file to another's data
        raise InputError(f"{lead}{name!r} names two different files: {found[0]} (from the "
                         f"working folder) and {found[1]} (beside the control file); give an "
                         "absolute path, or run from another folder")
    if found:
        return found[0]
    folder = next((c for c in tried if c.is_dir()), None)
    if folder is not None:
        raise InputError(f"{lead}{name!r} is a folder ({folder}); expected a file")
    other = next((c for c in tried if c.exists()), None)
    if other is not None:  # a pipe, a device or a socket: it cannot be read twice
        raise InputError(f"{lead}{name!r} is not a regular file ({other}: a pipe, device or "
                         "socket); expected a file")
    raise FileNotFoundError(f"{lead}{name!r} not found (looked at "
                            + " and ".join(str(c) for c in tried) + ")")


def _read_ini(path) -> dict:
    """Read an INI-style control file as ``{section: {key: (value, line)}}``."""
    out, section = {}, None
    for i, text in enumerate(read_lines(path), start=1):
        s = text.strip()
        if not s or s[0] in "#;":
            continue
        m = re.fullmatch(r"\[([^\]]+)\]", s)
        if m:
            section = m.group(1).strip()
            out.setdefault(section, {})
            continue
        key, sep, value = s.partition("=")
        if not sep or not key.strip():
            raise InputError(f"{where(path, i)}: expected '[section]' or 'key = value', got "
                             f"{s[:80]!r}")
        if section is None:
            raise InputError(f"{where(path, i)}: {key.strip()!r} comes before any [section]")
        if key.strip() in out[section]:
            raise InputError(f"{where(path, i)}: {key.strip()!r} given twice in [{section}]")
        out[section][key.strip()] = (value.strip(), i)
    return out


def _get(ini, path, section, key, default=None):
    try:
        return ini[section][key]
    except KeyError:
        if default is not None:
            return default
        raise InputError(f"{path}: no {key!r} in [{section}]{_near_key(ini, key)}") from None


def _plain(text):
    """``text`` without invisible characters (format, control, spaces), case folded."""
    return "".join(c for c in text if unicodedata.category(c)[0] not in "CZ").casefold()


def _near_key(ini, key):
    """Where ``key`` is given in another section, or with another case or invisible characters."""
    for section, entries in ini.items():
        for k, (_, line) in entries.items():
            if k == key:
                return f"; line {line} gives it in [{section}] (the wrong section?)"
            if _plain(k) == _plain(key):
                return (f"; line {line} gives {k!r} in [{section}] (check its spelling, case "
                        "and any invisible characters)")
    return ""


def _values(ini, path, section, key, n, names, ranges=None):
    """``n`` numbers of one key, checked; a ``ValueError`` becomes an InputError with the line."""
    text, line = _get(ini, path, section, key)
    parts = text.split()
    if len(parts) < n or (n == 1 and len(parts) > 1):  # one number: more is not ignored
        what = "one number" if n == 1 else f"{n} numbers"
        hint = (" (degrees, minutes and seconds? give decimal degrees)"
                if n == 1 and key in ("Latitude0", "Longitude0") else "")
        raise InputError(f"{where(path, line, name=key)}: expected {what}, got "
                         f"{len(parts)}: {text!r}{hint}")
    try:
        return [number(v, key if n == 1 else f"{key} {nm}", **(ranges or {}).get(nm, {}))
                for v, nm in zip(parts[:n], names, strict=True)]
    except ValueError as exc:
        raise InputError(f"{where(path, line, name=key)}: {exc}") from None


def _sigmas(ini, path, key):
    """Return the sigmas (fields 4-6) of a position key; None where absent (0 fixes it).

    A sigma that is not a finite number of 0 or more is an InputError naming the line: read
    as free or as its absolute value, it would change what the site file asks for.
    """
    text, line = _get(ini, path, "Model-parameter", key)
    parts = text.split()[3:6]
    out = []
    for v, nm in zip(parts, ("sigma_E", "sigma_N", "sigma_U"), strict=False):
        try:
            out.append(number(v, f"{key} {nm}", lo=0.0))
        except ValueError as exc:
            raise InputError(f"{where(path, line, name=key)}: {exc} (0 fixes the "
                             "coordinate)") from None
    return out + [None] * (3 - len(out))


def profile_frame(depth, speed, source, lines=None, column=None) -> pd.DataFrame:
    """Check a sound-speed profile read from a survey's file; return ``depth``, ``sound_speed``.

    Parameters
    ----------
    depth, speed : array_like
    source : str
    lines : array_like of int, optional
        Each level's line in ``source``, to name where depths stop increasing.
    column : int, optional
        The depth's column (1-based), for the same message.

    Returns
    -------
    pandas.DataFrame

    Raises
    ------
    InputError
        Fewer than 2 levels, depths not increasing, or a speed outside 1300-1800 m/s.
    """
    d, c = np.asarray(depth, float), np.asarray(speed, float)
    if d.size < 2:
        raise InputError(f"{source}: a sound-speed profile needs 2 or more levels, got {d.size}")
    if np.any(np.diff(d) <= 0):
        k = int(np.flatnonzero(np.diff(d) <= 0)[0])
        if lines is None:
            raise InputError(f"{source}: depths must increase, got {d[k]:g} then {d[k + 1]:g} m")
        raise InputError(f"{where(source, int(lines[k + 1]), column, 'depth')}: depths must "
                         f"increase line after line, got {d[k]:g} then {d[k + 1]:g} m (a "
                         "repeated or swapped level)")
    if np.any((c < 1300.0) | (c > 1800.0)):
        k = int(np.flatnonzero((c < 1300.0) | (c > 1800.0))[0])
        raise InputError(f"{source}: sound speed {c[k]:g} m/s at {d[k]:g} m is outside "
                         "1300-1800 m/s")
    return pd.DataFrame({"depth": d, "sound_speed": c})


def profile_reaches(profile, depths, source) -> pd.DataFrame:
    """Check that a survey's profile reaches its transponders; return the profile.

    Below its last level a profile's speed is held constant, which is harmless over the last
    few metres and wrong over hundreds (a profile in km, a cast cut short, the wrong file):
    a profile ending more than 10 % of the deepest transponder's depth above it is refused,
    and so is one starting more than 10 % of that depth below the sea surface (above its
    first level the speed is held too: a cast whose top was cut, or the wrong file).

    Parameters
    ----------
    profile : pandas.DataFrame
        ``depth`` (m below the sea surface, increasing), ``sound_speed``.
    depths : array_like
        The transponders' prior depths below the sea surface (m); the index names them.
    source : str
        The profile's file, for the message.

    Returns
    -------
    pandas.DataFrame
        ``profile``.

    Raises
    ------
    InputError
    """
    d = pd.Series(depths, dtype=float)
    if d.empty:
        return profile
    deepest, last = float(d.max()), float(profile["depth"].iloc[-1])
    first = float(profile["depth"].iloc[0])
    if first > 0.1 * deepest:
        raise InputError(f"{source}: the sound-speed profile starts at {first:g} m, below a "
                         f"tenth of the deepest transponder's depth ({d.idxmax()} at "
                         f"{deepest:g} m): its first speed would be held up to the sea "
                         "surface; expected a profile from near the surface (depths in m, "
                         "positive down)")
    if last < 0.9 * deepest:
        raise InputError(f"{source}: the sound-speed profile ends at {last:g} m, above the "
                         f"deepest transponder ({d.idxmax()} at {deepest:g} m); expected a "
                         "profile down to the transponders (depths in m, positive down)")
    return profile


def _named_file(ini, path, section, key) -> Path:
    """Return the file a site file's ``key`` names; errors name the site file's line."""
    text, line = _get(ini, path, section, key)
    return resolve_path(text, Path(path).parent, where(path, line, name=key))


def _read_svp(path) -> pd.DataFrame:
    """Read GARPOS's ``svp.csv`` into ``depth`` (m), ``sound_speed`` (m/s)."""
    rows, cols = [], None
    for i, text in enumerate(read_lines(path), start=1):
        s = text.strip()
        if not s or s.startswith("#"):
            continue
        parts = [p.strip() for p in s.split(",")]
        if cols is None:
            cols = parts
            missing = {"depth", "speed"} - set(cols)
            if missing:
                raise InputError(f"{where(path, i)}: expected a header with 'depth' and "
                                 f"'speed', got {s[:80]!r}")
            continue
        if len(parts) != len(cols):
            raise InputError(f"{where(path, i)}: expected {len(cols)} fields, got {len(parts)}")
        vals = []
        for name, lo, hi in (("depth", -100.0, 12000.0), ("speed", 1300.0, 1800.0)):
            j = cols.index(name)
            try:
                vals.append(number(parts[j], name, lo=lo, hi=hi))
            except ValueError as exc:
                raise InputError(f"{where(path, i, j + 1, name)}: {exc}") from None
        rows.append([*vals, i])
    if cols is None:
        raise InputError(f"{path}: empty sound-speed profile")
    d, c, at = np.array(rows, float).reshape(-1, 3).T
    return profile_frame(d, c, str(path), lines=at, column=cols.index("depth") + 1)


def _parse_shot(parts, cols, stations):
    """One obs.csv data line -> dict of RawSurvey columns, or ValueError with the column."""
    if len(parts) != cols["_n"]:
        raise ValueError(f"expected {cols['_n']} comma-separated fields, got {len(parts)}")
    row = {}
    mt = parts[cols["MT"]].strip()
    if mt == UNKNOWN_STATION and mt not in stations:
        raise LookupError(f"transponder {UNKNOWN_STATION}: a reply GARPOS could not assign "
                          "to a transponder")
    if mt not in stations:
        raise LookupError(f"column {cols['MT'] + 1} (MT): transponder {mt!r} is not one of the "
                          f"site's Stations {list(stations)}")
    row["transponder"] = mt
    for name, out in OBS_COLUMNS.items():
        if name == "MT":
            continue
        lo, hi, lo_open = OBS_RANGES[name]
        try:
            row[out] = number(parts[cols[name]], name, lo=lo, hi=hi, lo_open=lo_open)
        except ValueError as exc:
            raise ValueError(f"column {cols[name] + 1} ({exc})") from None
    if not 0.0 < row["t_rx"] - row["t_tx"] < 120.0:
        raise ValueError(f"column {cols['RT'] + 1} (RT): expected 0-120 s after ST, got "
                         f"{row['t_rx'] - row['t_tx']:g} s")
    for name, out in (("SET", "set"), ("LN", "survey_line")):
        if name in cols:
            row[out] = parts[cols[name]].strip()
    if "flag" in cols:
        try:
            row["file_flag"] = flag(parts[cols["flag"]], "flag")
        except ValueError as exc:
            raise ValueError(f"column {cols['flag'] + 1} ({exc})") from None
    return row


def _read_obs(path, stations, *, strict=False):
    """Read GARPOS's ``obs.csv`` shots (a repeated transponder and ``ST`` is skipped)."""
    rows, skipped, cols, first = [], [], None, {}
    for i, text in enumerate(read_lines(path), start=1):
        s = text.strip()
        if not s or s.startswith("#"):
            continue
        parts = s.split(",")
        if cols is None:
            names = [p.strip() for p in parts]
            twice = sorted({n for n in names if n and names.count(n) > 1})
            if twice:
                raise InputError(f"{where(path, i)}: the header names column(s) {twice} "
                                 "more than once (expected GARPOS's obs.csv: "
                                 f"{list(OBS_COLUMNS)})")
            cols = {n: j for j, n in enumerate(names) if n}
            missing = [n for n in OBS_COLUMNS if n not in cols]
            if missing:
                raise InputError(f"{where(path, i)}: the header lacks column(s) {missing} "
                                 f"(expected GARPOS's obs.csv: {list(OBS_COLUMNS)})")
            cols["_n"] = len(names)
            continue
        try:
            row = _parse_shot(parts, cols, stations)
        except LookupError as exc:
            if strict and not str(exc).startswith(f"transponder {UNKNOWN_STATION}"):
                raise InputError(f"{where(path, i)}: {exc}") from None
            skipped.append((i, text, str(exc)))
            continue
        except ValueError as exc:
            bad(strict, str(path), i, text, str(exc), skipped)
            continue
        key = (row["transponder"], row["t_tx"])
        if key in first:
            bad(strict, str(path), i, text,
                f"a second shot of {key[0]} transmitted at ST {key[1]:.6f} (the first is line "
                f"{first[key]}; a transponder replies once per transmission)", skipped)
            continue
        first[key] = i
        rows.append({"line": i, **row})
    if cols is None:
        raise InputError(f"{path}: no header line (expected GARPOS's obs.csv)")
    return rows, skipped


def read_garpos(site_file, *, obs=None, svp=None, strict=False) -> RawSurvey:
    """Read a GARPOS survey: the site file and the shots and profile it names (``docs/gnssa.md``).

    Parameters
    ----------
    site_file : str or pathlib.Path
        ``*-initcfg.ini``.
    obs, svp : str or pathlib.Path, optional
        Instead of the site file's ``datacsv`` and ``SoundSpeed``.
    strict : bool, default False
        Raise on a shot line that does not parse instead of skipping it.

    Returns
    -------
    RawSurvey

    Raises
    ------
    FileNotFoundError, InputError
    """
    site_file = Path(site_file)
    ini = _read_ini(site_file)
    origin = _values(ini, site_file, "Site-parameter", "Latitude0", 1, ["value"],
                     {"value": {"lo": -90.0, "hi": 90.0}})
    origin += _values(ini, site_file, "Site-parameter", "Longitude0", 1, ["value"],
                      {"value": {"lo": -360.0, "hi": 360.0}})
    origin += _values(ini, site_file, "Site-parameter", "Height0", 1, ["value"],
                      {"value": {"lo": -1e4, "hi": 1e4}})
    text, line = _get(ini, site_file, "Site-parameter", "Stations")
    stations = text.split()
    if (not stations or len(set(stations)) != len(stations)
            or any(ch in text for ch in ",;")):
        raise InputError(f"{where(site_file, line, name='Stations')}: expected distinct "
                         f"transponder names separated by spaces, got {text!r}")
    for st in stations:
        if f"{st}_dPos" not in ini.get("Model-parameter", {}):
            raise InputError(f"{where(site_file, line, name='Stations')}: station {st!r} has "
                             f"no '{st}_dPos' in [Model-parameter]")
    horizontal = {"lo": -1e5, "hi": 1e5}
    cent = (_values(ini, site_file, "Model-parameter", "dCentPos", 3, ["east", "north", "up"],
                    {"east": horizontal, "north": horizontal,
                     "up": {"lo": -12000.0, "hi": 12000.0}})
            if "dCentPos" in ini.get("Model-parameter", {}) else [0.0, 0.0, 0.0])
    pos, sig = {}, {}
    for st in stations:
        e, n, u = _values(ini, site_file, "Model-parameter", f"{st}_dPos", 3,
                          ["east", "north", "up"], {"east": horizontal, "north": horizontal,
                                                    "up": {"lo": -12000.0, "hi": 0.0}})
        pos[st] = (e + cent[0], n + cent[1], u + cent[2])
        if not -12000.0 <= pos[st][2] <= 0.0:
            key = f"{st}_dPos"
            at = where(site_file, ini["Model-parameter"][key][1], name=key)
            raise InputError(f"{at}: up + dCentPos up = {pos[st][2]:g} m; expected a seafloor "
                             "transponder, in [-12000, 0] m")
        sig[st] = _sigmas(ini, site_file, f"{st}_dPos")
    try:  # downward below 0: the transducer above its antenna, out of the water
        atd = _values(ini, site_file, "Model-parameter", "ATDoffset", 3,
                      ["forward", "rightward", "downward"],
                      {"forward": {"lo": -100.0, "hi": 100.0},
                       "rightward": {"lo": -100.0, "hi": 100.0},
                       "downward": {"lo": 0.0, "hi": 100.0}})
    except InputError as exc:
        if "ATDoffset downward: expected a number in [0, 100], got '-" not in str(exc):
            raise  # not a negative downward (150, '12x', nan): the message says it all
        raise InputError(f"{exc}: the transducer is under the water and the GNSS antenna above "
                         "it, so the offset is positive downward (a sign slipped?)") from None
    obs_path = Path(obs) if obs is not None else _named_file(ini, site_file, "Data-file",
                                                              "datacsv")
    svp_path = Path(svp) if svp is not None else _named_file(ini, site_file, "Obs-parameter",
                                                              "SoundSpeed")
    rows, skipped = _read_obs(obs_path, stations, strict=strict)
    if not rows:
        raise InputError(f"{obs_path}: no shot lines found ({len(skipped)} lines skipped"
                         + (f": {skip_reasons(skipped)})" if skipped else ")"))
    pings = pd.DataFrame(rows)
    pings.insert(2, "time", pings["t_tx"] - pings["t_tx"].min())
    transponders = pd.DataFrame(pos, index=["east", "north", "up"]).T
    header = {"site": _get(ini, site_file, "Obs-parameter", "Site_name", ("", 0))[0],
              "campaign": _get(ini, site_file, "Obs-parameter", "Campaign", ("", 0))[0],
              "lat": origin[0], "lon": origin[1], "height": origin[2],
              "transponders": transponders, "atd_offset": np.asarray(atd, float),
              "ss_prof": profile_reaches(_read_svp(svp_path), -transponders["up"],
                                         str(svp_path)),
              "ss_prof_source": svp_path.name,
              "surface_depth": 0.0,
              "position_sigmas": pd.DataFrame(sig, index=["east", "north", "up"]).T,
              "atd_sigmas": _sigmas(ini, site_file, "ATDoffset"),
              "centre_sigmas": (_sigmas(ini, site_file, "dCentPos")
                                if "dCentPos" in ini.get("Model-parameter", {}) else None),
              "files": {"site": str(site_file), "obs": str(obs_path), "svp": str(svp_path)}}
    return RawSurvey("garpos", str(site_file), pings, header,
                     pd.DataFrame(skipped, columns=["line", "text", "reason"]))


def _jday(date: str) -> str:
    """Return ``YYYY-DDD`` (GARPOS's ``Date(jday)``) of a ``YYYY-MM-DD`` date."""
    from datetime import date as _date

    d = _date.fromisoformat(str(date))
    return f"{d.year}-{d.timetuple().tm_yday:03d}"


def write_garpos(out_dir, pings, header, *, site="SIM", campaign="0000.sim",
                 date="2024-01-01", sigmas=(3.0, 3.0, 3.0)) -> Path:
    """Write a survey as GARPOS's site, shots and profile files; return the site file.

    Parameters
    ----------
    out_dir : str or pathlib.Path
    pings : pandas.DataFrame
        As :func:`read_garpos` returns.
    header : dict
        ``lat``, ``lon``, ``height``, ``transponders``, ``atd_offset`` and ``ss_prof``.
    site, campaign, date : str
    sigmas : tuple of float, default (3, 3, 3)
        Every ``<station>_dPos``'s sigmas (east, north, up; m): the prior positions' sds,
        which ``locate`` reads as Gaussian priors (0 holds the coordinate).

    Returns
    -------
    pathlib.Path
    """
    out = output_folder(out_dir)
    stem = f"{site}.{campaign}"
    site_file, obs_file, svp_file = (out / f"{stem}-{k}" for k in ("initcfg.ini", "obs.csv",
                                                                    "svp.csv"))
    tp = header["transponders"]
    lines = ["[Obs-parameter]", f" Site_name   = {site}", f" Campaign    = {campaign}",
             f" Date(UTC)   = {date}", f" Date(jday)  = {_jday(date)}",
             # GARPOS copies the frame's name into its results and needs the key
             " Ref.Frame   = ITRF2014", f" SoundSpeed  = {svp_file.name}", "",
             "[Data-file]", f" datacsv     = {obs_file.name}", f" N_shot      = {len(pings)}",
             "", "[Site-parameter]", f" Latitude0   = {header['lat']:.8f}",
             f" Longitude0  = {header['lon']:.8f}", f" Height0     = {header['height']:.2f}",
             f" Stations    = {' '.join(map(str, tp.index))}", "", "[Model-parameter]",
             "# MT_Pos     :   east  north  up  sigma_E  sigma_N  sigma_U  cov_NU  cov_UE  cov_EN"]
    se, sn, su = (float(v) for v in sigmas)
    for st, r in tp.iterrows():
        lines.append(f" {st}_dPos    = {r['east']:11.4f} {r['north']:11.4f} {r['up']:11.4f}"
                     f" {se:11.4f} {sn:11.4f} {su:11.4f}   0.000e+00   0.000e+00   0.000e+00")
    f, r_, d = np.asarray(header["atd_offset"], float)
    lines += [" dCentPos    =      0.0000      0.0000      0.0000      0.0000      0.0000"
              "      0.0000   0.000e+00   0.000e+00   0.000e+00",
              "# ANT_to_TD  :    forward  rightward  downward  sigma_F  sigma_R  sigma_D  "
              "cov_RD  cov_DF  cov_FR",
              f" ATDoffset   = {f:11.4f} {r_:11.4f} {d:11.4f}      0.0000      0.0000      0.0000"
              "   0.000e+00   0.000e+00   0.000e+00", ""]
    # each file through write_file: staged with the command's run (all or nothing)
    write_file(site_file, lambda tmp: tmp.write_text("\n".join(lines) + "\n"))
    prof = header["ss_prof"]
    write_file(svp_file, lambda tmp: tmp.write_text("depth,speed\n" + "".join(
        f"{z:.3f},{c:.4f}\n" for z, c in zip(prof["depth"], prof["sound_speed"], strict=True))))
    table = pd.DataFrame({
        "SET": pings.get("set", "S01"), "LN": pings.get("survey_line", "L01"),
        "MT": pings["transponder"].astype(str), "TT": pings["twtt"].map("{:.7f}".format),
        "ResiTT": 0.0, "TakeOff": 0.0, "gamma": 0.0,
        "flag": pings.get("file_flag", pd.Series(False, index=pings.index)).astype(bool),
        "ST": pings["t_tx"].map("{:.6f}".format)})
    for name, col in OBS_COLUMNS.items():
        if name not in ("MT", "TT", "ST"):
            table[name] = pings[col].map("{:.6f}".format if name == "RT" else "{:.5f}".format
                                         if name.startswith("ant") else "{:.3f}".format)
    table = table[["SET", "LN", "MT", "TT", "ResiTT", "TakeOff", "gamma", "flag", "ST",
                   *[n for n in OBS_COLUMNS if n not in ("MT", "TT", "ST")]]]
    def obs(tmp):
        with open(tmp, "w", newline="") as fh:
            fh.write(f"# cfgfile = {site_file.name}\n")
            table.to_csv(fh, index=True)

    write_file(obs_file, obs)
    return site_file
