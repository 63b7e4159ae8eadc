"""The effects a survey can hide: the shared vocabulary of the simulator and the diagnosis."""

from __future__ import annotations

import numpy as np

#: Effects the simulator can hide and the diagnosis can find.
EFFECTS = ("range_bias", "sound_speed", "plane_drift", "second_reflector", "early_outliers",
           "nav_drift", "beacon_bias", "beacon_position")
#: The effects of one beacon (the others are shared by all beacons).
PER_BEACON = ("beacon_bias", "beacon_position")
#: Unit of each effect's magnitude (``beacon_position``: the distance between the
#: reported and the true position).
UNITS = {"range_bias": "m", "sound_speed": "1", "plane_drift": "m", "second_reflector": "m",
         "early_outliers": "1", "nav_drift": "m", "beacon_bias": "m", "beacon_position": "m"}
#: Options of the simulator's effects that are not effects themselves: ``second_fraction``
#: (the direct replies the second plane takes, default 0.15), ``nav_drift_direction``
#: (degrees from +x, default 45), ``beacon`` (the beacon of the per-beacon effects; default
#: the first), and the direction of a position error, ``beacon_position_direction`` (degrees
#: counter-clockwise from +x, default 45) and ``beacon_position_dip`` (degrees below the
#: horizontal, default 0).
EFFECT_OPTIONS = ("second_fraction", "nav_drift_direction", "beacon",
                  "beacon_position_direction", "beacon_position_dip")


def term(name: str, beacon=None) -> str:
    """Name an effect as the diagnosis does: ``name``, or ``"name:beacon"`` for one beacon's."""
    return name if beacon is None else f"{name}:{beacon}"


def split_term(t: str) -> tuple:
    """Split a term of :func:`term` into ``(effect name, beacon or None)``."""
    name, _, beacon = t.partition(":")
    return name, (beacon or None)


def term_order(t: str) -> tuple:
    """Sort key of terms: the order of :data:`EFFECTS`, then the beacon."""
    name, beacon = split_term(t)
    return EFFECTS.index(name), beacon or ""


def check_effects(effects):
    """Validate a mapping of effect names (and options) to magnitudes; return it as floats.

    Parameters
    ----------
    effects : dict or None
        Names of :data:`EFFECTS` or :data:`EFFECT_OPTIONS` (``"beacon"``: a beacon id).

    Raises
    ------
    ValueError
        An unknown name, a value that is not a finite number, or one out of range.
    """
    eff = dict(effects or {})
    unknown = set(eff) - set(EFFECTS) - set(EFFECT_OPTIONS)
    if unknown:
        raise ValueError(f"effects: unknown name(s) {sorted(unknown)}; known: {list(EFFECTS)}")
    if "beacon" in eff:
        eff["beacon"] = str(eff["beacon"])
    for k, v in eff.items():
        if k == "beacon":
            continue
        if not isinstance(v, (int, float, np.integer, np.floating)) or not np.isfinite(v):
            raise ValueError(f"effects[{k!r}]: expected a finite number, got {v!r}")
        eff[k] = float(v)
    if eff.get("sound_speed", 0.0) <= -1.0:
        raise ValueError(f"effects['sound_speed']: expected > -1, got {eff['sound_speed']}")
    if "early_outliers" in eff and not 0.0 <= eff["early_outliers"] < 1.0:
        raise ValueError("effects['early_outliers']: expected an outlier fraction in [0, 1), "
                         f"got {eff['early_outliers']}")
    if not 0.0 <= eff.get("second_fraction", 0.15) < 1.0:
        raise ValueError("effects['second_fraction']: expected a fraction in [0, 1), "
                         f"got {eff['second_fraction']}")
    # an option without the effect it shapes would be ignored without a word
    needs = {"second_fraction": ("second_reflector",), "nav_drift_direction": ("nav_drift",),
             "beacon": PER_BEACON, "beacon_position_direction": PER_BEACON,
             "beacon_position_dip": PER_BEACON}
    for option, effects_of in needs.items():
        if option in eff and not any(k in eff for k in effects_of):
            raise ValueError(f"effects[{option!r}]: shapes {' or '.join(effects_of)}, which is "
                             "not given; expected it with that effect")
    return eff


def effect_weights(w, eff, bid):
    """Return the class probabilities (dp, mp, mp2, ol) once the effects are applied.

    Parameters
    ----------
    w : sequence of 3 float
        The beacon's weights of dp, mp and ol without effects.
    """
    w_dp, w_mp, w_ol = (float(v) for v in w)
    w_mp2 = eff.get("second_fraction", 0.15) if "second_reflector" in eff else 0.0
    if "early_outliers" in eff:
        w_dp += w_ol - eff["early_outliers"]
        w_ol = eff["early_outliers"]
    w_dp -= w_mp2
    if w_dp <= 0:
        raise ValueError(f"beacon {bid!r}: the effects leave no direct path "
                         f"(w_dp = {w_dp:.3f}); lower the outlier or second-reflector fraction")
    return np.array([w_dp, w_mp, w_mp2, w_ol])


def per_beacon_target(eff, beacons):
    """Return the beacon of the per-beacon effects (or None) and its reported position's offset.

    Parameters
    ----------
    beacons : dict
        The survey's beacons, by id (the first is the default target).

    Returns
    -------
    target : str or None
    offset : numpy.ndarray or None
        Reported minus true position (east, north, down; m) with ``beacon_position``.

    Raises
    ------
    ValueError
        For an unknown ``effects["beacon"]``.
    """
    if not any(k in eff for k in PER_BEACON):
        return None, None
    target = eff.get("beacon", next(iter(beacons)))
    if target not in beacons:
        raise ValueError(f"effects['beacon']: expected one of {list(beacons)}, got {target!r}")
    if "beacon_position" not in eff:
        return target, None
    az = np.deg2rad(eff.get("beacon_position_direction", 45.0))
    dip = np.deg2rad(eff.get("beacon_position_dip", 0.0))
    return target, eff["beacon_position"] * np.array(
        [np.cos(dip) * np.cos(az), np.cos(dip) * np.sin(az), np.sin(dip)])
