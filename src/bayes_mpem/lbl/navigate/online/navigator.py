"""``Navigator``: classify each range as it arrives and keep the position (``docs/stream.md``)."""

from __future__ import annotations

import json
import math
import os
import warnings
from operator import attrgetter

import pandas as pd

from ...._rng import RNGLike, as_generator
from ...._validate import check_choice, check_int, check_range
from ....exceptions import InputError, NavigationWarning
from ....io.boundary import LIMITS, limit_problem
from ....io.lines import Ping, make_ping
from ....io.results import write_json
from ....io.tables import read_beacons, read_pings
from ....mixture.densities import CLASSES
from ...em.path_choice import CLEAR_MARGIN, check_path_choice
from ..dive import SAME_EPOCH_TOLERANCE
from ..driver import MIN_SEPARATION
from .ekf import PositionFilter
from .kernel import class_probabilities, log_weight, ranges
from .reflector import BeaconModel, DirectPathScale
from .result import PingResult, label_of
from .warmup import batch_start, prior_model, provisional_classes

#: Written into every saved state; a state of another format is refused.
STATE_FORMAT = "bayes-mpem navigator state"
STATE_VERSION = 1
#: Switch a beacon's multipath geometry when the other is likelier by this many nats
#: (the margin beyond which :func:`~bayes_mpem.lbl.em.path_choice.choose_path` warns).
PATH_MARGIN = CLEAR_MARGIN
#: A class whose probability is below this does not update the filter.
MIN_CLASS_PROB = 1e-9
#: Default of ``max_gap`` (s): a line further ahead of the previous one is refused.
MAX_GAP = 3600.0
#: Lines of one time must agree on the dead-reckoned position within this (m): half the
#: warm-up batch fit's tolerance, so that an accepted line never makes that fit refuse.
_SAME_TIME_SPREAD = SAME_EPOCH_TOLERANCE / 2
#: A line further ahead than ``max_gap`` is refused, unless it is the last of this many + 1
#: lines in a row that jumped ahead together (each within ``max_gap`` of the one before): a
#: real pause of the stream (the vehicle at the surface), not one bad time stamp.
GAP_CONFIRM = 3
#: Options a state of an earlier build may lack, with the value they then take.
_OPTION_DEFAULTS = {"max_gap": MAX_GAP}
#: The values a line may carry (:data:`~bayes_mpem.io.boundary.LIMITS`), checked on a
#: :class:`~bayes_mpem.io.lines.Ping` given directly.
_PING_LIMITS = ("time", "range", "x", "y", "depth")
_REPLY_REASON = {"no_reply": "empty range: the ping got no reply",
                 "dead_reckoning": "dead-reckoning line: no beacon"}


#: Bounds of the options beyond "positive": ``navigate``'s own (``cli/options.py``: beyond
#: them its arithmetic overflows), and for the others the limits of a coordinate or range
#: (:data:`~bayes_mpem.io.boundary.LIMITS`). A saved state is held to them too.
_OPTION_BOUNDS = {"start_sd": (0.01, 1e6), "heading_sd": (1e-6, 180.0), "scale_sd": (1e-6, 1.0),
                  "plane_sd": (0.01, 1e6), "provisional_sd": (0.01, 1e6),
                  "prior_sigma_mp": (1e-3, 1e4), "sigma_floor": (1e-6, 1e4),
                  "sigma_dp": (1e-3, 1e4), "beta_walk": (0.0, 1.0), "scale_walk": (0.0, 1.0),
                  "max_gap": (1e-6, 1e10)}


def _bounded(name: str, value):
    low, high = _OPTION_BOUNDS[name]
    return check_range(name, value, low=low, high=high, include_low=True, include_high=True)


def _options(o: dict) -> dict:
    check_int("warmup", o["warmup"], minimum=2)
    check_range("alpha", o["alpha"], low=0.5, high=1.0, include_low=False, include_high=True)
    check_choice("multipath", o["multipath"], ("signal", "outlier"))
    check_path_choice(o["path"])
    o["dr_noise"] = check_range("dr_noise", o["dr_noise"], low=1e-4, high=100.0,
                                include_low=True, include_high=True)
    for k in ("start_sd", "heading_sd", "scale_sd", "plane_sd", "provisional_sd",
              "prior_sigma_mp", "sigma_floor", "beta_walk", "scale_walk"):
        o[k] = _bounded(k, o[k])
    if o["sigma_dp"] is not None:
        _bounded("sigma_dp", o["sigma_dp"])
    check_int("min_pings", o["min_pings"], minimum=1)
    check_int("prior_pings", o["prior_pings"], minimum=1)
    o["max_gap"] = _bounded("max_gap", o.get("max_gap", MAX_GAP))
    return o


