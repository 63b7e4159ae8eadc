"""The joint model of the diagnosis: all beacons' replies, the effects, the class densities."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ...io.survey import Survey
from ...mixture.densities import (
    first_arrival_logpdf,
    gaussian_logpdf,
    responsibilities,
    safe_log,
    uniform_logpdf,
)
from ..model import geometry
from .params import Params, beacon_mask

# --------------------------------------------------------------------------- data


@dataclass(frozen=True)
class Ranges:
    """All replies of the fitted beacons, concatenated; per-range beacon index ``bi``.

    Attributes
    ----------
    z, x, y, vdepth, time : numpy.ndarray
        Per reply: the range, the vehicle's position and depth (m), the time (s).
    tau : numpy.ndarray
        Per reply: the time normalised to ``[0, 1]`` over the survey.
    bi : numpy.ndarray
        Per reply: the index of its beacon in ``ids``.
    rows : numpy.ndarray
        Per reply: its row in the input pings table.
    bx, by, bz, lo, hi : numpy.ndarray
        Per beacon: its position and outlier window ``[lo, hi]`` (m).
    ids : tuple of str
    """

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
        """Number of replies."""
        return int(self.z.size)

    @property
    def nb(self) -> int:
        """Number of beacons."""
        return len(self.ids)

    def subset(self, mask) -> Ranges:
        """Keep the replies of ``mask`` (boolean or indices); windows and beacons kept."""
        return replace(self, **{k: getattr(self, k)[mask] for k in
                                ("z", "x", "y", "vdepth", "time", "tau", "bi", "rows")})


def ranges(survey: Survey, fittable) -> Ranges:
    """Concatenate the replies of the fitted beacons (outlier windows: their range span).

    Parameters
    ----------
    survey : Survey
        The whole survey (its first and last ping set ``tau``).
    """
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
    return Ranges(**cat, tau=(cat["time"] - t0) / span, bx=pos[:, 0], by=pos[:, 1],
                   bz=pos[:, 2], lo=np.asarray(lo), hi=np.maximum(np.asarray(hi),
                                                                  np.asarray(lo) + 1e-6),
                   ids=tuple(d.beacon for d in fittable))


# --------------------------------------------------------------------------- model


def offsets(d: Ranges, p: Params | None = None, effects=()):
    """Offsets of the vehicle from the beacon at every reply (navigation and positions corrected).

    Parameters
    ----------
    p : Params, optional
        Needed with ``nav_drift`` or a ``beacon_position`` term.

    Returns
    -------
    ex, ey, h, dz : numpy.ndarray
        Vehicle minus beacon (east, north), horizontal distance, ``z_beacon - z_vehicle`` (m).
    """
    bx, by, bz = d.bx[d.bi], d.by[d.bi], d.bz[d.bi]
    if p is not None:
        on = beacon_mask(effects, "beacon_position", d.ids)
        if on.any():
            corr = np.where(on[:, None], p.bpos, 0.0)[d.bi]
            bx, by, bz = bx + corr[:, 0], by + corr[:, 1], bz + corr[:, 2]
    ex = d.x - bx
    ey = d.y - by
    if "nav_drift" in effects:
        ex = ex + p.nav[0] * d.tau
        ey = ey + p.nav[1] * d.tau
    return ex, ey, np.hypot(ex, ey), bz - d.vdepth


def biases(d: Ranges, p: Params, effects):
    """Return the range bias of every reply: the shared one plus its beacon's own (m)."""
    b = np.full(d.n, p.bias if "range_bias" in effects else 0.0)
    on = beacon_mask(effects, "beacon_bias", d.ids)
    if on.any():
        b = b + np.where(on, p.bbias, 0.0)[d.bi]
    return b


def predict(d: Ranges, p: Params, effects, path, names=None):
    """Class means and, with ``names``, their Jacobians.

    Parameters
    ----------
    names : list of tuple, optional
        Mean parameters (:func:`~bayes_mpem.lbl.diagnosis.params.mean_names`).

    Returns
    -------
    mu : dict of numpy.ndarray
        ``"dp"``, ``"mp"`` and (with ``second_reflector``) ``"mp2"``.
    jac : dict of numpy.ndarray
        Only with ``names``: per class, ``(n, len(names))`` derivatives.
    """
    ex, ey, h, dz = offsets(d, p, effects)
    bz = dz + d.vdepth  # the beacon's depth, corrected where its position is fitted
    direct = np.hypot(h, dz)
    plane = p.plane[d.bi] + (p.drift * d.tau if "plane_drift" in effects else 0.0)
    d0 = bz - plane
    k = 1.0 + (p.scale if "sound_speed" in effects else 0.0)
    b = biases(d, p, effects)
    mp = geometry.multipath_range(h, dz, d0, path, direct=direct)
    mu = {"dp": k * direct + b, "mp": k * mp + b}
    second = "second_reflector" in effects
    if second:
        d02 = bz - p.plane2
        mp2 = geometry.multipath_range(h, dz, d02, path, direct=direct)
        mu["mp2"] = k * mp2 + b
    if names is None:
        return mu
    jac = {c: np.zeros((d.n, len(names))) for c in mu}
    dmp_dd0 = geometry.multipath_derivative(h, dz, d0, path)
    levers = [2.0 * d0 - dz] + ([2.0 * d02 - dz] if second else [])
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
            jac["mp2"][:, col] = _plane2_derivative(h, dz, d02, path, k)
        elif key in ("nav_x", "nav_y"):
            _nav_columns(jac, col, ex if key == "nav_x" else ey, d.tau, direct,
                         [geometry.reflected_leg(h, dz, d0)]
                         + ([geometry.reflected_leg(h, dz, d02)] if second else []),
                         path, k)
        else:
            _beacon_columns(jac, col, key, d.bi == j, (ex, ey, dz, direct, h), levers,
                            path, k)
    return mu, jac


