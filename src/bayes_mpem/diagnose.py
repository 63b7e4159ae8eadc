"""Find the effect hidden in a survey: which of the paper's assumptions the data break.

The paper's model assumes one static reflector, a homogeneous medium, exact
navigation and a calibrated system. :func:`diagnose` fits that model to every
beacon at once (the *baseline*), then each extension of a fixed vocabulary
(:data:`EFFECTS`), and keeps an extension only when it predicts held-out ranges
clearly better (K-fold cross-validated log predictive density). Effects are
added greedily, so two effects present at once are both found.

The joint model
---------------
For range ``i`` of beacon ``b`` at normalised time ``tau_i`` (0 at the first
ping of the survey, 1 at the last), with the vehicle at the reported position
plus the navigation correction ``tau_i (e_x, e_y)``:

* direct path ``mu_dp = k D_i + beta``, multipath ``mu_mp = k M_i(P_b + delta
  tau_i) + beta`` off a plane at depth ``P_b + delta tau_i``, a second
  multipath ``mu_mp2 = k M_i(P_2) + beta``, with ``k = 1 + f``;
* Gaussian scatter per beacon and class; outliers uniform over the beacon's
  listening window, or, with first-arrival detection, uniform between the
  window start and the direct path;
* learned mixing weights per beacon.

Each effect switches on one part: ``range_bias`` (``beta``, m),
``sound_speed`` (``f = factor - 1``), ``plane_drift`` (``delta``, m from the
first to the last ping), ``second_reflector`` (``P_2``, m, with its weight and
scatter per beacon), ``early_outliers`` (the first-arrival outlier density;
magnitude = fraction of replies that are outliers) and ``nav_drift`` (``|(e_x,
e_y)|``, m at the last ping). The baseline, all switched off, is the mixture
model of :mod:`bayes_mpem.mixture`, fitted to all beacons together.

Fitting is an ECM algorithm: E-step; closed-form weights; a safeguarded
Gauss-Newton step on the mean parameters (plane depths and effect parameters,
analytic Jacobian) that never increases the weighted squared error; closed-form
scatters.

Examples
--------
>>> from bayes_mpem.simulate import simulate_survey
>>> from bayes_mpem.diagnose import diagnose
>>> sim = simulate_survey("abe58", rng=2, n_cycles=700, effects={"range_bias": 6.0})
>>> dx = diagnose(sim.survey, rng=0, progress=False)
>>> [e.name for e in dx.effects]
['range_bias']
>>> abs(dx.effects[0].magnitude - 6.0) < 0.5
True
"""

from __future__ import annotations

import json
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from . import geometry
from ._rng import RNGLike, as_generator
from .data import Survey, load_survey
from .em import fit_mixture_em, histogram_modes
from .fitting import fittable_beacons

__all__ = ["EFFECTS", "UNITS", "Diagnosis", "Effect", "JointFit", "covariates", "diagnose",
           "fit_joint", "residual_checks"]

#: The vocabulary of effects, in the order they are tried.
EFFECTS = ("range_bias", "sound_speed", "plane_drift", "second_reflector", "early_outliers",
           "nav_drift")
#: Unit of each effect's magnitude.
UNITS = {"range_bias": "m", "sound_speed": "1", "plane_drift": "m", "second_reflector": "m",
         "early_outliers": "1", "nav_drift": "m"}
_DESCRIPTION = {
    "range_bias": "every returned range is offset by a constant (e.g. a wrong turn-around time)",
    "sound_speed": "ranges are scaled by a constant factor (a wrong sound speed)",
    "plane_drift": "the reflecting plane's depth changes during the dive (tide, depth-sensor "
                   "drift)",
    "second_reflector": "a second family of multipath from another plane",
    "early_outliers": "spurious returns arrive only before the true one (first-arrival "
                      "detection)",
    "nav_drift": "the navigation drifts away from the truth over the dive",
}
_EPS_LATE = 1e-3  # share of the early-outlier density left over the whole window
_LOG_SQRT_2PI = 0.5 * np.log(2.0 * np.pi)


# --------------------------------------------------------------------------- data


@dataclass(frozen=True)
class _Ranges:
    """All replies of the fitted beacons, concatenated; per-range beacon index ``bi``."""

    z: np.ndarray
    x: np.ndarray
    y: np.ndarray
    vdepth: np.ndarray
    time: np.ndarray
    tau: np.ndarray
    bi: np.ndarray
    rows: np.ndarray
    bx: np.ndarray  # per beacon
    by: np.ndarray
    bz: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    ids: tuple

    @property
    def n(self) -> int:
        return int(self.z.size)

    @property
    def nb(self) -> int:
        return len(self.ids)

    def subset(self, mask) -> _Ranges:
        """The same survey restricted to ``mask`` (windows and beacons kept)."""
        return replace(self, **{k: getattr(self, k)[mask] for k in
                                ("z", "x", "y", "vdepth", "time", "tau", "bi", "rows")})