class Navigator:
    """Online classification of ranges and filtering of the vehicle's position.

    Parameters
    ----------
    beacons : str, pathlib.Path or pandas.DataFrame
        The beacons table (``beacon, x, y, depth``).
    warmup : int, default 200
        Replies fitted in batch (:func:`~bayes_mpem.lbl.navigate.navigate`)
        before the online estimator takes over.
    alpha : float, default 1.0
        Step-size exponent of the online EM, ``gamma_n = n^-alpha`` with ``n``
        the beacon's reply count, in (1/2, 1].
    multipath : {"signal", "outlier"}
        Multipath replies update the position (default) or are outliers.
    path : {"auto", "triangle", "double"}
        Multipath geometry: chosen per beacon by the warm-up fit (default), or forced.
    dr_noise : float, default 0.1
        Random-walk level ``q`` of the dead reckoning (m / sqrt(s)).
    start_sd, heading_sd, scale_sd, plane_sd : float
        The warm-up fit's priors (m, degrees, -, m), as
        :func:`~bayes_mpem.lbl.navigate.navigate`; ``start_sd`` is also the
        provisional answers' position sd.
    sigma_dp : float, optional
        Fix sigma_DP (m); default learned.
    min_pings : int, default 30
        A beacon with fewer warm-up replies starts from the prior below.
    provisional_sd : float, default 100
        Scales (m) of the provisional classes during the warm-up.
    prior_sigma_mp : float, default 20
        sigma_MP (m) of a beacon too rare in the warm-up; its plane starts at
        the sea surface, its weights equal.
    prior_pings : int, default 20
        How many replies that prior counts for.
    beta_walk : float, default 1e-5
        Random walk of the heading bias (rad / sqrt(s)).
    scale_walk : float, default 1e-6
        Random walk of the speed scale (1 / sqrt(s)).
    sigma_floor : float, default 0.05
        Smallest scale (m).
    max_gap : float, default 3600
        Refuse a line timed more than this many seconds after the previous one (a
        clock jump), unless :data:`GAP_CONFIRM` + 1 lines in a row agree on it.
    rng : None, int or numpy.random.Generator
        Seeds the warm-up fit's path choice (one seed is drawn and kept in the state).

    Examples
    --------
    >>> from bayes_mpem.lbl.navigate import simulate_dive
    >>> sim = simulate_dive("abe58", rng=3, n_cycles=120)
    >>> nav = Navigator(sim.survey.beacons.reset_index(), warmup=200, rng=0)
    >>> cols = ["time", "beacon", "range", "x", "y", "depth"]
    >>> out = [nav.update(dict(zip(cols, row))) for row in
    ...        sim.survey.table[cols].itertuples(index=False)]
    >>> out[-1].phase, out[-1].label in ("dp", "mp", "ol", "no_reply")
    ('online', True)
    """

    def __init__(self, beacons, *, warmup: int = 200, alpha: float = 1.0,
                 multipath: str = "signal", path: str = "auto", dr_noise: float = 0.1,
                 start_sd: float = 1000.0, heading_sd: float = 5.0, scale_sd: float = 0.05,
                 plane_sd: float = 1000.0, sigma_dp: float | None = None, min_pings: int = 30,
                 provisional_sd: float = 100.0, prior_sigma_mp: float = 20.0,
                 prior_pings: int = 20, beta_walk: float = 1e-5, scale_walk: float = 1e-6,
                 sigma_floor: float = 0.05, max_gap: float = MAX_GAP, rng: RNGLike = None):
        self.options = _options(dict(
            warmup=warmup, alpha=alpha, multipath=multipath, path=path, dr_noise=dr_noise,
            start_sd=start_sd, heading_sd=heading_sd, scale_sd=scale_sd, plane_sd=plane_sd,
            sigma_dp=sigma_dp, min_pings=min_pings, provisional_sd=provisional_sd,
            prior_sigma_mp=prior_sigma_mp, prior_pings=prior_pings, beta_walk=beta_walk,
            scale_walk=scale_walk, sigma_floor=sigma_floor, max_gap=max_gap))
        self.beacons = read_beacons(beacons)
        self.seed = int(as_generator(rng).integers(2 ** 62))
        self.phase = "warmup"
        self.last = None  # (time, dead-reckoned x, y) of the previous line
        self.first_time = None
        self.buffer = []  # warm-up replies
        self.windows = {}  # warm-up: per beacon the smallest and largest range
        self.filter = None
        self.models = {}
        self.dp = None
        self.warmup_record = None
        self._ahead = []  # times of the latest lines refused for a gap (not saved)
        self._setup()

    def _setup(self):
        self._xyz = {b: tuple(float(v) for v in r) for b, r in
                     zip(self.beacons.index, self.beacons[["x", "y", "depth"]].to_numpy(),
                         strict=True)}
        o = self.options
        self._q2 = o["dr_noise"] ** 2
        self._alpha, self._floor = o["alpha"], o["sigma_floor"]

    # ------------------------------------------------------------------ checks
    def _as_ping(self, ping) -> Ping:
        """Validate a line before anything changes (a refused line leaves no trace)."""
        if isinstance(ping, Ping):
            if ping.beacon is not None and ping.beacon not in self._xyz:
                raise InputError(f"beacon {ping.beacon!r} is not in the beacons table")
            if ping.beacon is not None and ping.depth is None:
                raise InputError("a ping needs the vehicle's depth")
            for k in _PING_LIMITS:
                v, lim = getattr(ping, k), LIMITS[k]
                if v is None or ((v >= lim.low if lim.include_low else v > lim.low)
                                 and v <= lim.high):
                    continue
                problem = limit_problem(k, v)
                if problem is not None:
                    raise InputError(f"{k}: expected a value within the limits of "
                                     f"docs/input.md, got {problem}")
        else:
            ping = make_ping(dict(ping), "ping", self._xyz)
        if self.last is not None:
            t0 = self.last[0]
            if ping.time < t0:
                raise InputError(f"time {ping.time:g} s is before the previous line's {t0:g} s: "
                                 "lines must come in time order")
            if (self.phase == "warmup" and ping.time == t0
                    and max(abs(ping.x - self.last[1]),
                        abs(ping.y - self.last[2])) > _SAME_TIME_SPREAD):
                raise InputError(f"x, y ({ping.x:g}, {ping.y:g}) m differ from the previous "
                                 f"line's ({self.last[1]:g}, {self.last[2]:g}) m at the same "
                                 f"time {t0:g} s: expected one dead-reckoned position per time "
                                 f"(within {_SAME_TIME_SPREAD:g} m)")
            if ping.time - t0 > self.options["max_gap"] and not self._sustained_gap(ping.time):
                raise InputError(f"time {ping.time:g} s is {ping.time - t0:g} s after the "
                                 f"previous line's {t0:g} s: expected a gap of at most "
                                 f"{self.options['max_gap']:g} s (max_gap, --max-gap); the "
                                 f"line is refused, the stream goes on from {t0:g} s (a gap "
                                 f"is adopted when {GAP_CONFIRM + 1} lines in a row agree "
                                 "on it)")
        self._ahead = []
        return ping

    def _sustained_gap(self, t: float) -> bool:
        """Whether ``t`` ends a run of lines that all jumped ahead together (a real pause)."""
        run, gap = self._ahead, self.options["max_gap"]
        if run and run[-1] <= t <= run[-1] + gap:
            run.append(t)
        else:
            self._ahead = run = [t]
        return len(run) > GAP_CONFIRM

    # ------------------------------------------------------------------ update
    def update(self, ping) -> PingResult:
        """Take one line (a ping, a ping without reply, or a dead-reckoning line).

        Parameters
        ----------
        ping : Ping or mapping
            ``time``, ``beacon``, ``range``, ``x``, ``y``, ``depth``
            (:func:`~bayes_mpem.io.lines.make_ping`).

        Returns
        -------
        PingResult

        Raises
        ------
        InputError
            A bad value, an unknown beacon, or a time before the previous
            line's; the navigator is left as it was.

        Warns
        -----
        NavigationWarning
            Once, when the warm-up's batch fit warned (its messages are in
            :attr:`warmup_record`).
        """
        ping = self._as_ping(ping)
        if self.first_time is None:
            self.first_time = ping.time
        if self.phase == "warmup":
            return self._warmup_step(ping)
        return self._online_step(ping)

    def _warmup_step(self, ping: Ping) -> PingResult:
        last, self.last = self.last, (ping.time, ping.x, ping.y)
        sd = math.sqrt(self.options["start_sd"] ** 2
                       + self._q2 * (ping.time - self.first_time))
        kind = ping.kind
        if kind != "reply":
            return PingResult(ping.time, ping.beacon, None, "no_reply" if ping.beacon else None,
                              None, None, None, ping.x, ping.y, sd, sd, 0.0, "warmup",
                              _REPLY_REASON[kind])
        z = ping.range
        had = ping.beacon in self.windows
        w = self.windows.setdefault(ping.beacon, [z, z])
        before = list(w)
        w[0], w[1] = min(w[0], z), max(w[1], z)
        self.buffer.append([ping.time, ping.beacon, z, ping.x, ping.y, ping.depth])
        if len(self.buffer) >= self.options["warmup"]:
            try:
                return self._finish_warmup(ping)
            except InputError:  # the line is refused, the navigator left as it was
                self.buffer.pop()
                self.last = last
                if had:
                    w[:] = before
                else:
                    del self.windows[ping.beacon]
                raise
        p = provisional_classes(ping, self._xyz[ping.beacon], w, self.options["provisional_sd"])
        return PingResult(ping.time, ping.beacon, z, label_of(p), *p, ping.x, ping.y, sd, sd, 0.0,
                          "warmup")

    def _finish_warmup(self, ping: Ping) -> PingResult:
        o = self.options
        self.filter, self.models, self.dp, p, self.warmup_record = batch_start(
            self.buffer, self.beacons, o, self.seed,
            {"sigma_mp": o["prior_sigma_mp"], "n": o["prior_pings"]})
        self.buffer, self.windows, self.phase = [], {}, "online"
        f = self.filter
        out = PingResult(ping.time, ping.beacon, ping.range, label_of(p), *p, f.x, f.y,
                         *f.position_sd(), "warmup")
        if self.warmup_record["warnings"]:
            warnings.warn("the warm-up's batch fit warned: "
                          + "; ".join(self.warmup_record["warnings"]), NavigationWarning,
                          stacklevel=3)
        return out

    def _new_beacon(self, bid: str, ping: Ping) -> BeaconModel:
        """Start a beacon first heard after the warm-up (:func:`.warmup.prior_model`)."""
        o = self.options
        bx, by, bz = xyz = self._xyz[bid]
        direct, mp, *_ = ranges(ping.x, ping.y, ping.depth, bx, by, bz, bz, False)
        m = prior_model(xyz, {"sigma_mp": o["prior_sigma_mp"], "n": o["prior_pings"]},
                        mp_on=o["multipath"] == "signal" and mp - direct >= MIN_SEPARATION,
                        path=o["path"], d0_min=max(0.0, bz - ping.depth),
                        window=(ping.range, ping.range))
        self.models[bid] = m
        return m

    # long function: the four steps of one ping in order (predict, classify, correct,
    # learn) on local floats; split, each would pass a dozen of them around
    def _online_step(self, ping: Ping) -> PingResult:
        f = self.filter
        t0, x0, y0 = self.last
        dx, dy, dt = ping.x - x0, ping.y - y0, ping.time - t0
        if dt > 0.0 or dx != 0.0 or dy != 0.0:
            f.predict(dx, dy, dt, self._q2)
        self.last = (ping.time, ping.x, ping.y)
        kind = ping.kind
        if kind != "reply":
            return PingResult(ping.time, ping.beacon, None, "no_reply" if ping.beacon else None,
                              None, None, None, f.x, f.y, *f.position_sd(), "online",
                              _REPLY_REASON[kind])
        z, depth = ping.range, ping.depth
        m = self.models.get(ping.beacon) or self._new_beacon(ping.beacon, ping)
        m.observe(z, depth)
        xp, yp = f.x, f.y
        direct, mp, gdx, gdy, gmx, gmy, jac = ranges(xp, yp, depth, *m.xyz, m.d0, m.double)
        s_dp2 = self.dp.sigma ** 2
        sd_dp = math.sqrt(s_dp2 + f.range_variance(gdx, gdy))
        s_mp2 = m.sigma_mp ** 2 + jac * jac * m.d0_variance()
        w = m.weights
        p_dp, p_mp, p_ol, lse = class_probabilities(
            z, direct, mp, sd_dp, math.sqrt(s_mp2 + f.range_variance(gmx, gmy)), m.log_outlier(),
            log_weight(w[0]), log_weight(w[1]) if m.mp_on else -math.inf, log_weight(w[2]))
        alt = m.alt
        if alt is not None:  # the other geometry, classified at the same prediction
            alt.observe(z, depth)
            a_pred = ranges(xp, yp, depth, *m.xyz, alt.d0, alt.double)
            a_p = self._classify(alt, z, direct, a_pred, sd_dp)
        # correct: class-weighted Kalman updates, linearised at the predicted position
        if p_dp > MIN_CLASS_PROB:
            f.update(z - direct, gdx, gdy, s_dp2 / p_dp)
        if p_mp > MIN_CLASS_PROB:
            f.update(z - mp - gmx * (f.x - xp) - gmy * (f.y - yp), gmx, gmy,
                     max(s_mp2, s_dp2) / p_mp)
        # learn: statistics at the corrected position (expected squares under the filter)
        ex, ey = f.x - xp, f.y - yp
        r_dp = z - direct - gdx * ex - gdy * ey
        self.dp.learn(p_dp, r_dp * r_dp + f.range_variance(gdx, gdy), self._alpha, self._floor)
        u = z - mp - gmx * ex - gmy * ey + jac * (m.d0 - m.d0_ref)
        m.learn(p_dp, p_mp, p_ol, jac, u, u * u + f.range_variance(gmx, gmy), self._alpha,
                self._floor)
        if alt is not None:
            _, mp_a, _, _, gax, gay, jac_a = a_pred
            u = z - mp_a - gax * ex - gay * ey + jac_a * (alt.d0 - alt.d0_ref)
            alt.learn(*a_p[:3], jac_a, u, u * u + f.range_variance(gax, gay), self._alpha,
                      self._floor)
            self.models[ping.beacon] = m.weigh(a_p[3] - lse, self._alpha, PATH_MARGIN)
        sd_x, sd_y, cxy = f.position_sd()
        return PingResult(ping.time, ping.beacon, z, label_of((p_dp, p_mp, p_ol)), p_dp, p_mp,
                          p_ol, f.x, f.y, sd_x, sd_y, cxy, "online")

    def _classify(self, m, z, direct, pred, sd_dp):
        """Class probabilities and log-likelihood of a reply under model ``m`` (its multipath)."""
        _, mp, _, _, gmx, gmy, jac = pred
        sd_mp = math.sqrt(m.sigma_mp ** 2 + jac * jac * m.d0_variance()
                          + self.filter.range_variance(gmx, gmy))
        w = m.weights
        return class_probabilities(z, direct, mp, sd_dp, sd_mp, m.log_outlier(), log_weight(w[0]),
                                   log_weight(w[1]), log_weight(w[2]))

    def run(self, pings) -> pd.DataFrame:
        """Feed a whole pings table, row by row, as if it arrived live.

        Parameters
        ----------
        pings : str, pathlib.Path or pandas.DataFrame
            The ``fit`` pings table (validated as a whole first; rows in time order).

        Returns
        -------
        pandas.DataFrame
            One row per input row, the fields of :class:`PingResult`.

        Raises
        ------
        InputError
            A bad table, an unknown beacon or a row out of time order (the rows
            before it are taken).
        """
        _, a = read_pings(pings)
        rng = a["range"]
        rows = []
        for i in range(rng.size):
            z = float(rng[i])
            rows.append(self.update(Ping(float(a["time"][i]), a["beacon"][i],
                                         None if z != z else z, float(a["x"][i]),
                                         float(a["y"][i]), float(a["depth"][i]))))
        cols = zip(*map(attrgetter(*PingResult.__slots__), rows), strict=True) if rows else ()
        cols = dict(zip(PingResult.__slots__, cols, strict=False))
        text = ("beacon", "label", "phase", "reason")  # object columns, None kept as None
        return pd.DataFrame({k: pd.Series(cols.get(k, ()), dtype=object if k in text else float)
                             for k in PingResult.__slots__})

    # ------------------------------------------------------------------ reading the state
    def reflectors(self) -> dict:
        """Per beacon the current reflector, scales and weights.

        Returns
        -------
        dict
            ``{beacon: {"d0", "d0_sd", "sigma_mp", "sigma_dp", "weights", "path",
            "mp", "n"}}`` (empty during the warm-up).
        """
        return {bid: {"d0": m.d0, "d0_sd": math.sqrt(m.d0_variance()), "sigma_mp": m.sigma_mp,
                      "sigma_dp": self.dp.sigma, "weights": dict(zip(CLASSES, m.weights,
                                                                     strict=True)),
                      "path": "double" if m.double else "triangle", "mp": m.mp_on, "n": m.n}
                for bid, m in self.models.items()}

    def nuisances(self) -> dict:
        """Return the dead reckoning's heading bias (degrees) and speed scale, with their sd.

        Returns
        -------
        dict
            Empty during the warm-up.
        """
        f = self.filter
        if f is None:
            return {}
        return {"heading_bias_deg": math.degrees(f.beta),
                "heading_bias_sd_deg": math.degrees(math.sqrt(max(f.p[7], 0.0))),
                "speed_scale": f.scale, "speed_scale_sd": math.sqrt(max(f.p[9], 0.0))}

    # ------------------------------------------------------------------ saving
    def to_dict(self) -> dict:
        """Return the whole state as a JSON-ready document (floats round-trip exactly).

        Returns
        -------
        dict
        """
        b = self.beacons
        return {"format": STATE_FORMAT, "version": STATE_VERSION, "options": self.options,
                "beacons": {"beacon": list(b.index), "x": b["x"].tolist(),
                            "y": b["y"].tolist(), "depth": b["depth"].tolist()},
                "seed": self.seed, "phase": self.phase, "last": self.last,
                "first_time": self.first_time, "buffer": self.buffer, "windows": self.windows,
                "filter": None if self.filter is None else self.filter.to_dict(),
                "models": {k: m.to_dict() for k, m in self.models.items()},
                "dp": None if self.dp is None else self.dp.to_dict(),
                "warmup_record": self.warmup_record}

    @classmethod
    def from_dict(cls, d: dict) -> Navigator:
        """Rebuild a navigator from :meth:`to_dict`.

        Parameters
        ----------
        d : dict

        Returns
        -------
        Navigator

        Raises
        ------
        InputError
            Not a navigator state (or of another version).
        """
        if not isinstance(d, dict) or d.get("format") != STATE_FORMAT:
            raise InputError(f"expected a saved navigator state (format {STATE_FORMAT!r}), "
                             f"got {type(d).__name__}")
        if d.get("version") != STATE_VERSION:
            raise InputError(f"navigator state version {d.get('version')!r}: this version "
                             f"reads version {STATE_VERSION}")
        try:
            self = cls._from_checked(_check_state(d))
        except InputError:
            raise
        except (KeyError, TypeError, ValueError, IndexError, AttributeError) as err:
            raise InputError(f"not a valid navigator state ({type(err).__name__}: "
                             f"{err})") from None
        problem = _non_finite(self.to_dict())
        if problem:
            raise InputError(f"not a valid navigator state: {problem}")
        return self

    @classmethod
    def _from_checked(cls, d: dict) -> Navigator:
        self = cls.__new__(cls)
        self.options = _options({**_OPTION_DEFAULTS, **d["options"]})
        self.beacons = read_beacons(pd.DataFrame(d["beacons"]))
        self.seed, self.phase, self.first_time = d["seed"], d["phase"], d["first_time"]
        self.last = None if d["last"] is None else tuple(d["last"])
        self.buffer, self.windows = d["buffer"], d["windows"]
        self.filter = None if d["filter"] is None else PositionFilter.from_dict(d["filter"])
        self.models = {k: BeaconModel.from_dict(v) for k, v in d["models"].items()}
        self.dp = None if d["dp"] is None else DirectPathScale.from_dict(d["dp"])
        self.warmup_record = d["warmup_record"]
        self._ahead = []
        self._setup()
        return self

    def save(self, path) -> None:
        """Write the state to ``path`` (JSON), atomically (a temporary file, then renamed).

        Parameters
        ----------
        path : str or pathlib.Path
        """
        path = os.fspath(path)
        d = self.to_dict()
        problem = _non_finite(d)
        if problem:  # never overwrite a good state with one that cannot be resumed
            raise InputError(f"{path}: the state was not saved: {problem}")
        tmp = path + ".tmp"
        write_json(tmp, d, indent=None)
        os.replace(tmp, path)

    @classmethod
    def load(cls, path) -> Navigator:
        """Read a state written by :meth:`save`.

        Parameters
        ----------
        path : str or pathlib.Path

        Returns
        -------
        Navigator

        Raises
        ------
        InputError
            The file is not a navigator state, or one with a missing part, a value
            of the wrong type or a number that is not finite (naming the file).
        """
        name = os.fspath(path)
        try:
            with open(path, "rb") as fh:
                raw = fh.read()
            d = json.loads(raw.decode("utf-8"), parse_constant=_no_constant)
        except UnicodeDecodeError as err:
            raise InputError(f"{name}: not a navigator state (not UTF-8 text: "
                             f"{err.reason})") from None
        except ValueError as err:
            raise InputError(f"{name}: not a navigator state (invalid JSON: {err})") from None
        except IsADirectoryError:
            raise InputError(f"{name}: not a navigator state (a folder)") from None
        try:
            return cls.from_dict(d)
        except InputError as err:
            raise InputError(f"{name}: {err}") from None


