"""Model checks of a navigation: ``fit``'s checks of the direct-path residuals at the track.

What they find and why: ``docs/model-checks.md``.
"""

from __future__ import annotations

import numpy as np

from ..survey.model_checks import covariates, direct_path_checks, trend_checks
from .objective import predictions


def model_checks(nav) -> dict:
    """Per beacon, the model checks of the direct-path residuals at the navigated track.

    Parameters
    ----------
    nav : Navigation
        The result of :func:`~bayes_mpem.lbl.navigate.navigate`.

    Returns
    -------
    dict
        ``{"flags": [messages], "beacons": {id: [checks]}}``, each check as in
        :mod:`bayes_mpem.lbl.survey.model_checks`.

    Examples
    --------
    >>> from bayes_mpem.lbl.navigate import navigate
    >>> from bayes_mpem.lbl.navigate.simulate import simulate_ship
    >>> sim = simulate_ship(rng=0, n_cycles=200)
    >>> checks = model_checks(navigate(sim.survey, rng=0))
    >>> sorted(checks) == ["beacons", "flags"]
    True
    """
    d = nav.dive
    pred = predictions(d, nav.state)
    r = d.z - pred.direct
    p = nav.track[d.epoch]
    xyz = d.beacon_xyz[d.beacon]
    cov = covariates(p[:, 0] - xyz[:, 0], p[:, 1] - xyz[:, 1], xyz[:, 2] - d.zdepth,
                     d.times[d.epoch], d.zdepth)
    sigma = float(nav.state.sigma_dp)
    out, flags = {}, []
    for j, bid in enumerate(d.beacon_ids):
        m = d.beacon == j
        if not m.any():
            continue
        w = nav.resp[m, 0]
        checks = direct_path_checks(r[m], w, sigma)
        checks += trend_checks({"dp": r[m]}, {"dp": sigma}, {"dp": w},
                               {k: v[m] for k, v in cov.items()})
        out[bid] = checks
        flags += [f"beacon {bid}: {c['message']}" for c in checks if c["flagged"]]
    return {"flags": flags, "beacons": out}


def residual_summary(nav) -> dict:
    """Return the direct-path residuals' spread and how much of it is slow (in time).

    Returns
    -------
    dict
        ``rms`` of the confident (p > 0.9) direct-path residuals (m), ``slow_rms``: the
        rms of their running mean over 10 min (m), and ``lag1``: the correlation of
        consecutive residuals in time.

    Examples
    --------
    >>> from bayes_mpem.lbl.navigate import navigate
    >>> from bayes_mpem.lbl.navigate.simulate import simulate_ship
    >>> s = residual_summary(navigate(simulate_ship(rng=0, n_cycles=200).survey, rng=0))
    >>> sorted(s)
    ['lag1', 'rms', 'slow_rms']
    """
    d = nav.dive
    r = d.z - predictions(d, nav.state).direct
    keep = nav.resp[:, 0] > 0.9
    t, r = d.times[d.epoch][keep], r[keep]
    order = np.argsort(t, kind="stable")
    t, r = t[order], r[order]
    if r.size < 3:
        return {"rms": None, "slow_rms": None, "lag1": None}
    lo, hi = np.searchsorted(t, t - 300.0), np.searchsorted(t, t + 300.0, side="right")
    c = np.concatenate([[0.0], np.cumsum(r)])
    slow = (c[hi] - c[lo]) / (hi - lo)
    a, b = r[:-1] - r.mean(), r[1:] - r.mean()
    return {"rms": float(np.sqrt(np.mean(r * r))), "slow_rms": float(np.sqrt(np.mean(slow ** 2))),
            "lag1": float(np.sum(a * b) / np.sqrt(np.sum(a * a) * np.sum(b * b)))}