def _ranges(survey: Survey, fittable) -> _Ranges:
    t_all = survey.time
    t0, t1 = float(np.min(t_all)), float(np.max(t_all))
    span = t1 - t0 if t1 > t0 else 1.0
    parts = {k: [] for k in ("z", "x", "y", "vdepth", "time", "bi", "rows")}
    pos, lo, hi = [], [], []
    for j, d in enumerate(fittable):
        parts["z"].append(d.range)
        parts["x"].append(d.x)
        parts["y"].append(d.y)
        parts["vdepth"].append(d.depth)
        parts["time"].append(d.time)
        parts["bi"].append(np.full(d.n, j))
        parts["rows"].append(d.rows)
        pos.append(d.position)
        lo.append(float(d.range.min()))
        hi.append(float(d.range.max()))
    cat = {k: np.concatenate(v) for k, v in parts.items()}
    pos = np.asarray(pos, float).reshape(-1, 3)
    return _Ranges(**cat, tau=(cat["time"] - t0) / span, bx=pos[:, 0], by=pos[:, 1],
                   bz=pos[:, 2], lo=np.asarray(lo), hi=np.maximum(np.asarray(hi),
                                                                  np.asarray(lo) + 1e-6),
                   ids=tuple(d.beacon for d in fittable))


# --------------------------------------------------------------------------- model


@dataclass
class _Params:
    plane: np.ndarray       # (B,) plane depth at the first ping
    sigma: np.ndarray       # (B, 3) dp, mp, mp2
    weights: np.ndarray     # (B, 4) dp, mp, mp2, ol
    bias: float = 0.0
    scale: float = 0.0      # f = factor - 1
    drift: float = 0.0      # plane depth change, first -> last ping
    plane2: float = np.nan  # second plane depth
    nav: np.ndarray = field(default_factory=lambda: np.zeros(2))  # correction at the last ping

    def copy(self) -> _Params:
        return _Params(self.plane.copy(), self.sigma.copy(), self.weights.copy(), self.bias,
                       self.scale, self.drift, self.plane2, self.nav.copy())


def _mean_names(effects, nb):
    names = [("plane", j) for j in range(nb)]
    for e, keys in (("range_bias", ["bias"]), ("sound_speed", ["scale"]),
                    ("plane_drift", ["drift"]), ("second_reflector", ["plane2"]),
                    ("nav_drift", ["nav_x", "nav_y"])):
        if e in effects:
            names += [(k, None) for k in keys]
    return names


def _get_vector(p: _Params, names):
    out = []
    for k, j in names:
        if k == "plane":
            out.append(p.plane[j])
        elif k == "nav_x":
            out.append(p.nav[0])
        elif k == "nav_y":
            out.append(p.nav[1])
        else:
            out.append(getattr(p, k))
    return np.asarray(out, float)


def _set_vector(p: _Params, names, v) -> _Params:
    q = p.copy()
    for (k, j), val in zip(names, v, strict=True):
        if k == "plane":
            q.plane[j] = val
        elif k == "nav_x":
            q.nav[0] = val
        elif k == "nav_y":
            q.nav[1] = val
        else:
            setattr(q, k, float(val))
    return q


def _offsets(d: _Ranges, p: _Params | None = None, effects=()):
    """Vehicle minus beacon ``(ex, ey)``, horizontal distance ``h`` and ``dz = z_beacon -
    z_vehicle`` of every reply; navigation corrected when ``nav_drift`` is switched on."""
    ex = d.x - d.bx[d.bi]
    ey = d.y - d.by[d.bi]
    if "nav_drift" in effects:
        ex = ex + p.nav[0] * d.tau
        ey = ey + p.nav[1] * d.tau
    return ex, ey, np.hypot(ex, ey), d.bz[d.bi] - d.vdepth