def _no_constant(name):
    raise ValueError(f"{name} is not a JSON number")


#: The parts of a saved state and their JSON types (None: may also be null).
_STATE_SCHEMA = {"options": (dict,), "beacons": (dict,), "seed": (int,),
                 "phase": (str,), "last": (list, None), "first_time": (int, float, None),
                 "buffer": (list,), "windows": (dict,), "filter": (dict, None),
                 "models": (dict,), "dp": (dict, None), "warmup_record": (dict, None)}
#: The options a state holds (:class:`Navigator`'s keywords but ``rng``).
_OPTION_NAMES = ("warmup", "alpha", "multipath", "path", "dr_noise", "start_sd", "heading_sd",
                 "scale_sd", "plane_sd", "sigma_dp", "min_pings", "provisional_sd",
                 "prior_sigma_mp", "prior_pings", "beta_walk", "scale_walk", "sigma_floor",
                 "max_gap")
#: The filter's heading bias (rad) and speed scale a state may hold: a heading bias beyond a
#: full turn or a speed scale beyond 10 is a slip, not a dive.
_BETA_MAX, _SCALE_MAX = 2.0 * math.pi, 10.0
#: The largest variance of the filter's position (m^2): an sd of the coordinates' limit.
_POSITION_VAR_MAX = LIMITS["x"].high ** 2
#: Slack on a mean probability (rounding of the running means).
_PROB_SLACK = 1e-9


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _interval(where: str, v, low: float, high: float, what: str, *,
              include_low: bool = True) -> str | None:
    """Return what is wrong with a number that must lie in ``[low, high]`` (or None)."""
    if _is_number(v) and (v >= low if include_low else v > low) and v <= high:
        return None
    return (f"{where} is {v!r:.40}, expected {what} in {'[' if include_low else '('}{low:g}, "
            f"{high:g}]")


