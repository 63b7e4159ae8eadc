"""`bayes-mpem locate` on GNSS-A campaigns from an independently written generator (issue 26).

The generator below was written from the physics, without reading the package's own model
or simulator (``survey_in/`` and ``acoustics/``); only the GARPOS file format was taken from
``io/garpos.py`` and ``docs/gnssa.md``, and the attitude convention (yaw-pitch-roll, heading
clockwise from north, pitch bow up, roll starboard down) from ``io/geodesy.py``'s docstring.
What it does differently from the model (``docs/gnssa.md``, "On an independently written
generator"):

* the sound speed is a Munk profile with a 50 m mixed layer, plus a near-surface change that
  is a sum of random sinusoids and an Ornstein-Uhlenbeck process (not a B-spline, not a scale
  of the profile), plus an internal-wave heave of the thermocline (an Ornstein-Uhlenbeck
  displacement with a mode-1 shape), plus horizontal gradients (a shallow one decaying over
  500 m and a deep one uniform in depth) whose size and direction drift in time;
* travel times are exact eigenrays through 1 m spherical shells (the Earth a sphere of the
  WGS84 Gaussian radius, the sea surface through the frame's origin) for the horizontally
  uniform part of the field at each leg's time, plus the gradients' delay to first order
  along that ray (``-int dc / c^2 ds``);
* the ship moves continuously between transmit and receive (the receive leg is solved with
  the ship's position at the true reception time), with heave, pitch, roll, crab angle and a
  lever arm; GNSS noise is white plus a time-correlated (Ornstein-Uhlenbeck) part; the logged
  attitude is noisy;
* outliers are late multipath replies (0.5-20 ms late) and spurious times (+-0.5 s), and some
  replies are missing.

Run ``python benchmarks/gnssa_independent.py SEEDS [VARIANT ...]``; variants ``full`` (the
default), ``static`` (no time-varying sound speed), ``meancast`` (svp.csv the campaign's
time-mean profile instead of the cast at the first shot), ``whitegnss`` (GNSS noise 2 cm
white), ``nograd`` (no gradients), ``clean`` (no noise, no outliers), ``nonoise``,
``nooutliers``, ``nothing`` (no field change, no noise: the frame check), ``narrow`` (the
circle's radius and the star's half-length a quarter of the depth: narrow tracks, the
star's just above ``auto``'s gate, where it is tested), ``hour`` and ``halfhour`` (campaigns
of 1 and 0.5 h: the gate's hour and the short campaigns' note), ``hourbad`` and
``halfhourbad`` (the same with the site file's positions 6 m from the truth, sd per
coordinate, while its sigmas say 3 m: priors that understate their error); a variant ending
in ``+gradoff`` locates with ``--gradients off``, one in ``+corroff`` with ``--correlation
off``, one in ``+prioroff`` with ``--position-prior off`` (the site file's 3 m sigmas not
used as priors), instead of the defaults. Writes the section ``gnssa-independent[-VARIANTS]`` of
``docs/gnssa.md``.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import sys
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one thread: the machine is shared

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
DOC = HERE.parent / "docs" / "gnssa.md"
AXES = ("east", "north", "up")
STATIONS = ("M11", "M12", "M13", "M14")
WGS84_A, WGS84_F = 6378137.0, 1.0 / 298.257223563
DZ = 1.0  # ray-tracing layer thickness (m)
Z_MAX = 3300.0  # deepest level of the profile (m)


@dataclass(frozen=True)
class Config:
    """One campaign's settings; ``scenario`` A (circle, all four per shot) or B (star, in turn)."""

    scenario: str = "A"
    hours: float = 6.0
    depth: float = 3000.0
    side: float = 1500.0
    profile: str = "munk"  # or "constant" (1500 m/s everywhere: straight rays)
    varying: bool = True  # the time-varying part of the sound speed
    gradients: bool = True
    noise: bool = True  # GNSS, timing and attitude noise
    outliers: bool = True
    lat: float = 38.0
    lon: float = 143.5
    earth: str = "sphere"  # or "flat" (a radius of 1e9 m: flat layers, for checks)
    gnss_ou: bool = True  # the correlated part of the GNSS noise (else 2 cm white)
    cast: str = "first"  # svp.csv: the profile at the first shot, or "mean" over the campaign
    radius: float = 1.0  # the circle's radius and the star's half-length, in depths
    prior_error: float = 2.0  # sd of the site file's positions about the truth (m; it says 3)


