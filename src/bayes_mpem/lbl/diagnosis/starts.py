"""Starting points of the diagnosis' joint fits."""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np

from ..._rng import as_generator
from ..em.em_mixture import fit_mixture_em, histogram_modes
from ..em.path_choice import choose_path
from ..model import geometry
from ..simulation.effects import split_term
from .ecm import JointFit
from .model import Ranges, biases, implied_depths, predict
from .params import Params, beacon_mask, get_vector, mean_names, set_vector


def _modes(v, k):
    """Return the ``k`` strongest modes of the depths ``v`` (5 m bins, 25 m apart, > 4 ranges)."""
    return histogram_modes(v, k, min_count=4) if v.size >= 10 else []


def _second_starts(d, p, effects, path, resp):
    """Give starts for a second plane: modes of the implied depths of poorly explained ranges."""
    depth = implied_depths(d, p, effects, path)
    top = float(np.min(d.vdepth))
    usable = np.isfinite(depth) & (depth < top) & (depth > -0.2 * top)
    # the beacons' consensus plane (median weighted by multipath counts) is the main reflector:
    # a candidate on it would only relabel the two families
    n_mp = np.bincount(d.bi, weights=resp[:, 1], minlength=d.nb)
    order = np.argsort(p.plane)
    cum = np.cumsum(n_mp[order])
    main = float(p.plane[order][np.searchsorted(cum, 0.5 * cum[-1])])
    starts = []
    for cand in _modes(depth[usable & (resp[:, 3] > 0.5)], 4):
        if abs(cand - main) < 30.0:
            continue
        q = p.copy()
        q.plane2 = cand
        share = np.maximum(0.5 * q.weights[:, 3], 0.01)
        q.weights[:, 2] = share
        q.weights[:, 3] = np.maximum(q.weights[:, 3] - share, 0.005)
        q.weights = q.weights / q.weights.sum(1, keepdims=True)
        q.sigma[:, 2] = np.median(q.sigma[:, 1])
        starts.append(q)
        clash = np.abs(q.plane - cand) < 30.0
        if clash.any():
            r = q.copy()
            for j in np.flatnonzero(clash):
                own = usable & (d.bi == j) & (resp[:, 0] < 0.5)
                alt = [m for m in _modes(depth[own], 3) if abs(m - cand) > 30.0]
                if alt:
                    r.plane[j] = min(alt[0], float(np.min(d.vdepth[d.bi == j])))
            starts.append(r)
    return starts


def baseline_start(d: Ranges, fittable, path, rng):
    """Start the joint baseline from per-beacon mixture-EM fits.

    Returns
    -------
    params : Params
    path : str
        The multipath geometry chosen.
    logliks : dict
        Total log-likelihood of the per-beacon fits for each geometry tried.
    """
    nb = d.nb
    paths = geometry.PATHS if path == "auto" else (path,)
    best, logliks = None, {}
    seed = int(as_generator(rng).integers(2**31))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # flags: on the final joint fit (residuals.beacon_flags)
        # auto: both geometries per beacon, the fits fit/sample/compare choose from; the
        # joint model shares one geometry, so the choice here is by the summed
        # log-likelihoods. A forced geometry is fitted alone (no margin is reported here).
        if path == "auto":
            fits = [choose_path(data, "auto", rng=seed + j).fits
                    for j, data in enumerate(fittable)]
        else:
            fits = [{path: fit_mixture_em(data, path=path, rng=seed + j)}
                    for j, data in enumerate(fittable)]
    for pth in paths:
        plane = np.empty(nb)
        sigma = np.empty((nb, 3))
        weights = np.zeros((nb, 4))
        total = 0.0
        for j, fit in enumerate(fits):
            r = fit[pth]
            plane[j] = d.bz[j] - r.d0
            sigma[j] = (r.sigma_dp, r.sigma_mp, r.sigma_mp)
            weights[j] = (r.weights["dp"], r.weights["mp"], 0.0, r.weights["ol"])
            total += r.loglik if r.loglik is not None and np.isfinite(r.loglik) else -np.inf
        logliks[pth] = total
        if best is None or total > best[2]:
            best = (Params(plane=plane, sigma=sigma, weights=weights), pth, total)
    return best[0], best[1], logliks


