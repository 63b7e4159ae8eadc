"""A GNSS-acoustic array survey with a known truth, for testing the array location."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .._rng import RNGLike, as_generator
from .._validate import check_choice, check_int, check_positive, check_probability
from ..acoustics.profile import SoundSpeedProfile
from ..acoustics.turning import direct_times
from ..io.geodesy import atd_offset_enu, earth_radius
from ..io.raw import RawSurvey
from .array import to_sphere


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


#: Track shapes of :func:`simulate_gnssa` (``track=``).
TRACKS = ("star", "circle", "star+circle", "station")
#: How a sound-speed field makes the travel times (``travel_time=``).
TRAVEL_TIME_MODELS = ("ray", "gamma")

_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(16)
_ZETA, _W_ZETA = 0.5 * (_GL_NODES + 1.0), 0.5 * _GL_WEIGHTS


def _reference_speed(z):
    """Return the reference profile of :func:`reference_profile` at depths ``z`` (m/s)."""
    z = np.asarray(z, float)
    return 1482.0 + 33.0 * np.exp(-z / 350.0) + 0.017 * z


@dataclass(frozen=True)
class SoundSpeedField:
    """A sound speed changing in time and across the array, added to the reference profile.

    ``dV(z, x, t) = b(t) exp(-z / decay) + (x - centre) . (g_s(t) exp(-z / shallow_decay)
    + g_d(t))`` m/s, with ``b(t) = sum_j A_j sin(2 pi t / P_j + phi_j)`` and the horizontal
    gradients ``g_s`` (shallow) and ``g_d`` (deep) of constant size, their azimuths turning
    once per ``gradient_period``.

    Attributes
    ----------
    amplitudes : tuple of float
        ``A_j``, m/s at the sea surface.
    periods : tuple of float
        ``P_j``, s.
    phases : tuple of float
        ``phi_j``, rad.
    decay : float
        e-folding depth of ``b`` (m).
    shallow, deep : float
        Sizes of ``g_s`` at the surface and of ``g_d``, (m/s)/km.
    shallow_decay : float
        e-folding depth of the shallow gradient (m).
    gradient_period : float
        s.
    gradient_phases : tuple of float
        Azimuths (rad, clockwise from north) of ``g_s`` and ``g_d`` at ``t = 0``.
    centre : tuple of float
        East, north (m) about which the gradients act (the true array centre).
    depth : float
        Depth (m) of the water column over which :meth:`coefficients` averages.
    """

    amplitudes: tuple
    periods: tuple
    phases: tuple
    decay: float
    shallow: float
    deep: float
    shallow_decay: float
    gradient_period: float
    gradient_phases: tuple
    centre: tuple
    depth: float

    def bulk(self, t):
        """Return ``b(t)``, the surface change of the speed (m/s).

        Parameters
        ----------
        t : array_like
            Times (s).

        Returns
        -------
        numpy.ndarray
        """
        t = np.asarray(t, float)
        out = np.zeros_like(t)
        for a, p, ph in zip(self.amplitudes, self.periods, self.phases, strict=True):
            out = out + a * np.sin(2 * np.pi * t / p + ph)
        return out

    def gradients(self, t):
        """Return ``g_s(t)``, ``g_d(t)``: arrays ``(n, 2)`` of east, north gradients, (m/s)/m.

        Parameters
        ----------
        t : array_like
            Times (s).

        Returns
        -------
        tuple of numpy.ndarray
        """
        t = np.asarray(t, float)
        out = []
        for size, ph in zip((self.shallow, self.deep), self.gradient_phases, strict=True):
            az = 2 * np.pi * t / self.gradient_period + ph
            out.append(1e-3 * size * np.stack([np.sin(az), np.cos(az)], axis=-1))
        return out

    def delta_v(self, z, east, north, t):
        """Return the change of the speed (m/s) at depth ``z``, ``east``, ``north``, time ``t``.

        Parameters
        ----------
        z, east, north : array_like
            Depth, east and north of the points (m).
        t : array_like
            Times (s).

        Returns
        -------
        numpy.ndarray
        """
        gs, gd = self.gradients(t)
        z = np.asarray(z, float)
        de, dn = np.asarray(east) - self.centre[0], np.asarray(north) - self.centre[1]
        fs = np.exp(-z / self.shallow_decay)
        return (self.bulk(t) * np.exp(-z / self.decay) + de * (gs[..., 0] * fs + gd[..., 0])
                + dn * (gs[..., 1] * fs + gd[..., 1]))

    def delta_time(self, t, ship, pos):
        """Return the first-order change (s) of a one-way time, ``ship`` to ``pos``.

        ``-integral dV / c_ref^2 ds`` along the straight chord (the eigenray's
        horizontal course differs from the chord to second order).

        Parameters
        ----------
        t : array_like
            Times (s).
        ship, pos : numpy.ndarray
            ``(n, 3)`` east, north, up of the transducer and the transponder (m).

        Returns
        -------
        numpy.ndarray
        """
        e, n, u = (np.asarray(v, float)[:, None] for v in ship)
        z_ = _ZETA[None, :]
        pe, pn, pu = (float(v) for v in pos)
        ze = -((1 - z_) * u + z_ * pu)
        de = (1 - z_) * e + z_ * pe
        dn = (1 - z_) * n + z_ * pn
        length = np.sqrt((pe - e[:, 0]) ** 2 + (pn - n[:, 0]) ** 2 + (pu - u[:, 0]) ** 2)
        tt = np.broadcast_to(np.asarray(t, float)[:, None], ze.shape)
        dv = self.delta_v(ze, de, dn, tt)
        return -length * np.sum(_W_ZETA * dv / _reference_speed(ze) ** 2, axis=1)

    def coefficients(self, t):
        """Return GARPOS's ``a0``, ``a1`` (east, north) and ``a2`` (east, north) at times ``t``.

        Averages over a vertical ray from the surface to :attr:`depth` with weight
        ``1 / c_ref``: ``a0 = int dV / c^2 dz / int 1 / c dz`` (so that
        ``dV0 = a0 V0`` with ``V0`` the harmonic mean), and the shallow (deep)
        gradient weighted by ``1 - z / depth`` (``z / depth``), times ``L = 1 km``.

        Parameters
        ----------
        t : array_like
            Times (s).
        """
        t = np.atleast_1d(np.asarray(t, float))
        z = self.depth * _ZETA
        w = _W_ZETA / _reference_speed(z)
        inv = np.sum(w)
        c = _reference_speed(z)
        a0 = np.sum(w * (self.bulk(t)[:, None] * np.exp(-z / self.decay)) / c, axis=1) / inv
        gs, gd = self.gradients(t)
        fs = np.exp(-z / self.shallow_decay)
        g = gs[:, None, :] * fs[None, :, None] + gd[:, None, :]  # (n, nz, 2) (m/s)/m
        rel = g / c[None, :, None]
        a1 = 1e3 * np.sum((w * (1 - _ZETA))[None, :, None] * rel, axis=1) / inv
        a2 = 1e3 * np.sum((w * _ZETA)[None, :, None] * rel, axis=1) / inv
        return a0, a1, a2

    def gamma(self, t, ship, pos):
        """Return GARPOS's ``gamma(t, p, x)`` of one leg.

        ``a0 + a1 . (p - centre) / L + a2 . (x - centre) / L``, L = 1 km.

        Parameters
        ----------
        t : array_like
            Times (s).
        ship, pos : numpy.ndarray
            ``(n, 3)`` east, north, up of the transducer and the transponder (m).

        Returns
        -------
        numpy.ndarray
        """
        a0, a1, a2 = self.coefficients(t)
        dp = np.column_stack([ship[0] - self.centre[0], ship[1] - self.centre[1]]) / 1e3
        dx = (np.array([pos[0], pos[1]]) - np.asarray(self.centre)) / 1e3
        return a0 + np.sum(a1 * dp, axis=1) + a2 @ dx

    def series(self, t) -> pd.DataFrame:
        """Return the field's truth at times ``t``.

        Columns ``time``, ``surface_dv`` (m/s), ``dV0`` (m/s), ``grad1_east``,
        ``grad1_north``, ``grad2_east``, ``grad2_north`` ((m/s)/km).

        Parameters
        ----------
        t : array_like
            Times (s).
        """
        t = np.atleast_1d(np.asarray(t, float))
        a0, a1, a2 = self.coefficients(t)
        v0 = self.v0()
        return pd.DataFrame({"time": t, "surface_dv": self.bulk(t), "dV0": a0 * v0,
                             "grad1_east": a1[:, 0] * v0, "grad1_north": a1[:, 1] * v0,
                             "grad2_east": a2[:, 0] * v0, "grad2_north": a2[:, 1] * v0})

    def v0(self) -> float:
        """Return ``V0``: the profile's harmonic mean from the surface to :attr:`depth`."""
        z = self.depth * _ZETA
        return float(1.0 / np.sum(_W_ZETA / _reference_speed(z)))


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

    def truth_record(self) -> dict:
        """Return the truth as plain JSON types (what ``truth.json`` holds).

        Returns
        -------
        dict
            ``frame``; ``transponders`` and ``prior`` (``{id: {"east", "north",
            "up"}}``, m); ``array_centre`` (the true positions' mean, m);
            ``sigma_s``; ``spurious`` (``transponder`` and ``t_tx`` of each
            spurious reply); ``sound_speed`` (``model``, ``unit``,
            ``reference_m_s`` (the profile's harmonic mean ``V0`` from the
            surface to the mean transponder depth) and ``series``: ``time_s``,
            ``dV0_m_s`` (GARPOS's ``dV0``: the change of the depth-averaged
            speed) and, for a field, ``surface_dv_m_s``); ``gradients``
            (``unit`` "(m/s)/km", ``time_s`` and the shallow ``grad1_*`` and deep
            ``grad2_*`` east and north series, GARPOS's ``gradV1``, ``gradV2``
            about the array centre; None without gradients); ``settings``.
        """
        def enu(df):
            return {str(k): {c: float(r[c]) for c in ("east", "north", "up")}
                    for k, r in df.iterrows()}

        true = self.truth["transponders"]
        spur = self.pings.loc[self.truth["spurious"], ["transponder", "t_tx"]]
        v0 = float(self.truth["sound_speed"][0] / self.truth["scale"][0])
        if "series" in self.truth:
            ser = self.truth["series"]
            series = {"time_s": ser["time"].tolist(), "dV0_m_s": ser["dV0"].tolist(),
                      "surface_dv_m_s": ser["surface_dv"].tolist()}
            field = self.truth["field"]
            grads = None if not (field.shallow or field.deep) else {
                "unit": "(m/s)/km", "time_s": ser["time"].tolist(),
                **{k: ser[k].tolist() for k in ("grad1_east", "grad1_north", "grad2_east",
                                                "grad2_north")}}
            model = "field"
        else:
            first = ~self.pings["t_tx"].duplicated().to_numpy()
            series = {"time_s": self.pings["t_tx"].to_numpy()[first].tolist(),
                      "dV0_m_s": (self.truth["sound_speed"][first] - v0).tolist()}
            grads, model = None, "scale"
        h = self.header
        return {
            "frame": {"origin": {"lat": h["lat"], "lon": h["lon"], "height": h["height"]},
                      "axes": "local east, north, up (m) about the origin; up = 0 at the sea "
                              "surface"},
            "transponders": enu(true), "prior": enu(h["transponders"]),
            "array_centre": {c: float(true[c].mean()) for c in ("east", "north", "up")},
            "sigma_s": float(self.truth["sigma"]),
            "spurious": {"n": int(len(spur)), "transponder": spur["transponder"].tolist(),
                         "t_tx": spur["t_tx"].astype(float).tolist()},
            "sound_speed": {"model": model, "unit": "m/s", "reference_m_s": v0,
                            "series": series},
            "gradients": grads, "settings": dict(self.settings)}

    def write(self, out_dir, fmt: str = "garpos") -> dict:
        """Write the survey in a reference format, and ``truth.json`` beside it.

        Parameters
        ----------
        out_dir : str or pathlib.Path
            Created if missing.
        fmt : {"garpos", "gnatss"}
            :func:`~bayes_mpem.io.garpos.write_garpos` (the site file and its
            ``obs.csv``, ``svp.csv``) or :func:`~bayes_mpem.io.gnatss.write_gnatss`
            (``config.yaml`` and its files).

        Returns
        -------
        dict
            ``survey`` (the file to give ``bayes-mpem locate``) and ``truth``.
        """
        from pathlib import Path

        from ..io.results import write_json

        check_choice("fmt", fmt, ("garpos", "gnatss"))
        if fmt == "garpos":
            from ..io.garpos import write_garpos

            # the sigmas the priors were drawn with (a prior sd of 0 would hold it)
            survey = write_garpos(out_dir, self.pings, self.header,
                                  sigmas=self.settings.get("prior_sd", (3.0, 3.0, 3.0)))
        else:
            from ..io.gnatss import write_gnatss

            survey = write_gnatss(out_dir, self.pings, self.header)
        truth = write_json(Path(out_dir) / "truth.json", {"format": fmt,
                                                          **self.truth_record()})
        return {"survey": survey, "truth": truth}