VARIANTS = {
    "full": {},
    "static": {"varying": False},
    "nograd": {"gradients": False},
    "clean": {"noise": False, "outliers": False},
    "meancast": {"cast": "mean"},
    "whitegnss": {"gnss_ou": False},
    "nonoise": {"noise": False},
    "nooutliers": {"outliers": False},
    "nothing": {"varying": False, "gradients": False, "noise": False, "outliers": False},
    "narrow": {"radius": 0.25},
    "hour": {"hours": 1.0},
    "halfhour": {"hours": 0.5},
    "hourbad": {"hours": 1.0, "prior_error": 6.0},
    "halfhourbad": {"hours": 0.5, "prior_error": 6.0},
}


def gaussian_radius(lat):
    """Gaussian mean radius sqrt(M N) of the WGS84 ellipsoid at latitude ``lat`` (degrees)."""
    e2 = WGS84_F * (2.0 - WGS84_F)
    s2 = np.sin(np.radians(lat)) ** 2
    m = WGS84_A * (1.0 - e2) / (1.0 - e2 * s2) ** 1.5
    n = WGS84_A / np.sqrt(1.0 - e2 * s2)
    return float(np.sqrt(m * n))


def ou_path(rng, t_grid, sd, tau):
    """An Ornstein-Uhlenbeck path of stationary sd ``sd`` and time scale ``tau`` on ``t_grid``."""
    out = np.empty(t_grid.size)
    out[0] = rng.normal(0.0, sd)
    a = np.exp(-np.diff(t_grid) / tau)
    eps = rng.normal(0.0, 1.0, t_grid.size - 1) * sd * np.sqrt(1.0 - a**2)
    for i in range(1, t_grid.size):
        out[i] = a[i - 1] * out[i - 1] + eps[i - 1]
    return out


class Ocean:
    """The sound-speed field c(x, y, z, t) = c0(z) + uniform(z, t) + gradient . (x - x0)."""

    def __init__(self, cfg: Config, rng, centre):
        self.cfg, self.centre = cfg, np.asarray(centre[:2], float)
        span = cfg.hours * 3600.0 + 900.0
        self.tg = np.arange(-300.0, span, 10.0)
        # near-surface change: 4 random sinusoids (periods 1.5-12 h) + OU (0.3 m/s, 20 min)
        per = rng.uniform(1.5, 12.0, 4) * 3600.0
        amp = rng.uniform(0.4, 1.0, 4)
        ph = rng.uniform(0, 2 * np.pi, 4)
        surf = (amp[:, None] * np.sin(2 * np.pi * self.tg[None, :] / per[:, None]
                                      + ph[:, None])).sum(0)
        self.surf = surf + ou_path(rng, self.tg, 0.3, 1200.0)
        # internal-wave heave of the thermocline: OU, sd 10 m, 40 min, mode-1 shape
        self.heave = ou_path(rng, self.tg, 10.0, 2400.0)
        # gradients, (m/s)/m: shallow (surface value ~3e-4, e-fold 500 m), deep (~2e-5)
        self.g_s = (rng.uniform(2e-4, 4e-4), rng.uniform(0, 2 * np.pi),
                    rng.choice([-1, 1]) * rng.uniform(0.5, 1.5) / 21600.0,
                    rng.uniform(8, 16) * 3600.0, rng.uniform(0, 2 * np.pi))
        self.g_d = (rng.uniform(1e-5, 3e-5), rng.uniform(0, 2 * np.pi),
                    rng.choice([-1, 1]) * rng.uniform(0.3, 1.0) / 21600.0,
                    rng.uniform(8, 16) * 3600.0, rng.uniform(0, 2 * np.pi))

    def c0(self, z):
        """The background profile (m/s) at depth ``z`` (m)."""
        if self.cfg.profile == "constant":
            return np.full_like(np.asarray(z, float), 1500.0)
        zz = np.maximum(np.asarray(z, float), 50.0)  # a 50 m mixed layer
        eta = 2.0 * (zz - 1300.0) / 1300.0
        return 1500.0 * (1.0 + 0.00737 * (eta - 1.0 + np.exp(-eta)))

    def dc0(self, z):
        """d c0 / dz (1/s)."""
        if self.cfg.profile == "constant":
            return np.zeros_like(np.asarray(z, float))
        z = np.asarray(z, float)
        eta = 2.0 * (z - 1300.0) / 1300.0
        return np.where(z < 50.0, 0.0, 1500.0 * 0.00737 * (2.0 / 1300.0) * (1.0 - np.exp(-eta)))

    def uniform(self, z, t):
        """The horizontally uniform change (m/s) at depths ``z`` (K,) and times ``t`` (N,)."""
        if not self.cfg.varying:
            return np.zeros((np.size(t), np.size(z)))
        s = np.interp(t, self.tg, self.surf)[:, None]
        h = np.interp(t, self.tg, self.heave)[:, None]
        w = np.exp(-(np.maximum(z - 50.0, 0.0) / 150.0) ** 2)[None, :]
        mode = np.sin(np.pi * np.clip(z, 0, self.cfg.depth) / self.cfg.depth)[None, :]
        return s * w - h * mode * self.dc0(z)[None, :]

    def gradient(self, z, t):
        """East and north gradients of c ((m/s)/m), each (N, K)."""
        if not self.cfg.gradients:
            zero = np.zeros((np.size(t), np.size(z)))
            return zero, zero
        t = np.asarray(t, float)[:, None]
        out = []
        for (mag, az0, rate, per, ph), shape in ((self.g_s, np.exp(-z / 500.0)),
                                                 (self.g_d, np.ones_like(z))):
            m = mag * (1.0 + 0.3 * np.sin(2 * np.pi * t / per + ph))
            az = az0 + 2 * np.pi * rate * t
            out.append((m * np.sin(az) * shape[None, :], m * np.cos(az) * shape[None, :]))
        return out[0][0] + out[1][0], out[0][1] + out[1][1]