def start_for(d, base: JointFit, effects, path):
    """Give starting points for a model with ``effects`` from a fit of a nested model.

    ``base``'s parameters; for a new ``second_reflector``, one start per candidate plane;
    for a new per-beacon term, also one from its ranges alone (:func:`direct_path_offset`).
    """
    p = base.params.copy()
    if "second_reflector" in effects and "second_reflector" not in base.effects:
        return _second_starts(d, p, effects, path, base.resp)
    new = [t for t in effects if t not in base.effects and split_term(t)[1] is not None]
    if new:
        return [p, direct_path_offset(d, p, effects, path, new[0])]
    return [p]


def direct_path_offset(d: Ranges, p: Params, effects, path, t, *, scale=10.0, n_iter=30):
    """Start a per-beacon term where its bias or position puts its ranges on the direct path.

    Parameters
    ----------
    t : str
        ``"beacon_bias:<id>"`` or ``"beacon_position:<id>"``.
    scale : float, default 10
        Cauchy scale (m) of the reweighted least squares.
    """
    name, bid = split_term(t)
    j = d.ids.index(bid)
    names = [n for n in mean_names((t,), d.ids) if n[0] != "plane"]
    sel = d.bi == j
    sub = d.subset(sel)
    q = p.copy()
    for _ in range(n_iter):
        mu, jac = predict(sub, q, effects, path, names)
        r = sub.z - mu["dp"]
        w = 1.0 / (1.0 + (r / scale) ** 2)
        jw = jac["dp"] * w[:, None]
        try:
            step = np.linalg.solve(jw.T @ jac["dp"] + 1e-9 * np.eye(len(names)), jw.T @ r)
        except np.linalg.LinAlgError:
            break
        q = set_vector(q, names, get_vector(q, names) + step)
        if np.max(np.abs(step)) < 1e-3:
            break
    q.weights[j] = (0.5, 0.3, 0.0, 0.2) if q.weights[j, 2] == 0 else (0.45, 0.25, 0.1, 0.2)
    q.sigma[j, 0] = max(float(q.sigma[j, 0]), 3.0)
    return q


def replant(d: Ranges, fit: JointFit, fittable, path, rng) -> Params | None:
    """Re-find each beacon's plane for ``fit``'s model: a fresh start (None if nothing moves)."""
    p = fit.params
    k = 1.0 + (p.scale if "sound_speed" in fit.effects else 0.0)
    b = biases(d, p, fit.effects)
    moved_beacon = beacon_mask(fit.effects, "beacon_position", d.ids)
    q = p.copy()
    moved = False
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for j, data in enumerate(fittable):
            sel = d.bi == j
            tau = d.tau[sel]
            x, y = data.x, data.y
            if "nav_drift" in fit.effects:
                x, y = x + p.nav[0] * tau, y + p.nav[1] * tau
            z = (data.range - b[sel]) / k
            # a reply shorter than the fitted bias is no path at all: leave it out of this
            # beacon's restart (the joint fit still scores it, as an outlier)
            keep = z > 0
            position = data.position + (p.bpos[j] if moved_beacon[j] else 0.0)
            corrected = replace(data, range=z[keep], x=x[keep], y=y[keep],
                                depth=data.depth[keep], time=data.time[keep],
                                rows=data.rows[keep], position=position)
            try:
                r = fit_mixture_em(corrected, path=path, rng=rng, n_init=4)
            except ValueError:  # fewer than 3 replies left: the beacon keeps its plane
                continue
            plane = float(position[2] - r.d0)
            if "plane_drift" in fit.effects:
                plane -= p.drift * float(np.mean(tau))
            q.plane[j] = plane
            q.sigma[j, :2] = (r.sigma_dp * k, r.sigma_mp * k)
            w_mp2 = q.weights[j, 2]
            q.weights[j] = (r.weights["dp"] * (1 - w_mp2), r.weights["mp"] * (1 - w_mp2), w_mp2,
                            r.weights["ol"] * (1 - w_mp2))
            # a class whose weight reached 0 never comes back in the ECM (its
            # responsibilities stay 0): a revived direct path or multipath counts as a move
            if (abs(plane - p.plane[j]) > 5.0
                    or np.max(np.abs(q.weights[j, :2] - p.weights[j, :2])) > 0.05):
                moved = True
    return q if moved else None
