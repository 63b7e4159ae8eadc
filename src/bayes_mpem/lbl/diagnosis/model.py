"""Model (moved from ``diagnose``)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ...io.survey import Survey
from ...mixture.densities import LOG_SQRT_2PI
from .. import geometry

#: The vocabulary of effects, in the order they are tried.
EFFECTS = ("range_bias", "sound_speed", "plane_drift", "second_reflector", "early_outliers",
           "nav_drift")
#: Unit of each effect's magnitude.
UNITS = {"range_bias": "m", "sound_speed": "1", "plane_drift": "m", "second_reflector": "m",
         "early_outliers": "1", "nav_drift": "m"}
_EPS_LATE = 1e-3  # share of the early-outlier density left over the whole window


# --------------------------------------------------------------------------- data


@dataclass(frozen=True)
class Ranges:
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

    def subset(self, mask) -> Ranges:
        """The same survey restricted to ``mask`` (windows and beacons kept)."""
        return replace(self, **{k: getattr(self, k)[mask] for k in
                                ("z", "x", "y", "vdepth", "time", "tau", "bi", "rows")})


def ranges(survey: Survey, fittable) -> Ranges:
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


@dataclass
class Params:
    plane: np.ndarray       # (B,) plane depth at the first ping
    sigma: np.ndarray       # (B, 3) dp, mp, mp2
    weights: np.ndarray     # (B, 4) dp, mp, mp2, ol
    bias: float = 0.0
    scale: float = 0.0      # f = factor - 1
    drift: float = 0.0      # plane depth change, first -> last ping
    plane2: float = np.nan  # second plane depth
    nav: np.ndarray = field(default_factory=lambda: np.zeros(2))  # correction at the last ping

    def copy(self) -> Params:
        return Params(self.plane.copy(), self.sigma.copy(), self.weights.copy(), self.bias,
                       self.scale, self.drift, self.plane2, self.nav.copy())


def mean_names(effects, nb):
    names = [("plane", j) for j in range(nb)]
    for e, keys in (("range_bias", ["bias"]), ("sound_speed", ["scale"]),
                    ("plane_drift", ["drift"]), ("second_reflector", ["plane2"]),
                    ("nav_drift", ["nav_x", "nav_y"])):
        if e in effects:
            names += [(k, None) for k in keys]
    return names


def get_vector(p: Params, names):
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


def set_vector(p: Params, names, v) -> Params:
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


def offsets(d: Ranges, p: Params | None = None, effects=()):
    """Vehicle minus beacon ``(ex, ey)``, horizontal distance ``h`` and ``dz = z_beacon -
    z_vehicle`` of every reply; navigation corrected when ``nav_drift`` is switched on."""
    ex = d.x - d.bx[d.bi]
    ey = d.y - d.by[d.bi]
    if "nav_drift" in effects:
        ex = ex + p.nav[0] * d.tau
        ey = ey + p.nav[1] * d.tau
    return ex, ey, np.hypot(ex, ey), d.bz[d.bi] - d.vdepth


def predict(d: Ranges, p: Params, effects, path, names=None):
    """Class means ``{"dp", "mp"[, "mp2"]}`` and, with ``names``, their Jacobians."""
    ex, ey, h, dz = offsets(d, p, effects)
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


def _log_dens(d: Ranges, p: Params, effects, path, mu=None):
    """(n, 4) log densities of every range under dp, mp, mp2, ol (mp2 = -inf when off)."""
    if mu is None:
        mu = predict(d, p, effects, path)
    sig = p.sigma[d.bi]
    out = np.empty((d.n, 4))
    for c, name in enumerate(("dp", "mp", "mp2")):
        if name in mu:
            r = (d.z - mu[name]) / sig[:, c]
            out[:, c] = -0.5 * r * r - np.log(sig[:, c]) - LOG_SQRT_2PI
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


def e_step(d, p, effects, path, mu=None):
    ld, mu = _log_dens(d, p, effects, path, mu)
    with np.errstate(divide="ignore"):
        lw = np.log(p.weights)[d.bi]
    a = ld + lw
    m = np.max(a, axis=1)
    e = np.exp(a - m[:, None])
    s = e.sum(axis=1)
    return e / s[:, None], m + np.log(s), mu


def weighted_sse(d, p, effects, path, resp):
    mu = predict(d, p, effects, path)
    sig = p.sigma[d.bi]
    tot = 0.0
    for c, name in enumerate(("dp", "mp", "mp2")):
        if name in mu:
            r = d.z - mu[name]
            tot += float(np.sum(resp[:, c] * r * r / (sig[:, c] * sig[:, c])))
    return tot


SECOND_GAP = 50.0  # m: the second plane lies at least this far below the main reflector


def main_plane(p: Params) -> float:
    """Depth of the main reflector: the median of the beacons' planes."""
    return float(np.median(p.plane))


def is_feasible(d, p, effects):
    """Planes above the vehicle at every ping; the second plane below the main one."""
    plane = p.plane[d.bi] + (p.drift * d.tau if "plane_drift" in effects else 0.0)
    ok = bool(np.all(plane <= d.vdepth))
    if "second_reflector" in effects:
        ok = ok and main_plane(p) + SECOND_GAP <= p.plane2 <= float(np.min(d.vdepth))
    if "sound_speed" in effects:
        ok = ok and abs(p.scale) < 0.5
    return ok


def repair(d, p, effects) -> Params:
    """Move an infeasible start just inside the constraints (planes 0.5 m above the vehicle)."""
    q = p.copy()
    drift = q.drift * d.tau if "plane_drift" in effects else np.zeros(d.n)
    for j in range(d.nb):
        sel = d.bi == j
        if sel.any():
            q.plane[j] = min(q.plane[j], float(np.min(d.vdepth[sel] - drift[sel])) - 0.5)
    if "second_reflector" in effects:
        lo, hi = main_plane(q) + SECOND_GAP, float(np.min(d.vdepth)) - 0.5
        q.plane2 = float(np.clip(q.plane2, lo, max(lo, hi)))
    return q


def implied_depths(d, p, effects, path):
    """Per-range depth of the plane that would make each range a multipath."""
    k = 1.0 + (p.scale if "sound_speed" in effects else 0.0)
    b = p.bias if "range_bias" in effects else 0.0
    z = (d.z - b) / k
    _, _, h, dz = offsets(d, p, effects)
    d0k = geometry.invert_plane_height(z, h, dz, path)
    return d.bz[d.bi] - d0k
