"""A GNSS-acoustic array survey with a known truth, for testing the array location."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .._rng import RNGLike, as_generator
from .._validate import check_int, check_positive, check_probability
from ..acoustics.profile import SoundSpeedProfile
from ..acoustics.turning import direct_times
from ..io.geodesy import atd_offset_enu
from ..io.raw import RawSurvey


def reference_profile(max_depth: float, step: float = 25.0) -> pd.DataFrame:
    """Tabulate ``c(z) = 1482 + 33 exp(-z / 350) + 0.017 z`` m/s, every ``step`` m.

    Parameters
    ----------
    max_depth : float
        Deepest level (m).
    step : float, default 25

    Returns
    -------
    pandas.DataFrame
        ``depth``, ``sound_speed``.

    Examples
    --------
    >>> prof = reference_profile(1000.0)
    >>> round(float(prof["sound_speed"].iloc[0]), 1), round(float(prof["sound_speed"].min()), 1)
    (1515.0, 1498.1)
    """
    z = np.arange(0.0, float(max_depth) + step, step)
    return pd.DataFrame({"depth": z, "sound_speed": 1482.0 + 33.0 * np.exp(-z / 350.0)
                         + 0.017 * z})


@dataclass(frozen=True)
class GnssaSimulation:
    """A simulated GNSS-A survey and its truth.

    Attributes
    ----------
    pings : pandas.DataFrame
        One row per reply, the columns of a GARPOS survey
        (:func:`~bayes_mpem.io.garpos.read_garpos`): ``line``, ``transponder``,
        ``twtt``, ``time``, ``t_tx``, ``t_rx`` and the antenna ``e/n/u`` and
        ``head/pitch/roll`` at ``_tx`` and ``_rx``.
    header : dict
        ``lat``, ``lon``, ``height``, ``transponders`` (the prior positions),
        ``atd_offset``, ``ss_prof``, ``surface_depth``.
    truth : dict
        ``transponders`` (DataFrame of the true ``east``, ``north``, ``up``),
        ``spurious`` (bool per ping), ``scale`` (the profile's factor per ping),
        ``sound_speed`` (the scaled profile's harmonic mean from the surface to
        the mean transponder depth, per ping), ``sigma`` (s).
    settings : dict
    """

    pings: pd.DataFrame = field(repr=False)
    header: dict = field(repr=False)
    truth: dict = field(repr=False)
    settings: dict = field(default_factory=dict)

    def raw(self, fmt: str = "garpos") -> RawSurvey:
        """Return the survey as a reader would (before writing it to files).

        Parameters
        ----------
        fmt : {"garpos", "gnatss"}
        """
        return RawSurvey(fmt, "simulated", self.pings.copy(), dict(self.header),
                         pd.DataFrame(columns=["line", "text", "reason"]))


def _track(t, radius, speed, rot):
    """Ship position (east, north) and course (deg) at times ``t`` along a star of transits."""
    angles = np.radians([180.0, 0.0, 90.0, 270.0, 135.0, 315.0, 45.0, 225.0])
    way = radius * np.column_stack([np.cos(angles + rot), np.sin(angles + rot)])
    seg = np.diff(np.vstack([way, way[:1]]), axis=0)
    length = np.hypot(seg[:, 0], seg[:, 1])
    cum = np.concatenate([[0.0], np.cumsum(length)])
    s = (speed * t) % cum[-1]
    k = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
    f = ((s - cum[k]) / length[k])[:, None]
    pos = way[k] + f * seg[k]
    course = np.degrees(np.arctan2(seg[k, 0], seg[k, 1])) % 360.0
    return pos[:, 0], pos[:, 1], course


def _ship(t, track, settings, phases):
    """Return the true antenna east, north, up and heading, pitch, roll at times ``t``."""
    e, n, course = track(t)
    a = settings
    heading = (course + 1.0 * np.sin(2 * np.pi * t / 31.0 + phases[0])) % 360.0
    pitch = a["pitch_amplitude"] * np.sin(2 * np.pi * t / 7.0 + phases[1])
    roll = a["roll_amplitude"] * np.sin(2 * np.pi * t / 9.0 + phases[2])
    up = a["antenna_height"] + 0.5 * np.sin(2 * np.pi * t / 8.0 + phases[3])
    return [e, n, up, heading, pitch, roll]


def _logged(ship, sd, gen):
    """Return the antenna as a GNSS receiver logs it: the true position plus noise."""
    noise = gen.normal(0.0, sd, (3, ship[0].size))
    return [ship[0] + noise[0], ship[1] + noise[1], ship[2] + noise[2], *ship[3:]]


def _legs(profile, tx, rx, pos):
    """One-way times (s, unscaled) from the transducer at transmit and to it at receive."""
    out = []
    for e, n, u in (tx, rx):
        h = np.hypot(e - pos[0], n - pos[1])
        ray = direct_times(profile, -u, np.full(u.size, -pos[2]), h)
        if not ray.valid.all():  # pragma: no cover - the reference profile has none
            raise RuntimeError("simulated geometry has pings no eigenray reaches")
        out.append(ray.time)
    return out


def simulate_gnssa(*, n_transponders: int = 4, depth: float = 1500.0, hours: float = 4.0,
                   shot_interval: float = 20.0, ship_speed: float = 2.5, sigma: float = 5e-5,
                   p_spurious: float = 0.05, p_missing: float = 0.02,
                   speed_amplitude: float = 0.5, atd_offset=(1.5, -0.8, 12.0),
                   origin=(38.0, 143.0, 0.0), prior_sd=(3.0, 3.0, 5.0),
                   rng: RNGLike = None) -> GnssaSimulation:
    """Simulate a GNSS-acoustic survey of an array of transponders.

    Parameters
    ----------
    n_transponders : int, default 4
    depth : float, default 1500
        Mean transponder depth (m); each is within about 10 m of it.
    hours : float, default 4
        Length of the survey.
    shot_interval : float, default 20
        Seconds between interrogations (whole seconds keep GNATSS's time stamps exact);
        every transponder replies to each.
    ship_speed : float, default 2.5
        m/s, along transits across the array (a star of diameters and chords of
        a circle of ``0.9 depth``).
    sigma : float, default 5e-5
        Timing noise of a true reply (s).
    p_spurious : float, default 0.05
        Share of replies replaced by a spurious one, uniform over the
        transponder's travel times widened by 10 % each side.
    p_missing : float, default 0.02
        Share of replies missing.
    speed_amplitude : float, default 0.5
        Size (m/s) of the change in time of the sound speed: the profile is
        scaled by ``1 + (0.7 sin(2 pi t / 6 h + a) + 0.3 sin(2 pi t / 2 h + b))
        * speed_amplitude / 1500``.
    atd_offset : tuple of float, default (1.5, -0.8, 12.0)
        The transducer seen from the antenna: forward, rightward, downward (m);
        the antenna is 10 m above the sea surface.
    origin : tuple of float, default (38.0, 143.0, 0.0)
        Latitude, longitude, height of the frame's origin (the sea surface).
    prior_sd : tuple of float, default (3, 3, 5)
        Standard deviations (m) of the prior positions' errors (east, north, up).
    rng : None, int or numpy.random.Generator

    Returns
    -------
    GnssaSimulation

    Examples
    --------
    >>> sim = simulate_gnssa(n_transponders=3, hours=0.5, rng=1)
    >>> sorted(sim.pings["transponder"].unique())
    ['M01', 'M02', 'M03']
    """
    check_int("n_transponders", n_transponders, minimum=1)
    for name, v in (("depth", depth), ("hours", hours), ("shot_interval", shot_interval),
                    ("ship_speed", ship_speed), ("sigma", sigma)):
        check_positive(name, v)
    check_probability("p_spurious", p_spurious, open_interval=False)
    check_probability("p_missing", p_missing, open_interval=False)
    gen = as_generator(rng)
    ids = [f"M{k + 1:02d}" for k in range(n_transponders)]
    ang = 2 * np.pi * np.arange(n_transponders) / n_transponders + gen.uniform(0, 2 * np.pi)
    true = pd.DataFrame({"east": 0.5 * depth * np.cos(ang), "north": 0.5 * depth * np.sin(ang),
                         "up": -(depth + gen.normal(0.0, 10.0, n_transponders))}, index=ids)
    prior = true + gen.normal(0.0, 1.0, (n_transponders, 3)) * np.asarray(prior_sd)
    prof_df = reference_profile(depth + 200.0)
    profile = SoundSpeedProfile(prof_df["depth"], prof_df["sound_speed"], source="simulated")
    settings = {"antenna_height": 10.0, "pitch_amplitude": 2.0, "roll_amplitude": 3.0,
                "gnss_sd": 0.02}
    phases = gen.uniform(0, 2 * np.pi, 6)
    rot = gen.uniform(0.0, 2 * np.pi)

    def track(t):
        return _track(t, 0.9 * depth, ship_speed, rot)

    amp = speed_amplitude / 1500.0

    def scale(t):
        return 1.0 + amp * (0.7 * np.sin(2 * np.pi * t / 21600.0 + phases[4])
                            + 0.3 * np.sin(2 * np.pi * t / 7200.0 + phases[5]))

    t_tx = np.arange(0.0, hours * 3600.0, shot_interval)
    ship_tx = _ship(t_tx, track, settings, phases)
    tx = _transducer(ship_tx, atd_offset)
    logged_tx = _columns(_logged(ship_tx, settings["gnss_sd"], gen), "tx")
    s = scale(t_tx)
    frames = []
    for st in ids:
        pos = true.loc[st].to_numpy()
        twtt = 2 * np.hypot(np.hypot(tx[0] - pos[0], tx[1] - pos[1]), tx[2] - pos[2]) / 1500.0
        for _ in range(3):  # the receive position depends on the travel time
            rx = _transducer(_ship(t_tx + twtt, track, settings, phases), atd_offset)
            t_a, t_b = _legs(profile, tx, rx, pos)
            twtt = (t_a + t_b) / s
        frames.append(pd.DataFrame({"transponder": st, "twtt_true": twtt, "t_tx": t_tx,
                                    "scale": s, **logged_tx}))
    pings = pd.concat(frames, ignore_index=True).sort_values(["t_tx", "transponder"],
                                                            kind="stable")
    pings = pings.reset_index(drop=True)
    n = len(pings)
    twtt = pings.pop("twtt_true").to_numpy() + gen.normal(0.0, sigma, n)
    spurious = gen.random(n) < p_spurious
    for st in ids:
        sel = spurious & (pings["transponder"] == st).to_numpy()
        ref = twtt[(pings["transponder"] == st).to_numpy()]
        lo, hi = 0.9 * ref.min(), 1.1 * ref.max()
        twtt[sel] = gen.uniform(lo, hi, sel.sum())
    pings["twtt"] = twtt
    pings["t_rx"] = pings["t_tx"] + twtt
    rx = _logged(_ship(pings["t_rx"].to_numpy(), track, settings, phases), settings["gnss_sd"],
                 gen)
    for k, v in _columns(rx, "rx").items():
        pings[k] = v
    keep = gen.random(n) >= p_missing
    pings, spurious = pings[keep].reset_index(drop=True), spurious[keep]
    hm = profile.harmonic_mean(0.0, float(-true["up"].mean()))
    truth = {"transponders": true, "spurious": spurious, "scale": pings.pop("scale").to_numpy(),
             "sigma": float(sigma)}
    truth["sound_speed"] = hm * truth["scale"]
    pings.insert(0, "line", np.arange(1, len(pings) + 1))
    pings.insert(3, "time", pings["t_tx"] - pings["t_tx"].min())
    cols = ["line", "transponder", "twtt", "time", "t_tx", "t_rx"] + [
        f"{c}_{end}" for end in ("tx", "rx") for c in ("e", "n", "u", "head", "pitch", "roll")]
    header = {"lat": float(origin[0]), "lon": float(origin[1]), "height": float(origin[2]),
              "transponders": prior, "atd_offset": np.asarray(atd_offset, float),
              "ss_prof": prof_df, "surface_depth": 0.0, "site": "SIM"}
    return GnssaSimulation(pings=pings[cols], header=header, truth=truth,
                           settings={"n_transponders": n_transponders, "depth": depth,
                                     "hours": hours, "shot_interval": shot_interval,
                                     "ship_speed": ship_speed, "sigma": sigma,
                                     "p_spurious": p_spurious, "p_missing": p_missing,
                                     "speed_amplitude": speed_amplitude,
                                     "atd_offset": list(map(float, atd_offset))})


def _transducer(ship, atd_offset):
    e, n, u, h, p, r = ship
    de, dn, du = atd_offset_enu(*atd_offset, h, p, r)
    return e + de, n + dn, u + du


def _columns(ship, end):
    return dict(zip([f"{c}_{end}" for c in ("e", "n", "u", "head", "pitch", "roll")], ship,
                    strict=True))