def _limited(where: str, v, kind: str) -> str | None:
    """Return :func:`_interval`'s verdict with the limits of ``LIMITS[kind]``."""
    lim = LIMITS[kind]
    return _interval(where, v, lim.low, lim.high, f"{lim.what} ({lim.unit})",
                     include_low=lim.include_low)


def _keys(m, where: str, names, optional=()) -> str | None:
    """Return what is wrong with a part's keys (a missing one, an unknown one), or None."""
    if not isinstance(m, dict):
        return f"{where} is {type(m).__name__}, expected an object"
    missing = [k for k in names if k not in m and k not in optional]
    if missing:
        return f"{where}.{missing[0]} is missing"
    unknown = sorted(map(str, set(m) - set(names)))
    if unknown:
        return f"{where}.{unknown[0]} is not one of its fields ({', '.join(names)})"
    return None


def _first(problems) -> str | None:
    """Return the first problem ``problems`` yields, or None.

    It stops there: a check may assume that the ones before it passed.
    """
    return next((p for p in problems if p), None)


def _check_state(d: dict) -> dict:
    """Return ``d`` (:meth:`Navigator.to_dict`) checked part by part (else InputError).

    Every part present with its type, every number finite and within its limits, the
    phase consistent with the rest: a state that passes gives answers, not errors.
    """
    for key, types in _STATE_SCHEMA.items():
        if key not in d:
            raise InputError(f"not a valid navigator state: the part {key!r} is missing")
        v = d[key]
        allowed = tuple(t for t in types if t is not None)
        ok = (v is None and None in types) or (isinstance(v, allowed)
                                               and not isinstance(v, bool))
        if not ok:
            raise InputError(f"not a valid navigator state: {key!r} is "
                             f"{type(v).__name__}, expected "
                             f"{' or '.join('null' if t is None else t.__name__ for t in types)}")
    unknown = sorted(set(d) - {"format", "version", *_STATE_SCHEMA})
    if unknown:
        raise InputError(f"not a valid navigator state: the part {unknown[0]!r} is not one of "
                         f"a state's ({', '.join(_STATE_SCHEMA)})")
    if d["phase"] not in ("warmup", "online"):
        raise InputError(f"not a valid navigator state: phase {d['phase']!r}, expected "
                         "'warmup' or 'online'")
    if (d["phase"] == "online") != (d["filter"] is not None and d["dp"] is not None):
        f = "null" if d["filter"] is None else "set"
        raise InputError("not a valid navigator state: the phase and the filter disagree "
                         f"(phase {d['phase']!r}, filter {f})")
    problem = _first(_state_problems(d))
    if problem:
        raise InputError(f"not a valid navigator state: {problem}")
    return d


