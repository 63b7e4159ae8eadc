"""Fitting the joint model of the diagnosis by ECM, and its held-out predictive density.

The joint model (:mod:`.model`) is fitted to all beacons at once by an ECM
algorithm: an E-step; closed-form mixing weights; a safeguarded Gauss-Newton
step on the mean parameters (plane depths and effect parameters, analytic
Jacobian; :func:`bayes_mpem.mixture.gauss_newton.safeguarded_step`) that never
increases the weighted squared error; closed-form scatters. The
log-likelihood therefore never decreases.

* :func:`baseline_start` starts the baseline (no effect) from the per-beacon
  mixture EM with both geometries (:func:`bayes_mpem.lbl.path_choice.choose_path`),
  and picks the multipath geometry of the joint model;
* :func:`start_for` and :func:`replant` give starting points for a model
  with more effects;
* :func:`fit_joint` runs the ECM from several starts and keeps the best, a
  :class:`JointFit`;
* :func:`heldout` scores each reply by K-fold cross-validation, the
  criterion the driver (:func:`bayes_mpem.lbl.diagnosis.driver.diagnose`)
  keeps an effect by.

Examples
--------
>>> from bayes_mpem.lbl.simulate import simulate_survey
>>> from bayes_mpem.lbl.survey import fittable_beacons
>>> from bayes_mpem.lbl.diagnosis.model import ranges
>>> sim = simulate_survey("abe58", rng=2, n_cycles=300, effects={"range_bias": 6.0})
>>> fittable, _ = fittable_beacons(sim.survey, 30)
>>> d = ranges(sim.survey, fittable)
>>> start, path, _ = baseline_start(d, fittable, "triangle", 0)
>>> fit = fit_joint(d, ("range_bias",), start, path=path)
>>> abs(fit.magnitudes(d)["range_bias"] - 6.0) < 0.5
True
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace
from functools import partial

import numpy as np

from ..._rng import as_generator
from ...mixture.gauss_newton import safeguarded_step
from .. import geometry
from ..em_mixture import fit_mixture_em, histogram_modes
from ..path_choice import choose_path
from .constraints import is_feasible, repair
from .model import (
    Params,
    Ranges,
    e_step,
    get_vector,
    implied_depths,
    mean_names,
    predict,
    set_vector,
    weighted_sse,
)


def _feasible_sse(d, p, names, effects, path, resp, v):
    """``(weighted SSE, parameters)`` at mean vector ``v``; ``None`` where infeasible."""
    cand = set_vector(p, names, v)
    if not is_feasible(d, cand, effects):
        return None
    return weighted_sse(d, cand, effects, path, resp), cand


def _gauss_newton(d, p, effects, path, resp, n_steps=2):
    """Safeguarded Gauss-Newton on the mean parameters; never increases the weighted SSE."""
    names = mean_names(effects, d.nb)
    sig = p.sigma[d.bi]
    q0 = weighted_sse(d, p, effects, path, resp)
    info = None
    for _ in range(n_steps):
        mu, jac = predict(d, p, effects, path, names)
        m = len(names)
        a = np.zeros((m, m))
        g = np.zeros(m)
        for c, name in enumerate(("dp", "mp", "mp2")):
            if name not in mu:
                continue
            w = resp[:, c] / (sig[:, c] * sig[:, c])
            jw = jac[name] * w[:, None]
            a += np.einsum("ni,nj->ij", jw, jac[name])
            g += np.einsum("ni,n->i", jw, d.z - mu[name])
        info = a
        ridge = 1e-9 * np.maximum(np.diag(a), 1e-12) + 1e-12
        try:
            step = np.linalg.solve(a + np.diag(ridge), g)
        except np.linalg.LinAlgError:
            break
        objective = partial(_feasible_sse, d, p, names, effects, path, resp)
        out = safeguarded_step(objective, get_vector(p, names), step, q0)
        if out is None:
            break
        p, q0 = out.aux, out.value
        if np.max(np.abs(out.step)) < 1e-10:
            break
    return p, names, info


def _m_step(d, p, effects, path, resp, sigma_floor, mp2_floor):
    p = p.copy()
    nb = d.nb
    counts = np.bincount(d.bi, minlength=nb).astype(float)
    w = np.stack([np.bincount(d.bi, weights=resp[:, c], minlength=nb) for c in range(4)], 1)
    p.weights = w / np.maximum(counts, 1.0)[:, None]
    p, names, info = _gauss_newton(d, p, effects, path, resp)
    mu = predict(d, p, effects, path)
    for c, name in enumerate(("dp", "mp", "mp2")):
        if name not in mu:
            continue
        r2 = (d.z - mu[name]) ** 2
        num = np.bincount(d.bi, weights=resp[:, c] * r2, minlength=nb)
        den = np.bincount(d.bi, weights=resp[:, c], minlength=nb)
        ok = den > 1e-3
        # a second family is no sharper than the direct path (its scatter includes the
        # direct path's): stops it from collapsing onto a handful of coincident ranges. The
        # floor is fixed for the whole run, so every M-step stays a conditional maximisation.
        floor = mp2_floor[ok] if name == "mp2" else sigma_floor
        p.sigma[ok, c] = np.maximum(np.sqrt(num[ok] / den[ok]), floor)
    return p, names, info


@dataclass
class JointFit:
    """A fit of the joint model (baseline or extended) to all beacons.

    Attributes
    ----------
    effects : tuple of str
        The extensions switched on.
    params : object
        Fitted parameters (internal layout; use :meth:`beacons` and :meth:`magnitudes`).
    resp : numpy.ndarray
        ``(n, 4)`` class probabilities (dp, mp, mp2, ol) of every reply.
    loglik : float
    n_iter : int
    converged : bool
    se : dict
        Approximate standard errors of the mean parameters (Gauss-Newton
        information given the class probabilities).
    """

    effects: tuple
    params: Params
    resp: np.ndarray
    loglik: float
    n_iter: int
    converged: bool
    path: str
    se: dict = field(default_factory=dict)
    history: list = field(default_factory=list)

    def magnitudes(self, data: Ranges) -> dict:
        """Signed magnitude of every effect switched on (see :data:`UNITS`).

        Parameters
        ----------
        data : Ranges
            The replies the fit was made on.

        Returns
        -------
        dict of str to float
        """
        p, out = self.params, {}
        if "range_bias" in self.effects:
            out["range_bias"] = p.bias
        if "sound_speed" in self.effects:
            out["sound_speed"] = p.scale
        if "plane_drift" in self.effects:
            out["plane_drift"] = p.drift
        if "second_reflector" in self.effects:
            out["second_reflector"] = p.plane2
        if "early_outliers" in self.effects:
            out["early_outliers"] = float(self.resp[:, 3].mean())
        if "nav_drift" in self.effects:
            out["nav_drift"] = float(np.hypot(*p.nav))
        return {k: float(v) for k, v in out.items()}

    def beacons(self, data: Ranges) -> dict:
        """Per-beacon parameters: ``d0`` (plane height above the beacon at the first ping), ...

        Parameters
        ----------
        data : Ranges
            The replies the fit was made on.

        Returns
        -------
        dict
            Per beacon id: ``n_ranges``, ``d0``, ``plane_depth``, ``sigma_dp``,
            ``sigma_mp``, ``weights`` (``d0_last``, ``sigma_mp2`` with the effects).
        """
        p, out = self.params, {}
        for j, bid in enumerate(data.ids):
            sel = data.bi == j
            entry = {
                "n_ranges": int(sel.sum()),
                "d0": float(data.bz[j] - p.plane[j]),
                "plane_depth": float(p.plane[j]),
                "sigma_dp": float(p.sigma[j, 0]),
                "sigma_mp": float(p.sigma[j, 1]),
                "weights": {"dp": float(p.weights[j, 0]), "mp": float(p.weights[j, 1]),
                            "ol": float(p.weights[j, 3])},
            }
            if "plane_drift" in self.effects:
                entry["d0_last"] = float(data.bz[j] - p.plane[j] - p.drift)
            if "second_reflector" in self.effects:
                entry["weights"]["mp2"] = float(p.weights[j, 2])
                entry["sigma_mp2"] = float(p.sigma[j, 2])
            out[bid] = entry
        return out


def _modes(v, k):
    """Return the ``k`` strongest modes of the depths ``v`` (5 m bins, 25 m apart, > 4 ranges)."""
    return histogram_modes(v, k, min_count=4) if v.size >= 10 else []


def _second_starts(d, p, effects, path, resp):
    """Give starts for a second plane: modes of the implied depths of poorly explained ranges.

    A beacon whose own plane sits on a candidate depth (its strongest multipath
    family may be the second plane's) also gets a start with its plane moved to
    its next mode, so that the shared plane and the beacon's own are not confused.
    """
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


def _run(d, p, effects, path, *, max_iter, tol, sigma_floor):
    mp2_floor = np.maximum(sigma_floor, p.sigma[:, 0])
    if "second_reflector" in effects:
        p = p.copy()
        p.sigma[:, 2] = np.maximum(p.sigma[:, 2], mp2_floor)
    resp, ll_i, mu = e_step(d, p, effects, path)
    ll = float(ll_i.sum())
    hist = [ll]
    converged = False
    info, names = None, mean_names(effects, d.nb)
    for it in range(1, max_iter + 1):
        p, names, info = _m_step(d, p, effects, path, resp, sigma_floor, mp2_floor)
        resp, ll_i, mu = e_step(d, p, effects, path)
        new = float(ll_i.sum())
        hist.append(new)
        if abs(new - ll) < tol * d.n:
            ll = new
            converged = True
            break
        ll = new
    se = {}
    if info is not None:
        try:
            cov = np.linalg.inv(info + np.diag(1e-12 + 1e-9 * np.abs(np.diag(info))))
            for i, (k, j) in enumerate(names):
                key = f"plane[{d.ids[j]}]" if k == "plane" else k
                se[key] = float(np.sqrt(max(cov[i, i], 0.0)))
        except np.linalg.LinAlgError:
            pass
    return JointFit(effects=tuple(effects), params=p, resp=resp, loglik=ll, n_iter=it,
                    converged=converged, path=path, se=se, history=hist)


def baseline_start(d: Ranges, fittable, path, rng):
    """Start the joint baseline from per-beacon mixture-EM fits.

    Parameters
    ----------
    d : Ranges
    fittable : list of BeaconData
        The beacons of ``d``, in order.
    path : {"auto", "triangle", "double"}
        ``"auto"`` picks the multipath geometry with the higher total likelihood.
    rng : None, int or numpy.random.Generator
        Seeds the per-beacon fits.

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
        # both geometries per beacon, the fits fit/sample/compare choose from; the joint
        # model shares one geometry, so the choice here is by the summed log-likelihoods
        choices = [choose_path(data, "auto", rng=seed + j) for j, data in enumerate(fittable)]
    for pth in paths:
        plane = np.empty(nb)
        sigma = np.empty((nb, 3))
        weights = np.zeros((nb, 4))
        total = 0.0
        for j, choice in enumerate(choices):
            r = choice.fits[pth]
            plane[j] = d.bz[j] - r.d0
            sigma[j] = (r.sigma_dp, r.sigma_mp, r.sigma_mp)
            weights[j] = (r.weights["dp"], r.weights["mp"], 0.0, r.weights["ol"])
            total += choice.loglik[pth]
        logliks[pth] = total
        if best is None or total > best[2]:
            best = (Params(plane=plane, sigma=sigma, weights=weights), pth, total)
    return best[0], best[1], logliks


def start_for(d, base: JointFit, effects, path):
    """Give starting points for a model with ``effects``, from a fit of a nested model.

    Parameters
    ----------
    d : Ranges
    base : JointFit
        The fit of a model with fewer effects.
    effects : tuple of str
    path : {"triangle", "double"}

    Returns
    -------
    list of Params
        ``base``'s parameters; for a new ``second_reflector``, one start per
        candidate plane (possibly none).
    """
    p = base.params.copy()
    if "second_reflector" in effects and "second_reflector" not in base.effects:
        return _second_starts(d, p, effects, path, base.resp)
    return [p]


def fit_joint(d: Ranges, effects, start: Params | list, *, path="triangle", max_iter=300,
              tol=1e-7, sigma_floor=0.05) -> JointFit:
    """Fit the joint model with ``effects`` from one or several starting points (best kept).

    Parameters
    ----------
    d : Ranges
        The replies (``Diagnosis.data``).
    effects : tuple of str
        Extensions switched on (names of :data:`~bayes_mpem.lbl.effects.EFFECTS`).
    start : parameters or list of them
        Starting points; infeasible ones are moved just inside the constraints.
    path : {"triangle", "double"}
    max_iter : int, default 300
    tol : float, default 1e-7
        Stop when the log-likelihood gains less than ``tol`` per reply.
    sigma_floor : float, default 0.05

    Returns
    -------
    JointFit

    Raises
    ------
    ValueError
        When no start can be made feasible.
    """
    starts = start if isinstance(start, list) else [start]
    best = None
    for s in starts:
        if not is_feasible(d, s, effects):
            s = repair(d, s, effects)
            if not is_feasible(d, s, effects):
                continue
        r = _run(d, s, effects, path, max_iter=max_iter, tol=tol, sigma_floor=sigma_floor)
        if best is None or r.loglik > best.loglik:
            best = r
    if best is None:
        raise ValueError(f"no feasible starting point for the model with {sorted(effects)}")
    return best


def replant(d: Ranges, fit: JointFit, fittable, path, rng) -> Params | None:
    """Re-find each beacon's plane for ``fit``'s model: a fresh start.

    Each beacon's plane, scales and weights are re-found by the per-beacon
    mixture EM (its multi-start over plane heights) on ranges corrected by the
    fitted bias, scale and navigation drift. A beacon whose baseline plane was
    pulled to a wrong family (e.g. the direct path of a mis-scaled survey)
    stays there when the effect is switched on; this gives it a way out.

    Parameters
    ----------
    d : Ranges
    fit : JointFit
    fittable : list of BeaconData
        The beacons of ``d``, in order.
    path : {"triangle", "double"}
    rng : None, int or numpy.random.Generator
        Seeds the per-beacon fits.

    Returns
    -------
    Params or None
        ``None`` when no plane moves by more than 5 m.
    """
    p = fit.params
    k = 1.0 + (p.scale if "sound_speed" in fit.effects else 0.0)
    b = p.bias if "range_bias" in fit.effects else 0.0
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
            z = (data.range - b) / k
            # a reply shorter than the fitted bias is no path at all: leave it out of this
            # beacon's restart (the joint fit still scores it, as an outlier)
            keep = z > 0
            corrected = replace(data, range=z[keep], x=x[keep], y=y[keep],
                                depth=data.depth[keep], time=data.time[keep],
                                rows=data.rows[keep])
            try:
                r = fit_mixture_em(corrected, path=path, rng=rng, n_init=4)
            except ValueError:  # fewer than 3 replies left: the beacon keeps its plane
                continue
            plane = float(d.bz[j] - r.d0)
            if "plane_drift" in fit.effects:
                plane -= p.drift * float(np.mean(tau))
            if abs(plane - p.plane[j]) > 5.0:
                moved = True
            q.plane[j] = plane
            q.sigma[j, :2] = (r.sigma_dp * k, r.sigma_mp * k)
            w_mp2 = q.weights[j, 2]
            q.weights[j] = (r.weights["dp"] * (1 - w_mp2), r.weights["mp"] * (1 - w_mp2), w_mp2,
                            r.weights["ol"] * (1 - w_mp2))
    return q if moved else None


# --------------------------------------------------------------------------- selection


def heldout(d: Ranges, effects, full: JointFit, folds, path, **kw):
    """Score every range by K-fold cross-validation, each fold warm-started at ``full``.

    Parameters
    ----------
    d : Ranges
    effects : tuple of str
    full : JointFit
        The fit to all ranges (its parameters start every fold).
    folds : numpy.ndarray
        Fold number of every range.
    path : {"triangle", "double"}
    **kw
        ``max_iter``, ``tol`` and ``sigma_floor`` of the ECM.

    Returns
    -------
    numpy.ndarray
        Held-out log predictive density of every range.
    """
    out = np.empty(d.n)
    for k in np.unique(folds):
        test = folds == k
        fit_k = _run(d.subset(~test), full.params.copy(), full.effects, path, **kw)
        dt = d.subset(test)
        _, ll_i, _ = e_step(dt, fit_k.params, effects, path)
        out[test] = ll_i
    return out