def leg_times(ocean, radius, src, dst, t):
    """One-way times (s) from ``src`` to ``dst`` (N, 3; east-north-up) at times ``t`` (N,).

    The exact eigenray through spherical shells DZ thick (Snell's law ``r sin(i) / c``
    conserved, a straight segment in each shell), found by Newton's method on the ray
    parameter; the horizontal gradients' delay added to first order along that ray.
    """
    out = np.empty(len(src))
    for lo in range(0, len(src), 400):
        sl = slice(lo, lo + 400)
        out[sl] = _leg_chunk(ocean, radius, src[sl], dst[sl], np.asarray(t)[sl])
    return out


def _leg_chunk(ocean, radius, src, dst, t):
    centre = np.array([0.0, 0.0, -radius])
    vs, vd = src - centre, dst - centre
    rs, rd = np.linalg.norm(vs, axis=1), np.linalg.norm(vd, axis=1)
    phi = np.arctan2(np.linalg.norm(np.cross(vs, vd), axis=1), (vs * vd).sum(1))
    zs, zd = radius - rs, radius - rd
    top, bot = np.minimum(zs, zd), np.maximum(zs, zd)
    # horizontal ends ordered shallow -> deep
    shallow = np.where((zs <= zd)[:, None], src, dst)[:, :2]
    deep = np.where((zs <= zd)[:, None], dst, src)[:, :2]
    edges = np.arange(-20.0, Z_MAX + DZ, DZ)
    zmid = 0.5 * (edges[:-1] + edges[1:])
    c = ocean.c0(zmid)[None, :] + ocean.uniform(zmid, t)
    za = np.clip(edges[None, :-1], top[:, None], bot[:, None])
    zb = np.clip(edges[None, 1:], top[:, None], bot[:, None])
    ra, rb = radius - za, radius - zb
    used = zb > za
    pmax = np.where(used, ra / c, np.inf).min(1)  # a ray parameter above this turns
    # start: the straight chord's impact parameter over the harmonic-mean speed
    chord = dst - src
    length = np.linalg.norm(chord, axis=1)
    b0 = np.linalg.norm(np.cross(vs, chord), axis=1) / length
    cmean = (zb - za).sum(1) / ((zb - za) / c).sum(1)
    p = np.minimum(b0 / cmean, 0.999 * pmax)
    for _ in range(30):
        b = p[:, None] * c * used
        sa, sb = np.sqrt(ra**2 - b**2), np.sqrt(rb**2 - b**2)
        seg = (ra**2 - rb**2) / (sa + sb)  # straight segment length in each shell
        dphi = np.arcsin(np.clip(seg * b / (ra * rb), -1, 1))
        f = dphi.sum(1) - phi
        dfdp = (c * (ra**2 - rb**2) / (sa * sb * (sa + sb))).sum(1)
        step = f / dfdp
        p = np.clip(p - step, 0.0, (1.0 - 1e-12) * pmax)
        if np.max(np.abs(f)) * radius < 1e-7:
            break
    else:  # pragma: no cover - a ray that did not converge is a generator bug
        raise RuntimeError(f"eigenray: {np.max(np.abs(f)) * radius:.3g} m off after 30 steps")
    b = p[:, None] * c * used
    sa, sb = np.sqrt(ra**2 - b**2), np.sqrt(rb**2 - b**2)
    seg = (ra**2 - rb**2) / (sa + sb)
    dphi = np.arcsin(np.clip(seg * b / (ra * rb), -1, 1))
    tt = (seg / c).sum(1)
    # gradients to first order: -int dc / c^2 ds, dc = g . (x - x0) at each shell's midpoint
    frac = (np.cumsum(dphi, 1) - 0.5 * dphi) / np.maximum(phi, 1e-300)[:, None]
    frac = np.where(phi[:, None] > 0, frac, 0.0)
    xe = shallow[:, 0:1] + frac * (deep[:, 0:1] - shallow[:, 0:1]) - ocean.centre[0]
    xn = shallow[:, 1:2] + frac * (deep[:, 1:2] - shallow[:, 1:2]) - ocean.centre[1]
    ge, gn = ocean.gradient(zmid, t)
    return tt - (seg * (ge * xe + gn * xn) / c**2).sum(1)


