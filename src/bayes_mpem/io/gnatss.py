"""GNATSS GNSS-acoustic surveys: the config, the travel times, the positions, the profile.

Details: ``docs/gnssa.md``.
"""

from __future__ import annotations

import glob
import re
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np
import pandas as pd

from ..exceptions import InputError
from .fields import number, where
from .garpos import profile_frame, profile_reaches, resolve_path
from .geodesy import atd_offset_enu, ecef_to_enu, enu_to_ecef, enu_to_geodetic, geodetic_to_enu
from .raw import RawSurvey, bad, read_lines, skip_reasons
from .results import output_folder, write_file

#: The J2000 epoch GNATSS counts its times from (2000-01-01 12:00:00, no leap seconds).
J2000 = datetime(2000, 1, 1, 12, 0, 0)
_DATE = re.compile(r"^\d{1,2}-[A-Za-z]{3}-\d{2}$")
#: Decimal places of a time used to match a travel time with a position (1 microsecond).
TIME_DECIMALS = 6


def _yaml_node(root, keys):
    node = root
    for k in keys:
        if node is None:
            return None
        if hasattr(node, "value") and isinstance(node.value, list) and isinstance(k, int):
            node = node.value[k] if k < len(node.value) else None
        elif hasattr(node, "value") and isinstance(node.value, list):
            node = next((v for kn, v in node.value if getattr(kn, "value", None) == k), None)
        else:
            return None
    return node


def _no_repeated_keys(node, path):
    """Refuse a key given twice in one mapping (YAML keeps the last one silently)."""
    import yaml

    if isinstance(node, yaml.MappingNode):
        seen = {}
        for k, v in node.value:
            name = getattr(k, "value", None)
            if isinstance(name, str) and name in seen:
                raise InputError(f"{where(path, k.start_mark.line + 1, name=name)}: {name!r} "
                                 f"given twice in one mapping (first at line {seen[name]})")
            seen[name] = k.start_mark.line + 1
            _no_repeated_keys(v, path)
    elif isinstance(node, yaml.SequenceNode):
        for v in node.value:
            _no_repeated_keys(v, path)


class _Config:
    """The config's values with the line each came from."""

    def __init__(self, path):
        import yaml

        self.path = Path(path)
        text = "\n".join(read_lines(path))
        try:
            self.data = yaml.safe_load(text) or {}
            self.root = yaml.compose(text)
        except yaml.YAMLError as exc:
            mark = getattr(exc, "problem_mark", None)
            line = None if mark is None else mark.line + 1
            raise InputError(f"{where(path, line)}: not valid YAML "
                             f"({getattr(exc, 'problem', exc)})") from None
        if not isinstance(self.data, dict):
            raise InputError(f"{path}: expected a YAML mapping (GNATSS's config.yaml)")
        _no_repeated_keys(self.root, path)

    def get(self, *keys, default=KeyError):
        node = self.data
        for k in keys:
            try:
                node = node[k]
            except (KeyError, IndexError, TypeError):
                if default is KeyError:
                    raise InputError(f"{self.path}: no {'.'.join(map(str, keys))!r} (expected "
                                     "GNATSS's config.yaml)") from None
                return default
        return node

    def where(self, *keys) -> str:
        """Name the config's line holding ``keys`` (the file alone when not found)."""
        node = _yaml_node(self.root, keys)
        line = None if node is None else node.start_mark.line + 1
        return where(self.path, line, name=".".join(map(str, keys)))

    def flag(self, *keys, default):
        """Return a true/false value (``true``/``false``, 1/0); else raise, naming the line."""
        value = self.get(*keys, default=default)
        if not isinstance(value, bool) and value not in (0, 1):
            raise InputError(f"{self.where(*keys)}: expected true or false, got {value!r}")
        return bool(value)

    def number(self, *keys, default=KeyError, **limits):
        value = self.get(*keys, default=default)
        try:
            return number(value, ".".join(map(str, keys)), **limits)
        except ValueError as exc:
            node = _yaml_node(self.root, keys)
            line = None if node is None else node.start_mark.line + 1
            raise InputError(f"{where(self.path, line)}: {exc}") from None


