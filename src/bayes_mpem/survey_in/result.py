"""What locating the transponders of a survey returns, and the files it writes."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..io.results import write_csv, write_json, writing

#: Columns of ``classified.csv`` after the first seven, per ping: the ship's
#: transducer (``east``, ``north``, m in the survey's frame) and the moment
#: (``time``, s), the residual (observed minus predicted two-way travel time of a
#: true reply, ms) and the azimuth of the ship seen from the transponder (degrees
#: clockwise from north).
PING_COLUMNS = ("time", "east", "north", "residual_ms", "azimuth_deg")


def classified_table(pings: pd.DataFrame, p_true, skipped: pd.DataFrame, *, reasons=None,
                     extra=()) -> pd.DataFrame:
    """Build ``classified.csv``: one row per ping and per skipped line, in file order.

    Parameters
    ----------
    pings : pandas.DataFrame
        ``line``, ``transponder``, ``twtt`` and the :data:`PING_COLUMNS` (and
        ``file`` when a survey spans several files).
    p_true : array_like
        Probability of a true reply per ping; NaN for a ping left out (its
        reason in ``reasons``).
    skipped : pandas.DataFrame
        ``line``, ``reason`` (and ``file``) of the lines that are not pings.
    reasons : array_like of str, optional
        Per ping, why it was left out ("" when it was not).
    extra : sequence of str
        Further columns of ``pings`` to keep (e.g. ``file_flag``).

    Returns
    -------
    pandas.DataFrame
        ``line``, ``transponder``, ``twtt``, ``p_true``, ``p_spurious``, ``label``
        (``true``, ``spurious`` or ``skipped``), ``reason``, then
        :data:`PING_COLUMNS` and ``extra`` (``file`` second when present).

    Examples
    --------
    >>> import pandas as pd
    >>> pings = pd.DataFrame({"line": [2, 3], "transponder": "A", "twtt": [1.0, 9.0],
    ...                       "time": [0.0, 5.0], "east": 0.0, "north": 0.0,
    ...                       "residual_ms": [0.1, 8000.0], "azimuth_deg": 0.0})
    >>> skipped = pd.DataFrame({"line": [1], "reason": ["no reply"]})
    >>> classified_table(pings, [0.99, 0.0], skipped)["label"].tolist()
    ['skipped', 'true', 'spurious']
    """
    p = np.asarray(p_true, float)
    left = np.isnan(p)
    lab = np.where(left, "skipped", np.where(p >= 0.5, "true", "spurious")).astype(object)
    why = np.full(len(pings), "", dtype=object) if reasons is None else np.asarray(reasons,
                                                                                  object)
    cls = pd.DataFrame({"line": pings["line"].to_numpy(),
                        "transponder": pings["transponder"].astype(str).to_numpy(),
                        "twtt": pings["twtt"].to_numpy(float), "p_true": p,
                        "p_spurious": 1.0 - p, "label": lab, "reason": why})
    for c in (*PING_COLUMNS, *extra, *(["file"] if "file" in pings.columns else [])):
        cls[c] = pings[c].to_numpy()
    if len(skipped):
        sk = pd.DataFrame({"line": skipped["line"].to_numpy(), "transponder": "",
                           "twtt": np.nan, "p_true": np.nan, "p_spurious": np.nan,
                           "label": "skipped", "reason": skipped["reason"].to_numpy()})
        if "file" in skipped.columns:
            sk["file"] = skipped["file"].to_numpy()
        cls = pd.concat([cls, sk], ignore_index=True)
    keys = ["line"]
    if "file" in cls.columns:
        cls.insert(1, "file", cls.pop("file"))
        keys = ["file", "line"]
    return cls.sort_values(keys, kind="stable").reset_index(drop=True)


@dataclass(frozen=True)
class SurveyInResult:
    """Every transponder of a survey, located.

    Attributes
    ----------
    summary : dict
        ``{"transponders": {id: {"lat", "lon", "depth", "sound_speed", ...}}, ...}``
        (the content of ``summary.json``).
    classified : pandas.DataFrame
        One row per ping line and per skipped line of the file, in file order:
        ``line``, ``transponder``, ``twtt``, ``p_true``, ``p_spurious``, ``label``
        (``true``, ``spurious`` or ``skipped``) and ``reason``.
    posteriors : dict
        ``{id: LocationPosterior}`` when the posterior was sampled, else empty.
    fits : dict
        ``{id: LocateResult}``, the EM fit of each transponder (not written).

    Examples
    --------
    >>> import pandas as pd
    >>> res = SurveyInResult({"transponders": {}}, pd.DataFrame({"line": [1]}))
    >>> res.to_dict()
    {'transponders': {}}
    """

    summary: dict
    classified: pd.DataFrame
    posteriors: dict = field(default_factory=dict, repr=False)
    fits: dict = field(default_factory=dict, repr=False)

    def to_dict(self) -> dict:
        """Return the content of ``summary.json``."""
        return self.summary

    def write(self, out_dir) -> dict:
        """Write ``summary.json`` and ``classified.csv`` to ``out_dir``.

        Parameters
        ----------
        out_dir : str or pathlib.Path
            Created if missing.

        Returns
        -------
        dict
            Paths written, keyed ``summary`` and ``classified``.
        """
        with writing(out_dir) as out:
            return {"classified": write_csv(out / "classified.csv", self.classified),
                    "summary": write_json(out / "summary.json", self.summary)}