def _predict(d: _Ranges, p: _Params, effects, path, names=None):
    """Class means ``{"dp", "mp"[, "mp2"]}`` and, with ``names``, their Jacobians."""
    ex, ey, h, dz = _offsets(d, p, effects)
    bz = d.bz[d.bi]
    direct = np.hypot(h, dz)
    plane = p.plane[d.bi] + (p.drift * d.tau if "plane_drift" in effects else 0.0)
    lever = 2.0 * (bz - plane) - dz
    refl = np.hypot(h, lever)
    k = 1.0 + (p.scale if "sound_speed" in effects else 0.0)
    b = p.bias if "range_bias" in effects else 0.0
    tri = path == "triangle"
    mp = 0.5 * (direct + refl) if tri else refl
    mu = {"dp": k * direct + b, "mp": k * mp + b}
    second = "second_reflector" in effects
    if second:
        lever2 = 2.0 * (bz - p.plane2) - dz
        refl2 = np.hypot(h, lever2)
        mp2 = 0.5 * (direct + refl2) if tri else refl2
        mu["mp2"] = k * mp2 + b
    if names is None:
        return mu
    n, m = d.n, len(names)
    jac = {c: np.zeros((n, m)) for c in mu}
    safe_d = np.maximum(direct, 1e-9)
    safe_r = np.maximum(refl, 1e-9)
    half = 0.5 if tri else 1.0
    dmp_dd0 = half * 2.0 * lever / safe_r  # d mp / d d0 (d0 = bz - plane)
    for col, (key, j) in enumerate(names):
        if key == "plane":
            sel = d.bi == j
            jac["mp"][sel, col] = -k * dmp_dd0[sel]
        elif key == "bias":
            for c in jac:
                jac[c][:, col] = 1.0
        elif key == "scale":
            jac["dp"][:, col] = direct
            jac["mp"][:, col] = mp
            if second:
                jac["mp2"][:, col] = mp2
        elif key == "drift":
            jac["mp"][:, col] = -k * dmp_dd0 * d.tau
        elif key == "plane2":
            jac["mp2"][:, col] = -k * half * 2.0 * lever2 / np.maximum(refl2, 1e-9)
        elif key in ("nav_x", "nav_y"):
            e = ex if key == "nav_x" else ey
            dd = e * d.tau / safe_d
            dr = e * d.tau / safe_r
            jac["dp"][:, col] = k * dd
            jac["mp"][:, col] = k * (0.5 * (dd + dr) if tri else dr)
            if second:
                dr2 = e * d.tau / np.maximum(refl2, 1e-9)
                jac["mp2"][:, col] = k * (0.5 * (dd + dr2) if tri else dr2)
    return mu, jac


def _log_dens(d: _Ranges, p: _Params, effects, path, mu=None):
    """(n, 4) log densities of every range under dp, mp, mp2, ol (mp2 = -inf when off)."""
    if mu is None:
        mu = _predict(d, p, effects, path)
    sig = p.sigma[d.bi]
    out = np.empty((d.n, 4))
    for c, name in enumerate(("dp", "mp", "mp2")):
        if name in mu:
            r = (d.z - mu[name]) / sig[:, c]
            out[:, c] = -0.5 * r * r - np.log(sig[:, c]) - _LOG_SQRT_2PI
        else:
            out[:, c] = -np.inf
    width = d.hi[d.bi] - d.lo[d.bi]
    if "early_outliers" in effects:
        cut = np.maximum(mu["dp"] - d.lo[d.bi], 1.0)
        inside = d.z <= mu["dp"]
        out[:, 3] = np.where(inside, np.log((1.0 - _EPS_LATE) / cut + _EPS_LATE / width),
                             np.log(_EPS_LATE / width))
    else:
        out[:, 3] = -np.log(width)
    return out, mu


def _e_step(d, p, effects, path, mu=None):
    ld, mu = _log_dens(d, p, effects, path, mu)
    with np.errstate(divide="ignore"):
        lw = np.log(p.weights)[d.bi]
    a = ld + lw
    m = np.max(a, axis=1)
    e = np.exp(a - m[:, None])
    s = e.sum(axis=1)
    return e / s[:, None], m + np.log(s), mu


def _weighted_sse(d, p, effects, path, resp):
    mu = _predict(d, p, effects, path)
    sig = p.sigma[d.bi]
    tot = 0.0
    for c, name in enumerate(("dp", "mp", "mp2")):
        if name in mu:
            r = d.z - mu[name]
            tot += float(np.sum(resp[:, c] * r * r / (sig[:, c] * sig[:, c])))
    return tot


_SECOND_GAP = 50.0  # m: the second plane lies at least this far below the main reflector


def _main_plane(p: _Params) -> float:
    """Depth of the main reflector: the median of the beacons' planes."""
    return float(np.median(p.plane))


def _feasible(d, p, effects):
    """Planes above the vehicle at every ping; the second plane below the main one."""
    plane = p.plane[d.bi] + (p.drift * d.tau if "plane_drift" in effects else 0.0)
    ok = bool(np.all(plane <= d.vdepth))
    if "second_reflector" in effects:
        ok = ok and _main_plane(p) + _SECOND_GAP <= p.plane2 <= float(np.min(d.vdepth))
    if "sound_speed" in effects:
        ok = ok and abs(p.scale) < 0.5
    return ok


def _repair(d, p, effects) -> _Params:
    """Move an infeasible start just inside the constraints (planes 0.5 m above the vehicle)."""
    q = p.copy()
    drift = q.drift * d.tau if "plane_drift" in effects else np.zeros(d.n)
    for j in range(d.nb):
        sel = d.bi == j
        if sel.any():
            q.plane[j] = min(q.plane[j], float(np.min(d.vdepth[sel] - drift[sel])) - 0.5)
    if "second_reflector" in effects:
        lo, hi = _main_plane(q) + _SECOND_GAP, float(np.min(d.vdepth)) - 0.5
        q.plane2 = float(np.clip(q.plane2, lo, max(lo, hi)))
    return q