def true_speed_change(truth: dict, time_s, origins=None) -> np.ndarray:
    """Return a simulated campaign's change of the depth-averaged speed (m/s) at ``time_s``.

    GARPOS's ``dV0``. ``truth.json`` gives it about the true array centre; a fit with the
    gradient terms reports its speed about its own points (``summary.json``'s
    ``gradients["origins_m"]``: the mean ship position for the shallow term, the priors'
    mean for the deep one), where the gradients add ``gradV`` times the offset.

    Parameters
    ----------
    truth : dict
        :meth:`GnssaSimulation.truth_record` (``truth.json``).
    time_s : array_like
        Times (s, the shots' scale).
    origins : dict, optional
        ``{"shallow": [east, north], "deep": [east, north]}`` (m); None: the array centre.

    Returns
    -------
    numpy.ndarray
    """
    t = np.asarray(time_s, float)
    ser = truth["sound_speed"]["series"]
    dv = np.interp(t, ser["time_s"], ser["dV0_m_s"])
    grads = truth.get("gradients")
    if origins is None or not grads:
        return dv
    centre = truth["array_centre"]
    for term, level in (("shallow", "grad1"), ("deep", "grad2")):
        for axis, c in zip(("east", "north"), origins[term], strict=True):
            dv = dv + np.interp(t, grads["time_s"], grads[f"{level}_{axis}"]) * (
                (c - centre[axis]) / 1000.0)
    return dv


