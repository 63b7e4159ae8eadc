"""Reader of SeaGap GNSS-acoustic surveys (``obsdata.inp`` and companion files).

Returns a :class:`~bayes_mpem.io.raw.RawSurvey` with the transducer positions
from the antenna track and the lever arm, the transponders' prior positions and
the sound-speed profile (see :mod:`bayes_mpem.io.raw` for the format).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..exceptions import InputError
from .raw import RawSurvey, bad, read_lines

# --------------------------------------------------------------------------- SeaGap

_SEAGAP_COLS = ("transponder", "twtt", "t_tx", "e_tx", "n_tx", "u_tx", "head_tx", "pitch_tx",
                "roll_tx", "t_rx", "e_rx", "n_rx", "u_rx", "head_rx", "pitch_rx", "roll_rx",
                "shot", "flag")


def _numeric_table(path, ncols, what, strict, skipped):
    rows = []
    for i, text in enumerate(read_lines(path), start=1):
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
            bad(strict, str(path), i, text, str(exc), skipped)
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