def _gauss_newton(d, p, effects, path, resp, n_steps=2):
    """Safeguarded Gauss-Newton on the mean parameters; never increases the weighted SSE."""
    names = _mean_names(effects, d.nb)
    sig = p.sigma[d.bi]
    q0 = _weighted_sse(d, p, effects, path, resp)
    info = None
    for _ in range(n_steps):
        mu, jac = _predict(d, p, effects, path, names)
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
        v0 = _get_vector(p, names)
        accepted = False
        for _half in range(30):
            cand = _set_vector(p, names, v0 + step)
            if _feasible(d, cand, effects):
                q1 = _weighted_sse(d, cand, effects, path, resp)
                if q1 <= q0:
                    p, q0, accepted = cand, q1, True
                    break
            step = 0.5 * step
        if not accepted or np.max(np.abs(step)) < 1e-10:
            break
    return p, names, info


def _m_step(d, p, effects, path, resp, sigma_floor, mp2_floor):
    p = p.copy()
    nb = d.nb
    counts = np.bincount(d.bi, minlength=nb).astype(float)
    w = np.stack([np.bincount(d.bi, weights=resp[:, c], minlength=nb) for c in range(4)], 1)
    p.weights = w / np.maximum(counts, 1.0)[:, None]
    p, names, info = _gauss_newton(d, p, effects, path, resp)
    mu = _predict(d, p, effects, path)
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
    params: _Params
    resp: np.ndarray
    loglik: float
    n_iter: int
    converged: bool
    path: str
    se: dict = field(default_factory=dict)
    history: list = field(default_factory=list)

    def magnitudes(self, data: _Ranges) -> dict:
        """Signed magnitude of every effect switched on (see :data:`UNITS`)."""
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

    def beacons(self, data: _Ranges) -> dict:
        """Per-beacon parameters: ``d0`` (plane height above the beacon at the first ping), ..."""
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


def _implied_depths(d, p, effects, path):
    """Per-range depth of the plane that would make each range a multipath."""
    k = 1.0 + (p.scale if "sound_speed" in effects else 0.0)
    b = p.bias if "range_bias" in effects else 0.0
    z = (d.z - b) / k
    _, _, h, dz = _offsets(d, p, effects)
    d0k = geometry.invert_plane_height(z, h, dz, path)
    return d.bz[d.bi] - d0k


def _modes(v, k):
    """The ``k`` strongest modes of the depths ``v`` (5 m bins, 25 m apart, > 4 ranges)."""
    return histogram_modes(v, k, min_count=4) if v.size >= 10 else []


def _second_starts(d, p, effects, path, resp):
    """Starts for a second plane: modes of the implied depths of poorly explained ranges.

    A beacon whose own plane sits on a candidate depth (its strongest multipath
    family may be the second plane's) also gets a start with its plane moved to
    its next mode, so that the shared plane and the beacon's own are not confused.
    """
    depth = _implied_depths(d, p, effects, path)
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
    resp, ll_i, mu = _e_step(d, p, effects, path)
    ll = float(ll_i.sum())
    hist = [ll]
    converged = False
    info, names = None, _mean_names(effects, d.nb)
    for it in range(1, max_iter + 1):
        p, names, info = _m_step(d, p, effects, path, resp, sigma_floor, mp2_floor)
        resp, ll_i, mu = _e_step(d, p, effects, path)
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


def _baseline_start(d: _Ranges, fittable, path, rng):
    """Per-beacon mixture-EM fits as the joint baseline's start; ``path="auto"`` picks the
    multipath geometry with the higher total likelihood. Returns ``(params, path, logliks)``."""
    nb = d.nb
    paths = geometry.PATHS if path == "auto" else (path,)
    best, logliks = None, {}
    seed = int(as_generator(rng).integers(2**31))
    for pth in paths:
        plane = np.empty(nb)
        sigma = np.empty((nb, 3))
        weights = np.zeros((nb, 4))
        total = 0.0
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # flags are reported on the joint fit instead
            for j, data in enumerate(fittable):
                r = fit_mixture_em(data, path=pth, rng=seed + j)
                plane[j] = d.bz[j] - r.d0
                sigma[j] = (r.sigma_dp, r.sigma_mp, r.sigma_mp)
                weights[j] = (r.weights["dp"], r.weights["mp"], 0.0, r.weights["ol"])
                total += float(r.loglik)
        logliks[pth] = total
        if best is None or total > best[2]:
            best = (_Params(plane=plane, sigma=sigma, weights=weights), pth, total)
    return best[0], best[1], logliks


def _start_for(d, base: JointFit, effects, path):
    """Starting points for a model with ``effects``, from a fit of a nested model."""
    p = base.params.copy()
    if "second_reflector" in effects and "second_reflector" not in base.effects:
        return _second_starts(d, p, effects, path, base.resp)
    return [p]


