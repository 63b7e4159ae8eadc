"""The M-step's objective of the navigation model, and its Gauss-Newton normal equations.

Given the class probabilities and the scales, ``(p_1 .. p_K, beta, s, d0_1 .. d0_B)`` minimise::

    Phi = 1/2 sum_i [a_i (f_dp,i - z_i)^2 + b_i (f_mp,i - z_i)^2]
        + 1/2 sum_k lambda_k |p_k - p_{k-1} - s R(beta) Delta_k|^2
        + 1/2 |p_1 - d_1|^2 / s_start^2 + 1/2 beta^2 / s_beta^2 + 1/2 (s - 1)^2 / s_scale^2
        + 1/2 sum_b (d0_b - z_b)^2 / s_plane^2

with ``a_i = P(dp)_i / sigma_DP^2``, ``b_i = P(mp)_i / sigma_MP,b^2``,
``lambda_k = 1 / (q^2 dt_k)`` (the dead-reckoning random walk), ``d_1`` the
first dead-reckoned fix and ``z_b`` the beacon depth; the weak priors of
``docs/navigate.md`` (*The model*).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .dive import Dive
from .model import RangePrediction, predict_ranges, rotation
from .normal import Normal


class Priors(NamedTuple):
    """The weak priors and the random-walk level of the model.

    Attributes
    ----------
    q : float
        Dead-reckoning random-walk level (m / sqrt(s)).
    start_sd : float
        Prior sd of the first position about the first dead-reckoned fix (m).
    heading_sd : float
        Prior sd of the heading bias (rad), centred on 0.
    scale_sd : float
        Prior sd of the speed scale, centred on 1.
    plane_sd : float
        Prior sd of each plane height about the sea surface (m).
    min_dt : float
        Floor on the time between epochs (s), against an infinite weight.
    range_scale_sd : float
        Prior sd of the range scale (about 1), where it is estimated.
    """

    q: float
    start_sd: float
    heading_sd: float
    scale_sd: float
    plane_sd: float
    min_dt: float = 1e-3
    range_scale_sd: float = 0.01


@dataclass(frozen=True)
class State:
    """The parameters of the navigation model.

    Attributes
    ----------
    track : numpy.ndarray
        ``(K, 2)`` horizontal positions at the epochs (m).
    beta : float
        Heading bias of the dead reckoning (rad).
    scale : float
        Speed scale of the dead reckoning.
    d0 : numpy.ndarray
        ``(B,)`` plane heights above the beacons (m).
    double : numpy.ndarray
        ``(B,)`` bool: the beacon's multipath is the double bounce (else triangle).
    sigma_dp : float
        Direct-path scale (m), shared by every beacon (a property of the sensor).
    sigma_mp : numpy.ndarray
        ``(B,)`` multipath scales (m).
    weights : numpy.ndarray
        ``(B, 3)`` mixing weights of dp, mp, ol.
    range_scale : float
        Every predicted range is multiplied by it (a sound-speed scale: the
        ranges' sound speed over the true mean one); 1 unless estimated.
    """

    track: np.ndarray
    beta: float
    scale: float
    d0: np.ndarray
    double: np.ndarray
    sigma_dp: float
    sigma_mp: np.ndarray
    weights: np.ndarray
    range_scale: float = 1.0

    def replace(self, **changes) -> State:
        """Return a copy with ``changes``.

        Parameters
        ----------
        **changes
            Fields to replace.
        """
        return dataclasses.replace(self, **changes)


def predictions(dive: Dive, state: State, track=None, d0=None,
                range_scale=None) -> RangePrediction:
    """Predicted ranges of every reply at ``state`` (or at another track / plane heights).

    Every range and derivative is multiplied by the range scale.

    Parameters
    ----------
    track : numpy.ndarray, optional
        ``(K, 2)`` instead of ``state.track``.
    d0 : numpy.ndarray, optional
        ``(B,)`` instead of ``state.d0``.
    range_scale : float, optional
        Instead of ``state.range_scale``.
    """
    track = state.track if track is None else track
    d0 = state.d0 if d0 is None else d0
    k = state.range_scale if range_scale is None else range_scale
    p = track[dive.epoch]
    b = dive.beacon
    xyz = dive.beacon_xyz[b]
    pred = predict_ranges(p[:, 0], p[:, 1], dive.zdepth, (xyz[:, 0], xyz[:, 1], xyz[:, 2]),
                          d0[b], state.double[b])
    if k == 1.0:
        return pred
    return RangePrediction(*(k * v for v in pred))


def _motion_residuals(dive: Dive, track, beta, scale):
    """``(K - 1, 2)``: ``p_k - p_{k-1} - s R(beta) Delta_k`` for every step."""
    R, _ = rotation(beta)
    return track[1:] - track[:-1] - scale * (dive.delta @ R.T)


def _motion_weights(dive: Dive, priors: Priors) -> np.ndarray:
    """``lambda_k = 1 / (q^2 dt_k)`` of every step (``dt`` floored at ``priors.min_dt``).

    Where the dead-reckoning table has a gap, the step's variance grows by
    ``dive.dr_gap_var`` (the motion across the gap is unknown).
    """
    var = priors.q ** 2 * np.maximum(dive.dt, priors.min_dt)
    if dive.dr_gap_var is not None:
        var = var + dive.dr_gap_var
    return 1.0 / var


def prior_penalty(dive: Dive, state: State, priors: Priors, track=None, beta=None, scale=None,
                  d0=None, range_scale=None) -> float:
    """Return the motion and prior part of the objective (``Phi`` without the ranges).

    Parameters
    ----------
    track, beta, scale, d0, range_scale : optional
        Values to use instead of the state's.
    """
    track = state.track if track is None else track
    beta = state.beta if beta is None else beta
    scale = state.scale if scale is None else scale
    d0 = state.d0 if d0 is None else d0
    k = state.range_scale if range_scale is None else range_scale
    u = _motion_residuals(dive, track, beta, scale)
    lam = _motion_weights(dive, priors)
    start = track[0] - dive.dr[0]
    plane = d0 - dive.beacon_xyz[:, 2]
    return 0.5 * float(np.add.reduce(lam * (u * u).sum(axis=1))
                       + (start @ start) / priors.start_sd ** 2
                       + beta * beta / priors.heading_sd ** 2
                       + (scale - 1.0) ** 2 / priors.scale_sd ** 2
                       + np.add.reduce(plane * plane) / priors.plane_sd ** 2
                       + (k - 1.0) ** 2 / priors.range_scale_sd ** 2)


def objective(dive: Dive, state: State, a, b, priors: Priors, **values) -> float:
    """``Phi`` of the module docstring at ``state`` (or at the ``values`` given).

    Parameters
    ----------
    a, b : numpy.ndarray
        ``(n,)`` weights of the direct-path and multipath squared residuals.
    **values
        ``track``, ``beta``, ``scale``, ``d0``, ``range_scale`` to use instead of the
        state's.
    """
    pred = predictions(dive, state, values.get("track"), values.get("d0"),
                       values.get("range_scale"))
    e_dp, e_mp = pred.direct - dive.z, pred.multipath - dive.z
    ranges = 0.5 * float(np.add.reduce(a * e_dp * e_dp + b * e_mp * e_mp))
    return ranges + prior_penalty(dive, state, priors, **values)


def _range_terms(dive, pred, a, b, k):
    """Track blocks and gradient of the range terms, summed per epoch."""
    def acc(w):
        return np.bincount(dive.epoch, weights=w, minlength=k)

    gd, gm = pred.grad_direct, pred.grad_multipath
    e_dp, e_mp = pred.direct - dive.z, pred.multipath - dive.z
    diag = np.column_stack([acc(a * gd[:, 0] ** 2 + b * gm[:, 0] ** 2),
                            acc(a * gd[:, 0] * gd[:, 1] + b * gm[:, 0] * gm[:, 1]),
                            acc(a * gd[:, 1] ** 2 + b * gm[:, 1] ** 2)])
    grad = np.column_stack([acc(a * gd[:, 0] * e_dp + b * gm[:, 0] * e_mp),
                            acc(a * gd[:, 1] * e_dp + b * gm[:, 1] * e_mp)])
    return diag, grad, e_mp


def _range_scale_terms(dive, state, pred, a, b, free_d0, priors, B, C, grad_g):
    """Fill the range scale's column (the last global) of ``B``, ``C`` and ``grad_g``."""
    k, c = dive.n_epochs, C.shape[0] - 1
    kk = state.range_scale
    jd, jm = pred.direct / kk, pred.multipath / kk  # derivatives of the ranges in the scale
    e_dp, e_mp = pred.direct - dive.z, pred.multipath - dive.z
    gd, gm = pred.grad_direct, pred.grad_multipath
    for ax in range(2):
        B[:, ax, c] = np.bincount(dive.epoch, weights=a * gd[:, ax] * jd + b * gm[:, ax] * jm,
                                  minlength=k)
    C[c, c] = np.add.reduce(a * jd * jd + b * jm * jm) + 1.0 / priors.range_scale_sd ** 2
    for col, j in enumerate(free_d0, start=2):
        m = dive.beacon == j
        C[c, col] = C[col, c] = np.add.reduce(b[m] * pred.d_multipath_d0[m] * jm[m])
    grad_g[c] = (np.add.reduce(a * jd * e_dp + b * jm * e_mp)
                 + (kk - 1.0) / priors.range_scale_sd ** 2)


def normal_equations(dive: Dive, state: State, a, b, priors: Priors, free_d0,
                     free_k: bool = False) -> Normal:
    """Gradient and Gauss-Newton Hessian of :func:`objective` in the sparse form.

    The globals are ordered ``beta, scale, d0[free_d0[0]], d0[free_d0[1]], ...``,
    then the range scale if ``free_k``.

    Parameters
    ----------
    a, b : numpy.ndarray
        ``(n,)`` weights of the direct-path and multipath squared residuals.
    free_d0 : sequence of int
        Beacons whose plane height is estimated.
    free_k : bool, default False
        Estimate the range scale.
    """
    k = dive.n_epochs
    pred = predictions(dive, state)
    diag, grad, e_mp = _range_terms(dive, pred, a, b, k)
    g = 2 + len(free_d0) + bool(free_k)
    B = np.zeros((k, 2, g))
    C = np.zeros((g, g))
    grad_g = np.zeros(g)
    for col, j in enumerate(free_d0, start=2):
        m = np.flatnonzero(dive.beacon == j)
        w = b[m] * pred.d_multipath_d0[m]
        for ax in range(2):
            B[:, ax, col] = np.bincount(dive.epoch[m], weights=w * pred.grad_multipath[m, ax],
                                        minlength=k)
        C[col, col] = np.add.reduce(w * pred.d_multipath_d0[m]) + 1.0 / priors.plane_sd ** 2
        grad_g[col] = (np.add.reduce(w * e_mp[m])
                       + (state.d0[j] - dive.beacon_xyz[j, 2]) / priors.plane_sd ** 2)
    if free_k:
        _range_scale_terms(dive, state, pred, a, b, free_d0, priors, B, C, grad_g)
    lam = _motion_weights(dive, priors)
    R, dR = rotation(state.beta)
    rot = dive.delta @ R.T
    u = state.track[1:] - state.track[:-1] - state.scale * rot
    V = np.stack([-state.scale * (dive.delta @ dR.T), -rot], axis=-1)  # (K-1, 2, 2)
    for col in (0, 2):
        diag[:-1, col] += lam
        diag[1:, col] += lam
    grad[1:] += lam[:, None] * u
    grad[:-1] -= lam[:, None] * u
    lv = lam[:, None, None] * V
    B[1:, :, :2] += lv
    B[:-1, :, :2] -= lv
    C[:2, :2] += np.einsum("kag,kah->gh", lv, V)
    grad_g[:2] += np.einsum("kag,ka->g", lv, u)
    diag[0, 0] += 1.0 / priors.start_sd ** 2
    diag[0, 2] += 1.0 / priors.start_sd ** 2
    grad[0] += (state.track[0] - dive.dr[0]) / priors.start_sd ** 2
    C[0, 0] += 1.0 / priors.heading_sd ** 2
    grad_g[0] += state.beta / priors.heading_sd ** 2
    C[1, 1] += 1.0 / priors.scale_sd ** 2
    grad_g[1] += (state.scale - 1.0) / priors.scale_sd ** 2
    return Normal(diag, lam, B.reshape(2 * k, g), C, grad.ravel(), grad_g)


def missing_information(dive: Dive, state: State, resp, free_d0, free_k: bool = False):
    """Return the information the uncertain classes cost (Louis, 1982), in the sparse layout.

    Subtracted from :func:`normal_equations`, it gives the observed information of the
    mixture (``docs/navigate.md``, *Uncertainty*).

    Parameters
    ----------
    resp : numpy.ndarray
        ``(n, 3)`` class probabilities.
    free_d0 : sequence of int
        Beacons whose plane height is estimated (the globals' order of
        :func:`normal_equations`).
    free_k : bool, default False
        The range scale is estimated (the last global).

    Returns
    -------
    diag : numpy.ndarray
        ``(K, 3)`` to subtract from :attr:`.normal.Normal.diag`.
    B : numpy.ndarray
        ``(2K, G)`` to subtract from :attr:`.normal.Normal.B`.
    C : numpy.ndarray
        ``(G, G)`` to subtract from :attr:`.normal.Normal.C`.
    """
    k = dive.n_epochs
    pred = predictions(dive, state)
    p_d, p_m = resp[:, 0], resp[:, 1]
    su = (pred.direct - dive.z) / state.sigma_dp ** 2
    u = su[:, None] * pred.grad_direct
    sv = (pred.multipath - dive.z) / state.sigma_mp[dive.beacon] ** 2
    v = sv[:, None] * pred.grad_multipath
    cu, cv, cx = p_d * (1 - p_d), p_m * (1 - p_m), p_d * p_m
    block = (cu[:, None, None] * u[:, :, None] * u[:, None, :]
             + cv[:, None, None] * v[:, :, None] * v[:, None, :]
             - cx[:, None, None] * (u[:, :, None] * v[:, None, :] + v[:, :, None] * u[:, None, :]))
    diag = np.column_stack([np.bincount(dive.epoch, weights=block[:, a, b], minlength=k)
                            for a, b in ((0, 0), (0, 1), (1, 1))])
    g = 2 + len(free_d0) + bool(free_k)
    B = np.zeros((k, 2, g))
    C = np.zeros((g, g))
    vd = sv * pred.d_multipath_d0
    for col, j in enumerate(free_d0, start=2):
        m = dive.beacon == j
        for ax in range(2):
            w = (cv[m] * v[m, ax] - cx[m] * u[m, ax]) * vd[m]
            B[:, ax, col] = np.bincount(dive.epoch[m], weights=w, minlength=k)
        C[col, col] = np.add.reduce(cv[m] * vd[m] ** 2)
    if free_k:  # the scores in the range scale: su * f_dp / s, sv * f_mp / s
        c = g - 1
        uk = su * pred.direct / state.range_scale
        vk = sv * pred.multipath / state.range_scale
        for ax in range(2):
            w = (cu * u[:, ax] * uk + cv * v[:, ax] * vk
                 - cx * (u[:, ax] * vk + v[:, ax] * uk))
            B[:, ax, c] = np.bincount(dive.epoch, weights=w, minlength=k)
        C[c, c] = np.add.reduce(cu * uk * uk + cv * vk * vk - 2.0 * cx * uk * vk)
        for col, j in enumerate(free_d0, start=2):
            m = dive.beacon == j
            C[c, col] = C[col, c] = np.add.reduce((cv[m] * vk[m] - cx[m] * uk[m]) * vd[m])
    return diag, B.reshape(2 * k, g), C
