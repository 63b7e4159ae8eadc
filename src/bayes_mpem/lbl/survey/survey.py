"""The per-beacon survey loop and the tables every survey result shares."""

from __future__ import annotations

import warnings

import numpy as np

from ..._validate import check_int
from ...exceptions import SkippedBeaconWarning
from ...io.survey import Survey
from ...mixture.densities import CLASSES

#: The fewest replies a beacon can be fitted with (both EMs need 3 ranges).
MIN_PINGS = 3


def check_min_pings(min_pings) -> int:
    """Check ``min_pings`` before any work: an integer >= :data:`MIN_PINGS`.

    Raises
    ------
    ValueError
        Naming ``min_pings``.
    """
    return check_int("min_pings", min_pings, minimum=MIN_PINGS)


class Failure(str):
    """The reason a beacon's fit failed (not finite): its rows are labelled ``failed``."""


def non_finite(document, where: str = "") -> list:
    """Dotted names of the non-finite numbers of a (nested) result document.

    Parameters
    ----------
    where : str, optional
        Prefix of the names.
    """
    if isinstance(document, dict):
        return [n for k, v in document.items()
                for n in non_finite(v, f"{where}.{k}" if where else str(k))]
    if isinstance(document, (list, tuple)):
        return [n for i, v in enumerate(document) for n in non_finite(v, f"{where}[{i}]")]
    if isinstance(document, (float, np.floating)) and not np.isfinite(document):
        return [where]
    return []


def _culprit_rows(survey: Survey, data, *, factor: float = 100.0) -> list:
    """Rows of a beacon whose values stand far out from the others (what breaks a fit)."""
    dist = np.sqrt((data.x - data.position[0]) ** 2 + (data.y - data.position[1]) ** 2
                   + (data.depth - data.position[2]) ** 2)
    out = np.zeros(data.n, bool)
    for v in (data.range - dist, data.x, data.y, data.depth):
        med = np.median(v)
        mad = max(1.4826 * float(np.median(np.abs(v - med))), 1.0)
        out |= ~np.isfinite(v) | (np.abs(v - med) > factor * mad)
    return [survey.row_name(int(r)) for r in data.rows[out][:10]]


def beacons_table(survey: Survey) -> dict:
    """Beacon positions as ``{id: {"x", "y", "depth"}}`` (written into summaries)."""
    return {b: {k: float(v) for k, v in row.items()}
            for b, row in survey.beacons[["x", "y", "depth"]].iterrows()}


def classified_table(survey: Survey, fitted: dict, skipped: dict, extra: dict | None = None):
    """Every input row with its class probabilities, ``label`` and ``reason``.

    Parameters
    ----------
    fitted : dict
        ``{beacon: (rows, probs)}``: rows of the input table and ``(n, 3)`` probabilities.
    skipped : dict
        ``{beacon: reason}`` of beacons left unfitted.
    extra : dict, optional
        ``{column: {beacon: (n,) values}}``: more per-range columns (NaN elsewhere).

    Returns
    -------
    pandas.DataFrame
        The input table plus ``p_dp``, ``p_mp``, ``p_ol``, ``extra``, ``label``, ``reason``.
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
        label[m] = "failed" if isinstance(why, Failure) else "skipped"
        reason[m] = str(why)
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


def fittable_beacons(survey: Survey, min_pings: int, *, stacklevel: int = 3):
    """Split the beacons into those with enough replies and those left unfitted (warned).

    Returns
    -------
    fittable : list of BeaconData
    skipped : dict
        ``{beacon: reason}``.
    """
    fittable, skipped = [], {}
    for bid in survey.beacon_ids:
        data = survey.for_beacon(bid)
        if data.n < min_pings:
            why = (f"beacon {bid} has {data.n} replies ({data.n_no_reply} pings without reply), "
                   f"fewer than min_pings={min_pings}")
            warnings.warn(why + "; left unfitted", SkippedBeaconWarning, stacklevel=stacklevel)
            skipped[bid] = why
        else:
            fittable.append(data)
    return fittable, skipped


def option_subset(kwargs: dict) -> dict:
    """Pick the options of ``kwargs`` that :func:`~.posterior.check_sample_options` checks."""
    keys = ("n_ensembles", "concentration", "sigma_dp", "path", "tau_factor", "min_ess",
            "max_steps", "n_draws", "sampler")
    return {k: kwargs[k] for k in keys if k in kwargs}


def _skip_beacon(skipped: dict, beacon: str, why: str, *, stacklevel: int = 3) -> None:
    """Record ``beacon`` as left unsampled with ``why``, and warn."""
    warnings.warn(why + "; left unsampled", SkippedBeaconWarning, stacklevel=stacklevel)
    skipped[beacon] = why


def over_beacons(survey: Survey, min_pings: int, analyse, *, skip_on=(), check=None):
    """Run ``analyse`` on every beacon with enough replies: the one survey loop.

    Parameters
    ----------
    analyse : callable
        ``analyse(BeaconData) -> result`` for one beacon, in table order.
    skip_on : tuple of exception classes, default ()
        Exceptions that leave one beacon out (the message its reason); any other propagates.
    check : callable, optional
        ``check(result) -> list of str``: the result's non-finite values. A beacon with any is
        left out with a :class:`Failure` naming them and the rows that stand out.

    Returns
    -------
    results, skipped : dict
        ``{beacon: result}`` and ``{beacon: reason}`` (each warned as SkippedBeaconWarning).
    """
    # stacklevel 4: past the helper, this function and fit/sample/compare, to their caller
    fittable, skipped = fittable_beacons(survey, min_pings, stacklevel=4)
    results = {}
    for data in fittable:
        try:
            result = analyse(data)
        except skip_on as exc:
            _skip_beacon(skipped, data.beacon, str(exc), stacklevel=4)
            continue
        bad = check(result) if check is not None else []
        if bad:
            rows = _culprit_rows(survey, data)
            why = (f"beacon {data.beacon}: the fit failed: {', '.join(bad[:5])} not finite; "
                   + (f"rows that stand out: {', '.join(rows)}" if rows else
                      "no single row stands out"))
            warnings.warn(why, SkippedBeaconWarning, stacklevel=4)
            skipped[data.beacon] = Failure(why)
        else:
            results[data.beacon] = result
    return results, skipped