def fit_joint(d: _Ranges, effects, start: _Params | list, *, path="triangle", max_iter=300,
              tol=1e-7, sigma_floor=0.05) -> JointFit:
    """Fit the joint model with ``effects`` from one or several starting points (best kept).

    Parameters
    ----------
    d : _Ranges
        The replies (``Diagnosis.data``).
    effects : tuple of str
        Extensions switched on (names of :data:`EFFECTS`).
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
        if not _feasible(d, s, effects):
            s = _repair(d, s, effects)
            if not _feasible(d, s, effects):
                continue
        r = _run(d, s, effects, path, max_iter=max_iter, tol=tol, sigma_floor=sigma_floor)
        if best is None or r.loglik > best.loglik:
            best = r
    if best is None:
        raise ValueError(f"no feasible starting point for the model with {sorted(effects)}")
    return best


def _replant(d: _Ranges, fit: JointFit, fittable, path, rng) -> _Params | None:
    """A fresh start for ``fit``'s model: each beacon's plane, scales and weights re-found by
    the per-beacon mixture EM (its multi-start over plane heights) on ranges corrected by the
    fitted bias, scale and navigation drift. ``None`` when no plane moves by more than 5 m.

    A beacon whose baseline plane was pulled to a wrong family (e.g. the direct path of a
    mis-scaled survey) stays there when the effect is switched on; this gives it a way out.
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
            if np.any(z <= 0):
                continue
            corrected = replace(data, range=z, x=x, y=y)
            try:
                r = fit_mixture_em(corrected, path=path, rng=rng, n_init=4)
            except ValueError:
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


def _heldout(d: _Ranges, effects, full: JointFit, folds, path, **kw):
    """Per-range held-out log predictive density, K-fold, each fold warm-started at ``full``."""
    out = np.empty(d.n)
    for k in np.unique(folds):
        test = folds == k
        fit_k = _run(d.subset(~test), full.params.copy(), full.effects, path, **kw)
        dt = d.subset(test)
        _, ll_i, _ = _e_step(dt, fit_k.params, effects, path)
        out[test] = ll_i
    return out


@dataclass(frozen=True)
class Effect:
    """One effect found in the data.

    Attributes
    ----------
    name : str
        One of :data:`EFFECTS`.
    magnitude : float
        Signed size in :attr:`unit` (see :data:`UNITS`).
    unit : str
    beacons : list of str
        Beacons it was fitted on (all fitted beacons: every effect is shared).
    delta_elpd, delta_elpd_se : float
        Gain in held-out log predictive density (nats) over the model without
        it when it was added, and its standard error.
    magnitude_se : float or None
        Approximate standard error of the magnitude.
    evidence : str
        A sentence a person can read.
    detail : dict
        Extra numbers (e.g. the drift's direction).
    """

    name: str
    magnitude: float
    unit: str
    beacons: list
    delta_elpd: float
    delta_elpd_se: float
    magnitude_se: float | None
    evidence: str
    detail: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """JSON-ready dict."""
        return {"name": self.name, "magnitude": self.magnitude, "unit": self.unit,
                "beacons": list(self.beacons), "delta_elpd": self.delta_elpd,
                "delta_elpd_se": self.delta_elpd_se, "magnitude_se": self.magnitude_se,
                "evidence": self.evidence, **({"detail": self.detail} if self.detail else {})}


@dataclass
class Diagnosis:
    """What :func:`diagnose` found.

    Attributes
    ----------
    effects : list of Effect
        Effects kept, in the order they were added; empty for clean data.
    baseline, final : JointFit
        The paper's model fitted to all beacons, and the model with the effects.
    candidates : list of dict
        Every extension tried: ``round``, ``name``, ``delta_elpd``, ``se``, ``kept``.
    residual_checks : list of dict
        Residual structure left by the final model (:func:`residual_checks`);
        ``unexplained`` lists the significant ones.
    skipped : dict
        Beacons left out, with the reason.
    survey : Survey
    settings : dict
    """

    effects: list
    baseline: JointFit
    final: JointFit
    candidates: list
    residual_checks: list
    skipped: dict
    survey: Survey = field(repr=False)
    data: _Ranges = field(repr=False)
    settings: dict = field(default_factory=dict)

    @property
    def unexplained(self) -> list:
        """Residual checks that fail under the final model."""
        return [c for c in self.residual_checks if c["significant"]]

    def to_dict(self) -> dict:
        """The content of ``diagnosis.json``."""
        d = self.data
        return {
            "effects": [e.to_dict() for e in self.effects],
            "beacons": self.baseline.beacons(d),
            "final_model": {"effects": self.final.magnitudes(d),
                            "beacons": self.final.beacons(d),
                            "loglik": self.final.loglik},
            "baseline_loglik": self.baseline.loglik,
            "candidates": self.candidates,
            "unexplained": self.unexplained,
            "residual_checks": self.residual_checks,
            "skipped_beacons": self.skipped,
            "settings": self.settings,
        }

    def write(self, out_dir, *, figures: bool = True) -> dict:
        """Write ``diagnosis.json`` (and the figures) to ``out_dir``.

        Parameters
        ----------
        out_dir : str or pathlib.Path
            Created if missing.
        figures : bool, default True

        Returns
        -------
        dict
            Paths written.
        """
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        paths = {"diagnosis": out / "diagnosis.json"}
        paths["diagnosis"].write_text(json.dumps(self.to_dict(), indent=2, default=_json) + "\n")
        if figures:
            from .diagnose_plots import write_figures

            paths.update(write_figures(self, out))
        return paths

    def summary(self) -> str:
        """A few lines for a terminal."""
        if not self.effects and not self.unexplained:
            lines = ["No effect found: the paper's model explains these data "
                     f"({len(self.candidates)} extensions tried, none clearly better)."]
        elif not self.effects:
            lines = ["No effect of the vocabulary predicts these data better "
                     f"({len(self.candidates)} extensions tried), but residual structure is "
                     "left that the model does not explain:"]
        else:
            lines = ["Effects found:"]
            for e in self.effects:
                lines.append(f"  {e.name}: {e.magnitude:+.4g} {e.unit}  ({e.evidence})")
        for c in self.unexplained:
            lines.append(f"  unexplained: {c['message']}")
        return "\n".join(lines)


