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
        Beacon id.
    position : numpy.ndarray
        Shape (3,): beacon x, y, depth (depth positive down).
    range, x, y, depth, time : numpy.ndarray
        Shape (n,): reported one-way ranges (finite, > 0) and vehicle position/time per reply.
    rows : numpy.ndarray
        Shape (n,) int64: 0-based positions of these pings in :attr:`Survey.table`.
    n_no_reply : int
        Pings to this beacon that got no reply.
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
            Beacon x, y, depth (length 3, finite).
        time : array_like, optional
            Ping times; default ``arange(n)``.
        beacon : str or int, optional
            Beacon id (stored as str), default ``"1"``.

        Returns
        -------
        BeaconData
            With ``rows = arange(n)`` and ``n_no_reply = 0``.

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

    Arrays are read-only with one entry per row of :attr:`table` (RangeIndex 0..N-1).

    Attributes
    ----------
    table : pandas.DataFrame
        Pings as given (CSV: text columns as read; DataFrame: a copy), extra columns kept.
    beacon : numpy.ndarray
        (N,) object array of str beacon ids.
    time, range, x, y, depth : numpy.ndarray
        (N,) float64; ``range`` is NaN for a ping with no reply.
    beacons : pandas.DataFrame
        Index = beacon id (str), float columns ``x``, ``y``, ``depth``, in file order.
    pings_source, beacons_source : str
        Labels of the inputs (path or ``"pings DataFrame"``).
    lines : numpy.ndarray or None
        ``(N,)`` file line of each row (CSV; as ``grep -n``), else ``None``.
    comment_lines : int
        ``#`` comment lines skipped in the pings file.

    Examples
    --------
    >>> pings = pd.DataFrame({"time": [0, 1], "beacon": ["A", "A"], "range": [10.0, None],
    ...                       "x": [0, 1], "y": [0, 0], "depth": [5, 5]})
    >>> beacons = pd.DataFrame({"beacon": ["A"], "x": [3], "y": [4], "depth": [20]})
    >>> s = load_survey(pings, beacons)
    >>> len(s), int(s.no_reply.sum()), s.for_beacon("A").n
    (2, 1, 1)
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
        """Where row ``pos`` is in the input: ``"line 17"`` (CSV) or ``"row 15"``.

        Parameters
        ----------
        pos : int
            0-based position in :attr:`table`.

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
        """Select the replies of one beacon.

        Parameters
        ----------
        beacon_id : str or int
            Beacon id (compared as a stripped string; ``1`` and ``"1"`` are the same).

        Returns
        -------
        BeaconData
            Replies only; ``rows`` index :attr:`table`, ``n_no_reply`` counts the rest.

        Raises
        ------
        InputError
            If the id is not in the beacons table (the message lists the known ids).
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
        The pings table; an existing :class:`Survey` is returned unchanged (``beacons`` must
        then be None).
    beacons : str, os.PathLike or pandas.DataFrame
        The beacons table.

    Returns
    -------
    Survey

    Raises
    ------
    FileNotFoundError
        If a path does not exist.
    InputError
        On any invalid input, including pings to beacons absent from the beacons table.

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