def _state_problems(d: dict):
    """Yield the problems of a state whose parts have their types, in order."""
    yield _non_finite({k: d[k] for k in ("last", "first_time", "buffer", "windows", "filter",
                                         "models", "dp")})
    yield _keys(d["options"], "options", _OPTION_NAMES, optional=_OPTION_DEFAULTS)
    try:
        _options({**_OPTION_DEFAULTS, **d["options"]})
    except (ValueError, TypeError) as err:
        yield f"options.{err}"
    yield from _beacons_problems(d["beacons"])
    yield from _progress_problems(d)
    yield from (_warmup_problems if d["phase"] == "warmup" else _online_problems)(d)


def _beacons_problems(b: dict):
    cols = ("beacon", "x", "y", "depth")
    yield _keys(b, "beacons", cols)
    n = len(b["beacon"]) if isinstance(b["beacon"], list) else -1
    for k in cols:
        if not isinstance(b[k], list) or len(b[k]) != n or n < 1:
            yield (f"beacons.{k} is {b[k]!r:.40}, expected a list of one value per beacon "
                   f"({max(n, 1)} or more)")
    for i, bid in enumerate(b["beacon"]):
        if not isinstance(bid, str) or not bid:
            yield f"beacons.beacon[{i}] is {bid!r:.40}, expected a beacon's name (text)"
        for k in ("x", "y", "depth"):
            yield _limited(f"beacons.{k}[{i}]", b[k][i], k)
    if len(set(b["beacon"])) != n:
        yield "beacons.beacon names a beacon twice, expected each once"