def _json(v):
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    if isinstance(v, np.ndarray):
        return v.tolist()
    raise TypeError(f"not JSON serialisable: {type(v)}")


def _evidence(name, fit: JointFit, d: _Ranges, delta, se, n_folds):
    mag = fit.magnitudes(d)[name]
    gain = f"held-out log predictive density +{delta:.1f} ± {se:.1f} nats ({n_folds}-fold CV)"
    p = fit.params
    if name == "range_bias":
        what = f"ranges are {abs(mag):.2f} m too {'long' if mag > 0 else 'short'}"
    elif name == "sound_speed":
        what = (f"ranges are scaled by {1 + mag:.5f}: a sound speed {abs(mag) * 100:.2f} % too "
                f"{'high' if mag > 0 else 'low'}")
    elif name == "plane_drift":
        what = (f"the reflector moves {abs(mag):.2f} m {'deeper' if mag > 0 else 'shallower'} "
                "from the first to the last ping")
    elif name == "second_reflector":
        share = float(fit.resp[:, 2].mean())
        what = (f"{share * 100:.1f} % of replies bounce off a second plane {mag:.1f} m deep")
    elif name == "early_outliers":
        late = _late_share(d, fit)
        what = (f"{mag * 100:.1f} % of replies are outliers, all before the true arrival "
                f"(share after it: {late * 100:.1f} %)")
    else:
        err = -p.nav
        what = (f"the reported navigation is off by {mag:.1f} m at the last ping "
                f"(east {err[0]:+.1f} m, north {err[1]:+.1f} m), growing with time")
    return f"{what}; {gain}"


def _late_share(d, fit: JointFit):
    mu = _predict(d, fit.params, fit.effects, fit.path)
    p_ol = fit.resp[:, 3]
    late = (d.z > mu["dp"]) * p_ol
    return float(late.sum() / max(p_ol.sum(), 1e-12))


# --------------------------------------------------------------------------- residual checks

_COVARIATES = ("time", "range", "elevation", "vehicle_depth", "bearing")


def covariates(d: _Ranges) -> dict:
    """Per-reply covariates the residuals are checked against (reported navigation).

    Parameters
    ----------
    d : _Ranges
        ``Diagnosis.data``.

    Returns
    -------
    dict of numpy.ndarray
        ``time`` (s), ``range`` (direct-path length, m), ``elevation`` (deg,
        positive when the vehicle is above the beacon), ``vehicle_depth`` (m),
        ``bearing`` (deg clockwise from +y, of the vehicle seen from the beacon).
    """
    ex, ey, h, dz = _offsets(d)
    return {"time": d.time, "range": np.hypot(h, dz),
            "elevation": np.degrees(np.arctan2(dz, h)), "vehicle_depth": d.vdepth,
            "bearing": np.degrees(np.arctan2(ex, ey)) % 360.0}