def _beacon_columns(jac, col, key, sel, geo, levers, path, k):
    """Fill column ``col`` with ``d mu / d`` a beacon's own bias or position correction."""
    if key == "bbias":
        for c in jac:
            jac[c][sel, col] = 1.0
        return
    ex, ey, dz, direct, h = (g[sel] for g in geo)
    # d(length)/d(correction): the vehicle offset shrinks as the beacon moves towards it;
    # a deeper beacon lengthens dz, and the reflected leg's lever 2 d0 - dz by as much
    lever_arms = {"bpos_x": -ex, "bpos_y": -ey}
    dd = (lever_arms[key] if key in lever_arms else dz) / np.maximum(direct, 1e-9)
    jac["dp"][sel, col] = k * dd
    for name, lever in zip(("mp", "mp2"), levers, strict=False):
        lev = lever[sel]
        refl = np.maximum(np.hypot(h, lev), 1e-9)
        dr = (lever_arms[key] if key in lever_arms else lev) / refl
        jac[name][sel, col] = k * (0.5 * (dd + dr) if path == "triangle" else dr)


def _plane2_derivative(h, dz, d02, path, k):
    """``d mu_mp2 / d plane2 = -k d z_MP / d d0`` at the second plane.

    ``multipath_derivative`` up to rounding; this operation order keeps the fits bit-identical.
    """
    half = 0.5 if path == "triangle" else 1.0
    lever2 = 2.0 * d02 - dz
    return -k * half * 2.0 * lever2 / np.maximum(np.hypot(h, lever2), 1e-9)


def _nav_columns(jac, col, e, tau, direct, refl, path, k):
    """Fill column ``col`` of every class with ``d mu / d nav`` along offset ``e``."""
    dd = e * tau / np.maximum(direct, 1e-9)
    jac["dp"][:, col] = k * dd
    for name, r in zip(("mp", "mp2"), refl, strict=False):
        dr = e * tau / np.maximum(r, 1e-9)
        jac[name][:, col] = k * (0.5 * (dd + dr) if path == "triangle" else dr)


def _log_densities(d: Ranges, p: Params, effects, path, mu=None):
    """Log densities of every range under each class."""
    if mu is None:
        mu = predict(d, p, effects, path)
    sig = p.sigma[d.bi]
    out = np.empty((d.n, 4))
    for c, name in enumerate(("dp", "mp", "mp2")):
        if name in mu:
            out[:, c] = gaussian_logpdf(d.z - mu[name], sig[:, c])
        else:
            out[:, c] = -np.inf
    lo, hi = d.lo[d.bi], d.hi[d.bi]
    if "early_outliers" in effects:
        out[:, 3] = first_arrival_logpdf(d.z, mu["dp"], lo, hi, min_early=1.0)
    else:
        out[:, 3] = uniform_logpdf(lo, hi)
    return out, mu


def e_step(d, p, effects, path, mu=None):
    """Class probabilities and per-range log-likelihood at ``p``.

    Parameters
    ----------
    mu : dict, optional
        The class means (:func:`predict`), when already computed.

    Returns
    -------
    resp : numpy.ndarray
        ``(n, 4)`` class probabilities (dp, mp, mp2, ol).
    loglik : numpy.ndarray
    mu : dict
    """
    ld, mu = _log_densities(d, p, effects, path, mu)
    resp, loglik = responsibilities(ld + safe_log(p.weights)[d.bi])
    return resp, loglik, mu


def weighted_sse(d, p, effects, path, resp):
    """Weighted squared error of the Gaussian classes, ``sum resp (z - mu)**2 / sigma**2``."""
    mu = predict(d, p, effects, path)
    sig = p.sigma[d.bi]
    tot = 0.0
    for c, name in enumerate(("dp", "mp", "mp2")):
        if name in mu:
            r = d.z - mu[name]
            tot += float(np.sum(resp[:, c] * r * r / (sig[:, c] * sig[:, c])))
    return tot


def implied_depths(d, p, effects, path):
    """Per-range depth of the plane that would make each range a multipath (NaN where none).

    Parameters
    ----------
    effects : tuple of str
        The effects switched on are removed first.
    """
    k = 1.0 + (p.scale if "sound_speed" in effects else 0.0)
    z = (d.z - biases(d, p, effects)) / k
    _, _, h, dz = offsets(d, p, effects)
    d0k = geometry.invert_plane_height(z, h, dz, path)
    return dz + d.vdepth - d0k