def _progress_problems(d: dict):
    """Yield the problems of the seed, ``last`` and ``first_time``."""
    if d["seed"] < 0:
        yield f"seed is {d['seed']}, expected an integer >= 0"
    last, first = d["last"], d["first_time"]
    if (last is None) != (first is None):
        yield (f"last is {last!r:.40} and first_time {first!r:.40}, expected both null (no "
               "line yet) or both set")
    if last is None:
        return
    if len(last) != 3:
        yield f"last is {last!r:.60}, expected [time, x, y] (3 numbers)"
    for i, k in enumerate(("time", "x", "y")):
        yield _limited(f"last[{i}]", last[i], k)
    yield _interval("first_time", first, LIMITS["time"].low, last[0],
                    "a time (s) no later than last[0]")


def _warmup_problems(d: dict):
    """Yield the problems of the warm-up's kept replies and ranges (and of online leftovers)."""
    for key, empty in (("models", {}), ("warmup_record", None)):
        if d[key] != empty:
            yield f"{key} is {d[key]!r:.40}, expected {json.dumps(empty)} during the warm-up"
    buffer, known, warmup = d["buffer"], set(d["beacons"]["beacon"]), d["options"]["warmup"]
    if len(buffer) >= warmup:
        yield (f"buffer holds {len(buffer)} replies, expected fewer than the warm-up's "
               f"{warmup}")
    if buffer and d["last"] is None:
        yield "last is null with replies in buffer, expected [time, x, y] of the last line"
    spans = {}
    for i, row in enumerate(buffer):
        if not (isinstance(row, list) and len(row) == 6 and row[1] in known):
            yield (f"buffer[{i}] is {row!r:.60}, expected [time, a known beacon, range, x, y, "
                   "depth]")
        yield _interval(f"buffer[{i}][0]", row[0],
                        d["first_time"] if i == 0 else buffer[i - 1][0], d["last"][0],
                        "a time (s) between the reply before's (or first_time) and last[0]")
        for j, k in ((2, "range"), (3, "x"), (4, "y"), (5, "depth")):
            yield _limited(f"buffer[{i}][{j}]", row[j], k)
        lo, hi = spans.get(row[1], (row[2], row[2]))
        spans[row[1]] = (min(lo, row[2]), max(hi, row[2]))
    if set(d["windows"]) != set(spans):
        yield (f"windows has beacons {sorted(map(str, d['windows']))}, expected those of "
               f"buffer {sorted(spans)}")
    for bid, (lo, hi) in spans.items():
        w = d["windows"][bid]
        if not (isinstance(w, list) and len(w) == 2 and all(map(_is_number, w))
                and w[0] <= lo and hi <= w[1]):
            yield (f"windows.{bid} is {w!r:.60}, expected [smallest, largest] range of beacon "
                   f"{bid!r} in buffer ([{lo!r}, {hi!r}] or wider)")


