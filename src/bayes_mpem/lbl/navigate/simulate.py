"""Simulated dives for navigation: a true track, a drifting dead reckoning, LBL replies.

Examples
--------
>>> sim = simulate_dive("abe58", rng=0, n_cycles=50, heading_bias=1.0)
>>> sim.truth["navigation"]["heading_bias_deg"], len(sim.true_track)
(1.0, 50)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..._rng import RNGLike, as_generator
from ..._validate import check_positive, check_range
from ...io.results import write_csv, writing
from ...io.survey import Survey, load_survey
from ..model import geometry
from ..simulation.presets import preset_config, preset_track
from ..simulation.simulate import Simulation, simulate_lbl
from .model import rotation


@dataclass(frozen=True)
class DiveSimulation:
    """A simulated dive: dead-reckoned pings, and the truth.

    Attributes
    ----------
    simulation : Simulation
        The pings (``x``, ``y`` dead-reckoned; ``true_class`` column) and beacons;
        ``config["navigation"]`` holds the dead-reckoning errors and shadowing.
    true_track : pandas.DataFrame
        One row per cycle: ``time``, ``x``, ``y``, ``depth`` (the truth), ``dr_x``,
        ``dr_y`` (the dead reckoning) and ``n_blocked`` (beacons whose direct path
        is blocked then).
    blocked : numpy.ndarray
        ``(N,)`` bool per ping: its direct path was blocked.
    """

    simulation: Simulation
    true_track: pd.DataFrame = field(repr=False)
    blocked: np.ndarray = field(repr=False)

    @property
    def survey(self) -> Survey:
        """The dead-reckoned survey (what a navigation engineer has)."""
        return self.simulation.survey

    @property
    def labels(self) -> np.ndarray:
        """True class of every ping (``dp``, ``mp``, ``ol``, ``no_reply``)."""
        return self.simulation.labels

    @property
    def truth(self) -> dict:
        """Per beacon the reflector (as :class:`Simulation`), and ``navigation``."""
        return {**self.simulation.truth, "navigation": self.simulation.config["navigation"]}

    def write(self, out_dir) -> dict:
        """Write ``pings.csv``, ``beacons.csv``, ``truth.json`` and ``true_track.csv``.

        Parameters
        ----------
        out_dir : str or pathlib.Path
            Created if missing.

        Returns
        -------
        dict
            The paths written.
        """
        with writing(out_dir) as out:
            paths = self.simulation.write(out)
            paths["true_track"] = write_csv(out / "true_track.csv", self.true_track)
        return paths


def degrade(time, x, y, *, heading_bias, speed_scale, dr_noise, start_error, rng=None):
    """Make a dead reckoning from a true track, with the errors the navigation model assumes.

    Parameters
    ----------
    time, x, y : array_like
        The true track (s, m), times increasing.
    heading_bias : float
        Degrees, counter-clockwise.
    speed_scale : float
        True over dead-reckoned displacement.
    dr_noise : float
        Random-walk level ``q`` (m / sqrt(s)).
    start_error : float
        Standard deviation (m, per axis) of the first fix's error.

    Returns
    -------
    numpy.ndarray
        ``(K, 2)`` dead-reckoned positions.

    Examples
    --------
    >>> dr = degrade([0, 10, 20], [0, 10, 20], [0, 0, 0], heading_bias=90.0, speed_scale=1.0,
    ...              dr_noise=1e-9, start_error=0.0, rng=0)
    >>> np.round(dr, 6).tolist()
    [[0.0, 0.0], [0.0, -10.0], [0.0, -20.0]]
    """
    gen = as_generator(rng)
    p = np.column_stack([np.asarray(x, float), np.asarray(y, float)])
    dt = np.diff(np.asarray(time, float))
    w = gen.normal(0.0, 1.0, (dt.size, 2)) * (dr_noise * np.sqrt(dt))[:, None]
    R, _ = rotation(-np.deg2rad(heading_bias))
    delta = (np.diff(p, axis=0) - w) @ R.T / speed_scale
    start = p[0] + gen.normal(0.0, start_error, 2)
    return np.vstack([start, start + np.cumsum(delta, axis=0)])


def degrade_pings(pings, *, heading_bias, speed_scale=1.0, dr_noise=0.1, start_error=10.0,
                  rng=None):
    """Replace a pings table's true positions by a dead reckoning made from them (:func:`degrade`).

    Parameters
    ----------
    pings : pandas.DataFrame
        Columns ``time``, ``x``, ``y`` (the truth) and the rest of a pings table.
    heading_bias, speed_scale, dr_noise, start_error, rng
        As :func:`degrade`.

    Returns
    -------
    pings : pandas.DataFrame
        A copy with ``x``, ``y`` dead-reckoned.
    truth : pandas.DataFrame
        One row per distinct time: ``time``, ``x``, ``y`` (the truth), ``dr_x``, ``dr_y``.

    Examples
    --------
    >>> p = pd.DataFrame({"time": [0.0, 0.0, 60.0], "x": [0.0, 0.0, 60.0], "y": [0.0] * 3})
    >>> dr, truth = degrade_pings(p, heading_bias=0.0, dr_noise=1e-9, start_error=0.0, rng=0)
    >>> dr["x"].round(6).tolist(), len(truth)
    ([0.0, 0.0, 60.0], 2)
    """
    t = np.asarray(pings["time"], float)
    times, inv = np.unique(t, return_inverse=True)
    cnt = np.bincount(inv)
    x = np.bincount(inv, weights=np.asarray(pings["x"], float)) / cnt
    y = np.bincount(inv, weights=np.asarray(pings["y"], float)) / cnt
    dr = degrade(times, x, y, heading_bias=heading_bias, speed_scale=speed_scale,
                 dr_noise=dr_noise, start_error=start_error, rng=rng)
    out = pings.copy()
    out["x"], out["y"] = dr[inv, 0], dr[inv, 1]
    return out, pd.DataFrame({"time": times, "x": x, "y": y, "dr_x": dr[:, 0],
                              "dr_y": dr[:, 1]})


def _block(gen, table, cfg, truth, shadow_range, windows):
    """Turn blocked direct-path replies into surface bounces; return the blocked mask."""
    b = cfg["beacons"]
    bx = np.array([b[k]["x"] for k in table["beacon"]])
    by = np.array([b[k]["y"] for k in table["beacon"]])
    bz = np.array([b[k]["depth"] for k in table["beacon"]])
    h = np.hypot(table["true_x"].to_numpy() - bx, table["true_y"].to_numpy() - by)
    t = table["time"].to_numpy()
    blocked = np.zeros(len(table), bool)
    if shadow_range is not None:
        blocked |= h > shadow_range
    for t0, t1 in windows:
        blocked |= (t >= t0) & (t <= t1)
    turn = blocked & (table["true_class"].to_numpy() == "dp")
    dz = bz - table["depth"].to_numpy()
    d0 = np.array([truth[k]["d0"] for k in table["beacon"]])
    paths = np.array([truth[k]["path"] for k in table["beacon"]])
    mp = geometry.multipath_range(h, dz, d0, paths)
    s_mp = np.array([truth[k]["sigma_mp"] for k in table["beacon"]])
    noise = gen.normal(0.0, 1.0, len(table)) * s_mp
    table.loc[turn, "range"] = (mp + noise)[turn]
    table.loc[turn, "true_class"] = "mp"
    return blocked


def _check_windows(windows):
    out = []
    for i, w in enumerate(windows or ()):
        try:
            t0, t1 = (float(v) for v in w)
        except (TypeError, ValueError):
            raise ValueError(f"shadow_windows[{i}]: expected a pair of times (start, end), "
                             f"got {w!r}") from None
        if not t1 >= t0:
            raise ValueError(f"shadow_windows[{i}]: expected start <= end, got {w!r}")
        out.append((t0, t1))
    return out


def simulate_dive(
    preset: str = "abe58",
    *,
    rng: RNGLike = None,
    n_cycles: int | None = None,
    path: str = "triangle",
    heading_bias: float | None = None,
    speed_scale: float | None = None,
    dr_noise: float = 0.1,
    start_error: float = 10.0,
    shadow_range: float | None = None,
    shadow_windows=(),
    **overrides,
) -> DiveSimulation:
    """Simulate a dive: true track, drifting dead reckoning, LBL replies (optionally shadowed).

    Parameters
    ----------
    preset : {"abe58", "random"}
        The survey (beacons, noise, class weights, lawnmower track) of
        :func:`~bayes_mpem.lbl.simulation.simulate.simulate_survey`.
    rng : None, int or numpy.random.Generator
        The only source of randomness.
    n_cycles : int, optional
        Ping cycles (default: the preset's).
    path : {"triangle", "double"}
        Multipath geometry of the replies.
    heading_bias : float, optional
        Heading bias of the dead reckoning (degrees, counter-clockwise); default
        drawn uniform in [-2, 2].
    speed_scale : float, optional
        The true displacement is this times the dead-reckoned one; default
        drawn uniform in [0.98, 1.02].
    dr_noise : float, default 0.1
        Random-walk level ``q`` of the dead reckoning (m / sqrt(s)).
    start_error : float, default 10
        Standard deviation (m, per axis) of the first dead-reckoned fix's error.
    shadow_range : float, optional
        Block the direct path of every reply from a beacon farther than this
        (horizontal distance, m).
    shadow_windows : sequence of (float, float)
        Block the direct path of every reply between these times (s, inclusive).
    **overrides
        Preset entries to replace (``weights``, ``sigma_mp``, ``sigma_dp``, ...).

    Returns
    -------
    DiveSimulation

    Raises
    ------
    ValueError
        For an unknown preset or override, or a bad option.
    """
    check_positive("dr_noise", dr_noise)
    check_range("start_error", start_error, low=0, include_low=True)
    if shadow_range is not None:
        check_positive("shadow_range", shadow_range)
    windows = _check_windows(shadow_windows)
    gen = as_generator(rng)
    cfg = preset_config(preset, gen, n_cycles, overrides)
    track = preset_track(cfg)
    sim = simulate_lbl(cfg["beacons"], track, sigma_dp=cfg["sigma_dp"], sigma_mp=cfg["sigma_mp"],
                       weights=cfg["weights"], plane_depth=cfg["plane_depth"], path=path,
                       p_no_reply=cfg["p_no_reply"], window=tuple(cfg["window"]),
                       beacon_offset=0.0, rng=gen)
    beta = float(gen.uniform(-2.0, 2.0)) if heading_bias is None else float(heading_bias)
    scale = float(gen.uniform(0.98, 1.02)) if speed_scale is None else check_positive(
        "speed_scale", speed_scale)
    dr = degrade(track["time"], track["x"], track["y"], heading_bias=beta, speed_scale=scale,
                 dr_noise=float(dr_noise), start_error=float(start_error), rng=gen)
    table = sim.survey.table.copy()
    cycle = np.searchsorted(track["time"], table["time"].to_numpy())
    table["true_x"], table["true_y"] = track["x"][cycle], track["y"][cycle]
    blocked = _block(gen, table, cfg, sim.truth, shadow_range, windows)
    table["x"], table["y"] = dr[cycle, 0], dr[cycle, 1]
    labels = table["true_class"].to_numpy().astype(object)
    survey = load_survey(table.drop(columns=["true_x", "true_y"]), sim.survey.beacons.reset_index())
    n_blocked = np.bincount(cycle, weights=blocked, minlength=dr.shape[0]).astype(int)
    true_track = pd.DataFrame({"time": track["time"], "x": track["x"], "y": track["y"],
                               "depth": track["depth"], "dr_x": dr[:, 0], "dr_y": dr[:, 1],
                               "n_blocked": n_blocked})
    nav = {"heading_bias_deg": beta, "speed_scale": scale, "dr_noise": float(dr_noise),
           "start_error": float(start_error), "shadow_range": shadow_range,
           "shadow_windows": [list(w) for w in windows],
           "blocked_replies": int(np.sum(blocked & (labels != "no_reply")))}
    config = {**sim.config, "preset": preset, "n_cycles": cfg["n_cycles"],
              "box": list(cfg["box"]), "altitude": cfg["altitude"],
              "cycle_seconds": cfg["cycle_seconds"], "navigation": nav}
    return DiveSimulation(Simulation(survey, sim.truth, labels, config), true_track, blocked)


def stagger(sim: DiveSimulation) -> DiveSimulation:
    """Keep one beacon per cycle, in turn: the staggered schedule of a ship over an array.

    Cycle ``k`` keeps only its ping to beacon ``k mod B`` (the beacons in the
    order of the beacons table), so every epoch has at most one range, as a
    GNSS-A ship that interrogates one transponder per shot records them.

    Returns
    -------
    DiveSimulation
        The same truth, the pings thinned (``true_track`` keeps every cycle;
        ``n_blocked`` counts the kept pings only).

    Examples
    --------
    >>> sim = stagger(simulate_dive("abe58", rng=0, n_cycles=40))
    >>> int(sim.survey.table.groupby("time").size().max())
    1
    """
    table = sim.survey.table
    ids = [str(b) for b in sim.survey.beacons.index]
    cycle = np.searchsorted(sim.true_track["time"].to_numpy(), table["time"].to_numpy())
    keep = table["beacon"].astype(str).to_numpy() == np.asarray(ids, object)[cycle % len(ids)]
    survey = load_survey(table[keep].reset_index(drop=True),
                         sim.survey.beacons.reset_index())
    s = sim.simulation
    n_blocked = np.bincount(cycle[keep], weights=sim.blocked[keep],
                            minlength=len(sim.true_track)).astype(int)
    config = {**s.config, "schedule": "staggered"}
    return DiveSimulation(Simulation(survey, s.truth, s.labels[keep], config),
                          sim.true_track.assign(n_blocked=n_blocked), sim.blocked[keep])


def simulate_ship(*, rng: RNGLike = None, n_cycles: int = 1200, sigma_dp: float = 0.2,
                  transducer_depth: float = 8.0, outlier_weight: float = 0.02,
                  **kwargs) -> DiveSimulation:
    """Simulate a surface ship over the ABE58 array: staggered schedule, no multipath.

    The ``"abe58"`` preset with a flat sea floor, the transducer at
    ``transducer_depth`` m, every reply a direct path or (``outlier_weight``)
    an outlier, one beacon per cycle (:func:`stagger`).

    Parameters
    ----------
    sigma_dp : float, default 0.2
        Range noise (m).
    transducer_depth : float, default 8
        Depth of the ship's transducer (m).
    **kwargs
        Passed to :func:`simulate_dive` (``heading_bias``, ``dr_noise``, ...).

    Examples
    --------
    >>> sim = simulate_ship(rng=0, n_cycles=40)
    >>> set(sim.labels) <= {"dp", "ol", "no_reply"}
    True
    """
    cfg = preset_config("abe58", as_generator(0))
    w = (1.0 - outlier_weight, 0.0, outlier_weight)
    return stagger(simulate_dive(
        "abe58", rng=rng, n_cycles=n_cycles, sigma_dp=float(sigma_dp), relief=0.0,
        altitude=cfg["seafloor"] - float(transducer_depth),
        weights={b: w for b in cfg["beacons"]}, **kwargs))
