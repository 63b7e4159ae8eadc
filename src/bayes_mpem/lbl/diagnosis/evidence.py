"""What a kept effect means, in words and numbers, and which fits are not credible."""

from __future__ import annotations

import numpy as np

from ..simulation.effects import EFFECTS, split_term
from .constraints import SECOND_GAP, main_plane
from .ecm import JointFit
from .model import Ranges, predict


def effect_evidence(name, fit: JointFit, d: Ranges, delta, se, n_folds):
    """Describe a kept effect and the held-out gain that supports it.

    Parameters
    ----------
    name : str
        The effect's term.
    delta, se : float
        Held-out gain (nats) and its standard error.
    """
    mag = fit.magnitudes(d)[name]
    gain = f"held-out log predictive density +{delta:.1f} ± {se:.1f} nats ({n_folds}-fold CV)"
    p = fit.params
    name, bid = split_term(name)
    if bid is not None:
        return f"{_beacon_evidence(name, bid, mag, p, d)}; {gain}"
    if name == "range_bias":
        what = f"ranges are {abs(mag):.2f} m too {'long' if mag > 0 else 'short'}"
    elif name == "sound_speed":
        what = (f"ranges are scaled by {1 + mag:.5f}: a sound speed {abs(mag) * 100:.2f} % too "
                f"{'high' if mag > 0 else 'low'}")
    elif name == "plane_drift":
        what = (f"the reflector moves {abs(mag):.2f} m {'deeper' if mag > 0 else 'shallower'} "
                "from the first to the last ping")
    elif name == "second_reflector":
        share = float(fit.resp[:, 2].mean())
        what = (f"{share * 100:.1f} % of replies bounce off a second plane {mag:.1f} m deep")
    elif name == "early_outliers":
        late = _late_share(d, fit)
        what = (f"{mag * 100:.1f} % of replies are outliers, all before the true arrival "
                f"(share after it: {late * 100:.1f} %)")
    else:
        err = -p.nav
        what = (f"the reported navigation is off by {mag:.1f} m at the last ping "
                f"(east {err[0]:+.1f} m, north {err[1]:+.1f} m), growing with time")
    return f"{what}; {gain}"


def _beacon_evidence(name, bid, mag, p, d):
    j = d.ids.index(bid)
    if name == "beacon_bias":
        return (f"beacon {bid}'s ranges are {abs(mag):.2f} m too "
                f"{'long' if mag > 0 else 'short'} (its own turn-around time or delay)")
    e, n = -p.bpos[j, :2]
    return (f"beacon {bid}'s reported position is {mag:.1f} m from where its ranges put it, "
            f"horizontally (reported minus fitted: east {e:+.1f} m, north {n:+.1f} m)")


def _late_share(d, fit: JointFit):
    mu = predict(d, fit.params, fit.effects, fit.path)
    p_ol = fit.resp[:, 3]
    late = (d.z > mu["dp"]) * p_ol
    return float(late.sum() / max(p_ol.sum(), 1e-12))


# --------------------------------------------------------------------------- driver


def check_effect_names(names, what):
    """Check that every name is in :data:`~bayes_mpem.lbl.simulation.effects.EFFECTS`.

    Parameters
    ----------
    what : str
        The option's name, for the message.

    Raises
    ------
    ValueError
    """
    bad = [e for e in names if split_term(e)[0] not in EFFECTS]
    if bad:
        raise ValueError(f"{what}: unknown effect(s) {bad}; known: {list(EFFECTS)}")


#: A second family must hold at least this share of the replies (and 20 of them).
MIN_SECOND_SHARE = 0.01


def not_credible(name, fit: JointFit, d: Ranges):
    """Say why a fitted extension is not a physical effect (``None`` if it is).

    A range bias, or a beacon's bias or position error, longer than every range of the
    survey is not an offset of a transponder: one beacon's ranges logged two-way were
    "explained" by a bias of -2,737 km and a beacon moved 2,739 km, both kept.
    """
    kind = split_term(name)[0]
    if kind in ("range_bias", "beacon_bias", "beacon_position"):
        size, longest = abs(fit.magnitudes(d)[name]), float(np.nanmax(d.z))
        if size > longest:
            return (f"{size:,.4g} m, longer than every range of the survey ({longest:,.0f} m): "
                    "not a physical offset (ranges in other units, or two-way?)")
        return None
    if kind != "second_reflector":
        return None
    share = float(fit.resp[:, 2].mean())
    if share < MIN_SECOND_SHARE or share * d.n < 20:
        return (f"the second family holds {share * 100:.2f} % of the replies "
                f"(< {MIN_SECOND_SHARE * 100:g} % or < 20 replies): a few coincident ranges, "
                "not a reflector")
    if fit.params.plane2 - (main_plane(fit.params) + SECOND_GAP) < 1.0:
        return (f"the second plane sits on its bound ({SECOND_GAP:g} m below the main "
                "reflector): not located")
    return None


def effect_magnitude_se(name, fit: JointFit):
    """Approximate standard error of an effect's magnitude (None where the fit gives none)."""
    se = fit.se
    name, bid = split_term(name)
    if name == "beacon_bias":
        return se.get(f"bbias[{bid}]")
    if name == "beacon_position":
        v = [se.get(f"bpos_{c}[{bid}]") for c in "xy"]
        return None if None in v else float(np.sqrt(np.mean(np.square(v))))
    if name == "range_bias":
        return se.get("bias")
    if name == "sound_speed":
        return se.get("scale")
    if name == "plane_drift":
        return se.get("drift")
    if name == "second_reflector":
        return se.get("plane2")
    if name == "nav_drift" and "nav_x" in se:
        return float(np.hypot(se["nav_x"], se["nav_y"]) / np.sqrt(2.0))
    return None


def effect_detail(name, fit: JointFit, d: Ranges | None = None):
    """Extra numbers of an effect for the report (error at the last ping, share, position offset).

    Parameters
    ----------
    d : Ranges, optional
        Needed for a ``beacon_position`` term.
    """
    p = fit.params
    name, bid = split_term(name)
    if name == "beacon_position" and d is not None:
        err = -p.bpos[d.ids.index(bid)]
        return {"east": float(err[0]), "north": float(err[1]),
                "direction_deg": float(np.degrees(np.arctan2(err[1], err[0])) % 360.0)}
    if name == "nav_drift":
        err = -p.nav
        return {"east_at_last_ping": float(err[0]), "north_at_last_ping": float(err[1]),
                "direction_deg": float(np.degrees(np.arctan2(err[1], err[0])) % 360.0)}
    if name == "second_reflector":
        return {"fraction": float(fit.resp[:, 2].mean())}
    return {}