class Ship:
    """The ship's antenna position and attitude as continuous functions of time."""

    def __init__(self, cfg: Config, rng, centre):
        self.cfg, self.centre, self.speed = cfg, np.asarray(centre[:2], float), 2.0
        self.rad = cfg.radius * cfg.depth  # circle radius / star half-length
        self.start = rng.uniform(0, 2 * np.pi)
        self.sense = rng.choice([-1.0, 1.0])
        self.waves = rng.uniform(0, 2 * np.pi, 8)
        self.crab = (rng.uniform(-4, 4), rng.uniform(1, 3) * 3600.0)
        if cfg.scenario == "B":  # star: four diameters joined by chords, rotated at random
            ang = self.start + np.radians([0, 180, 225, 45, 90, 270, 315, 135, 0])
            self.way = self.centre + self.rad * np.column_stack([np.sin(ang), np.cos(ang)])
            seg = np.linalg.norm(np.diff(self.way, axis=0), axis=1)
            self.cum = np.concatenate([[0.0], np.cumsum(seg)])

    def track(self, t):
        """Antenna east, north (m) and course (degrees) at times ``t`` (s)."""
        s = self.speed * np.asarray(t, float)
        if self.cfg.scenario == "A":
            wander = 20.0 * np.sin(2 * np.pi * t / 1800.0 + self.waves[0])
            ang = self.start + self.sense * s / self.rad
            r = self.rad + wander
            e = self.centre[0] + r * np.sin(ang)
            n = self.centre[1] + r * np.cos(ang)
            course = np.degrees(ang) + self.sense * 90.0
            return e, n, course
        s = np.mod(s, self.cum[-1])
        k = np.clip(np.searchsorted(self.cum, s, side="right") - 1, 0, len(self.cum) - 2)
        d = self.way[k + 1] - self.way[k]
        u = (s - self.cum[k]) / (self.cum[k + 1] - self.cum[k])
        pos = self.way[k] + u[:, None] * d
        return pos[:, 0], pos[:, 1], np.degrees(np.arctan2(d[:, 0], d[:, 1]))

    def state(self, t):
        """East, north, up of the antenna, heading, pitch, roll (degrees) at times ``t``."""
        t = np.asarray(t, float)
        e, n, course = self.track(t)
        w = self.waves
        heading = np.mod(course + self.crab[0] * np.cos(2 * np.pi * t / self.crab[1]), 360.0)
        pitch = 1.5 * np.sin(2 * np.pi * t / 6.5 + w[1]) + 0.5 * np.sin(2 * np.pi * t / 4.1 + w[2])
        roll = 3.0 * np.sin(2 * np.pi * t / 9.0 + w[3]) + 1.0 * np.sin(2 * np.pi * t / 13 + w[4])
        up = 13.0 + 0.6 * np.sin(2 * np.pi * t / 7.5 + w[5]) + 0.3 * np.sin(2 * np.pi * t / 11
                                                                            + w[6])
        return e, n, up, heading, pitch, roll


