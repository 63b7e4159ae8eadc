"""The answer to one line of a stream: :class:`PingResult`.

Examples
--------
>>> r = PingResult(1.0, "1", 100.0, "dp", 0.9, 0.05, 0.05, 0.0, 0.0, 1.0, 1.0, 0.0, "online")
>>> r.to_dict()["label"], r.to_dict()["reason"]
('dp', None)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ....mixture.densities import CLASSES


@dataclass(frozen=True, slots=True)
class PingResult:
    """The answer to one input line.

    Attributes
    ----------
    time : float
    beacon : str or None
    range : float or None
    label : str or None
        ``dp``, ``mp``, ``ol`` (the likeliest class), ``no_reply``, or None
        for a dead-reckoning line.
    p_dp, p_mp, p_ol : float or None
        Class probabilities from the model as it stood when the range arrived.
    x, y : float
        Filtered position after the line (m).
    sd_x, sd_y, cov_xy : float
        Its uncertainty (m, m, m^2).
    phase : str
        ``"warmup"`` (provisional) or ``"online"``.
    reason : str or None
        Why a line has no class.
    """

    time: float
    beacon: str | None
    range: float | None
    label: str | None
    p_dp: float | None
    p_mp: float | None
    p_ol: float | None
    x: float
    y: float
    sd_x: float
    sd_y: float
    cov_xy: float
    phase: str
    reason: str | None = None

    def to_dict(self) -> dict:
        """Return the answer as a JSON-ready mapping (non-finite numbers as None).

        Returns
        -------
        dict
        """
        out = {}
        for k in self.__slots__:
            v = getattr(self, k)
            out[k] = None if isinstance(v, float) and not math.isfinite(v) else v
        return out


def label_of(p) -> str:
    """Return the likeliest class (the first on a tie, as ``fit``).

    Parameters
    ----------
    p : sequence of 3 float
        Probabilities of dp, mp, ol.

    Examples
    --------
    >>> label_of((0.2, 0.4, 0.4))
    'mp'
    """
    i = 0
    if p[1] > p[i]:
        i = 1
    if p[2] > p[i]:
        i = 2
    return CLASSES[i]