def _online_problems(d: dict):
    """Yield the problems of the filter, the scales and every beacon's model."""
    for key, empty in (("buffer", []), ("windows", {})):
        if d[key] != empty:
            yield f"{key} is {d[key]!r:.40}, expected {json.dumps(empty)} after the warm-up"
    if d["last"] is None:
        yield "last is null, expected [time, x, y] of the last line after the warm-up"
    b = d["beacons"]
    xyz = {bid: [b["x"][i], b["y"][i], b["depth"][i]] for i, bid in enumerate(b["beacon"])}
    strangers = sorted(map(str, set(d["models"]) - set(xyz)))
    if strangers:
        yield f"beacon {strangers[0]!r} of its models is not among its beacons"
    record = d["warmup_record"]
    if not isinstance(record, dict) or not isinstance(record.get("beacons"), dict):
        yield (f"warmup_record is {record!r:.40}, expected the warm-up's record (an object "
               "with 'beacons')")
    lost = sorted(map(str, set(record["beacons"]) - set(d["models"])))
    if lost:
        yield (f"models.{lost[0]} is missing, expected a model for every beacon the warm-up "
               f"fitted ({', '.join(map(str, record['beacons']))})")
    yield from _filter_problems(d["filter"])
    yield from _dp_problems(d["dp"])
    for bid, m in d["models"].items():
        yield from _model_problems(m, f"models.{bid}", xyz[bid])


def _filter_problems(f: dict):
    from .ekf import COV_NAMES

    yield _keys(f, "filter", ("x", "y", "beta", "scale", "cov", "beta_walk", "scale_walk"))
    yield _limited("filter.x", f["x"], "x")
    yield _limited("filter.y", f["y"], "y")
    yield _interval("filter.beta", f["beta"], -_BETA_MAX, _BETA_MAX, "a heading bias (rad)")
    yield _interval("filter.scale", f["scale"], 0.0, _SCALE_MAX, "a speed scale",
                    include_low=False)
    for k in ("beta_walk", "scale_walk"):
        yield _interval(f"filter.{k}", f[k], *_OPTION_BOUNDS[k], "a random walk")
    c = f["cov"]
    yield _keys(c, "filter.cov", COV_NAMES)
    for k in COV_NAMES:
        if not _is_number(c[k]):
            yield f"filter.cov.{k} is {c[k]!r:.40}, expected a finite number"
    for k, top in (("xx", _POSITION_VAR_MAX), ("yy", _POSITION_VAR_MAX),
                   ("bb", _BETA_MAX ** 2), ("ss", _SCALE_MAX ** 2)):
        yield _interval(f"filter.cov.{k}", c[k], 0.0, top, "a variance", include_low=False)
    if not _positive_definite([c[k] for k in COV_NAMES]):
        yield ("filter.cov is not positive definite, expected the covariance of (x, y, beta, "
               f"s) (xx, xy, xb, xs, yy, ... = {', '.join(f'{c[k]:.3g}' for k in COV_NAMES)})")


def _positive_definite(p) -> bool:
    """Whether the 4 x 4 covariance of the upper triangle ``p`` (:data:`.ekf.COV_NAMES`) is.

    Cholesky of the correlation matrix (the diagonal checked > 0 before): scale-free, so a
    variance of 1e-7 rad^2 beside one of 1 m^2 is judged on the correlations alone.
    """
    rows = ((0, 1, 2, 3), (1, 4, 5, 6), (2, 5, 7, 8), (3, 6, 8, 9))
    sd = [math.sqrt(p[rows[i][i]]) for i in range(4)]
    r = [[p[rows[i][j]] / sd[i] / sd[j] for j in range(4)] for i in range(4)]
    low = [[0.0] * 4 for _ in range(4)]
    for j in range(4):
        pivot = r[j][j] - sum(low[j][k] ** 2 for k in range(j))
        if not pivot > 1e-12:
            return False
        low[j][j] = math.sqrt(pivot)
        for i in range(j + 1, 4):
            low[i][j] = (r[i][j] - sum(low[i][k] * low[j][k] for k in range(j))) / low[j][j]
    return True


