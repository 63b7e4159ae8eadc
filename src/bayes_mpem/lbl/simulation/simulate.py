"""Simulated LBL surveys with known truth."""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..._rng import RNGLike, as_generator
from ...acoustics.profile import SoundSpeedProfile
from ...acoustics.profile_checks import check_profile, check_sound_speed, nominal_sound_speed
from ...acoustics.turning import direct_times
from ...io.results import write_file, writing
from ...io.survey import Survey, load_survey
from ..model import geometry
from ..model.refracted import lbl_ranges
from .effects import EFFECTS, check_effects, effect_weights, per_beacon_target
from .presets import lawnmower_track, preset_config, preset_track  # noqa: F401 (re-exported)


@dataclass(frozen=True)
class Simulation:
    """A simulated survey and its truth.

    Attributes
    ----------
    survey : Survey
        As a user's files would give it, plus a ``true_class`` column.
    truth : dict
        Per beacon: ``d0``, ``plane_depth``, ``sigma_dp``, ``sigma_mp``, ``weights``, ``path``.
    labels : numpy.ndarray
        True class of every ping (``"no_reply"`` too).
    config : dict
        Everything needed to rerun the simulation.
    """

    survey: Survey
    truth: dict
    labels: np.ndarray = field(repr=False)
    config: dict = field(default_factory=dict, repr=False)

    def write(self, out_dir) -> dict:
        """Write ``pings.csv``, ``beacons.csv`` and ``truth.json`` to ``out_dir`` (created).

        Parameters
        ----------
        out_dir : str or pathlib.Path

        Returns
        -------
        dict
            The paths written, keyed ``pings``, ``beacons``, ``truth``.
        """
        truth = json.dumps({"beacons": self.truth, "config": self.config}, indent=2,
                           default=float) + "\n"
        with writing(out_dir) as out:
            return {
                "pings": write_file(out / "pings.csv", lambda tmp: self.survey.table.to_csv(
                    tmp, index=False, na_rep="", float_format="%.3f")),
                "beacons": write_file(out / "beacons.csv", lambda tmp: self.survey.beacons
                                      .reset_index().to_csv(tmp, index=False)),
                "truth": write_file(out / "truth.json", lambda tmp: tmp.write_text(truth))}


