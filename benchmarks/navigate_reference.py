"""Reference navigators for the benchmarks: a short-window trilateration and an EKF + RTS smoother.

Neither is part of the package: they are the plain methods a navigation
engineer would reach for first, written here so that ``navigate`` has
something honest to beat. Both see what ``navigate`` sees (a
:class:`~bayes_mpem.lbl.navigate.dive.Dive`: the ranges, the beacons, the
trusted depth and the dead reckoning) and return the track with a 2x2
covariance per epoch.

* :func:`trilaterate`: at every epoch, the ranges within ``+- half_window``
  epochs, each moved to the epoch by the dead-reckoned displacement between
  them, are fitted by Gauss-Newton least squares for the horizontal position
  (depth known); the worst reply beyond 30 m, then beyond ``gate`` robust
  sigmas, is dropped and the fit repeated. Covariance ``s^2 (J^T J)^{-1}``
  with ``s`` the pooled residual scale (degrees of freedom corrected). Epochs
  with fewer than three ranges left in their window, or a singular fit, keep
  the dead reckoning shifted by the last fix's offset, with an infinite
  covariance.
* :func:`ekf_rts`: the state ``(x, y, beta, s)`` (position, heading bias,
  speed scale of the dead reckoning) with the motion model of
  :mod:`bayes_mpem.lbl.navigate.model` (``p_k = p_{k-1} + s R(beta) Delta_k +
  w_k``), the direct-path range as the measurement, innovations beyond
  ``gate`` sigmas rejected; an extended Kalman filter forward, a
  Rauch-Tung-Striebel smoother back. ``sigma`` is given (the truth), or
  estimated (``sigma=None``): the smoother is rerun with
  ``sigma^2 = mean(r^2 + H P H^T)`` over the accepted replies (the EM update of
  a state-space model's noise level) until it settles.
"""

from __future__ import annotations

import numpy as np

from bayes_mpem.lbl.navigate.model import dr_step, predict_ranges

INF = 1e12


def _ranges(dive, p, m):
    """Direct-path ranges and horizontal gradients of replies ``m`` at positions ``p``."""
    xyz = dive.beacon_xyz[dive.beacon[m]]
    pred = predict_ranges(p[:, 0], p[:, 1], dive.zdepth[m], (xyz[:, 0], xyz[:, 1], xyz[:, 2]),
                          0.0)
    return pred.direct, pred.grad_direct


def trilaterate(dive, *, half_window: int = 3, gate: float = 4.0, iters: int = 20,
                max_step: float = 20.0, accept: float = 30.0):
    """Short-window least-squares fixes (see the module docstring).

    Parameters
    ----------
    dive : Dive
    half_window : int, default 3
        Epochs on either side of the fixed one (7 epochs: every beacon of a
        four-beacon staggered schedule at least once, most twice).
    gate : float, default 4
        Residuals beyond this many robust sigmas (1.4826 MAD of the pooled
        first-pass residuals) are dropped.
    iters : int, default 20
        Gauss-Newton iterations per fix.
    max_step : float, default 20
        Longest Gauss-Newton step (m).
    accept : float, default 30
        First pass: the worst reply beyond this (m) is dropped and the fix
        repeated (a multipath or an outlier, or a wrong start); second pass the
        same beyond ``gate`` robust sigmas. A fix left with fewer than three
        replies is no fix; the next starts from the last fix's offset.

    Returns
    -------
    track : numpy.ndarray
        ``(K, 2)``.
    cov : numpy.ndarray
        ``(K, 2, 2)``.
    """
    k = dive.n_epochs
    order = np.argsort(dive.epoch, kind="stable")
    ep = dive.epoch[order]
    lo = np.searchsorted(ep, np.arange(k) - half_window, side="left")
    hi = np.searchsorted(ep, np.arange(k) + half_window, side="right")

    def fit(p0, m, keep, kk, limit):
        """Gauss-Newton fix, the worst reply beyond ``limit`` dropped and the fit repeated."""
        m = m[keep]
        while m.size >= 3:
            p = p0.copy()
            shift = dive.dr[dive.epoch[m]] - dive.dr[kk]  # each reply's epoch from the fixed one
            for _ in range(iters):
                f, g = _ranges(dive, p[None, :] + shift, m)
                try:
                    step = np.linalg.solve(g.T @ g, g.T @ (dive.z[m] - f))
                except np.linalg.LinAlgError:
                    return None
                step *= min(1.0, max_step / max(float(np.hypot(*step)), 1e-300))
                p = p + step
                if np.max(np.abs(step)) < 1e-4:
                    break
            f, g = _ranges(dive, p[None, :] + shift, m)
            r = dive.z[m] - f
            worst = int(np.argmax(np.abs(r)))
            if abs(r[worst]) <= limit:
                return p, r, g
            m = np.delete(m, worst)
        return None

    track = dive.dr.copy()
    jtj = np.full((k, 2, 2), np.nan)
    resid = [None] * k
    offset = np.zeros(2)
    for kk in range(k):
        m = order[lo[kk]:hi[kk]]
        p0 = dive.dr[kk] + offset
        out = fit(p0, m, np.ones(m.size, bool), kk, accept)
        if out is None:
            track[kk] = p0
            continue
        track[kk], resid[kk] = out[0], out[1]
        jtj[kk] = out[2].T @ out[2]
        offset = track[kk] - dive.dr[kk]
    pooled = np.concatenate([r for r in resid if r is not None] or [np.zeros(1)])
    robust = 1.4826 * float(np.median(np.abs(pooled))) or 1.0
    sse, dof = 0.0, 0
    for kk in range(k):
        if resid[kk] is None:
            continue
        m = order[lo[kk]:hi[kk]]
        p0 = track[kk]
        f, _ = _ranges(dive, p0[None, :] + dive.dr[dive.epoch[m]] - dive.dr[kk], m)
        keep = np.abs(dive.z[m] - f) <= gate * robust
        out = fit(p0, m, keep, kk, gate * robust)
        if out is None:
            resid[kk] = None
            continue
        track[kk], r, g = out
        jtj[kk] = g.T @ g
        sse += float(r @ r)
        dof += r.size - 2
    s2 = sse / max(dof, 1)
    cov = np.empty((k, 2, 2))
    for kk in range(k):
        ok = resid[kk] is not None and np.linalg.det(jtj[kk]) > 1e-12
        cov[kk] = s2 * np.linalg.inv(jtj[kk]) if ok else INF * np.eye(2)
    return track, cov