def _paths(cfg, key):
    keys = ("solver", "input_files", key, "path")
    value = cfg.get(*keys)
    text = "" if value is None else str(value)
    base = cfg.path.parent
    if any(ch in text for ch in "*?["):
        patterns = ([text] if Path(text).is_absolute()
                    else [str(root / text) for root in (Path.cwd(), base)])
        found = [m for m in (sorted(Path(f) for f in glob.glob(pat, recursive=True)
                                    if Path(f).is_file()) for pat in patterns) if m]
        if len(found) == 2 and sorted(f.resolve() for f in found[0]) != sorted(
                f.resolve() for f in found[1]):
            raise InputError(f"{cfg.where(*keys)}: {text!r} matches different files from the "
                             f"working folder ({Path.cwd()}: {len(found[0])}) and beside the "
                             f"config ({base}: {len(found[1])}); give an absolute path, or run "
                             "from another folder")
        if found:
            return found[0]
        raise FileNotFoundError(f"{cfg.where(*keys)}: no file matches {text!r} (from "
                                f"{Path.cwd()} or {base})")
    return [resolve_path(text, base, cfg.where(*keys))]


def _transponders(cfg):
    items = cfg.get("solver", "transponders")
    if not isinstance(items, list) or not items:
        raise InputError(f"{cfg.path}: 'solver.transponders' must be a non-empty list")
    site = str(cfg.get("site_id", default="SITE"))
    rows = []
    for k, item in enumerate(items):
        key = ("solver", "transponders", k)
        rows.append({
            "id": str(item.get("pxp_id") or f"{site}-{k + 1}") if isinstance(item, dict) else "",
            "lat": cfg.number(*key, "lat", lo=-90.0, hi=90.0),
            "lon": cfg.number(*key, "lon", lo=-360.0, hi=360.0),
            "height": cfg.number(*key, "height", lo=-12000.0, hi=0.0),
            "internal_delay": cfg.number(*key, "internal_delay", lo=0.0, hi=10.0)})
    ids = [r["id"] for r in rows]
    if len(set(ids)) != len(ids):
        raise InputError(f"{cfg.path}: transponder ids must be distinct, got {ids}")
    return pd.DataFrame(rows).set_index("id")


def _read_profile(paths):
    frames = []
    for path in paths:
        rows = []
        for i, text in enumerate(read_lines(path), start=1):
            parts = _fields(text)
            if not parts or parts[0].startswith("#"):
                continue
            if len(parts) < 2:
                raise InputError(f"{where(path, i)}: expected depth and sound speed, got "
                                 f"{text.strip()[:80]!r}")
            try:
                rows.append((-number(parts[0], "depth", lo=-12000.0, hi=100.0),
                             number(parts[1], "sound speed", lo=1300.0, hi=1800.0)))
            except ValueError as exc:
                raise InputError(f"{where(path, i, 1 if 'depth' in str(exc) else 2)}: "
                                 f"{exc}") from None
            if len(rows) > 1 and rows[-1][0] <= rows[-2][0]:
                raise InputError(f"{where(path, i, 1, 'depth')}: expected heights going "
                                 f"down level after level (GNATSS's first column is negative "
                                 f"below the sea surface), got {-rows[-2][0]:g} then "
                                 f"{-rows[-1][0]:g} m (a repeated or swapped level, or depths "
                                 "given positive?)")
        frames.append(pd.DataFrame(rows, columns=["depth", "sound_speed"]))
    prof = pd.concat(frames).drop_duplicates("depth").sort_values("depth")
    return profile_frame(prof["depth"], prof["sound_speed"], ", ".join(map(str, paths)))


def _fields(text: str) -> list[str]:
    """Split a line at spaces and tabs only: a CR, form feed or U+2028 stays in its field."""
    s = text.strip(" \t")
    return _BLANKS.split(s) if s else []


_BLANKS = re.compile(r"[ \t]+")


def _data_lines(paths):
    """Yield ``(path, line number, text, fields)`` of every line that is not blank or a comment."""
    for path in paths:
        for i, text in enumerate(read_lines(path), start=1):
            parts = _fields(text)
            if parts and not parts[0].startswith("#"):
                yield path, i, text, parts