def lever_enu(offset, heading, pitch, roll):
    """A vessel-frame offset (forward, rightward, downward) in east, north, up.

    R = Rz(heading) Ry(pitch) Rx(roll) acting on (forward, right, down) = (north, east, down)
    at zero attitude; heading clockwise from north, pitch bow up, roll starboard down.
    """
    h, p, r = (np.radians(np.asarray(v, float)) for v in (heading, pitch, roll))
    f, rt, d = offset
    # Rx(roll)
    y1 = rt * np.cos(r) - d * np.sin(r)
    z1 = rt * np.sin(r) + d * np.cos(r)
    # Ry(pitch)
    x2 = f * np.cos(p) + z1 * np.sin(p)
    z2 = -f * np.sin(p) + z1 * np.cos(p)
    # Rz(heading)
    north = x2 * np.cos(h) - y1 * np.sin(h)
    east = x2 * np.sin(h) + y1 * np.cos(h)
    return east, north, -z2


def campaign(seed: int, cfg: Config) -> dict:
    """Simulate one campaign; return the shots, the profile, the truth and the site."""
    rng = np.random.default_rng([seed, ord(cfg.scenario)])
    centre = np.array([rng.uniform(-50, 50), rng.uniform(-50, 50), 0.0])
    half = cfg.side / 2.0
    corners = np.array([[-half, half], [half, half], [half, -half], [-half, -half]])
    truth = np.column_stack([centre[0] + corners[:, 0] + rng.normal(0, 20, 4),
                             centre[1] + corners[:, 1] + rng.normal(0, 20, 4),
                             -(cfg.depth + rng.uniform(-20, 30, 4))])
    prior = truth + rng.normal(0, cfg.prior_error, truth.shape)
    ocean, ship = Ocean(cfg, rng, truth.mean(0)), Ship(cfg, rng, truth.mean(0))
    radius = gaussian_radius(cfg.lat) if cfg.earth == "sphere" else 1e9
    atd = np.array([1.2, -0.8, 18.0])
    interval = 40.0 if cfg.scenario == "A" else 20.0
    t_shot = np.arange(60.0, cfg.hours * 3600.0, interval)
    if cfg.scenario == "A":
        tx_t, mt = np.repeat(t_shot, 4), np.tile(np.arange(4), t_shot.size)
    else:
        tx_t, mt = t_shot, np.arange(t_shot.size) % 4
    tat = 0.3  # the transponders' turn-around delay (removed from TT, in RT)

    def transducer(t):
        e, n, u, h, p, r = ship.state(t)
        de, dn, du = lever_enu(atd, h, p, r)
        return np.column_stack([e + de, n + dn, u + du])

    src = transducer(tx_t)
    tgt = truth[mt]
    t1 = leg_times(ocean, radius, src, tgt, tx_t + 1.0)
    t2 = t1.copy()
    for _ in range(4):  # the ship moves while the reply travels back
        rx_t = tx_t + t1 + tat + t2
        rcv = transducer(rx_t)
        t2 = leg_times(ocean, radius, tgt, rcv, rx_t - 1.0)
    rx_t = tx_t + t1 + tat + t2
    tt = t1 + t2
    n = tt.size
    label = np.array(["true"] * n, dtype=object)
    if cfg.noise:
        tt = tt + rng.normal(0.0, 20e-6, n)
    if cfg.outliers:
        u = rng.uniform(size=n)
        late, spur = u < 0.03, (u >= 0.03) & (u < 0.05)
        tt = np.where(late, tt + rng.uniform(0.5e-3, 20e-3, n), tt)
        tt = np.where(spur, tt + rng.uniform(-0.5, 0.5, n), tt)
        label[late], label[spur] = "multipath", "spurious"
        keep = rng.uniform(size=n) > 0.02  # missing replies
    else:
        keep = np.ones(n, bool)
    # logged antenna and attitude (GNSS: white 1 cm + OU 1.7 cm, 60 s, per axis)
    ts = np.arange(0.0, cfg.hours * 3600.0 + 120.0, 1.0)
    gnss = [ou_path(rng, ts, 0.0173, 60.0) for _ in range(3)] if cfg.noise else None
    logs = {}
    for key, tk in (("0", tx_t), ("1", rx_t)):
        e, nn, up, h, p, r = ship.state(tk)
        ant = np.column_stack([e, nn, up])
        att = np.column_stack([h, p, r])
        if cfg.noise:
            white = 0.01 if cfg.gnss_ou else 0.02
            ant = ant + rng.normal(0.0, white, ant.shape) + cfg.gnss_ou * np.column_stack(
                [np.interp(tk, ts, g) for g in gnss])
            att = att + rng.normal(0.0, 1.0, att.shape) * np.array([0.05, 0.02, 0.02])
        logs[key] = (ant, att)
    z = np.arange(0.0, Z_MAX + DZ, DZ)
    # the CTD cast: the profile at the array centre at the first shot (or its time mean)
    when = np.array([t_shot[0]]) if cfg.cast == "first" else t_shot
    svp = ocean.c0(z) + ocean.uniform(z, when).mean(0)
    return {"cfg": cfg, "seed": seed, "t_tx": tx_t[keep], "t_rx": rx_t[keep],
            "mt": mt[keep], "tt": tt[keep], "label": label[keep],
            "ant0": logs["0"][0][keep], "att0": logs["0"][1][keep],
            "ant1": logs["1"][0][keep], "att1": logs["1"][1][keep],
            "truth": truth, "prior": prior, "atd": atd, "svp": (z, svp)}