def simulate_lbl(
    beacons: dict,
    track: dict,
    *,
    sigma_dp: float,
    sigma_mp: dict,
    weights: dict,
    plane_depth: float = 0.0,
    path: str = "triangle",
    p_no_reply: float = 0.05,
    window: tuple = (1.0, 6000.0),
    beacon_offset: float = 1.0,
    effects: dict | None = None,
    rng: RNGLike = None,
    ssp: SoundSpeedProfile | None = None,
    sound_speed: float | None = None,
) -> Simulation:
    """Simulate the replies of every beacon along a given track.

    Parameters
    ----------
    beacons : dict
        ``{id: {"x", "y", "depth"}}`` (m, depth positive down).
    track : dict
        Arrays ``time`` (s, one per ping cycle), ``x``, ``y``, ``depth``.
    sigma_mp, weights : dict
        Per beacon: the multipath scatter (m) and ``(w_dp, w_mp, w_ol)``.
    window : tuple of float, default (1, 6000)
        Listening window (m) of the uniform outliers.
    beacon_offset : float, default 1
        Seconds between the interrogations of successive beacons in a cycle.
    effects : dict, optional
        ``{name: magnitude}`` of :data:`~bayes_mpem.lbl.simulation.effects.EFFECTS`
        and :data:`~bayes_mpem.lbl.simulation.effects.EFFECT_OPTIONS` (``docs/diagnose.md``).
    ssp : SoundSpeedProfile, optional
        Refract the rays through this profile; a reply with no eigenray becomes an outlier.
    sound_speed : float, optional
        Nominal speed (m/s) that turns travel times into ranges; only with ``ssp``.

    Raises
    ------
    ValueError
        An unknown effect or impossible magnitude; ``sound_speed`` without ``ssp``; a profile
        that does not reach the beacons or the vehicle; a reflector below them with ``ssp``.
    TypeError
        ``ssp`` is not a :class:`~bayes_mpem.acoustics.SoundSpeedProfile`.
    """
    geometry.check_path(path)
    eff = check_effects(effects)
    gen = as_generator(rng)
    t, x, y, z = (np.asarray(track[k], float) for k in ("time", "x", "y", "depth"))
    refr = _check_ssp(ssp, sound_speed, beacons, z, plane_depth, eff)
    times = t[:, None] + np.arange(len(beacons))[None, :] * beacon_offset
    opts = {"eff": eff, "refr": refr, "t0": float(times.min()), "t1": float(times.max()),
            "scale": 1.0 + eff.get("sound_speed", 0.0), "bias": eff.get("range_bias", 0.0),
            "sigma_dp": sigma_dp, "plane_depth": plane_depth, "path": path,
            "p_no_reply": p_no_reply, "window": window}
    rows, truth, labels = [], {}, []
    n_ol = n_replies = 0
    target, offset = per_beacon_target(eff, beacons)
    for j, (bid, b) in enumerate(beacons.items()):
        w = np.asarray(weights[bid], float)
        if w.shape != (3,) or np.any(w < 0) or abs(w.sum() - 1) > 1e-9:
            raise ValueError(f"weights[{bid!r}]: expected 3 non-negative numbers summing to 1, "
                             f"got {weights[bid]!r}")
        own = opts if bid != target else {**opts, "bias": opts["bias"]
                                          + eff.get("beacon_bias", 0.0)}
        frame, truth[bid] = _beacon_replies(gen, bid, b, w, sigma_mp[bid],
                                            (t + j * beacon_offset, x, y, z), own)
        if bid == target and offset is not None:
            truth[bid]["reported_offset"] = offset.tolist()
        rows.append(frame)
        labels.append(frame["true_class"].to_numpy())
        n_ol += int(np.sum(labels[-1] == "ol"))
        n_replies += int(np.sum(labels[-1] != "no_reply"))
    pings = pd.concat(rows, ignore_index=True).sort_values("time", kind="stable")
    order = pings.index.to_numpy()
    pings = pings.reset_index(drop=True)
    reported = {k: dict(v) for k, v in beacons.items()}
    if offset is not None:
        for key, dv in zip(("x", "y", "depth"), offset, strict=True):
            reported[target][key] = float(reported[target][key]) + float(dv)
    bdf = pd.DataFrame([{"beacon": k, **v} for k, v in reported.items()])
    survey = load_survey(pings, bdf)
    all_labels = np.concatenate(labels)[order]
    realised = {k: v for k, v in eff.items() if k in EFFECTS}
    if "early_outliers" in realised:
        realised["early_outliers"] = n_ol / max(n_replies, 1)
    for v in truth.values():
        v["effects"] = realised
    config = {"beacons": beacons, "sigma_dp": sigma_dp, "sigma_mp": sigma_mp,
              "weights": {k: list(v) for k, v in weights.items()}, "plane_depth": plane_depth,
              "path": path, "p_no_reply": p_no_reply, "window": list(window),
              "effects": dict(eff)}
    if refr is not None:
        config["ssp"] = {"source": refr[0].source, "depth": refr[0].depths.tolist(),
                         "speed": refr[0].speeds.tolist()}
        config["sound_speed"] = refr[1]
    return Simulation(survey=survey, truth=truth, labels=all_labels, config=config)


def _model_ranges(refr, h, z, depth, d0_t, path, second):
    """Noise-free direct, multipath and second-reflector ranges, and the direct rays."""
    dz = depth - z
    rays = mp2 = None
    if refr is None:
        direct = geometry.direct_path(h, dz)
        mp = geometry.multipath_range(h, dz, d0_t, path, direct=direct)
    else:
        rays = direct_times(refr[0], z, depth, h)
        direct = refr[1] * rays.time
        mp = lbl_ranges(refr[0], refr[1], h, z, depth, depth - d0_t, path,
                        direct=rays).multipath
    if second is not None:
        if refr is None:
            mp2 = geometry.multipath_range(h, dz, depth - second, "triangle", direct=direct)
        else:
            mp2 = lbl_ranges(refr[0], refr[1], h, z, depth, second, "triangle",
                             direct=rays).multipath
    return direct, mp, mp2, rays