def _star(radius, rot):
    """Waypoints of a star of transits: four diameters joined by chords of the circle."""
    angles = np.radians([180.0, 0.0, 90.0, 270.0, 135.0, 315.0, 45.0, 225.0])
    return radius * np.column_stack([np.cos(angles + rot), np.sin(angles + rot)])


def _circle(radius, rot, n=72):
    """Waypoints of a circle (a regular polygon of ``n`` sides)."""
    a = rot + 2 * np.pi * np.arange(n) / n
    return radius * np.column_stack([np.cos(a), np.sin(a)])


def _track(t, radius, speed, rot):
    """Ship position (east, north) and course (deg) at times ``t`` along a star of transits."""
    return _polyline(t, _star(radius, rot), speed)


def _station(t, rot, half=50.0):
    """Hold station: a slow figure within ``half`` m of the centre."""
    w1, w2 = 2 * np.pi / 1800.0, 2 * np.pi / 2400.0
    e, n = half * np.sin(w1 * t + rot), half * np.sin(w2 * t + 2 * rot)
    course = np.degrees(np.arctan2(half * w1 * np.cos(w1 * t + rot),
                                   half * w2 * np.cos(w2 * t + 2 * rot))) % 360.0
    return e, n, course


def _polyline(t, way, speed):
    """Ship position and course at times ``t`` going round the closed polyline ``way``."""
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