def residual_checks(fit: JointFit, d: _Ranges, *, n_bins=10, alpha=1e-4) -> list:
    """Residual structure the model leaves, class by class, against each covariate.

    For the direct-path and multipath replies (class probability above 0.9) the
    standardised residuals are binned into ``n_bins`` quantile bins of each
    covariate (time, range, elevation angle, vehicle depth, bearing from the
    beacon) per beacon; the bin means are tested against zero with a
    chi-square test. A check is ``significant`` when its p-value is below
    ``alpha`` divided by the number of checks (Bonferroni).

    Parameters
    ----------
    fit : JointFit
    d : _Ranges
    n_bins : int, default 10
    alpha : float, default 1e-4

    Returns
    -------
    list of dict
        ``beacon``, ``class``, ``against``, ``chi2``, ``dof``, ``p_value``,
        ``max_bin_mean`` (m), ``significant``, ``message``.
    """
    from scipy import stats

    mu = _predict(d, fit.params, fit.effects, fit.path)
    p = fit.params
    cov = covariates(d)
    checks = []
    for c, name in enumerate(("dp", "mp")):
        for j, bid in enumerate(d.ids):
            sel = (d.bi == j) & (fit.resp[:, c] > 0.9)
            if sel.sum() < 5 * n_bins:
                continue
            sig = p.sigma[j, c]
            r = (d.z[sel] - mu[name][sel])
            for cname in _COVARIATES:
                v = cov[cname][sel]
                if np.ptp(v) <= 0:
                    continue
                edges = np.unique(np.quantile(v, np.linspace(0, 1, n_bins + 1)))
                idx = np.clip(np.searchsorted(edges, v, side="right") - 1, 0, edges.size - 2)
                nbin = np.bincount(idx, minlength=edges.size - 1)
                ok = nbin > 0
                means = np.bincount(idx, weights=r, minlength=edges.size - 1)[ok] / nbin[ok]
                chi2 = float(np.sum(means ** 2 * nbin[ok] / sig ** 2))
                dof = int(ok.sum())
                pval = float(stats.chi2.sf(chi2, dof))
                checks.append({"beacon": bid, "class": name, "against": cname, "chi2": chi2,
                               "dof": dof, "p_value": pval,
                               "max_bin_mean": float(np.max(np.abs(means)))})
    limit = alpha / max(len(checks), 1)
    for ch in checks:
        ch["significant"] = ch["p_value"] < limit
        ch["message"] = (f"beacon {ch['beacon']}: {ch['class']} residuals vary with "
                         f"{ch['against']} (bin means up to {ch['max_bin_mean']:.2f} m, "
                         f"p = {ch['p_value']:.1e})")
    return checks


# --------------------------------------------------------------------------- driver


def _check_effect_names(names, what):
    bad = [e for e in names if e not in EFFECTS]
    if bad:
        raise ValueError(f"{what}: unknown effect(s) {bad}; known: {list(EFFECTS)}")


