"""The parameters of the diagnosis' joint model, and the vector the Gauss-Newton step moves."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..simulation.effects import split_term

#: The mean parameters of each shared effect, in the order of the vector.
SHARED_KEYS = {"range_bias": ["bias"], "sound_speed": ["scale"], "plane_drift": ["drift"],
               "second_reflector": ["plane2"], "nav_drift": ["nav_x", "nav_y"]}
#: The mean parameters of each per-beacon effect (per beacon it is on).
#: A beacon's position is corrected horizontally: at the low elevations of a
#: near-bottom survey its depth trades off against its own plane (both move the
#: multipath alike, and the direct path barely sees it), so a depth error shows as
#: that beacon's plane off the sea surface instead (the plane check of the flags).
BEACON_KEYS = {"beacon_bias": ["bbias"], "beacon_position": ["bpos_x", "bpos_y"]}


@dataclass
class Params:
    """Parameters of the joint model (effect parameters unused while switched off).

    Attributes
    ----------
    plane : numpy.ndarray
        Per beacon, the depth of its reflecting plane at the first ping (m).
    sigma : numpy.ndarray
        ``(B, 3)`` scatter (m) of the direct path, multipath and second multipath.
    weights : numpy.ndarray
        ``(B, 4)`` weights of direct path, multipath, second multipath, outlier.
    bias, scale, drift, plane2 : float
        Range bias (m), sound-speed scale minus 1, plane drift over the survey (m), depth of
        the second plane (m).
    nav : numpy.ndarray
        Navigation correction (east, north; m) at the last ping, growing linearly from 0.
    bbias : numpy.ndarray
        ``(B,)`` each beacon's own range bias (m).
    bpos : numpy.ndarray
        ``(B, 3)`` true minus reported beacon position (east, north, down; m).
    """

    plane: np.ndarray       # (B,) plane depth at the first ping
    sigma: np.ndarray       # (B, 3) dp, mp, mp2
    weights: np.ndarray     # (B, 4) dp, mp, mp2, ol
    bias: float = 0.0
    scale: float = 0.0      # f = factor - 1
    drift: float = 0.0      # plane depth change, first -> last ping
    plane2: float = np.nan  # second plane depth
    nav: np.ndarray = field(default_factory=lambda: np.zeros(2))  # correction at the last ping
    bbias: np.ndarray | None = None  # (B,) a beacon's own range bias
    bpos: np.ndarray | None = None   # (B, 3) true minus reported beacon position (e, n, down)

    def __post_init__(self):  # noqa: D105
        nb = len(self.plane)
        self.bbias = np.zeros(nb) if self.bbias is None else np.asarray(self.bbias, float)
        self.bpos = np.zeros((nb, 3)) if self.bpos is None else np.asarray(self.bpos, float)

    def copy(self) -> Params:
        """Return a deep copy (arrays copied)."""
        return Params(self.plane.copy(), self.sigma.copy(), self.weights.copy(), self.bias,
                      self.scale, self.drift, self.plane2, self.nav.copy(), self.bbias.copy(),
                      self.bpos.copy())


def beacons_with(effects, name, ids) -> list:
    """Return the indices of the beacons the per-beacon effect ``name`` is on for."""
    out = []
    for t in effects:
        eff, bid = split_term(t)
        if eff == name and bid is not None:
            out.append(list(ids).index(bid))
    return sorted(out)


def beacon_mask(effects, name, ids):
    """Return a boolean per beacon: is ``name`` on for it."""
    m = np.zeros(len(ids), bool)
    m[beacons_with(effects, name, ids)] = True
    return m


def mean_names(effects, ids):
    """Names of the mean parameters fitted by Gauss-Newton: planes, shared, then per-beacon.

    Returns
    -------
    list of tuple
        ``("plane", j)`` for every beacon, ``(name, None)`` for the shared effects' parameters,
        ``(name, j)`` for the per-beacon ones.
    """
    names = [("plane", j) for j in range(len(ids))]
    for e, keys in SHARED_KEYS.items():
        if e in effects:
            names += [(k, None) for k in keys]
    for e, keys in BEACON_KEYS.items():
        for j in beacons_with(effects, e, ids):
            names += [(k, j) for k in keys]
    return names


_BPOS = {"bpos_x": 0, "bpos_y": 1, "bpos_z": 2}


def get_vector(p: Params, names):
    """Gather the mean parameters ``names`` (:func:`mean_names`) into a vector."""
    out = []
    for k, j in names:
        if k == "plane":
            out.append(p.plane[j])
        elif k == "nav_x":
            out.append(p.nav[0])
        elif k == "nav_y":
            out.append(p.nav[1])
        elif k == "bbias":
            out.append(p.bbias[j])
        elif k in _BPOS:
            out.append(p.bpos[j, _BPOS[k]])
        else:
            out.append(getattr(p, k))
    return np.asarray(out, float)


def set_vector(p: Params, names, v) -> Params:
    """Copy ``p`` with the mean parameters ``names`` set from the vector ``v``."""
    q = p.copy()
    for (k, j), val in zip(names, v, strict=True):
        if k == "plane":
            q.plane[j] = val
        elif k == "nav_x":
            q.nav[0] = val
        elif k == "nav_y":
            q.nav[1] = val
        elif k == "bbias":
            q.bbias[j] = val
        elif k in _BPOS:
            q.bpos[j, _BPOS[k]] = val
        else:
            setattr(q, k, float(val))
    return q


def without(p: Params, term, ids) -> Params:
    """Copy ``p`` with the parameters of ``term`` reset (the effect switched off)."""
    q = p.copy()
    name, bid = split_term(term)
    if bid is not None:
        j = list(ids).index(bid)
        if name == "beacon_bias":
            q.bbias[j] = 0.0
        else:
            q.bpos[j] = 0.0
    elif name == "range_bias":
        q.bias = 0.0
    elif name == "sound_speed":
        q.scale = 0.0
    elif name == "plane_drift":
        q.plane = q.plane + 0.5 * q.drift  # keep the mean plane
        q.drift = 0.0
    elif name == "nav_drift":
        q.nav = np.zeros(2)
    elif name == "second_reflector":
        q.weights[:, 3] += q.weights[:, 2]
        q.weights[:, 2] = 0.0
        q.plane2 = np.nan
    return q
