"""The ECM of the navigation model: E-step, conditional M-steps, annealed loop.

The steps: ``docs/navigate.md`` (*The estimator*).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ...mixture.densities import gaussian_logpdf, safe_log
from ...mixture.em import EMModel, run_em
from ...mixture.gauss_newton import safeguarded_step
from .dive import Dive
from .model import class_log_joint
from .normal import (
    cross_covariances,
    global_covariance,
    marginal_covariances,
    solve,
)
from .objective import Priors, State, normal_equations, objective, predictions, prior_penalty
from .options import MODELS, MULTIPATH  # noqa: F401 (re-exported)

#: Smallest share of a scale's replies left as residual degrees of freedom (see :func:`_scale`).
MIN_DOF = 0.1


@dataclass(frozen=True)
class Settings:
    """How the ECM runs (checked by :func:`~.driver.navigate`).

    Attributes
    ----------
    priors : Priors
    model : str
        One of :data:`MODELS`.
    mp_beacons : numpy.ndarray
        ``(B,)`` bool: beacons with a multipath class (``multipath="signal"``
        and enough replies).
    free_d0 : tuple of int
        Beacons whose plane height is estimated.
    fixed_resp : numpy.ndarray or None
        ``(n, 3)`` class probabilities given (the oracle), else None.
    fix_sigma_mp : numpy.ndarray
        ``(B,)`` bool: keep the beacon's sigma_MP as given.
    fix_sigma_dp : bool
    free_range_scale : bool
        Estimate the range scale (:attr:`.objective.State.range_scale`).
    sigma_floor : float
    anneal_start : float
    huber_c, gate : float
    gn_steps, max_iter : int
    tol : float
        Stop when no position moves more than ``tol`` m in an iteration, the
        plane heights neither, and the scales change by less than ``tol`` m.
    """

    priors: Priors
    model: str = "mixture"
    mp_beacons: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    free_d0: tuple = ()
    fixed_resp: np.ndarray | None = None
    fix_sigma_mp: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    fix_sigma_dp: bool = False
    free_range_scale: bool = False
    sigma_floor: float = 0.05
    anneal_start: float = 100.0
    huber_c: float = 1.345
    gate: float = 3.0
    gn_steps: int = 3
    max_iter: int = 300
    tol: float = 1e-3


#: the keys of :attr:`Run.history`
HISTORY = ("loglik", "log_posterior", "log_posterior_track", "anneal", "sigma_dp", "beta",
           "scale", "moved")


class Run(NamedTuple):
    """The outcome of :func:`run`.

    Attributes
    ----------
    state : State
    resp : numpy.ndarray
        ``(n, 3)`` class probabilities (or baseline weights) at ``state``.
    loglik : float
        Log-likelihood of the ranges at ``state`` (mixture; for a baseline the
        Gaussian log-likelihood of the weighted direct-path residuals).
    history : dict of list
        Per iteration: ``loglik``, ``log_posterior``, ``log_posterior_track`` (after
        the E- and track steps, at the iteration's starting scales and anneal floor),
        ``anneal``, ``sigma_dp``, ``beta``, ``scale``, ``moved`` (largest change, m).
    n_iter : int
    converged : bool
    """

    state: State
    resp: np.ndarray
    loglik: float
    history: dict
    n_iter: int
    converged: bool


def _effective_scales(state: State, tau: float):
    """Return sigma_DP and the sigma_MPs used at anneal floor ``tau``: ``max(sigma, tau)``."""
    return max(state.sigma_dp, tau), np.maximum(state.sigma_mp, tau)


def e_step(dive: Dive, state: State, settings: Settings, tau: float = 0.0):
    """Class probabilities (or a baseline's weights) and the log-likelihood of every reply.

    Parameters
    ----------
    tau : float, default 0
        Anneal floor of the scales.

    Returns
    -------
    resp : numpy.ndarray
        ``(n, 3)``.
    lse : numpy.ndarray
        ``(n,)`` per-reply log-likelihood.
    """
    s_dp, s_mp = _effective_scales(state, tau)
    pred = predictions(dive, state)
    b = dive.beacon
    if settings.model == "mixture" or settings.fixed_resp is not None:
        lw = safe_log(state.weights)
        lw[~settings.mp_beacons, 1] = -np.inf
        resp, lse = class_log_joint(dive.z, pred.direct, pred.multipath, s_dp, s_mp[b],
                                    dive.log_ol, lw[b])
        if settings.fixed_resp is not None:
            resp = settings.fixed_resp
        return resp, lse
    r = dive.z - pred.direct
    resp = np.zeros((dive.n, 3))
    if settings.model == "gaussian":
        resp[:, 0] = 1.0
    elif settings.model == "huber":
        resp[:, 0] = np.minimum(1.0, settings.huber_c * s_dp / np.maximum(np.abs(r), 1e-300))
    else:  # gate
        resp[:, 0] = np.abs(r) <= settings.gate * s_dp
    resp[:, 2] = 1.0 - resp[:, 0]
    return resp, resp[:, 0] * gaussian_logpdf(r, s_dp)


def _pack(state: State, free_d0, free_k=False):
    return np.concatenate([state.track.ravel(), [state.beta, state.scale],
                           state.d0[list(free_d0)], [state.range_scale] if free_k else []])


def _unpack(x, state: State, dive: Dive, free_d0, free_k=False):
    k = dive.n_epochs
    d0 = state.d0.copy()
    idx = list(free_d0)
    d0[idx] = np.clip(x[2 * k + 2:2 * k + 2 + len(idx)], dive.d0_min[idx], None)
    rs = float(min(max(x[-1], 0.5), 2.0)) if free_k else state.range_scale
    return state.replace(track=x[:2 * k].reshape(k, 2), beta=float(x[2 * k]),
                         scale=float(max(x[2 * k + 1], 1e-3)), d0=d0, range_scale=rs)


def gauss_newton(dive: Dive, state: State, a, b, settings: Settings) -> State:
    """Up to ``settings.gn_steps`` safeguarded Gauss-Newton steps on the track and globals.

    Parameters
    ----------
    a, b : numpy.ndarray
        ``(n,)`` weights of the squared direct-path and multipath residuals.

    Returns
    -------
    State
        Where the objective is no larger than at ``state`` (plane heights kept
        above every vehicle position, the speed scale positive).
    """
    free, fk = settings.free_d0, settings.free_range_scale
    pri = settings.priors

    def value(x):
        st = _unpack(x, state, dive, free, fk)
        return objective(dive, st, a, b, pri, track=st.track, beta=st.beta, scale=st.scale,
                         d0=st.d0, range_scale=st.range_scale), st

    current = objective(dive, state, a, b, pri)
    for _ in range(settings.gn_steps):
        ne = normal_equations(dive, state, a, b, pri, free, fk)
        try:
            step = solve(ne)
        except np.linalg.LinAlgError:
            break
        x = _pack(state, free, fk)
        out = safeguarded_step(value, x, np.concatenate([step.dp.ravel(), step.dg]), current)
        if out is None:
            break
        moved = float(np.max(np.abs(out.aux.track - state.track)))
        state, current = out.aux, out.value
        if moved < 1e-6:
            break
    return state


def leverages(dive: Dive, state: State, resp, settings: Settings):
    """Posterior variance of every reply's predicted ranges: ``J P J^T`` (Laplace).

    ``P`` from the class-weighted Gauss-Newton information at ``state``.

    Parameters
    ----------
    resp : numpy.ndarray
        ``(n, 3)`` class probabilities or weights.

    Returns
    -------
    v_dp, v_mp : numpy.ndarray or None
        ``(n,)`` each; None when the information cannot be factored.
    """
    a = resp[:, 0] / state.sigma_dp ** 2
    b = resp[:, 1] / state.sigma_mp[dive.beacon] ** 2
    fk = settings.free_range_scale
    ne = normal_equations(dive, state, a, b, settings.priors, settings.free_d0, fk)
    try:
        step = solve(ne)
        cov = marginal_covariances(ne, step)
    except np.linalg.LinAlgError:
        return None, None
    pred = predictions(dive, state)
    pk = cov[dive.epoch]
    gd, gm = pred.grad_direct, pred.grad_multipath
    v_dp = np.einsum("ia,iab,ib->i", gd, pk, gd)
    v_mp = np.einsum("ia,iab,ib->i", gm, pk, gm)
    if settings.free_d0 or fk:
        cross, gcov = cross_covariances(step), global_covariance(step)
        for col, j in enumerate(settings.free_d0, start=2):
            m = np.flatnonzero(dive.beacon == j)
            dd = pred.d_multipath_d0[m]
            v_mp[m] += (2.0 * dd * np.einsum("ia,ia->i", gm[m], cross[dive.epoch[m], :, col])
                        + dd * dd * gcov[col, col])
        if fk:  # the range scale moves every range: f / s per unit
            c = gcov.shape[0] - 1
            ck = cross[dive.epoch, :, c]
            for v, f, g in ((v_dp, pred.direct, gd), (v_mp, pred.multipath, gm)):
                jk = f / state.range_scale
                v += 2.0 * jk * np.einsum("ia,ia->i", g, ck) + jk * jk * gcov[c, c]
            for col, j in enumerate(settings.free_d0, start=2):
                m = dive.beacon == j
                v_mp[m] += (2.0 * pred.d_multipath_d0[m] * pred.multipath[m]
                            / state.range_scale * gcov[col, c])
    return np.maximum(v_dp, 0.0), np.maximum(v_mp, 0.0)


def _scale(sse, count, lev, floor):
    """``sqrt(sse / (count - lev))``: the residuals' degrees of freedom restored.

    ``lev`` (the summed leverages) is capped at ``(1 - MIN_DOF) count``: where the
    ranges cannot tell the scale from the track, at most a ``1 / MIN_DOF``-fold
    variance inflation (documented in docs/navigate.md).
    """
    dof = np.maximum(count - np.minimum(lev, (1.0 - MIN_DOF) * count), 1e-300)
    return np.maximum(np.sqrt(sse / dof), floor)


def scales_and_weights(dive: Dive, state: State, resp, settings: Settings, *,
                       expected: bool = True) -> State:
    """sigma_DP (pooled), sigma_MP and mixing weights per beacon.

    With ``expected``, the scales take MacKay's evidence update
    ``sigma^2 = sum p r^2 / (sum p - gamma)`` (``gamma`` from :func:`leverages`).

    Parameters
    ----------
    resp : numpy.ndarray
        ``(n, 3)`` class probabilities or weights.
    expected : bool, default True
        Restore the degrees of freedom the track takes.
    """
    pred = predictions(dive, state)
    e_dp, e_mp = dive.z - pred.direct, dive.z - pred.multipath
    floor = settings.sigma_floor
    v_dp = v_mp = None
    if expected:
        v_dp, v_mp = leverages(dive, state, resp, settings)
    h_dp = np.zeros(dive.n) if v_dp is None else v_dp / state.sigma_dp ** 2
    h_mp = (np.zeros(dive.n) if v_mp is None
            else v_mp / state.sigma_mp[dive.beacon] ** 2)
    s_dp = state.sigma_dp
    if not settings.fix_sigma_dp:
        if settings.model == "huber":
            n = float(dive.n)
            s_dp = float(_scale(n * (1.4826 * float(np.median(np.abs(e_dp)))) ** 2, n,
                                float(h_dp.sum()), floor))
        elif resp[:, 0].sum() > 0:
            p = resp[:, 0]
            s_dp = float(_scale(np.add.reduce(p * e_dp ** 2), p.sum(),
                                np.add.reduce(p * h_dp), floor))
    nb = len(dive.beacon_ids)
    r_mp = np.bincount(dive.beacon, weights=resp[:, 1], minlength=nb)
    sse = np.bincount(dive.beacon, weights=resp[:, 1] * e_mp ** 2, minlength=nb)
    lev = np.bincount(dive.beacon, weights=resp[:, 1] * h_mp, minlength=nb)
    s_mp = state.sigma_mp.copy()
    upd = settings.mp_beacons & ~settings.fix_sigma_mp & (r_mp > 0)
    s_mp[upd] = _scale(sse[upd], r_mp[upd], lev[upd], floor)
    w = state.weights.copy()
    if settings.model == "mixture" and settings.fixed_resp is None:
        n_b = np.maximum(np.bincount(dive.beacon, minlength=nb), 1)
        for j in range(3):
            w[:, j] = np.bincount(dive.beacon, weights=resp[:, j], minlength=nb) / n_b
    return state.replace(sigma_dp=float(s_dp), sigma_mp=s_mp, weights=w)


def _weights(dive, state, resp, tau):
    s_dp, s_mp = _effective_scales(state, tau)
    return resp[:, 0] / s_dp ** 2, resp[:, 1] / s_mp[dive.beacon] ** 2


class _Iterate(NamedTuple):
    """The ECM's parameters between two steps.

    The state, the anneal floor and what the last iteration did (``it`` 0 at the start).
    """

    state: State
    tau: float
    it: int = 0
    moved: float = 0.0
    lp_track: float = 0.0


class _NavigationECM(EMModel):
    """The navigation ECM as an :class:`~bayes_mpem.mixture.em.EMModel`.

    The E-step at the annealed scales; the M-step a track step, then the scales and weights.
    """

    def __init__(self, dive: Dive, settings: Settings):
        self.dive, self.settings = dive, settings

    def e_step(self, params):
        resp, lse = e_step(self.dive, params.state, self.settings, params.tau)
        return float(np.add.reduce(lse)), resp

    def m_step(self, params, resp):
        dive, settings, state, tau = self.dive, self.settings, params.state, params.tau
        a, b = _weights(dive, state, resp, tau)
        new = gauss_newton(dive, state, a, b, settings)
        # the log posterior after the E- and track steps, before the scales move: the
        # ECM guarantees it is no lower than the last iteration's (at the same scales)
        lp_track = float(np.add.reduce(e_step(dive, new, settings, tau)[1])) - prior_penalty(
            dive, new, settings.priors)
        new = scales_and_weights(dive, new, resp, settings, expected=tau == 0.0)
        moved = max(float(np.max(np.abs(new.track - state.track))),
                    float(np.max(np.abs(new.d0 - state.d0), initial=0.0)),
                    abs(new.sigma_dp - state.sigma_dp),
                    abs(new.range_scale - state.range_scale) * float(np.max(dive.z, initial=0.0)),
                    float(np.max(np.abs(new.sigma_mp - state.sigma_mp), initial=0.0)))
        s_min = min(new.sigma_dp, float(new.sigma_mp[settings.mp_beacons].min(initial=np.inf)))
        tau = tau * 0.5 if tau * 0.5 > s_min else 0.0
        return _Iterate(new, tau, params.it + 1, moved, lp_track)

    def change(self, old, new, gain):
        # converged once the floor has been off for two iterations and nothing moves
        if new.tau == 0.0 and old.tau == 0.0 and old.it > 0:
            return new.moved
        return np.inf

    def record(self, params, loglik, resp):
        if params.it == 0:
            return {}  # the history keeps iterations only
        state = params.state
        return {"loglik": loglik,
                "log_posterior": loglik - prior_penalty(self.dive, state, self.settings.priors),
                "log_posterior_track": params.lp_track, "anneal": params.tau,
                "sigma_dp": state.sigma_dp, "beta": state.beta, "scale": state.scale,
                "moved": params.moved}


def run(dive: Dive, state: State, settings: Settings, *, anneal: bool = True) -> Run:
    """Run the ECM loop from ``state`` to convergence or ``settings.max_iter``.

    Parameters
    ----------
    state : State
        The start (the dead reckoning, or an earlier run's state).
    anneal : bool, default True
        Floor the scales at ``settings.anneal_start`` m first, halving the floor
        every iteration until it no longer binds.
    """
    start = _Iterate(state, settings.anneal_start if anneal else 0.0)
    out = run_em(_NavigationECM(dive, settings), start, tol=settings.tol,
                 max_iter=settings.max_iter)
    hist = {k: list(out.history.get(k, ())) for k in HISTORY}
    return Run(out.params.state, out.resp, out.loglik, hist, out.n_iter, out.converged)