def _legs(profile, tx, rx, pos, radius=None):
    """One-way times (s, unscaled) from the transducer at transmit and to it at receive.

    With ``radius`` the layers follow a sphere touching the frame's origin: each end's
    depth is its depth below the sphere (:func:`~.array.to_sphere`) and the horizontal
    range the one that, with those depths, gives the (Cartesian) chord.
    """
    out = []
    for e, n, u in (tx, rx):
        h = np.hypot(e - pos[0], n - pos[1])
        za, zb = -u, np.full(u.size, -pos[2])
        if radius is not None:
            L = np.sqrt(h * h + (u - pos[2]) ** 2)
            za = -to_sphere(e, n, u, radius)[2]
            zb = np.full(u.size, -float(to_sphere(*pos, radius)[2]))
            h = np.sqrt(np.maximum(L * L - (za - zb) ** 2, 0.0))
        ray = direct_times(profile, za, zb, h)
        if not ray.valid.all():  # pragma: no cover - the reference profile has none
            raise RuntimeError("simulated geometry has pings no eigenray reaches")
        out.append(ray.time)
    return out


def _check_options(*, n_transponders, depth, hours, shot_interval, ship_speed, sigma,
                   p_spurious, p_missing, track, speed_model, travel_time, gradients,
                   speed_decay, shallow_decay, gradient_period, speed_periods,
                   speed_amplitudes, earth="sphere", schedule="all"):
    """Raise ValueError for an option :func:`simulate_gnssa` cannot take."""
    check_choice("earth", earth, ("sphere", "flat"))
    check_choice("schedule", schedule, ("all", "staggered"))
    check_int("n_transponders", n_transponders, minimum=1)
    for name, v in (("depth", depth), ("hours", hours), ("shot_interval", shot_interval),
                    ("ship_speed", ship_speed), ("sigma", sigma)):
        check_positive(name, v)
    check_probability("p_spurious", p_spurious, open_interval=False)
    check_probability("p_missing", p_missing, open_interval=False)
    check_choice("track", track, TRACKS)
    check_choice("speed_model", speed_model, ("scale", "field"))
    check_choice("travel_time", travel_time, TRAVEL_TIME_MODELS)
    if speed_model != "field" and (gradients or travel_time != "ray"):
        raise ValueError("gradients and travel_time='gamma' need speed_model='field'")
    if speed_model == "field":
        for name, v in (("speed_decay", speed_decay), ("shallow_decay", shallow_decay),
                        ("gradient_period", gradient_period), *(
                            (f"speed_periods[{j}]", p) for j, p in enumerate(speed_periods))):
            check_positive(name, v)
        if len(speed_amplitudes) != len(speed_periods):
            raise ValueError(f"speed_amplitudes and speed_periods: expected the same length, "
                             f"got {len(speed_amplitudes)} and {len(speed_periods)}")