def _read_positions(paths, std_dev, strict, skipped):
    """Map times (J2000 s, rounded) to (x, y, z, 3-D sigma) from POS_FREED_TRANS_TWTT files.

    A time given twice with two different positions maps to the reason it is not used.
    """
    out, first = {}, {}
    for path, i, text, parts in _data_lines(paths):
        try:
            if len(parts) != 13:
                raise ValueError(f"expected 13 numbers (time, X Y Z, 9 covariances), got "
                                 f"{len(parts)} fields")
            v = []
            for j, s in enumerate(parts):
                try:
                    v.append(number(s, "time" if j == 0 else "XYZ"[j - 1] if j < 4
                                    else "covariance"))
                except ValueError as exc:
                    raise ValueError(f"column {j + 1} ({exc})") from None
            r = float(np.sqrt(v[1] ** 2 + v[2] ** 2 + v[3] ** 2))
            if not 6.2e6 < r < 6.5e6:
                raise ValueError(f"columns 2-4: {r:.0f} m from the Earth's centre, not "
                                 "at the sea surface (6.2e6-6.5e6 m)")
            neg = [j for j in (4, 8, 12) if v[j] < 0]
            if neg:
                raise ValueError(f"column {neg[0] + 1} (covariance): a variance of "
                                 f"{v[neg[0]]:g}; expected 0 or more")
        except ValueError as exc:
            bad(strict, str(path), i, text, str(exc), skipped)
            skipped[-1] = (*skipped[-1], str(path))
            continue
        diag = np.array([v[4], v[8], v[12]])
        sig = float(np.sqrt(np.sum(diag**2) if std_dev else np.sum(diag)))
        t = round(v[0], TIME_DECIMALS)
        if t in first and isinstance(out[t], tuple) and out[t][:3] != (v[1], v[2], v[3]):
            out[t] = (f"two different positions at {v[0]:.6f} (J2000 s): {first[t][0]} line "
                      f"{first[t][1]} and line {i}")
            continue
        if t not in first:
            first[t] = (str(path), i)
            out[t] = (v[1], v[2], v[3], sig)
    return out


def _interrogation_time(parts, n):
    """J2000 seconds of a pxp_tt line and the index of its first travel time."""
    if _DATE.match(parts[0]):
        if len(parts) != 2 + n:
            raise ValueError(f"expected a date, a time and {n} travel times, got "
                             f"{len(parts)} fields (one travel time per transponder of the "
                             "config)")
        try:
            t = datetime.strptime(f"{parts[0].upper()} {parts[1]}", "%d-%b-%y %H:%M:%S.%f")
        except ValueError:
            raise ValueError(f"columns 1-2: expected a time like '26-JUN-23 00:00:07.00', got "
                             f"{parts[0] + ' ' + parts[1]!r}") from None
        return (t - J2000).total_seconds(), 2
    if len(parts) != 1 + n:
        raise ValueError(f"expected a J2000 time and {n} travel times, got {len(parts)} fields")
    return number(parts[0], "column 1 (J2000 time)"), 1