def _dp_problems(dp: dict):
    yield _keys(dp, "dp", ("fixed", "n", "sigma", "stats"))
    yield _check_fields(dp, "dp", {"sigma": "positive", "n": "count", "fixed": "bool",
                                   "stats": "numbers"})
    yield _interval("dp.sigma", dp["sigma"], 0.0, LIMITS["range"].high, "a scale (m)",
                    include_low=False)
    s = dp["stats"]
    if len(s) != 2:
        yield f"dp.stats has {len(s)} numbers, expected 2 (<g_DP>, <g_DP r^2>)"
    yield _interval("dp.stats[0]", s[0], 0.0, 1.0 + _PROB_SLACK, "a mean probability")
    yield _interval("dp.stats[1]", s[1], 0.0, math.inf, "a mean square (m^2)")


#: The fields of a beacon's model in a saved state, and what each must be.
_MODEL_FIELDS = {"d0": "number", "d0_min": "number", "d0_ref": "number", "evidence": "number",
                 "sigma_mp": "positive", "sumsq": "number", "n": "count", "double": "bool",
                 "mp_on": "bool", "stats": "numbers", "weights": "numbers", "window": "numbers",
                 "xyz": "numbers", "alt": "any"}


def _check_fields(m, where: str, fields: dict) -> str | None:
    """Return what is wrong with one part of a state (a missing field, a wrong type), or None."""
    if not isinstance(m, dict):
        return f"{where} is {type(m).__name__}, expected an object"
    for k, kind in fields.items():
        if k not in m:
            return f"{where}.{k} is missing"
        v = m[k]
        if kind == "any":
            continue
        if kind == "bool":
            ok = isinstance(v, bool)
        elif kind == "count":
            ok = isinstance(v, int) and not isinstance(v, bool) and v >= 1
        elif kind == "numbers":
            ok = isinstance(v, list) and all(map(_is_number, v))
        else:
            ok = _is_number(v) and (kind != "positive" or v > 0)
        if not ok:
            return f"{where}.{k} is {v!r:.40}, expected {_KIND_WORDS[kind]}"
    return None


_KIND_WORDS = {"bool": "true or false", "count": "a count >= 1",
               "numbers": "a list of finite numbers", "number": "a finite number",
               "positive": "a positive number"}


def _model_problems(m, where: str, xyz: list, *, alt: bool = False):
    """Yield the problems of a beacon's model (``xyz``: the beacon's position)."""
    from .reflector import BEACON_STATS

    yield _keys(m, where, tuple(_MODEL_FIELDS))
    yield _check_fields(m, where, _MODEL_FIELDS)
    for k, n in (("weights", 3), ("window", 2), ("xyz", 3), ("stats", len(BEACON_STATS))):
        if len(m[k]) != n:
            yield f"{where}.{k} has {len(m[k])} numbers, expected {n}"
    top, s, w = LIMITS["range"].high, m["stats"], m["weights"]
    for k in ("d0", "d0_min", "d0_ref"):
        yield _interval(f"{where}.{k}", m[k], 0.0, top, "a plane height (m)")
    yield _interval(f"{where}.sigma_mp", m["sigma_mp"], 0.0, top, "a scale (m)",
                    include_low=False)
    yield _interval(f"{where}.sumsq", m["sumsq"], 0.0, 1.0, "a sum of squared weights",
                    include_low=False)
    for i in range(3):
        yield _interval(f"{where}.weights[{i}]", w[i], 0.0, 1.0, "a weight")
    if abs(sum(w) - 1.0) > 1e-6:
        yield f"{where}.weights sum to {sum(w)!r}, expected 1"
    for i in range(3):
        yield _interval(f"{where}.stats[{i}]", s[i], 0.0, 1.0 + _PROB_SLACK,
                        f"a mean probability (<{BEACON_STATS[i]}>)")
    for i in (3, 5):
        yield _interval(f"{where}.stats[{i}]", s[i], 0.0, math.inf,
                        f"a mean square (<{BEACON_STATS[i]}>)")
    yield _limited(f"{where}.window[0]", m["window"][0], "range")
    yield _interval(f"{where}.window[1]", m["window"][1], m["window"][0], top,
                    "a range (m) no shorter than window[0]")
    if list(m["xyz"]) != list(xyz):
        yield f"{where}.xyz is {m['xyz']!r:.60}, expected the beacon's x, y, depth {xyz!r:.60}"
    if m["alt"] is None:
        return
    if alt:
        yield f"{where}.alt is {m['alt']!r:.40}, expected null (an alternative has none)"
    yield from _model_problems(m["alt"], f"{where}.alt", xyz, alt=True)
    if m["alt"]["double"] == m["double"]:
        yield (f"{where}.alt.double is {m['double']}, expected the other geometry than "
               f"{where}.double")


#: Parts of a state in which every value is a number (no null).
_NUMBERS_ONLY = ("last", "windows", "filter", "dp")


def _non_finite(doc, path="") -> str | None:
    """Return where a number is not finite (or null where a number belongs) in a state."""
    if isinstance(doc, dict):
        items = doc.items()
    elif isinstance(doc, (list, tuple)):
        items = ((f"[{i}]", v) for i, v in enumerate(doc))
    else:
        items = ()
    for k, v in items:
        if k == "warmup_record" or (k == "stats" and v is None):
            continue
        sub = f"{path}{k}" if str(k).startswith("[") else (f"{path}.{k}" if path else str(k))
        if v is None and path.split(".")[0].split("[")[0] in _NUMBERS_ONLY and k != "fixed":
            return f"{sub} is null, expected a number"
        if isinstance(v, float) and not math.isfinite(v):
            return f"{sub} is {v!r}, expected a finite number"
        if isinstance(v, (dict, list, tuple)):
            problem = _non_finite(v, sub)
            if problem:
                return problem
    return None