def _replies(pings, ids, track_at, settings, phases, sigma, p_spurious, p_missing, gen):
    """Add the noise, the spurious and missing replies and the receive positions."""
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
    rx = _logged(_ship(pings["t_rx"].to_numpy(), track_at, settings, phases),
                 settings["gnss_sd"], gen)
    for k, v in _columns(rx, "rx").items():
        pings[k] = v
    keep = gen.random(n) >= p_missing
    return pings[keep].reset_index(drop=True), spurious[keep]


def _staggered(pings, spurious, ids, shot_interval):
    """Keep the reply of transponder ``i mod K`` to interrogation ``i`` only."""
    shot = np.rint(pings["t_tx"].to_numpy() / shot_interval).astype(int)
    mine = shot % len(ids) == pings["transponder"].map(
        {st: k for k, st in enumerate(ids)}).to_numpy()
    return pings[mine].reset_index(drop=True), spurious[mine]


def _make_field(gen, true, amplitudes, periods, decay, sizes, shallow_decay, period):
    """Build the :class:`SoundSpeedField` of :func:`simulate_gnssa` (periods in hours)."""
    return SoundSpeedField(
        amplitudes=tuple(map(float, amplitudes)),
        periods=tuple(3600.0 * float(p) for p in periods),
        phases=tuple(gen.uniform(0, 2 * np.pi, len(periods))), decay=float(decay),
        shallow=float(sizes[0]), deep=float(sizes[1]), shallow_decay=float(shallow_decay),
        gradient_period=3600.0 * float(period),
        gradient_phases=tuple(gen.uniform(0, 2 * np.pi, 2)),
        centre=(float(true["east"].mean()), float(true["north"].mean())),
        depth=float(-true["up"].mean()))