def _draw_ranges(gen, w4, model, sigma_mp, opts):
    """Draw each ping's class and range, in the simulator's fixed order of random draws."""
    direct, mp, mp2, _ = model
    eff, n, window = opts["eff"], direct.size, opts["window"]
    scale, bias = opts["scale"], opts["bias"]
    if w4[2] > 0:
        cls = gen.choice(4, size=n, p=w4)
    else:  # the clean stream of draws, unchanged by the effects machinery
        cls = np.array([0, 1, 3])[gen.choice(3, size=n, p=w4[[0, 1, 3]])]
    rng_dp = scale * direct + bias + gen.normal(0.0, opts["sigma_dp"], n)
    rng_mp = scale * mp + bias + gen.normal(0.0, sigma_mp, n)
    rng_mp2 = rng_mp
    if mp2 is not None:
        rng_mp2 = scale * mp2 + bias + gen.normal(0.0, sigma_mp, n)
    if "early_outliers" in eff:
        # (with a profile, a ping with no direct eigenray: uniform over the whole window)
        arrival = (rng_dp if opts["refr"] is None
                   else np.where(np.isnan(rng_dp), window[1], rng_dp))
        rng_ol = window[0] + gen.random(n) * np.maximum(arrival - window[0], 0.0)
    else:
        rng_ol = gen.uniform(window[0], window[1], n)
    r = np.choose(cls, [rng_dp, rng_mp, rng_mp2, rng_ol])
    no_ray = np.isnan(r)  # (only with a profile: a class whose eigenray does not exist)
    below = ~no_ray & ~(r > 0)  # a range_bias beyond the range: no such direct path
    r = np.where(r > 0, r, rng_ol)  # a non-positive draw becomes an outlier, and is one
    lab = np.asarray(["dp", "mp", "mp2", "ol"], dtype=object)[cls]
    silent = gen.random(n) < opts["p_no_reply"]
    no_ray_counts = {c: int(np.sum(no_ray & ~silent & (lab == c))) for c in ("dp", "mp", "mp2")}
    lab[no_ray | below] = "ol"
    r = np.where(silent, np.nan, r)
    lab[silent] = "no_reply"
    return r, lab, no_ray_counts


def _beacon_replies(gen, bid, b, w, sigma_mp, ping, opts):
    """Simulate one beacon: its pings table and its ``truth`` entry (without ``effects``)."""
    eff, refr, plane_depth = opts["eff"], opts["refr"], opts["plane_depth"]
    tb, x, y, z = ping
    t0, t1 = opts["t0"], opts["t1"]
    tau = (tb - t0) / (t1 - t0) if t1 > t0 else np.zeros_like(tb)
    w4 = effect_weights(w, eff, bid)
    d0 = float(b["depth"]) - plane_depth
    h = geometry.horizontal_distance(x, y, b["x"], b["y"])
    d0_t = d0 - eff.get("plane_drift", 0.0) * tau
    model = _model_ranges(refr, h, z, float(b["depth"]), d0_t, opts["path"],
                          eff.get("second_reflector"))
    r, lab, no_ray_counts = _draw_ranges(gen, w4, model, sigma_mp, opts)
    xr, yr = x, y
    if "nav_drift" in eff:
        ang = np.deg2rad(eff.get("nav_drift_direction", 45.0))
        xr = x + eff["nav_drift"] * tau * np.cos(ang)
        yr = y + eff["nav_drift"] * tau * np.sin(ang)
    frame = pd.DataFrame({"time": tb, "beacon": bid, "range": r,
                          "x": xr, "y": yr, "depth": z, "true_class": lab})
    truth = {"d0": d0, "plane_depth": plane_depth, "sigma_dp": float(opts["sigma_dp"]),
             "sigma_mp": float(sigma_mp),
             "weights": dict(zip(("dp", "mp", "ol"), map(float, w), strict=True)),
             "path": opts["path"]}
    if eff:
        truth["weights_with_effects"] = dict(
            zip(("dp", "mp", "mp2", "ol"), map(float, w4), strict=True))
    if refr is not None:
        truth.update(sound_speed=refr[1], ssp=refr[0].source or repr(refr[0]),
                     no_ray={c: n for c, n in no_ray_counts.items()
                             if c != "mp2" or "second_reflector" in eff},
                     turning_direct=int(np.sum((lab != "no_reply") & model[3].turning)))
    return frame, truth