def _read_travel_times(paths, tp, cfg, positions, strict, skipped, pos_names):
    shift = (cfg.number("solver", "transducer_delay_time", default=0.0, lo=0.0, hi=10.0)
             + cfg.number("solver", "travel_times_correction", default=0.0, lo=-10.0, hi=10.0))
    limit = cfg.number("solver", "gps_sigma_limit", default=0.05, lo=0.0, lo_open=True)
    ids, delays, n = list(tp.index), tp["internal_delay"].to_numpy(), len(tp)
    rows, first = [], {}
    for path, i, text, parts in _data_lines(paths):
        try:
            t0, j0 = _interrogation_time(parts, n)
            t_key = round(t0, TIME_DECIMALS)
            if t_key in first:
                raise ValueError(f"a second interrogation at the time of {first[t_key]} (a "
                                 "transponder replies once per interrogation)")
            tts = [number(parts[j0 + k], f"column {j0 + k + 1} (transponder {ids[k]}, "
                          "microseconds)", lo=0.0, hi=6e7) for k in range(n)]
        except ValueError as exc:
            bad(strict, str(path), i, text, str(exc), skipped)
            skipped[-1] = (*skipped[-1], str(path))
            continue
        first[t_key] = f"{Path(path).name} line {i}"
        replies = [(k, tt * 1e-6) for k, tt in enumerate(tts) if tt > 0]
        if not replies:
            skipped.append((i, text, "no reply from any transponder", str(path)))
            continue
        st = t0 + shift
        for k, tt in replies:
            reason = None
            rt = st + tt
            tx, rx = (positions.get(round(t, TIME_DECIMALS)) for t in (st, rt))
            if tt - delays[k] <= 0:
                reason = (f"travel time {tt:.6f} s is not longer than the internal delay "
                          f"{delays[k]:g} s")
            elif isinstance(tx, str) or isinstance(rx, str):
                reason = tx if isinstance(tx, str) else rx
            elif tx is None or rx is None:
                reason = (f"no position at the {'transmit' if tx is None else 'receive'} "
                          f"time {st if tx is None else rt:.6f} (J2000 s) in {pos_names}")
            elif max(tx[3], rx[3]) > limit:
                reason = (f"position sigma {max(tx[3], rx[3]):.3f} m above "
                          f"gps_sigma_limit {limit:g} m")
            if reason is not None:
                skipped.append((i, text, f"transponder {ids[k]}: {reason}", str(path)))
                continue
            rows.append({"line": i, "file": str(path), "transponder": ids[k],
                         "twtt": tt - delays[k], "t_tx": st, "t_rx": rt,
                         "x_tx": tx[0], "y_tx": tx[1], "z_tx": tx[2],
                         "x_rx": rx[0], "y_rx": rx[1], "z_rx": rx[2]})
    return rows


