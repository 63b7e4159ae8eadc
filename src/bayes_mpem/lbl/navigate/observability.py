"""Where the ranges did not correct the navigation.

The flags: ``docs/navigate.md`` (*Where it cannot correct*).

Examples
--------
>>> import numpy as np
>>> major_sd(np.array([[[4.0, 0.0], [0.0, 1.0]]])).tolist()
[2.0]
"""

from __future__ import annotations

import numpy as np

#: A nuisance is "not identified" when its posterior sd exceeds this fraction of the prior's.
PRIOR_FRACTION = 0.5


def major_sd(cov) -> np.ndarray:
    """Return the standard deviation along the major axis of each 2x2 covariance.

    Parameters
    ----------
    cov : numpy.ndarray
        ``(K, 2, 2)``.

    Returns
    -------
    numpy.ndarray
        ``(K,)`` square root of the largest eigenvalue.
    """
    a, b, c = cov[:, 0, 0], cov[:, 0, 1], cov[:, 1, 1]
    lam = 0.5 * (a + c) + np.sqrt(0.25 * (a - c) ** 2 + b * b)
    return np.sqrt(np.maximum(lam, 0.0))


def _stretches(mask):
    """``(start, stop)`` index pairs (stop exclusive) of the runs of True in ``mask``."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1), strict=True))


def _reason(dive, resp, i0, i1) -> str:
    inside = (dive.epoch >= i0) & (dive.epoch < i1)
    useful = inside & (resp[:, 0] + resp[:, 1] >= 0.5)
    seen = sorted({dive.beacon_ids[j] for j in np.unique(dive.beacon[useful])})
    if not seen:
        return "no direct-path or multipath reply"
    if len(seen) == 1:
        return f"replies from beacon {seen[0]} only"
    return (f"replies from beacons {', '.join(seen)}, whose geometry leaves a direction "
            "unresolved")


def assess(dive, cov, resp, nuisances: dict, *, max_sd: float) -> list:
    """Flag where the ranges did not correct the navigation.

    Parameters
    ----------
    cov : numpy.ndarray
        ``(K, 2, 2)`` covariance of every epoch.
    resp : numpy.ndarray
        ``(n, 3)`` class probabilities of the replies.
    nuisances : dict
        ``{name: (posterior sd, prior sd, unit)}`` of the dead-reckoning nuisances.
    max_sd : float
        An epoch whose major-axis position sd exceeds this (m) is not corrected.

    Returns
    -------
    list of dict
        ``kind`` (``"track"`` or the nuisance's name), ``reason`` and, for the
        track, ``start``, ``end`` (s), ``n_epochs`` and ``max_sd`` (m).
    """
    sd = major_sd(cov)
    flags = []
    for i0, i1 in _stretches(sd > max_sd):
        flags.append({"kind": "track", "start": float(dive.times[i0]),
                      "end": float(dive.times[i1 - 1]), "n_epochs": int(i1 - i0),
                      "max_sd": float(sd[i0:i1].max()), "reason": _reason(dive, resp, i0, i1)})
    for name, (post, prior, unit) in nuisances.items():
        if post > PRIOR_FRACTION * prior:
            flags.append({"kind": name, "reason": (
                f"the ranges do not identify the {name.replace('_', ' ')}: posterior sd "
                f"{post:.3g} {unit} against the prior's {prior:.3g} {unit}")})
    return flags


def describe(flags: list) -> str:
    """One sentence per flag (at most three track stretches listed), for a warning.

    Parameters
    ----------
    flags : list of dict
        From :func:`assess`.

    Examples
    --------
    >>> print(describe([{"kind": "track", "start": 0.0, "end": 60.0, "n_epochs": 6,
    ...                  "max_sd": 250.0, "reason": "replies from beacon 1 only"}]))
    ... # doctest: +NORMALIZE_WHITESPACE
    navigation not corrected for t = 0-60 s (6 epochs, position sd up to 250 m): replies from
    beacon 1 only
    """
    track = [f for f in flags if f["kind"] == "track"]
    parts = [f"navigation not corrected for t = {f['start']:.0f}-{f['end']:.0f} s "
             f"({f['n_epochs']} epochs, position sd up to {f['max_sd']:.3g} m): {f['reason']}"
             for f in track[:3]]
    if len(track) > 3:
        parts.append(f"and {len(track) - 3} more stretches")
    parts += [f["reason"] for f in flags if f["kind"] != "track"]
    return "; ".join(parts)
