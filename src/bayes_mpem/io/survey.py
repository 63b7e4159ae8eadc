"""Reading and validating ping and beacon tables: the one place where user input is checked."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from ..exceptions import InputError
from .boundary import limit_problem, out_of_limits
from .tables import as_beacon_id, beacons_frame, pings_table, show


def _frozen(a: Any, dtype: Any = float) -> np.ndarray:
    out = np.array(a, dtype=dtype)  # always a copy
    out.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class BeaconData:
    """Replies of one beacon as read-only float64 arrays (no-reply pings excluded).

    Attributes
    ----------
    beacon : str
    position : numpy.ndarray
        Beacon x, y, depth (positive down).
    range, x, y, depth, time : numpy.ndarray
        Reported one-way ranges and the vehicle's position and time per reply.
    rows : numpy.ndarray
        Positions of these pings in :attr:`Survey.table`.
    n_no_reply : int
    """

    beacon: str
    position: np.ndarray
    range: np.ndarray
    x: np.ndarray
    y: np.ndarray
    depth: np.ndarray
    time: np.ndarray
    rows: np.ndarray
    n_no_reply: int = 0

    @property
    def n(self) -> int:
        """Number of replies."""
        return int(self.range.shape[0])

    def __repr__(self) -> str:
        """Short summary (sizes and source), not the data."""
        return (f"BeaconData(beacon={self.beacon!r}, n={self.n}, n_no_reply={self.n_no_reply}, "
                f"position={self.position.tolist()})")

    @classmethod
    def from_arrays(cls, range: Any, x: Any, y: Any, depth: Any, position: Any, *,
                    time: Any = None, beacon: Any = "1") -> BeaconData:
        """Build from plain arrays (simulations, benchmarks), validating them.

        Parameters
        ----------
        range, x, y, depth : array_like
            1-D, equal length, finite; ``range`` > 0.
        position : array_like
            Beacon x, y, depth.
        time : array_like, optional
            Default ``arange(n)``.
        beacon : str or int, optional
            Default ``"1"``.

        Returns
        -------
        BeaconData

        Raises
        ------
        InputError
            Naming the argument and the first bad index.
        """
        def as_float(arg: str, a: Any) -> np.ndarray:
            try:
                return np.array(a, dtype=float)
            except (TypeError, ValueError) as exc:
                raise InputError(f"{arg}: expected an array of numbers ({exc})") from None

        args = {"range": range, "x": x, "y": y, "depth": depth}
        if time is not None:
            args["time"] = time
        arrays = {k: as_float(k, v) for k, v in args.items()}
        n = arrays["range"].shape[0] if arrays["range"].ndim == 1 else -1
        for k, a in arrays.items():
            if a.ndim != 1:
                raise InputError(f"{k}: expected a 1-D array, got shape {a.shape}")
            if a.shape[0] != n:
                raise InputError(f"{k}: length {a.shape[0]} differs from range length {n}")
            bad = ~np.isfinite(a) | ((a <= 0) if k == "range" else False)
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                what = "a positive number" if k == "range" else "a finite number"
                raise InputError(f"{k}[{i}]: expected {what}, got {a[i]!r}")
            beyond = out_of_limits(k, a)
            if beyond.any():
                i = int(np.flatnonzero(beyond)[0])
                raise InputError(f"{k}[{i}]: {limit_problem(k, a[i])} (a physically "
                                 "possible value is expected)")
        pos = as_float("position", position)
        if pos.shape != (3,) or not np.isfinite(pos).all():
            raise InputError(f"position: expected 3 finite numbers (x, y, depth), got {pos!r}")
        bid = as_beacon_id(beacon)
        if not bid:
            raise InputError(f"beacon: expected a beacon id, got {show(beacon)}")
        t = arrays.get("time", np.arange(n, dtype=float))
        return cls(bid, _frozen(pos), *(_frozen(arrays[k]) for k in ("range", "x", "y", "depth")),
                   _frozen(t), _frozen(np.arange(n), np.int64), 0)


@dataclass(frozen=True, eq=False)
class Survey:
    """All pings (no-replies included) and the beacons, validated; see :func:`load_survey`.

    Attributes
    ----------
    table : pandas.DataFrame
        Pings as given, extra columns kept.
    beacon : numpy.ndarray
        (N,) str beacon ids.
    time, range, x, y, depth : numpy.ndarray
        (N,) float64, read-only; ``range`` is NaN for a ping with no reply.
    beacons : pandas.DataFrame
        Index = beacon id, float columns ``x``, ``y``, ``depth``, in file order.
    pings_source, beacons_source : str
    lines : numpy.ndarray or None
        File line of each row (CSV), else ``None``.
    comment_lines : int
    """

    table: pd.DataFrame
    beacon: np.ndarray
    time: np.ndarray
    range: np.ndarray
    x: np.ndarray
    y: np.ndarray
    depth: np.ndarray
    beacons: pd.DataFrame
    pings_source: str
    beacons_source: str
    lines: np.ndarray | None = None
    comment_lines: int = 0

    def row_name(self, pos: int) -> str:
        """Where row ``pos`` (0-based) is in the input: ``"line 17"`` (CSV) or ``"row 15"``.

        Parameters
        ----------
        pos : int

        Returns
        -------
        str
        """
        if self.lines is not None:
            return f"line {int(self.lines[pos])}"
        return f"row {self.table.index[pos]}"

    @property
    def no_reply(self) -> np.ndarray:
        """Boolean mask (N,) of pings without a reply."""
        return np.isnan(self.range)

    @property
    def beacon_ids(self) -> list[str]:
        """Beacon ids in beacons-table order."""
        return [str(b) for b in self.beacons.index]

    def __len__(self) -> int:
        """Return the number of pings."""
        return int(self.range.shape[0])

    def __repr__(self) -> str:
        """Short summary (sizes and source), not the data."""
        return (f"Survey({len(self)} pings, {int(self.no_reply.sum())} without reply, "
                f"beacons {self.beacon_ids}, from {self.pings_source!r})")

    def for_beacon(self, beacon_id: Any) -> BeaconData:
        """Select the replies of one beacon (``1`` and ``"1"`` are the same id).

        Parameters
        ----------
        beacon_id : str or int

        Returns
        -------
        BeaconData

        Raises
        ------
        InputError
            If the id is not in the beacons table.
        """
        bid = as_beacon_id(beacon_id)
        if bid not in self.beacons.index:
            raise InputError(f"unknown beacon {bid!r}; known beacon ids: "
                             f"{', '.join(map(repr, self.beacon_ids))}")
        mine = self.beacon == bid
        rows = np.flatnonzero(mine & ~self.no_reply)
        return BeaconData(bid, _frozen(self.beacons.loc[bid, ["x", "y", "depth"]].to_numpy()),
                          *(_frozen(getattr(self, k)[rows])
                            for k in ("range", "x", "y", "depth", "time")),
                          _frozen(rows, np.int64), int((mine & self.no_reply).sum()))


def load_survey(pings: Any, beacons: Any = None) -> Survey:
    """Read pings and beacons (paths or DataFrames), cross-check beacon ids, build a Survey.

    Parameters
    ----------
    pings : str, os.PathLike, pandas.DataFrame or Survey
        An existing :class:`Survey` is returned unchanged (``beacons`` must then be None).
    beacons : str, os.PathLike or pandas.DataFrame

    Returns
    -------
    Survey

    Raises
    ------
    FileNotFoundError, InputError
        A path that does not exist; any invalid input (all problems in one message).

    Examples
    --------
    >>> s = load_survey(pd.DataFrame({"time": [0], "beacon": [1], "range": [9.5], "x": [0],
    ...                               "y": [0], "depth": [1]}),
    ...                 pd.DataFrame({"beacon": [1], "x": [0], "y": [0], "depth": [10]}))
    >>> s.beacon_ids
    ['1']
    """
    if isinstance(pings, Survey):
        if beacons is not None:
            raise InputError("load_survey: pass beacons=None when pings is already a Survey")
        return pings
    if beacons is None:
        raise InputError("load_survey: a beacons table (path or DataFrame) is required")
    table, arr, problems = pings_table(pings, None)
    beacon_table, beacons_source = beacons_frame(beacons, None)
    known = [str(b) for b in beacon_table.index]
    known_text = ", ".join(map(repr, known[:20])) + (" ..." if len(known) > 20 else "")
    unknown = ~pd.Series(arr["beacon"]).isin(known + [""]).to_numpy()
    problems.add_mask(unknown, lambda pos: (
        f"{table.where(pos, 'beacon')}: beacon {arr['beacon'][pos]!r} is not in "
        f"{beacons_source}; known beacon ids: {known_text}"))
    problems.raise_if_any()
    lines = None if table.lines is None else _frozen(table.lines, np.int64)
    return Survey(table.frame, _frozen(arr["beacon"], object),
                  *(_frozen(arr[k]) for k in ("time", "range", "x", "y", "depth")),
                  beacon_table, table.source, beacons_source, lines, table.comments)


def check_beacon_data(data: Any, name: str = "data") -> BeaconData:
    """Return ``data`` if it is one beacon's replies; refuse a survey or a table, saying how.

    The one-beacon functions (``fit_mixture_em``, ``fit_paper_em``, ``sample_beacon``,
    ``compare_beacon``) stopped with an ``AttributeError`` on a :class:`Survey` or a
    DataFrame.

    Parameters
    ----------
    data : object
    name : str, default "data"
        The argument's name, for the message.

    Returns
    -------
    BeaconData

    Raises
    ------
    InputError
        What arrived and how to get a :class:`BeaconData` from it.
    """
    if isinstance(data, BeaconData):
        return data
    if isinstance(data, Survey):
        ids = data.beacon_ids
        how = (": pass one beacon's, survey.for_beacon(id) (beacons "
               f"{', '.join(ids[:6])}{', ...' if len(ids) > 6 else ''}), or fit every beacon "
               "with bayes_mpem.fit or bayes_mpem.sample")
    elif isinstance(data, pd.DataFrame):
        how = (": load the tables first, bayes_mpem.load_survey(pings, beacons).for_beacon(id), "
               "or build one with BeaconData.from_arrays")
    else:
        how = ""
    raise InputError(f"{name}: expected a BeaconData (one beacon's replies), got a "
                     f"{type(data).__name__}{how}")