def write_campaign(camp: dict, out) -> Path:
    """Write GARPOS's site, obs and svp files and ``truth.json``; return the site file."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    cfg = camp["cfg"]
    stem = f"IND{cfg.scenario}.{camp['seed']:04d}"
    site, obs, svp = (out / f"{stem}-{k}" for k in ("initcfg.ini", "obs.csv", "svp.csv"))
    lines = ["[Obs-parameter]", f" Site_name   = IND{cfg.scenario}",
             f" Campaign    = {camp['seed']:04d}", " Date(UTC)   = 2026-11-27",
             " Date(jday)  = 2026-331", " Ref.Frame   = ITRF2014",
             f" SoundSpeed  = {svp.name}", "", "[Data-file]", f" datacsv     = {obs.name}",
             f" N_shot      = {len(camp['tt'])}", "", "[Site-parameter]",
             f" Latitude0   = {cfg.lat:.8f}", f" Longitude0  = {cfg.lon:.8f}",
             " Height0     = 0.00", f" Stations    = {' '.join(STATIONS)}", "",
             "[Model-parameter]"]
    for st, (e, n, u) in zip(STATIONS, camp["prior"], strict=True):
        lines.append(f" {st}_dPos    = {e:.4f} {n:.4f} {u:.4f} 3.0 3.0 3.0 0.0 0.0 0.0")
    f, r, d = camp["atd"]
    lines += [" dCentPos    = 0.0 0.0 0.0 0.0 0.0 0.0 0.0 0.0 0.0",
              f" ATDoffset   = {f:.4f} {r:.4f} {d:.4f} 0.0 0.0 0.0 0.0 0.0 0.0", ""]
    site.write_text("\n".join(lines) + "\n")
    z, c = camp["svp"]
    svp.write_text("depth,speed\n" + "".join(f"{a:.1f},{b:.5f}\n" for a, b in zip(z, c,
                                                                                 strict=True)))
    head = ("idx,SET,LN,MT,TT,ResiTT,TakeOff,gamma,flag,ST,ant_e0,ant_n0,ant_u0,head0,pitch0,"
            "roll0,RT,ant_e1,ant_n1,ant_u1,head1,pitch1,roll1")
    rows = [f"# cfgfile = {site.name}", head]
    st0 = 36000.0  # seconds of the day of the first shot
    for i in range(len(camp["tt"])):
        a0, g0, a1, g1 = camp["ant0"][i], camp["att0"][i], camp["ant1"][i], camp["att1"][i]
        rows.append(
            f"{i},S01,L01,{STATIONS[camp['mt'][i]]},{camp['tt'][i]:.9f},0.0,0.0,0.0,False,"
            f"{st0 + camp['t_tx'][i]:.6f},{a0[0]:.5f},{a0[1]:.5f},{a0[2]:.5f},"
            f"{g0[0]:.4f},{g0[1]:.4f},{g0[2]:.4f},{st0 + camp['t_rx'][i]:.6f},"
            f"{a1[0]:.5f},{a1[1]:.5f},{a1[2]:.5f},{g1[0]:.4f},{g1[1]:.4f},{g1[2]:.4f}")
    obs.write_text("\n".join(rows) + "\n")
    truth = {"stations": dict(zip(STATIONS, camp["truth"].tolist(), strict=True)),
             "centre": camp["truth"].mean(0).tolist(), "frame": "east, north, up (m) of the "
             "site file's origin, as <station>_dPos", "config": cfg.__dict__,
             "labels": {k: int((camp["label"] == k).sum()) for k in ("true", "multipath",
                                                                     "spurious")}}
    (out / "truth.json").write_text(json.dumps(truth, indent=1))
    return site


def locate(site, out, options=()) -> tuple[dict, float]:
    """Run ``bayes-mpem locate SITE --out OUT [OPTIONS]`` in this process; summary, seconds."""
    from bayes_mpem.cli import main

    t0 = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        status = main(["locate", str(site), "--out", str(out), *options])
    seconds = time.perf_counter() - t0
    if status != 0:
        raise RuntimeError(f"bayes-mpem locate {site} --out {out}: exit status {status}")
    return json.loads((Path(out) / "summary.json").read_text()), seconds


def compare(summary: dict, truth: np.ndarray) -> dict:
    """Errors, sds and interval coverage of the centre and every coordinate against the truth."""
    cen = summary["array_centre"]["enu"]
    tc = truth.mean(0)
    res = {"centre_err": np.array([cen[a]["mean"] - tc[i] for i, a in enumerate(AXES)]),
           "centre_sd": np.array([cen[a]["sd"] for a in AXES]),
           "centre_cov": np.array([cen[a]["interval"][0] <= tc[i] <= cen[a]["interval"][1]
                                   for i, a in enumerate(AXES)])}
    errs, sds, cov = [], [], []
    for st, tr in zip(STATIONS, truth, strict=True):
        enu = summary["transponders"][st]["enu"]
        errs.append([enu[a]["mean"] - tr[i] for i, a in enumerate(AXES)])
        sds.append([enu[a]["sd"] for a in AXES])
        cov.append([enu[a]["interval"][0] <= tr[i] <= enu[a]["interval"][1]
                    for i, a in enumerate(AXES)])
    res["tp_err"], res["tp_sd"], res["tp_cov"] = np.array(errs), np.array(sds), np.array(cov)
    res["gradients"] = bool(summary["gradients"]["fitted"])
    prior = (summary.get("positions") or {}).get("prior") or {}
    check = prior.get("scaled", {}).get("check_as_given") if prior.get("scaled") else \
        prior.get("check")  # the check of the sigmas as given
    res["prior_p"] = None if not check else check["p_value"]
    res["prior_scaled"] = None if not prior else bool(prior.get("scaled"))
    return res


def run(seed: int, cfg: Config, folder, options=()) -> dict:
    """Simulate, write, locate (defaults, or ``options``) and compare one campaign."""
    camp = campaign(seed, cfg)
    site = write_campaign(camp, Path(folder) / "campaign")
    summary, seconds = locate(site, Path(folder) / "result", options)
    out = compare(summary, camp["truth"])
    out["seconds"], out["n"] = seconds, len(camp["tt"])
    return out


def table(rows: list[dict]) -> list[str]:
    """The measures of a list of ``run`` results, as Markdown table cells."""
    ce = np.array([r["centre_err"] for r in rows]) * 100
    z = np.array([r["centre_err"] / r["centre_sd"] for r in rows])
    cc = np.array([r["centre_cov"] for r in rows])
    tc = np.array([r["tp_cov"] for r in rows])
    tz = np.array([r["tp_err"] / r["tp_sd"] for r in rows])
    tmax = np.array([np.linalg.norm(r["tp_err"], axis=1).max() for r in rows]) * 100
    hor = np.hypot(ce[:, 0], ce[:, 1])
    rms = np.sqrt((z**2).mean(0))
    trms = np.sqrt((tz**2).reshape(-1, 3).mean(0))
    sd = np.array([r["centre_sd"] for r in rows]) * 100
    cov_t = tc.reshape(-1, 3).mean(0)
    cells = [
        f"{np.median(hor):.2f} / {np.median(np.abs(ce[:, 2])):.2f}",
        f"{hor.max():.2f} / {np.abs(ce[:, 2]).max():.2f}",
        " / ".join(f"{v:+.2f}" for v in ce.mean(0)),
        f"{np.median(tmax):.2f} ({tmax.max():.2f})",
        f"{100 * cc.mean():.0f} ({' / '.join(f'{100 * v:.0f}' for v in cc.mean(0))})",
        f"{100 * tc.mean():.0f} ({' / '.join(f'{100 * v:.0f}' for v in cov_t)})",
    ]
    cells.insert(3, " / ".join(f"{v:.2f}" for v in np.median(sd, 0)))
    return cells + [
        " / ".join(f"{v:.2f}" for v in rms),
        " / ".join(f"{v:.2f}" for v in trms),
        f"{np.median([r['seconds'] for r in rows]):.1f}",
        f"{int(np.median([r['n'] for r in rows]))}",
        f"{sum(r['gradients'] for r in rows)} of {len(rows)}",
        _conflicts(rows),
        _scaled(rows),
    ]


def _scaled(rows):
    """How many campaigns' priors ``--position-prior auto`` scaled up."""
    sc = [r["prior_scaled"] for r in rows if r.get("prior_scaled") is not None]
    return f"{sum(sc)} of {len(sc)}" if sc else "no prior"