def read_gnatss(config, *, strict=False) -> RawSurvey:
    """Read a GNATSS survey: the config and the travel times, positions and profile it names.

    The files and the columns read: ``docs/gnssa.md``.

    Parameters
    ----------
    config : str or pathlib.Path
        GNATSS's ``config.yaml``.
    strict : bool, default False
        Raise on a line that does not parse instead of skipping it with the reason.

    Returns
    -------
    RawSurvey
        ``format="gnatss"``; one ping a reply (``twtt`` the logged time minus the internal
        delay), the transducer ``e/n/u`` at ``_tx`` and ``_rx``; the array centre as origin.

    Raises
    ------
    FileNotFoundError, InputError
        An InputError also when no reply finds its positions (check ``transducer_delay_time``).
    """
    cfg = _Config(config)
    tp = _transponders(cfg)
    geoid = cfg.number("solver", "geoid_undulation", lo=-200.0, hi=200.0)
    centre = cfg.get("solver", "array_center", default=None)
    if centre:
        lat0 = cfg.number("solver", "array_center", "lat", lo=-90.0, hi=90.0)
        lon0 = cfg.number("solver", "array_center", "lon", lo=-360.0, hi=360.0)
        h0 = cfg.number("solver", "array_center", "alt", default=0.0, lo=-1e4, hi=1e4)
    else:
        lat0, lon0, h0 = float(tp["lat"].mean()), float(tp["lon"].mean()), 0.0
    std_dev = cfg.flag("solver", "std_dev", default=True)
    skipped = []
    tt_paths, pos_paths, ssp_paths = (_paths(cfg, k) for k in
                                      ("travel_times", "gps_solution", "sound_speed"))
    if len(ssp_paths) > 1:  # merged, the first file's speed won at every shared depth
        raise InputError(f"{cfg.where('solver', 'input_files', 'sound_speed', 'path')}: "
                         f"matches {len(ssp_paths)} files ({', '.join(f.name for f in ssp_paths)})"
                         "; expected one sound-speed profile for the campaign (GNATSS reads "
                         "one): give the cast to use")
    positions = _read_positions(pos_paths, std_dev, strict, skipped)
    if not any(isinstance(v, tuple) for v in positions.values()):
        names = [str(f) for f in pos_paths]
        bad_lines = [r for r in skipped if r[3] in names]
        twice = [v for v in positions.values() if isinstance(v, str)]
        why = ([f"{len(bad_lines)} lines skipped: {skip_reasons(bad_lines)}"] if bad_lines
               else []) + ([f"{len(twice)} times given twice with different positions, the "
                            f"first {twice[0]}"] if twice else [])
        raise InputError(f"{', '.join(names)}: no position can be used ("
                         + ("; ".join(why) or "no data line")
                         + "); expected lines of a J2000 time, X Y Z (m, ECEF) and 9 "
                         "covariances (GNATSS's POS_FREED_TRANS_TWTT)")
    rows = _read_travel_times(tt_paths, tp, cfg, positions, strict, skipped,
                              ", ".join(f.name for f in pos_paths))
    if not rows:
        timing = all("no position at the" in r[2] for r in skipped)
        raise InputError(f"{', '.join(map(str, tt_paths))}: no reply can be used ("
                         f"{len(skipped)} lines or replies skipped: {skip_reasons(skipped)})"
                         + (f"; do the files' timings align? check transducer_delay_time and "
                            f"travel_times_correction in {cfg.path}" if timing and skipped
                            else ""))
    p = pd.DataFrame(rows)
    for end in ("tx", "rx"):
        e, n, u = ecef_to_enu(p.pop(f"x_{end}"), p.pop(f"y_{end}"), p.pop(f"z_{end}"),
                              lat0, lon0, h0)
        p[f"e_{end}"], p[f"n_{end}"], p[f"u_{end}"] = e, n, u
    p.insert(3, "time", p["t_tx"] - p["t_tx"].min())
    e, n, u = geodetic_to_enu(tp["lat"], tp["lon"], tp["height"] + geoid, lat0, lon0, h0)
    transponders = pd.DataFrame({"east": e, "north": n, "up": u,
                                 "internal_delay": tp["internal_delay"]}, index=tp.index)
    header = {"site": str(cfg.get("site_id", default="")), "lat": lat0, "lon": lon0,
              "height": h0, "transponders": transponders, "atd_offset": None,
              "ss_prof": profile_reaches(_read_profile(ssp_paths), -tp["height"],
                                         ", ".join(map(str, ssp_paths))),
              "ss_prof_source": ", ".join(f.name for f in ssp_paths),
              "surface_depth": h0 - geoid,
              "geoid_undulation": geoid,
              "files": {"config": str(config), "travel_times": [str(f) for f in tt_paths],
                        "gps_solution": [str(f) for f in pos_paths],
                        "sound_speed": [str(f) for f in ssp_paths]}}
    skipped_df = pd.DataFrame(skipped, columns=["line", "text", "reason", "file"])
    return RawSurvey("gnatss", str(config), p, header, skipped_df)


def _transducer_ecef(pings, header, end):
    e, n, u = (pings[f"{c}_{end}"].to_numpy(float) for c in "enu")
    if header.get("atd_offset") is not None and f"head_{end}" in pings.columns:
        de, dn, du = atd_offset_enu(*header["atd_offset"], pings[f"head_{end}"],
                                    pings[f"pitch_{end}"], pings[f"roll_{end}"])
        e, n, u = e + de, n + dn, u + du
    return enu_to_ecef(e, n, u, header["lat"], header["lon"], header["height"])


