"""Reader of SeaGap GNSS-acoustic surveys (``obsdata.inp`` and companion files).

Details: ``docs/gnssa.md``.
"""

from __future__ import annotations

import math
import re
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from ..exceptions import InputError, LocateWarning
from .boundary import COMMENT, classify, limit_problem, read_text_lines
from .garpos import profile_frame, profile_reaches
from .raw import RawSurvey, bad

# --------------------------------------------------------------------------- SeaGap

_SEAGAP_COLS = ("transponder", "twtt", "t_tx", "e_tx", "n_tx", "u_tx", "head_tx", "pitch_tx",
                "roll_tx", "t_rx", "e_rx", "n_rx", "u_rx", "head_rx", "pitch_rx", "roll_rx",
                "shot", "flag")


#: The physical limit of each obsdata.inp column (the ids, shot and flag are integers).
_SEAGAP_KINDS = {"twtt": "twtt", "t_tx": "time", "t_rx": "time",
                 **{f"{a}_{e}": k for e in ("tx", "rx")
                    for a, k in (("e", "east"), ("n", "north"), ("u", "up"), ("head", "heading"),
                                 ("pitch", "angle"), ("roll", "angle"))}}
_INTEGER = re.compile(r"[+-]?\d+")


def _values(parts, names, kinds):
    """Parse one line's fields by name; return the values, or the reason they are unusable."""
    vals = {}
    for name, text in zip(names, parts, strict=True):
        if name in ("transponder", "shot", "flag"):
            if _INTEGER.fullmatch(text) is None:
                return f"{name} {text!r} is not an integer"
            vals[name] = int(text)
            continue
        try:
            v = float(text)
        except ValueError:
            return f"{name} {text!r} is not a number"
        why = limit_problem(kinds[name], v) if name in kinds else (
            None if math.isfinite(v) else f"{name} is {v!r}, not a finite number")
        if why:
            return f"{name}: {why}"
        vals[name] = v
    return vals


def _numeric_table(path, names, what, kinds, strict, skipped, check=None):
    """Rows of a whitespace-separated numeric file; a bad line is skipped (or raised)."""
    rows = []
    lines = read_text_lines(path)
    for i, kind, _ in classify(lines, (COMMENT,)):
        if kind in ("blank", "comment"):
            continue
        text = lines[i - 1]
        parts = text.split()
        vals = (f"expected {len(names)} numbers ({what}), got {len(parts)} fields"
                if len(parts) != len(names) else _values(parts, names, kinds))
        if check is not None and not isinstance(vals, str):
            vals = check({"line": i, **vals}) or vals
        if isinstance(vals, str):
            if skipped is None:
                raise InputError(f"{path} line {i}: {vals}")
            bad(strict, str(path), i, text, vals, skipped)
            continue
        rows.append({"line": i, **vals})
    return rows


_COMPANIONS = (
    ("transponders", ("pxp-ini.inp",), ("east", "north", "up", "c4", "c5", "c6"),
     {"east": "east", "north": "north", "up": "up"}),
    ("tr_ant", ("tr-ant.inp",), ("dx", "dy", "dz"), {}),
    ("ss_prof", ("ss_prof.inp", "ss_prof.zv"), ("depth", "sound_speed"),
     {"depth": "depth", "sound_speed": "sound_speed"}),
)


def _companions(here, paths):
    """Read the companion files: given, else the first of their default names beside."""
    header, files = {}, {}
    for key, names, cols, kinds in _COMPANIONS:
        arg = paths[key]
        found = [here / n for n in names if (here / n).exists()]
        path = Path(arg) if arg is not None else (found[0] if found else here / names[0])
        if arg is None and not found:
            continue
        files[key] = str(path)
        name = path.name
        if path.is_dir():
            raise InputError(f"{path}: is a folder; expected SeaGap's {names[0]} file beside "
                             "obsdata.inp")
        vals = _numeric_table(path, cols, name, kinds, strict=True, skipped=None)
        if not vals:
            raise InputError(f"{path}: no data lines (expected {len(cols)} numbers a line)")
        frame = pd.DataFrame(vals)
        if key == "tr_ant" and len(frame) != 1:
            raise InputError(f"{path} line {vals[1]['line']}: a second lever arm; expected one "
                             "line of 3 numbers (dx dy dz)")
        if key == "ss_prof":
            profile_frame(frame["depth"], frame["sound_speed"], str(path), lines=frame["line"],
                          column=1)
        if key == "transponders":
            t = frame[["east", "north", "up"]].reset_index(drop=True)
            t.index = [str(k + 1) for k in range(len(t))]
            header[key] = t
        elif key == "tr_ant":
            lever = frame[["dx", "dy", "dz"]].to_numpy()[0]
            if np.any(np.abs(lever) > 1000.0):
                raise InputError(f"{path}: a lever arm of {lever.tolist()} m; expected the "
                                 "transducer within 1 km of the antenna")
            header[key] = np.asarray(lever, float)
        else:
            header[key] = frame[["depth", "sound_speed"]].reset_index(drop=True)
            header["ss_prof_source"] = path.name
    header["files"] = {"positions": files.get("transponders"), "tr_ant": files.get("tr_ant"),
                       "ss_prof": files.get("ss_prof")}
    return header


