"""Survey presets of the LBL simulator: the ABE dive 58 survey and random surveys."""

from __future__ import annotations

import numpy as np

from ..._validate import check_choice

PRESETS = ("abe58", "random")

#: ABE dive 58 as described in the paper: recorded beacon depths (Table II),
#: sigma_DP fitted by the authors, sigma_MP like Table II's.
ABE58 = {
    "beacons": {
        "1": {"x": -800.0, "y": 1800.0, "depth": 2392.0},
        "2": {"x": 2600.0, "y": 1700.0, "depth": 2491.0},
        "3": {"x": 600.0, "y": -600.0, "depth": 2395.0},
        "4": {"x": 3500.0, "y": -800.0, "depth": 2472.0},
    },
    "sigma_dp": 3.97,
    "sigma_mp": {"1": 4.2, "2": 10.5, "3": 14.0, "4": 6.9},
    "weights": {
        "1": (0.70, 0.20, 0.10),
        "2": (0.60, 0.25, 0.15),
        "3": (0.55, 0.30, 0.15),
        "4": (0.50, 0.35, 0.15),
    },
    "n_cycles": 1315,  # ~5,000 replies after 5 % of pings go unanswered
    "box": (0.0, 1500.0, 0.0, 1200.0),
    "line_spacing": 100.0,
    "seafloor": 2430.0,
    "altitude": 30.0,
    "relief": 50.0,
    "p_no_reply": 0.05,
    "window": (1.0, 6000.0),
    "cycle_seconds": 12.0,
}



def _random_config(gen):
    """Draw a random survey configuration (3-5 beacons, depths 800-4,500 m)."""
    nb = int(gen.integers(3, 6))
    seafloor = float(gen.uniform(800.0, 4500.0))
    half = float(gen.uniform(600.0, 2000.0))
    box = (-half, half, -half * 0.8, half * 0.8)
    beacons = {}
    for i in range(nb):
        ang = 2 * np.pi * i / nb + gen.uniform(-0.4, 0.4)
        rad = half * gen.uniform(0.8, 2.0)
        beacons[str(i + 1)] = {"x": float(rad * np.cos(ang)), "y": float(rad * np.sin(ang)),
                               "depth": float(seafloor + gen.uniform(-60.0, 60.0))}
    weights = {}
    for k in beacons:
        w_mp = gen.uniform(0.12, 0.45)
        w_ol = gen.uniform(0.03, 0.2)
        weights[k] = (1.0 - w_mp - w_ol, w_mp, w_ol)
    altitude = float(gen.uniform(20.0, 0.5 * seafloor))  # from near-bottom to mid-water
    return {
        "beacons": beacons,
        "sigma_dp": float(gen.uniform(1.0, 6.0)),
        "sigma_mp": {k: float(gen.uniform(3.0, 20.0)) for k in beacons},
        "weights": weights,
        "n_cycles": int(gen.integers(800, 2000)),
        "box": box,
        "line_spacing": float(gen.uniform(80.0, 250.0)),
        "seafloor": seafloor,
        "altitude": altitude,
        "relief": float(gen.uniform(0.0, 60.0)),
        "p_no_reply": float(gen.uniform(0.0, 0.15)),
        "window": (1.0, float(3.0 * seafloor + 4.0 * half)),
        "cycle_seconds": float(gen.uniform(5.0, 20.0)),
    }


def lawnmower_track(box, spacing, n_points):
    """``(x, y)`` evenly spaced along a lawnmower pattern covering ``box`` (tracklines along x).

    Parameters
    ----------
    box : tuple of 4 floats
        ``(xmin, xmax, ymin, ymax)`` (m).
    """
    xmin, xmax, ymin, ymax = box
    ys = np.arange(ymin, ymax + 1e-9, spacing)
    verts = []
    for i, yv in enumerate(ys):
        xs = (xmin, xmax) if i % 2 == 0 else (xmax, xmin)
        verts += [(xs[0], yv), (xs[1], yv)]
    verts = np.asarray(verts)
    seg = np.hypot(*np.diff(verts, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    t = np.linspace(0.0, s[-1], int(n_points))
    return np.interp(t, s, verts[:, 0]), np.interp(t, s, verts[:, 1])


def _seafloor(x, y, mean, relief):
    return mean + relief * np.sin(2 * np.pi * x / 1500.0) + 0.6 * relief * np.cos(
        2 * np.pi * y / 900.0)


def preset_config(preset: str, gen, n_cycles: int | None = None,
                  overrides: dict | None = None) -> dict:
    """Return the settings of a preset survey, with ``overrides`` and ``n_cycles`` applied.

    Raises
    ------
    ValueError
        For an unknown preset or override.
    """
    check_choice("preset", preset, PRESETS)
    cfg = dict(ABE58) if preset == "abe58" else _random_config(gen)
    cfg.setdefault("plane_depth", 0.0)
    unknown = set(overrides or {}) - set(cfg)
    if unknown:
        raise ValueError(f"unknown simulation option(s) {sorted(unknown)}; "
                         f"known: {sorted(cfg)}")
    cfg.update(overrides or {})
    if n_cycles is not None:
        cfg["n_cycles"] = int(n_cycles)
    return cfg


def preset_track(cfg: dict) -> dict:
    """Return the bottom-following lawnmower track of a preset (one point per cycle).

    Parameters
    ----------
    cfg : dict
        From :func:`preset_config`.

    Returns
    -------
    dict
        Arrays ``time``, ``x``, ``y``, ``depth``.
    """
    x, y = lawnmower_track(cfg["box"], cfg["line_spacing"], cfg["n_cycles"])
    seafloor = _seafloor(x, y, cfg["seafloor"], cfg["relief"])
    return {"time": np.arange(x.size) * cfg["cycle_seconds"], "x": x, "y": y,
            "depth": np.maximum(seafloor - cfg["altitude"], 1.0)}
