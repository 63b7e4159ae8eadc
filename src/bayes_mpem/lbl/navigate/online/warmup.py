"""The start of a stream: provisional answers, then a batch fit that seeds the filter.

The warm-up: ``docs/stream.md``.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pandas as pd

from ....io.survey import BeaconData, load_survey
from ....mixture.densities import CLASSES
from ...em.path_choice import AUTO, choose_path
from .. import navigate
from ..dive import build_dive
from ..driver import MIN_SEPARATION, surface_separation
from ..model import predict_ranges
from .ekf import PositionFilter
from .kernel import class_probabilities, ranges
from .reflector import BeaconModel, DirectPathScale

#: Columns of a kept reply.
BUFFER_COLUMNS = ("time", "beacon", "range", "x", "y", "depth")
_THIRD = math.log(1.0 / 3.0)


def provisional_classes(ping, xyz, window, sd):
    """Class probabilities ``(p_dp, p_mp, p_ol)`` of a warm-up reply at its dead-reckoned position.

    The plane at the sea surface, both scales ``sd``, equal weights, outliers
    uniform over ``window``; no multipath class where the surface bounce would
    lag the direct path by less than :data:`~bayes_mpem.lbl.navigate.driver.MIN_SEPARATION`.

    Parameters
    ----------
    xyz : sequence of 3 float
        The beacon.

    Examples
    --------
    >>> from bayes_mpem.io.lines import Ping
    >>> p = provisional_classes(Ping(0.0, "1", 1414.0, 0.0, 0.0, 1500.0),
    ...                         (0.0, 1000.0, 2500.0), (500.0, 5000.0), 100.0)
    >>> [round(v, 3) for v in p]
    [0.947, 0.0, 0.053]
    """
    bx, by, bz = xyz
    direct, mp, *_ = ranges(ping.x, ping.y, ping.depth, bx, by, bz, bz, False)
    lw_mp = _THIRD if mp - direct >= MIN_SEPARATION else -math.inf
    log_ol = -math.log(max(window[1] - window[0], 1e-9))
    return class_probabilities(ping.range, direct, mp, sd, sd, log_ol, _THIRD, lw_mp,
                               _THIRD)[:3]


def _beacon_stats(z, xy, depth, xyz, d0, double, resp):
    """Return a beacon's batch sufficient statistics (:data:`.reflector.BEACON_STATS`)."""
    pred = predict_ranges(xy[:, 0], xy[:, 1], depth, xyz, d0, "double" if double else "triangle")
    r = z - pred.multipath
    jac = pred.d_multipath_d0
    g = resp[:, 1]
    return (float(resp[:, 0].mean()), float(g.mean()), float(resp[:, 2].mean()),
            float(np.mean(g * jac * jac)), float(np.mean(g * jac * r)), float(np.mean(g * r * r)))


def expected_squares(stats, sigma_mp):
    """Replace the plain sum of squares in ``stats`` by the batch's expected one.

    The batch ECM's ``sigma_MP`` is the fixed point of the expected squared residual
    ``r^2 + J P J^T`` (the track's uncertainty included); the plain ``<g r^2>`` is biased
    low by the degrees of freedom the track takes. The returned statistics give back
    ``sigma_mp`` exactly at the batch's plane height.

    Parameters
    ----------
    stats : tuple of 6 float
        :data:`.reflector.BEACON_STATS`.
    sigma_mp : float
        The batch's sigma_MP (m).

    Examples
    --------
    >>> expected_squares((0.7, 0.2, 0.1, 0.2, 0.0, 0.2 * 4.0), 3.0)[5]
    1.8
    """
    g_dp, g_mp, g_ol, jj, ju, _ = stats
    uu = g_mp * sigma_mp ** 2 + (ju * ju / jj if jj > 0.0 else 0.0)
    return (g_dp, g_mp, g_ol, jj, ju, uu)


def _alternative(model, data, xy, depth, seed):
    """Fit the other geometry (mixture EM at the batch track) as a :class:`BeaconModel`."""
    choice = choose_path(data, AUTO, rng=seed, fit_warnings=False)
    fit = choice.fits["triangle" if model.double else "double"]
    w = tuple(fit.weights[c] for c in CLASSES)
    d0 = max(fit.d0, model.d0_min)
    return BeaconModel.start(d0=d0, sigma_mp=max(fit.sigma_mp, 0.05), weights=w, n=model.n,
                             double=not model.double, mp_on=True, xyz=model.xyz,
                             d0_min=model.d0_min, window=model.window,
                             stats=_beacon_stats(data.range, xy, depth, model.xyz, d0,
                                                not model.double, fit.resp))


def prior_model(xyz, prior, *, mp_on, path, d0_min, window):
    """Start a beacon without a fit: plane at the sea surface, the prior's scale, equal weights.

    Parameters
    ----------
    prior : dict
        ``sigma_mp`` (m) and ``n`` (the replies it counts for).
    path : {"auto", "triangle", "double"}
        ``"auto"``: triangle, with the double bounce learned alongside.

    Examples
    --------
    >>> m = prior_model((0.0, 0.0, 100.0), {"sigma_mp": 20.0, "n": 20}, mp_on=True,
    ...                 path="auto", d0_min=0.0, window=(50.0, 60.0))
    >>> m.d0, m.double, m.alt.double
    (100.0, False, True)
    """
    kw = dict(d0=max(xyz[2], d0_min), sigma_mp=prior["sigma_mp"], n=prior["n"], mp_on=mp_on,
              weights=(1 / 3,) * 3 if mp_on else (0.5, 0.0, 0.5), xyz=xyz, d0_min=d0_min,
              window=window)
    m = BeaconModel.start(double=path == "double", **kw)
    if mp_on and path == AUTO:
        m.alt = BeaconModel.start(double=True, **kw)
    return m