def read_seagap(obsdata, *, pxp=None, tr_ant=None, ss_prof=None, strict=False) -> RawSurvey:
    """Read SeaGap GNSS-acoustic data (``obsdata.inp`` and its companion files; ``docs/gnssa.md``).

    A line is a ping only when its 18 fields are exact (integers whole, numbers finite and
    possible, the transponder one of ``pxp-ini.inp``); otherwise it is skipped with its reason.

    Parameters
    ----------
    obsdata : str or pathlib.Path
    pxp, tr_ant, ss_prof : str or pathlib.Path, optional
        ``pxp-ini.inp``, ``tr-ant.inp``, ``ss_prof.inp`` (or SeaGap's ``ss_prof.zv``); default
        beside ``obsdata``. Without ``tr-ant.inp`` the survey is refused (the shots are the
        antenna's); without a profile, a warning (the rays are straight unless one is given).
    strict : bool, default False

    Returns
    -------
    RawSurvey

    Raises
    ------
    FileNotFoundError, InputError
        Companion files must parse completely.
    """
    obsdata = Path(obsdata)
    header = _companions(obsdata.parent, {"transponders": pxp, "tr_ant": tr_ant,
                                          "ss_prof": ss_prof})
    header["files"]["obsdata"] = str(obsdata)
    if "tr_ant" not in header:  # the 18 columns are the antenna's: its offset is needed
        raise InputError(f"{obsdata.parent / 'tr-ant.inp'}: not found beside {obsdata.name}; "
                         "expected SeaGap's lever arm from the GNSS antenna to the transducer "
                         "(one line: dx dy dz, m): without it every shot would be located "
                         "from the antenna (write '0 0 0' where the antenna is the transducer)")
    if "ss_prof" not in header:
        warnings.warn(f"{obsdata}: no sound-speed profile beside it (ss_prof.inp or ss_prof.zv): "
                      "the rays are straight unless a profile is given (--ssp)", LocateWarning,
                      stacklevel=2)
    elif "transponders" in header:
        profile_reaches(header["ss_prof"], -header["transponders"]["up"],
                        header["files"]["ss_prof"])
    skipped = []
    known = list(header["transponders"].index) if "transponders" in header else None

    first = {}

    def check(vals):
        if known is not None and str(vals["transponder"]) not in known:
            return (f"transponder {vals['transponder']} is not in pxp-ini.inp (known: "
                    f"{', '.join(known)})")
        if not 0.0 < vals["t_rx"] - vals["t_tx"] < 120.0:
            return (f"t_rx (column 10): expected 0-120 s after t_tx, got "
                    f"{vals['t_rx'] - vals['t_tx']:g} s")
        key = (vals["transponder"], vals["t_tx"])
        if key in first:
            return (f"a second shot of transponder {key[0]} transmitted at {key[1]:.6f} (the "
                    f"first is line {first[key]}; a transponder replies once per transmission)")
        first[key] = vals["line"]
        return None

    rows = _numeric_table(obsdata, _SEAGAP_COLS, "obsdata.inp columns", _SEAGAP_KINDS, strict,
                          skipped, check)
    if not rows:
        raise InputError(f"{obsdata}: no data lines found (expected 18 columns; "
                         f"{len(skipped)} lines skipped)")
    pings = pd.DataFrame(rows, columns=["line", *_SEAGAP_COLS])
    pings["transponder"] = pings["transponder"].astype(str)
    pings.insert(2, "time", pings["t_tx"] - pings["t_tx"].iloc[0])
    skipped_df = pd.DataFrame(skipped, columns=["line", "text", "reason"])
    return RawSurvey("seagap", str(obsdata), pings, header, skipped_df)