def _conflicts(rows):
    """How many campaigns' prior check says the site file's sigmas are too small (p < 0.01)."""
    ps = [r["prior_p"] for r in rows if r.get("prior_p") is not None]
    return f"{sum(p < 0.01 for p in ps)} of {len(ps)}" if ps else "no prior"


MEASURES = ["centre error, median horizontal / vertical (cm)",
            "centre error, largest horizontal / vertical (cm)",
            "centre error, mean east / north / up (cm)",
            "centre sd, median east / north / up (cm)",
            "largest transponder error, median (largest) (cm)",
            "centre's 95 % intervals covering (%; east / north / up)",
            "transponders' coordinates' 95 % intervals covering (%; east / north / up)",
            "rms standardised error of the centre, east / north / up",
            "rms standardised error of the transponders, east / north / up",
            "seconds per `locate` (median)",
            "replies per campaign (median)",
            "gradients fitted (auto)",
            "prior check of the sigmas as given: too small (p < 0.01)",
            "priors scaled up (`--position-prior auto`)"]


def main(argv=None) -> int:
    """Run the study and write its section of ``docs/gnssa.md``."""
    sys.path.insert(0, str(HERE))
    from _report import commit, machine, write_section

    argv = sys.argv[1:] if argv is None else argv
    n_seeds = int(argv[0]) if argv else 10
    variants = argv[1:] or ["full"]
    t_all = time.perf_counter()
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        for variant in variants:
            data, _, fit = variant.partition("+")
            options = {"gradoff": ["--gradients", "off"],
                       "corroff": ["--correlation", "off"],
                       "prioroff": ["--position-prior", "off"]}.get(fit, [])
            for scen in ("A", "B"):
                cfg = replace(Config(scenario=scen), **VARIANTS[data])
                rows = []
                for seed in range(n_seeds):
                    r = run(seed, cfg, Path(tmp) / f"{data}{scen}{seed}", options)
                    rows.append(r)
                    print(variant, scen, seed, np.round(r["centre_err"] * 100, 2),
                          np.round(r["centre_err"] / r["centre_sd"], 2), r["centre_cov"],
                          f"{r['seconds']:.1f} s", flush=True)
                results[(variant, scen)] = table(rows)
    cols = [(v, s) for v in variants for s in ("A", "B")]
    head = "| measure | " + " | ".join(f"{v}, {s}" for v, s in cols) + " |"
    lines = [f"Written by `python benchmarks/gnssa_independent.py {' '.join(argv)}` "
             f"({machine()}; {time.perf_counter() - t_all:.0f} s; git {commit()}).", "",
             f"{n_seeds} seeds per column; A: circle of radius 3 km at 2 m/s, all four "
             "transponders every 40 s; B: star of four 6 km diameters, one transponder every "
             "20 s in turn; 6 h (`hour` 1 h, `halfhour` 0.5 h); `bayes-mpem locate SITE --out "
             "DIR` with its defaults"
             + ("; `narrow`: radius and half-length 750 m" if any(
                 v.startswith("narrow") for v in variants) else "")
             + ("; `...bad`: the site file's positions 6 m (sd) from the truth, its sigmas 3 m"
                if any(v.split("+")[0].endswith("bad") for v in variants) else "") + ".", "",
             head, "|---|" + "---|" * len(cols)]
    for i, m in enumerate(MEASURES):
        lines.append(f"| {m} | " + " | ".join(results[c][i] for c in cols) + " |")
    text = "\n".join(lines)
    print(text)
    name = "gnssa-independent" + ("" if variants == ["full"] else
                                  "-" + "-".join(v.replace("+", "-") for v in variants))
    write_section(DOC, name, text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