def diagnose(
    pings,
    beacons=None,
    *,
    effects=EFFECTS,
    path: str = "auto",
    n_folds: int = 5,
    min_gain: float = 4.0,
    min_z: float = 2.0,
    max_effects: int = 3,
    min_pings: int = 30,
    rng: RNGLike = None,
    progress: bool = True,
) -> Diagnosis:
    """Find which of the paper's assumptions the survey breaks, and by how much.

    Parameters
    ----------
    pings : str, pathlib.Path, pandas.DataFrame or Survey
        The pings table (``docs/input.md``) or a loaded survey.
    beacons : str, pathlib.Path or pandas.DataFrame, optional
        The beacons table (not needed with a Survey).
    effects : sequence of str, default all of :data:`EFFECTS`
        The candidate extensions.
    path : {"auto", "triangle", "double"}
        Multipath geometry: one reflected leg (the paper's finding), both, or
        (default) whichever gives the baseline the higher likelihood.
    n_folds : int, default 5
        Folds of the cross-validation (replies assigned at random).
    min_gain : float, default 4
        An effect is kept only if it raises the held-out log predictive
        density by more than this many nats ...
    min_z : float, default 2
        ... and by more than ``min_z`` standard errors of that gain.
    max_effects : int, default 3
        Stop after this many effects.
    min_pings : int, default 30
        Beacons with fewer replies are left out.
    rng : None, int or numpy.random.Generator
        Seeds the folds and the baseline's starts.
    progress : bool, default True
        Print one line per step to stderr.

    Returns
    -------
    Diagnosis

    Raises
    ------
    bayes_mpem.data.InputError
        For invalid input.
    ValueError
        For invalid options, or fewer than two beacons to fit.
    """
    import sys

    if path != "auto":
        geometry.check_path(path)
    effects = tuple(effects)
    _check_effect_names(effects, "effects")
    if int(n_folds) < 2:
        raise ValueError(f"n_folds: expected an integer >= 2, got {n_folds!r}")
    survey = load_survey(pings, beacons)
    gen = as_generator(rng)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fittable, skipped = fittable_beacons(survey, min_pings)
    skipped = dict(skipped)
    if not fittable:
        raise ValueError(f"no beacon has at least min_pings={min_pings} replies: {skipped}")
    d = _ranges(survey, fittable)
    folds = gen.permutation(np.arange(d.n) % int(n_folds))
    kw = {"max_iter": 300, "tol": 1e-7, "sigma_floor": 0.05}

    def say(msg):
        if progress:
            print(f"[diagnose] {msg}", file=sys.stderr, flush=True)

    start, path, path_ll = _baseline_start(d, fittable, path, gen)
    seed = int(gen.integers(2**31))
    base = fit_joint(d, (), start, path=path, **kw)
    say(f"baseline: {d.n} replies, {d.nb} beacons, {path} multipath, "
        f"log-likelihood {base.loglik:.1f}")
    current = base
    cur_ho = _heldout(d, (), base, folds, path, **kw)
    kept, candidates = [], []
    for rnd in range(1, int(max_effects) + 1):
        trials = []
        for name in effects:
            if name in current.effects:
                continue
            eff = tuple(sorted(set(current.effects) | {name}, key=EFFECTS.index))
            starts = _start_for(d, current, eff, path)
            if not starts:
                candidates.append({"round": rnd, "name": name, "delta_elpd": None, "se": None,
                                   "kept": False, "note": "no starting point"})
                continue
            try:
                fit_e = fit_joint(d, eff, starts, path=path, **kw)
            except ValueError as err:
                candidates.append({"round": rnd, "name": name, "delta_elpd": None, "se": None,
                                   "kept": False, "note": str(err)})
                continue
            fresh = _replant(d, fit_e, fittable, path, seed)
            if fresh is not None:
                try:
                    alt = fit_joint(d, eff, fresh, path=path, **kw)
                    if alt.loglik > fit_e.loglik:
                        fit_e = alt
                except ValueError:
                    pass
            ho = _heldout(d, eff, fit_e, folds, path, **kw)
            diff = ho - cur_ho
            delta = float(diff.sum())
            se = float(np.sqrt(d.n * np.var(diff)))
            why_not = _not_credible(name, fit_e, d)
            if why_not is None:
                trials.append((delta, se, name, fit_e, ho))
            candidates.append({"round": rnd, "name": name, "delta_elpd": delta, "se": se,
                               "magnitude": fit_e.magnitudes(d)[name], "kept": False,
                               **({"note": why_not} if why_not else {})})
            say(f"round {rnd}: {name:16s} delta elpd {delta:+10.1f} ± {se:.1f}")
        good = [t for t in trials if t[0] > min_gain and t[0] > min_z * t[1]]
        if not good:
            break
        delta, se, name, fit_e, ho = max(good, key=lambda t: t[0])
        for c in candidates:
            if c["round"] == rnd and c["name"] == name:
                c["kept"] = True
        mag = fit_e.magnitudes(d)[name]
        kept.append((name, delta, se))
        current, cur_ho = fit_e, ho
        say(f"kept {name} = {mag:+.4g} {UNITS[name]}")
    found = []
    for name, delta, se in kept:
        mags = current.magnitudes(d)
        found.append(Effect(
            name=name, magnitude=mags[name], unit=UNITS[name], beacons=list(d.ids),
            delta_elpd=delta, delta_elpd_se=se, magnitude_se=_magnitude_se(name, current),
            evidence=_evidence(name, current, d, delta, se, int(n_folds)),
            detail=_detail(name, current)))
    checks = residual_checks(current, d)
    settings = {"path": path, "path_loglik": path_ll, "n_folds": int(n_folds),
                "min_gain": float(min_gain),
                "min_z": float(min_z), "max_effects": int(max_effects),
                "candidates": list(effects), "min_pings": int(min_pings)}
    return Diagnosis(effects=found, baseline=base, final=current, candidates=candidates,
                     residual_checks=checks, skipped=skipped, survey=survey, data=d,
                     settings=settings)


#: A second family must hold at least this share of the replies (and 20 of them).
MIN_SECOND_SHARE = 0.01


def _not_credible(name, fit: JointFit, d: _Ranges):
    """Why a fitted extension is not a physical effect (``None`` if it is)."""
    if name != "second_reflector":
        return None
    share = float(fit.resp[:, 2].mean())
    if share < MIN_SECOND_SHARE or share * d.n < 20:
        return (f"the second family holds {share * 100:.2f} % of the replies "
                f"(< {MIN_SECOND_SHARE * 100:g} % or < 20 replies): a few coincident ranges, "
                "not a reflector")
    if fit.params.plane2 - (_main_plane(fit.params) + _SECOND_GAP) < 1.0:
        return (f"the second plane sits on its bound ({_SECOND_GAP:g} m below the main "
                "reflector): not located")
    return None


def _magnitude_se(name, fit: JointFit):
    se = fit.se
    if name == "range_bias":
        return se.get("bias")
    if name == "sound_speed":
        return se.get("scale")
    if name == "plane_drift":
        return se.get("drift")
    if name == "second_reflector":
        return se.get("plane2")
    if name == "nav_drift" and "nav_x" in se:
        return float(np.hypot(se["nav_x"], se["nav_y"]) / np.sqrt(2.0))
    return None


def _detail(name, fit: JointFit):
    p = fit.params
    if name == "nav_drift":
        err = -p.nav
        return {"east_at_last_ping": float(err[0]), "north_at_last_ping": float(err[1]),
                "direction_deg": float(np.degrees(np.arctan2(err[1], err[0])) % 360.0)}
    if name == "second_reflector":
        return {"fraction": float(fit.resp[:, 2].mean())}
    return {}