def write_gnatss(out_dir, pings, header, *, site="SIM", internal_delays=None,
                 transducer_delay=0.0, start=datetime(2024, 1, 1), position_sd=0.02) -> Path:
    """Write a survey as GNATSS's config and its travel-time, position and profile files.

    Parameters
    ----------
    out_dir : str or pathlib.Path
    pings : pandas.DataFrame
        As :func:`~bayes_mpem.io.garpos.read_garpos` returns.
    header : dict
        ``lat``, ``lon``, ``height``, ``transponders``, ``ss_prof``, and optionally
        ``atd_offset`` and ``surface_depth``.
    site : str
    internal_delays : sequence of float, optional
        Per transponder (s); default 0.2, 0.32, 0.44, ... .
    transducer_delay : float, default 0
    start : datetime.datetime
        The moment ``t_tx = 0``.
    position_sd : float, default 0.02
        Standard deviation (m) written into the position covariances.

    Returns
    -------
    pathlib.Path
        The config file.
    """
    import yaml

    out = output_folder(out_dir)
    tp = header["transponders"]
    geoid_undulation = float(header["height"]) - float(header.get("surface_depth", 0.0))
    ids = [str(i) for i in tp.index]
    delays = (np.asarray(internal_delays, float) if internal_delays is not None
              else 0.2 + 0.12 * np.arange(len(ids)))
    t0 = (start - J2000).total_seconds()
    logged = pings["t_tx"].to_numpy(float) - transducer_delay
    if np.any(np.abs(logged * 100 - np.rint(logged * 100)) > 1e-6):
        raise ValueError("t_tx - transducer_delay: the travel-time file's dates keep "
                         "hundredths of a second; put the interrogations on that grid")
    k_of = {t: k for k, t in enumerate(ids)}
    tt_us = np.rint((pings["twtt"].to_numpy(float)
                     + delays[[k_of[str(t)] for t in pings["transponder"]]]) * 1e6)
    st = t0 + pings["t_tx"].to_numpy(float)
    lines, pos = [], {}
    xyz = {end: np.column_stack(_transducer_ecef(pings, header, end)) for end in ("tx", "rx")}
    for t, idx in pd.Series(np.arange(len(pings))).groupby(st).groups.items():
        row = np.zeros(len(ids), dtype=np.int64)
        idx = np.asarray(idx)
        row[[k_of[str(pings["transponder"].iloc[i])] for i in idx]] = tt_us[idx].astype(np.int64)
        when = start + timedelta(seconds=float(t - t0 - transducer_delay))
        stamp = when.strftime("%d-%b-%y %H:%M:%S.") + f"{when.microsecond // 10000:02d}"
        lines.append(f"{stamp.upper()} " + " ".join(f"{v:9d}" for v in row))
        pos.setdefault(round(t, TIME_DECIMALS), xyz["tx"][idx[0]])
        for i in idx:
            pos.setdefault(round(t + tt_us[i] * 1e-6, TIME_DECIMALS), xyz["rx"][i])
    # each file through write_file: staged with the command's run (all or nothing)
    write_file(out / "pxp_tt", lambda tmp: tmp.write_text("\n".join(lines) + "\n"))
    var = position_sd**2
    cov = f"{var:.10E} 0.0 0.0 0.0 {var:.10E} 0.0 0.0 0.0 {var:.10E}"
    write_file(out / "POS_FREED_TRANS_TWTT", lambda tmp: tmp.write_text("".join(
        f"{t:.7f} {x:.4f} {y:.4f} {z:.4f} {cov}\n" for t, (x, y, z) in sorted(pos.items()))))
    prof = header["ss_prof"]
    write_file(out / "ctd_sv", lambda tmp: tmp.write_text("".join(
        f"{-z:.3f} {c:.4f}\n" for z, c in zip(prof["depth"], prof["sound_speed"], strict=True))))
    lat, lon, h = zip(*(enu_to_geodetic(r["east"], r["north"], r["up"], header["lat"],
                                        header["lon"], header["height"])
                        for _, r in tp.iterrows()), strict=True)
    config = {"site_id": site, "solver": {
        "transponders": [{"pxp_id": i, "lat": float(a), "lon": float(o),
                          "height": float(z - geoid_undulation), "internal_delay": float(d)}
                         for i, a, o, z, d in zip(ids, lat, lon, h, delays, strict=True)],
        "reference_ellipsoid": {"semi_major_axis": 6378137.0,
                                "reverse_flattening": 298.257223563},
        "gps_sigma_limit": 0.05, "std_dev": False,
        "geoid_undulation": float(geoid_undulation),
        "array_center": {"lat": float(header["lat"]), "lon": float(header["lon"]),
                         "alt": float(header["height"])},
        "transducer_delay_time": float(transducer_delay), "travel_times_correction": 0.0,
        "input_files": {"sound_speed": {"path": "ctd_sv"}, "travel_times": {"path": "pxp_tt"},
                        "gps_solution": {"path": "POS_FREED_TRANS_TWTT"}}},
        "output": {"path": "./output/"}}
    path = out / "config.yaml"
    write_file(path, lambda tmp: tmp.write_text(yaml.safe_dump(config, sort_keys=False)))
    return path
