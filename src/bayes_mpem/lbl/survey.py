"""Survey (moved from ``fitting``, ``sampling``)."""

from __future__ import annotations

import warnings

import numpy as np

from ..exceptions import SkippedBeaconWarning
from ..io.survey import Survey
from ..mixture.densities import CLASSES


def beacons_table(survey: Survey) -> dict:
    """Beacon positions as ``{id: {"x", "y", "depth"}}`` (written into summaries)."""
    return {b: {k: float(v) for k, v in row.items()}
            for b, row in survey.beacons[["x", "y", "depth"]].iterrows()}


def classified_table(survey: Survey, fitted: dict, skipped: dict, extra: dict | None = None):
    """Every input row with its class probabilities, ``label`` and ``reason``.

    Parameters
    ----------
    survey : Survey
    fitted : dict
        ``{beacon: (rows, probs)}``: positions in the input table and ``(n, 3)``
        class probabilities (dp, mp, ol).
    skipped : dict
        ``{beacon: reason}`` of beacons left unfitted.
    extra : dict, optional
        ``{column: {beacon: (n,) values}}``: more per-range columns (NaN elsewhere).

    Returns
    -------
    pandas.DataFrame
        The input table, same rows and order, plus ``p_dp``, ``p_mp``, ``p_ol``,
        any ``extra`` columns, ``label`` (``dp``, ``mp``, ``ol``, ``no_reply``,
        ``skipped``) and ``reason``.
    """
    n = len(survey)
    probs = np.full((n, 3), np.nan)
    label = np.full(n, "", dtype=object)
    reason = np.full(n, "", dtype=object)
    for rows, p in fitted.values():
        probs[rows] = p
        label[rows] = np.asarray(CLASSES)[np.argmax(p, axis=1)]
    for bid, why in skipped.items():
        m = survey.beacon == bid
        label[m] = "skipped"
        reason[m] = why
    nr = survey.no_reply
    label[nr] = "no_reply"
    reason[nr] = "empty range: the ping got no reply"
    out = survey.table.copy()
    for j, c in enumerate(CLASSES):
        out["p_" + c] = probs[:, j]
    for col, per_beacon in (extra or {}).items():
        v = np.full(n, np.nan)
        for bid, vals in per_beacon.items():
            v[fitted[bid][0]] = vals
        out[col] = v
    out["label"] = label
    out["reason"] = reason
    return out


def fittable_beacons(survey: Survey, min_pings: int):
    """Split the beacons into those with enough replies and those left unfitted.

    Parameters
    ----------
    survey : Survey
    min_pings : int

    Returns
    -------
    fittable : list of BeaconData
    skipped : dict
        ``{beacon: reason}``; a :class:`SkippedBeaconWarning` is issued for each.
    """
    fittable, skipped = [], {}
    for bid in survey.beacon_ids:
        data = survey.for_beacon(bid)
        if data.n < min_pings:
            why = (f"beacon {bid} has {data.n} replies ({data.n_no_reply} pings without reply), "
                   f"fewer than min_pings={min_pings}")
            warnings.warn(why + "; left unfitted", SkippedBeaconWarning, stacklevel=3)
            skipped[bid] = why
        else:
            fittable.append(data)
    return fittable, skipped


def option_subset(kwargs):
    keys = ("n_ensembles", "concentration", "sigma_dp", "path", "tau_factor", "min_ess",
            "max_steps", "n_draws")
    return {k: kwargs[k] for k in keys if k in kwargs}


def skip_beacon(skipped: dict, beacon: str, why: str) -> None:
    """Record ``beacon`` as unfitted with ``why`` and warn."""
    from ..exceptions import SkippedBeaconWarning

    warnings.warn(why + "; left unsampled", SkippedBeaconWarning, stacklevel=3)
    skipped[beacon] = why