def _check_ssp(ssp, sound_speed, beacons, z, plane_depth, eff):
    """``(profile, nominal speed)`` for a refracted simulation, or None for straight rays."""
    if ssp is None:
        if sound_speed is not None:
            raise ValueError("sound_speed: only used with a sound-speed profile (ssp=...); "
                             "to scale straight-ray ranges use effects={'sound_speed': ...}")
        return None
    depths = np.array([float(b["depth"]) for b in beacons.values()])
    deepest = max(float(depths.max()), float(z.max()) if z.size else 0.0)
    check_profile(ssp, deepest)
    c_nom = (nominal_sound_speed(ssp, float(depths.mean())) if sound_speed is None
             else check_sound_speed(sound_speed))
    top = min(float(depths.min()), float(z.min()) if z.size else np.inf)
    planes = {"plane_depth": float(plane_depth) + max(0.0, eff.get("plane_drift", 0.0))}
    if "second_reflector" in eff:
        planes["effects['second_reflector']"] = eff["second_reflector"]
    for name, zp in planes.items():
        if zp > top:
            raise ValueError(f"{name}: a refracted multipath needs the reflector above the "
                             f"vehicle and the beacons; it reaches {zp:g} m but the shallowest "
                             f"beacon or vehicle depth is {top:g} m")
    return ssp, c_nom


def simulate_survey(
    preset: str = "abe58",
    *,
    rng: RNGLike = None,
    path: str = "triangle",
    n_cycles: int | None = None,
    effects: dict | None = None,
    ssp: SoundSpeedProfile | None = None,
    sound_speed: float | None = None,
    **overrides,
) -> Simulation:
    """Simulate a bottom-following LBL survey from a preset.

    Parameters
    ----------
    preset : {"abe58", "random"}
        The paper's dive (:data:`~bayes_mpem.lbl.simulation.presets.ABE58`), or a plausible
        configuration drawn from ``rng``.
    rng : None, int or numpy.random.Generator
    path : {"triangle", "double"}
    n_cycles : int, optional
        Ping cycles (one interrogation of every beacon each).
    effects, ssp, sound_speed : optional
        See :func:`simulate_lbl`.
    **overrides
        Replace any preset entry (``weights``, ``sigma_mp``, ``plane_depth``, ...).

    Returns
    -------
    Simulation

    Raises
    ------
    ValueError
        For an unknown preset or override.
    """
    gen = as_generator(rng)
    cfg = preset_config(preset, gen, n_cycles, overrides)
    track = preset_track(cfg)
    sim = simulate_lbl(
        cfg["beacons"], track, sigma_dp=cfg["sigma_dp"], sigma_mp=cfg["sigma_mp"],
        weights=cfg["weights"], plane_depth=cfg["plane_depth"], path=path,
        p_no_reply=cfg["p_no_reply"], window=tuple(cfg["window"]), effects=effects, rng=gen,
        ssp=ssp, sound_speed=sound_speed,
    )
    config = {**sim.config, "preset": preset, "n_cycles": cfg["n_cycles"],
              "box": list(cfg["box"]), "altitude": cfg["altitude"]}
    return Simulation(sim.survey, sim.truth, sim.labels, config)