def _field_settings(field, periods, gradients, gradient_period, travel_time):
    return dict(speed_model="field", speed_amplitudes=list(field.amplitudes),
                speed_periods=[float(p) for p in periods], speed_decay=field.decay,
                gradients=bool(gradients), shallow_gradient=field.shallow,
                deep_gradient=field.deep, shallow_decay=field.shallow_decay,
                gradient_period=float(gradient_period), travel_time=travel_time)


# the simulation's steps (geometry, track, travel times, replies, truth) read best in order
# long function: each step is a few lines
def simulate_gnssa(*, n_transponders: int = 4, depth: float = 1500.0, hours: float = 4.0,
                   shot_interval: float = 20.0, ship_speed: float = 2.5, sigma: float = 5e-5,
                   p_spurious: float = 0.05, p_missing: float = 0.02,
                   speed_amplitude: float = 0.5, atd_offset=(1.5, -0.8, 12.0),
                   origin=(38.0, 143.0, 0.0), prior_sd=(3.0, 3.0, 5.0),
                   track: str = "star", track_radius=None, speed_model: str = "scale",
                   speed_amplitudes=(1.0, 0.7, 0.5), speed_periods=(12.42, 6.0, 2.0),
                   speed_decay: float = 400.0, gradients: bool = False,
                   shallow_gradient: float = 0.5, deep_gradient: float = 0.1,
                   shallow_decay: float = 300.0, gradient_period: float = 12.0,
                   travel_time: str = "ray", earth: str = "sphere",
                   schedule: str = "all", rng: RNGLike = None) -> GnssaSimulation:
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
        m/s along the track.
    sigma : float, default 5e-5
        Timing noise of a true reply (s).
    p_spurious : float, default 0.05
        Share of replies replaced by a spurious one, uniform over the
        transponder's travel times widened by 10 % each side.
    p_missing : float, default 0.02
        Share of replies missing.
    speed_amplitude : float, default 0.5
        ``speed_model="scale"``: size (m/s) of the change in time of the sound
        speed: the profile is scaled by ``1 + (0.7 sin(2 pi t / 6 h + a) + 0.3
        sin(2 pi t / 2 h + b)) * speed_amplitude / 1500``.
    atd_offset : tuple of float, default (1.5, -0.8, 12.0)
        The transducer seen from the antenna: forward, rightward, downward (m);
        the antenna is 10 m above the sea surface.
    origin : tuple of float, default (38.0, 143.0, 0.0)
        Latitude, longitude, height of the frame's origin (the sea surface).
    prior_sd : tuple of float, default (3, 3, 5)
        Standard deviations (m) of the prior positions' errors (east, north, up). Written
        by :meth:`GnssaSimulation.write` as the GARPOS site file's sigmas, which ``locate``
        reads as Gaussian priors; an sd of 0 is written as a sigma of 0, which holds that
        coordinate at its (then exact) prior position.
    track : {"star", "circle", "star+circle", "station"}, default "star"
        The ship's track about the array centre: crossing transits, a circle, both, or
        holding station within 50 m of the centre (a wave glider).
    track_radius : float, optional
        Radius (m) of the star and the circle; default ``0.9 depth``.
    speed_model : {"scale", "field"}, default "scale"
        The profile scaled in time (``speed_amplitude``), or a :class:`SoundSpeedField`
        added to it.
    speed_amplitudes : tuple of float, default (1.0, 0.7, 0.5)
        ``"field"``: surface amplitudes (m/s) of the sinusoids.
    speed_periods : tuple of float, default (12.42, 6.0, 2.0)
        ``"field"``: their periods (hours).
    speed_decay : float, default 400
        ``"field"``: e-folding depth (m) of the change in time.
    gradients : bool, default False
        ``"field"``: add the horizontal gradients.
    shallow_gradient, deep_gradient : float, default 0.5, 0.1
        Sizes (m/s)/km of the shallow gradient at the surface (decaying over
        ``shallow_decay`` m) and of the deep one (uniform in depth); their
        azimuths turn once per ``gradient_period`` hours.
    shallow_decay : float, default 300
    gradient_period : float, default 12
    travel_time : {"ray", "gamma"}, default "ray"
        ``"field"``: the times' change to first order along the chord
        (``-int dV / c^2 ds``), or GARPOS's model itself
        (``T exp(-gamma)`` with the field's ``a0``, ``a1``, ``a2``), to tell an
        estimator's error from the model's.
    earth : {"sphere", "flat"}, default "sphere"
        The profile's layers follow the Earth (a sphere of the WGS84 Gaussian radius at
        the origin's latitude, touching the frame's origin; the frame itself is
        Cartesian, as GARPOS's and GNATSS's), or are flat in the frame.
    schedule : {"all", "staggered"}, default "all"
        Every transponder replies to each interrogation, or they are interrogated in
        turn (interrogation ``i`` to transponder ``i mod n_transponders``): no two
        replies share a transducer position.
    rng : None, int or numpy.random.Generator
        The same seed gives the same track, noise and replies with and without the field.

    Returns
    -------
    GnssaSimulation
        With ``truth["field"]`` (the :class:`SoundSpeedField`, ``"field"`` only)
        and ``truth["series"]`` (its :meth:`~SoundSpeedField.series` every minute).

    Raises
    ------
    ValueError
        For an unknown ``track``, ``speed_model`` or ``travel_time``, or field options
        without ``speed_model="field"``.

    Examples
    --------
    >>> sim = simulate_gnssa(n_transponders=3, hours=0.5, rng=1)
    >>> sorted(sim.pings["transponder"].unique())
    ['M01', 'M02', 'M03']
    >>> sim = simulate_gnssa(hours=0.5, speed_model="field", gradients=True, rng=1)
    >>> list(sim.truth["series"].columns)[:3]
    ['time', 'surface_dv', 'dV0']
    """
    _check_options(n_transponders=n_transponders, depth=depth, hours=hours,
                   shot_interval=shot_interval, ship_speed=ship_speed, sigma=sigma,
                   p_spurious=p_spurious, p_missing=p_missing, track=track,
                   speed_model=speed_model, travel_time=travel_time, gradients=gradients,
                   speed_decay=speed_decay, shallow_decay=shallow_decay,
                   gradient_period=gradient_period, speed_periods=speed_periods,
                   speed_amplitudes=speed_amplitudes, earth=earth, schedule=schedule)
    radius_earth = earth_radius(origin[0]) if earth == "sphere" else None
    gen = as_generator(rng)
    field_gen = gen.spawn(1)[0] if speed_model == "field" else None  # gen's state untouched
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
    radius = 0.9 * depth if track_radius is None else float(track_radius)
    check_positive("track_radius", radius)
    way = (_circle(radius, rot) if track == "circle" else
           np.vstack([_star(radius, rot), _circle(radius, rot)]))

    def track_at(t):
        if track == "station":
            return _station(t, rot)
        if track == "star":
            return _track(t, radius, ship_speed, rot)
        return _polyline(t, way, ship_speed)

    amp = speed_amplitude / 1500.0

    def scale(t):
        return 1.0 + amp * (0.7 * np.sin(2 * np.pi * t / 21600.0 + phases[4])
                            + 0.3 * np.sin(2 * np.pi * t / 7200.0 + phases[5]))

    field = None if speed_model != "field" else _make_field(
        field_gen, true, speed_amplitudes, speed_periods, speed_decay,
        (shallow_gradient, deep_gradient) if gradients else (0.0, 0.0), shallow_decay,
        gradient_period)
    t_tx = np.arange(0.0, hours * 3600.0, shot_interval)
    ship_tx = _ship(t_tx, track_at, settings, phases)
    tx = _transducer(ship_tx, atd_offset)
    logged_tx = _columns(_logged(ship_tx, settings["gnss_sd"], gen), "tx")
    s = scale(t_tx) if field is None else 1.0 + field.coefficients(t_tx)[0]
    frames = []
    for st in ids:
        pos = true.loc[st].to_numpy()
        twtt = 2 * np.hypot(np.hypot(tx[0] - pos[0], tx[1] - pos[1]), tx[2] - pos[2]) / 1500.0
        for _ in range(3):  # the receive position depends on the travel time
            rx = _transducer(_ship(t_tx + twtt, track_at, settings, phases), atd_offset)
            t_a, t_b = _legs(profile, tx, rx, pos, radius_earth)
            if field is None:
                twtt = (t_a + t_b) / s
            elif travel_time == "ray":
                twtt = (t_a + t_b + field.delta_time(t_tx, tx, pos)
                        + field.delta_time(t_tx + twtt, rx, pos))
            else:
                g = 0.5 * (field.gamma(t_tx, tx, pos) + field.gamma(t_tx + twtt, rx, pos))
                twtt = (t_a + t_b) * np.exp(-g)
        frames.append(pd.DataFrame({"transponder": st, "twtt_true": twtt, "t_tx": t_tx,
                                    "scale": s, **logged_tx}))
    pings = pd.concat(frames, ignore_index=True).sort_values(["t_tx", "transponder"],
                                                            kind="stable")
    pings = pings.reset_index(drop=True)
    pings, spurious = _replies(pings, ids, track_at, settings, phases, sigma, p_spurious,
                               p_missing, gen)
    if schedule == "staggered":
        pings, spurious = _staggered(pings, spurious, ids, shot_interval)
    hm = profile.harmonic_mean(0.0, float(-true["up"].mean()))
    truth = {"transponders": true, "spurious": spurious, "scale": pings.pop("scale").to_numpy(),
             "sigma": float(sigma)}
    truth["sound_speed"] = hm * truth["scale"]
    if field is not None:
        truth["field"] = field
        truth["series"] = field.series(np.arange(0.0, hours * 3600.0 + 60.0, 60.0))
    pings.insert(0, "line", np.arange(1, len(pings) + 1))
    pings.insert(3, "time", pings["t_tx"] - pings["t_tx"].min())
    cols = ["line", "transponder", "twtt", "time", "t_tx", "t_rx"] + [
        f"{c}_{end}" for end in ("tx", "rx") for c in ("e", "n", "u", "head", "pitch", "roll")]
    header = {"lat": float(origin[0]), "lon": float(origin[1]), "height": float(origin[2]),
              "transponders": prior, "atd_offset": np.asarray(atd_offset, float),
              "ss_prof": prof_df, "surface_depth": 0.0, "site": "SIM"}
    sets = {"n_transponders": n_transponders, "depth": depth, "hours": hours,
            "shot_interval": shot_interval, "ship_speed": ship_speed, "sigma": sigma,
            "p_spurious": p_spurious, "p_missing": p_missing,
            "speed_amplitude": speed_amplitude, "atd_offset": list(map(float, atd_offset)),
            "earth": earth, "schedule": schedule,
            "prior_sd": [float(v) for v in np.broadcast_to(prior_sd, 3)]}
    if track != "star" or track_radius is not None:
        sets.update(track=track, track_radius=radius)
    if field is not None:
        sets.update(_field_settings(field, speed_periods, gradients, gradient_period,
                                    travel_time))
    return GnssaSimulation(pings=pings[cols], header=header, truth=truth, settings=sets)


def _transducer(ship, atd_offset):
    e, n, u, h, p, r = ship
    de, dn, du = atd_offset_enu(*atd_offset, h, p, r)
    return e + de, n + dn, u + du


def _columns(ship, end):
    return dict(zip([f"{c}_{end}" for c in ("e", "n", "u", "head", "pitch", "roll")], ship,
                    strict=True))