def _filter_smooth(dive, sigma, q, start_sd, heading_sd, scale_sd, gate):
    """One EKF pass forward and an RTS pass back; returns the smoothed states, covariances
    and, per reply, the residual at the smoothed state, H P H^T and whether it was accepted."""
    k = dive.n_epochs
    by_epoch = [[] for _ in range(k)]
    for i, e in enumerate(dive.epoch):
        by_epoch[e].append(i)
    x = np.array([*dive.dr[0], 0.0, 1.0])
    P = np.diag([start_sd ** 2, start_sd ** 2, heading_sd ** 2, scale_sd ** 2])
    xs_f, Ps_f, xs_p, Ps_p, Fs = [], [], [], [], []
    accepted = np.zeros(dive.n, bool)
    delta, dt = dive.delta, dive.dt
    for kk in range(k):
        if kk:
            p, d_beta, d_scale = dr_step(x[:2], delta[kk - 1], x[2], x[3])
            F = np.eye(4)
            F[:2, 2], F[:2, 3] = d_beta, d_scale
            x = np.array([*p, x[2], x[3]])
            Q = np.zeros((4, 4))
            Q[0, 0] = Q[1, 1] = q * q * max(dt[kk - 1], 1e-3)
            P = F @ P @ F.T + Q
            Fs.append(F)
        xs_p.append(x.copy())
        Ps_p.append(P.copy())
        for i in by_epoch[kk]:
            f, g = _ranges(dive, x[None, :2], np.array([i]))
            H = np.zeros(4)
            H[:2] = g[0]
            innov = dive.z[i] - f[0]
            S = H @ P @ H + sigma ** 2
            if innov * innov > gate * gate * S:
                continue
            K = P @ H / S
            x = x + K * innov
            P = P - np.outer(K, H @ P)
            P = 0.5 * (P + P.T)
            accepted[i] = True
        xs_f.append(x.copy())
        Ps_f.append(P.copy())
    xs, Ps = [None] * k, [None] * k
    xs[-1], Ps[-1] = xs_f[-1], Ps_f[-1]
    for kk in range(k - 2, -1, -1):
        F = Fs[kk]
        C = Ps_f[kk] @ F.T @ np.linalg.inv(Ps_p[kk + 1])
        xs[kk] = xs_f[kk] + C @ (xs[kk + 1] - xs_p[kk + 1])
        Ps[kk] = Ps_f[kk] + C @ (Ps[kk + 1] - Ps_p[kk + 1]) @ C.T
    xs, Ps = np.array(xs), np.array(Ps)
    f, g = _ranges(dive, xs[dive.epoch, :2], np.arange(dive.n))
    hph = np.einsum("ia,iab,ib->i", g, Ps[dive.epoch, :2, :2], g)
    return xs, Ps, dive.z - f, hph, accepted


def ekf_rts(dive, *, sigma=None, q: float = 0.1, start_sd: float = 100.0,
            heading_sd: float = np.deg2rad(5.0), scale_sd: float = 0.05, gate: float = 4.0,
            sigma_start: float = 1.0, max_rounds: int = 20):
    """EKF + RTS smoother at ``sigma`` (given), or at a sigma estimated by EM (``None``).

    Parameters
    ----------
    dive : Dive
    sigma : float, optional
        Range noise (m); estimated when None.
    q : float, default 0.1
        Random walk of the dead reckoning (m / sqrt(s)).
    start_sd, heading_sd, scale_sd : float
        Prior sd of the first position (m), the heading bias (rad), the speed scale.
    gate : float, default 4
        Innovations beyond this many sigmas are rejected.
    sigma_start : float, default 1
        First sigma of the estimation.
    max_rounds : int, default 20
        Smoother runs of the estimation at most.

    Returns
    -------
    track : numpy.ndarray
        ``(K, 2)``.
    cov : numpy.ndarray
        ``(K, 2, 2)``.
    sigma : float
        The sigma used (given or estimated).
    """
    s = sigma_start if sigma is None else float(sigma)
    for _ in range(1 if sigma is not None else max_rounds):
        xs, Ps, r, hph, acc = _filter_smooth(dive, s, q, start_sd, heading_sd, scale_sd, gate)
        if sigma is not None or not acc.any():
            break
        new = float(np.sqrt(np.mean(r[acc] ** 2 + hph[acc])))
        done = abs(new - s) < 1e-3 * s
        s = new
        if done:
            xs, Ps, *_ = _filter_smooth(dive, s, q, start_sd, heading_sd, scale_sd, gate)
            break
    return xs[:, :2], Ps[:, :2, :2], s
