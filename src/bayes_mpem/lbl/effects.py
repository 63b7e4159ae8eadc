"""The effects a survey can hide: the shared vocabulary of the simulator and the diagnosis.

:func:`bayes_mpem.lbl.simulate.simulate_survey` hides them in simulated data
(``effects={"range_bias": 5.0, ...}``) and :func:`bayes_mpem.diagnose` names
them in measured data. Every effect is common to all beacons (one clock, one
sound speed, one sea surface, one navigation); magnitudes are the change from
the first to the last ping where the effect drifts.
"""

from __future__ import annotations

import numpy as np

#: Effects the simulator can hide and the diagnosis can find.
EFFECTS = ("range_bias", "sound_speed", "plane_drift", "second_reflector", "early_outliers",
           "nav_drift")
#: Unit of each effect's magnitude.
UNITS = {"range_bias": "m", "sound_speed": "1", "plane_drift": "m", "second_reflector": "m",
         "early_outliers": "1", "nav_drift": "m"}
#: Options of the simulator's effects that are not effects themselves.
EFFECT_OPTIONS = ("second_fraction", "nav_drift_direction")


def check_effects(effects):
    """Validate a mapping of effect names to magnitudes (and the effect options).

    Parameters
    ----------
    effects : dict or None
        Names of :data:`EFFECTS` or :data:`EFFECT_OPTIONS` to finite numbers.

    Returns
    -------
    dict
        The same, as floats.

    Raises
    ------
    ValueError
        An unknown name, a value that is not a finite number, or one out of range.
    """
    eff = dict(effects or {})
    unknown = set(eff) - set(EFFECTS) - set(EFFECT_OPTIONS)
    if unknown:
        raise ValueError(f"effects: unknown name(s) {sorted(unknown)}; known: {list(EFFECTS)}")
    for k, v in eff.items():
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
    return eff


def effect_weights(w, eff, bid):
    """Return the class probabilities (dp, mp, mp2, ol) once the effects are applied.

    Parameters
    ----------
    w : sequence of 3 float
        The beacon's weights of dp, mp and ol without effects.
    eff : dict
        Checked effects (:func:`check_effects`).
    bid : str
        The beacon, for the error message.

    Returns
    -------
    numpy.ndarray
        Four probabilities.
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