def endpoint_covariance(nav) -> np.ndarray:
    """Return the joint covariance of ``(x, y, beta, s)`` at a navigation's last epoch.

    Returns
    -------
    numpy.ndarray
        ``(4, 4)``, marginalised over the plane heights.
    """
    out = np.zeros((4, 4))
    out[:2, :2] = nav.cov[-1]
    out[:2, 2:] = nav.track_global_cov[-1][:, :2]
    out[2:, :2] = out[:2, 2:].T
    out[2:, 2:] = nav.global_cov[:2, :2]
    return out


def batch_start(buffer, beacons: pd.DataFrame, opts: dict, seed: int, prior: dict):
    """Fit the kept replies in batch and build the online estimator's start from it.

    Parameters
    ----------
    buffer : list of list
        The kept replies (:data:`BUFFER_COLUMNS`).
    beacons : pandas.DataFrame
        The beacons table (index ``beacon``; ``x``, ``y``, ``depth``).
    opts : dict
        The navigator's options (``multipath``, ``path``, ``dr_noise``, ...).
    seed : int
        Seeds the batch fit's path choice.
    prior : dict
        ``sigma_mp`` and ``n`` of a beacon too rare in the warm-up for a fit.

    Returns
    -------
    filt : PositionFilter
    models : dict of str to BeaconModel
    dp : DirectPathScale
    answer : tuple
        The last reply's ``(p_dp, p_mp, p_ol)``.
    record : dict
        What the warm-up found (JSON-ready), with the batch fit's warnings.
    """
    pings = pd.DataFrame(buffer, columns=list(BUFFER_COLUMNS))
    survey = load_survey(pings, beacons.reset_index())
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        nav = navigate(survey, multipath=opts["multipath"], path=opts["path"],
                       dr_noise=opts["dr_noise"], start_sd=opts["start_sd"],
                       heading_sd=opts["heading_sd"], scale_sd=opts["scale_sd"],
                       plane_sd=opts["plane_sd"], sigma_dp=opts["sigma_dp"],
                       min_pings=opts["min_pings"], rng=seed)
    dive = build_dive(survey)
    st = nav.state
    filt = PositionFilter.start(st.track[-1, 0], st.track[-1, 1], st.beta, st.scale,
                                endpoint_covariance(nav), beta_walk=opts["beta_walk"],
                                scale_walk=opts["scale_walk"])
    lag = surface_separation(dive)
    counts = dive.replies_per_beacon()
    models = {}
    for j, bid in enumerate(dive.beacon_ids):
        if counts[j] == 0:
            continue
        xyz = tuple(dive.beacon_xyz[j])
        mp_on = opts["multipath"] == "signal" and bool(lag[j] >= MIN_SEPARATION)
        common = dict(n=int(counts[j]), double=bool(st.double[j]), mp_on=mp_on, xyz=xyz,
                      d0_min=float(dive.d0_min[j]), window=tuple(dive.window[j]))
        m = dive.beacon == j
        xy, depth = st.track[dive.epoch[m]], dive.zdepth[m]
        if nav.beacons[bid]["mp"] and not nav.beacons[bid].get("flags"):
            stats = expected_squares(
                _beacon_stats(dive.z[m], xy, depth, xyz, float(st.d0[j]), bool(st.double[j]),
                              nav.resp[m]), float(st.sigma_mp[j]))
            models[bid] = BeaconModel.start(
                d0=float(st.d0[j]), sigma_mp=float(st.sigma_mp[j]), weights=tuple(st.weights[j]),
                stats=stats, **common)
            if opts["path"] == AUTO:
                data = BeaconData.from_arrays(dive.z[m], xy[:, 0], xy[:, 1], depth, xyz,
                                              time=dive.times[dive.epoch[m]], beacon=bid)
                models[bid].alt = _alternative(models[bid], data, xy, depth, seed)
        else:  # too few replies, no multipath class, or a flagged fit: the prior
            models[bid] = prior_model(xyz, prior, mp_on=mp_on, path=opts["path"],
                                      d0_min=common["d0_min"], window=common["window"])
    # the batch's expected squares <g (r^2 + J P J^T)> = <g> sigma^2 (its scales' fixed point,
    # docs/navigate.md), not the plain <g r^2> that the track's degrees of freedom bias low
    g = float(nav.resp[:, 0].mean())
    dp = DirectPathScale(st.sigma_dp, dive.n, stats=(g, g * st.sigma_dp ** 2),
                         fixed=opts["sigma_dp"] is not None)
    record = {"replies": dive.n, "epochs": dive.n_epochs, "iterations": nav.n_iter,
              "converged": nav.converged, "corrected": nav.corrected,
              "heading_bias_deg": math.degrees(st.beta), "speed_scale": st.scale,
              "sigma_dp": st.sigma_dp,
              "beacons": {bid: {"d0": m.d0, "sigma_mp": m.sigma_mp, "mp": m.mp_on,
                                "path": "double" if m.double else "triangle"}
                          for bid, m in models.items()},
              "warnings": [f"{w.category.__name__}: {w.message}" for w in caught]}
    return filt, models, dp, tuple(float(v) for v in nav.resp[-1]), record
