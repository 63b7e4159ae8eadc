"""Fitting the joint model of the diagnosis by ECM, and its held-out predictive density."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial
from typing import NamedTuple

import numpy as np

from ...mixture.em import EMModel, best_run, run_em
from ...mixture.gauss_newton import safeguarded_step
from ..simulation.effects import split_term
from .constraints import is_feasible, repair
from .model import Ranges, e_step, predict, weighted_sse
from .params import Params, get_vector, mean_names, set_vector


def _feasible_sse(d, p, names, effects, path, resp, v):
    """``(weighted SSE, parameters)`` at mean vector ``v``; ``None`` where infeasible."""
    cand = set_vector(p, names, v)
    if not is_feasible(d, cand, effects):
        return None
    return weighted_sse(d, cand, effects, path, resp), cand


def _gauss_newton(d, p, effects, path, resp, n_steps=2):
    """Safeguarded Gauss-Newton on the mean parameters; never increases the weighted SSE."""
    names = mean_names(effects, d.ids)
    sig = p.sigma[d.bi]
    q0 = weighted_sse(d, p, effects, path, resp)
    info = None
    for _ in range(n_steps):
        mu, jac = predict(d, p, effects, path, names)
        m = len(names)
        a = np.zeros((m, m))
        g = np.zeros(m)
        for c, name in enumerate(("dp", "mp", "mp2")):
            if name not in mu:
                continue
            w = resp[:, c] / (sig[:, c] * sig[:, c])
            jw = jac[name] * w[:, None]
            a += np.einsum("ni,nj->ij", jw, jac[name])
            g += np.einsum("ni,n->i", jw, d.z - mu[name])
        info = a
        objective = partial(_feasible_sse, d, p, names, effects, path, resp)
        free = np.ones(len(names), bool)
        out = None
        while out is None and free.any():
            step = _solve(a, g, free)
            if step is None:
                break
            out = safeguarded_step(objective, get_vector(p, names), step, q0)
            # a plane on its bound (just above the vehicle) that the step pushes further
            # down makes every halving infeasible and would block all the other parameters
            # (a range bias stuck at 0): hold those planes and step the rest
            blocked = free & _pushed_past_bound(d, p, names, effects, step)
            if out is not None or not blocked.any():
                break
            free &= ~blocked
        if out is None:
            break
        p, q0 = out.aux, out.value
        if np.max(np.abs(out.step)) < 1e-10:
            break
    return p, names, info


def _solve(a, g, free):
    """Gauss-Newton step of the ``free`` mean parameters (the others held); None if singular."""
    step = np.zeros(g.size)
    af = a[np.ix_(free, free)]
    ridge = 1e-9 * np.maximum(np.diag(af), 1e-12) + 1e-12
    try:
        step[free] = np.linalg.solve(af + np.diag(ridge), g[free])
    except np.linalg.LinAlgError:
        return None
    return step


def _pushed_past_bound(d, p, names, effects, step):
    """Which mean parameters are planes that ``step`` moves below their beacon's vehicle."""
    drift = p.drift * d.tau if "plane_drift" in effects else np.zeros(d.n)
    out = np.zeros(len(names), bool)
    for i, (key, j) in enumerate(names):
        if key == "plane" and step[i] > 0:
            sel = d.bi == j
            out[i] = p.plane[j] + step[i] > float(np.min(d.vdepth[sel] - drift[sel]))
    return out


def _m_step(d, p, effects, path, resp, sigma_floor, mp2_floor):
    p = p.copy()
    nb = d.nb
    counts = np.bincount(d.bi, minlength=nb).astype(float)
    w = np.stack([np.bincount(d.bi, weights=resp[:, c], minlength=nb) for c in range(4)], 1)
    p.weights = w / np.maximum(counts, 1.0)[:, None]
    p, _, info = _gauss_newton(d, p, effects, path, resp)
    mu = predict(d, p, effects, path)
    for c, name in enumerate(("dp", "mp", "mp2")):
        if name not in mu:
            continue
        r2 = (d.z - mu[name]) ** 2
        num = np.bincount(d.bi, weights=resp[:, c] * r2, minlength=nb)
        den = np.bincount(d.bi, weights=resp[:, c], minlength=nb)
        ok = den > 1e-3
        # a second family is no sharper than the direct path (its scatter includes the
        # direct path's): stops it from collapsing onto a handful of coincident ranges. The
        # floor is fixed for the whole run, so every M-step stays a conditional maximisation.
        floor = mp2_floor[ok] if name == "mp2" else sigma_floor
        p.sigma[ok, c] = np.maximum(np.sqrt(num[ok] / den[ok]), floor)
    return _Fit(p, info)


class _Fit(NamedTuple):
    p: Params
    info: np.ndarray | None  # Gauss-Newton information of the last M-step


class _ECM(EMModel):
    """The ECM as a :class:`~bayes_mpem.mixture.em.EMModel`: parameters a ``_Fit``."""

    def __init__(self, d, effects, path, sigma_floor, mp2_floor):
        self.d, self.effects, self.path = d, effects, path
        self.sigma_floor, self.mp2_floor = sigma_floor, mp2_floor

    def e_step(self, fit):
        resp, ll_i, _ = e_step(self.d, fit.p, self.effects, self.path)
        return float(ll_i.sum()), resp

    def m_step(self, fit, resp):
        return _m_step(self.d, fit.p, self.effects, self.path, resp, self.sigma_floor,
                       self.mp2_floor)


@dataclass
class JointFit:
    """A fit of the joint model (baseline or extended) to all beacons.

    Attributes
    ----------
    effects : tuple of str
        The extensions switched on.
    params : Params
        Use :meth:`beacons` and :meth:`magnitudes` to read them.
    resp : numpy.ndarray
        ``(n, 4)`` class probabilities (dp, mp, mp2, ol) of every reply.
    loglik : float
    n_iter : int
    converged : bool
    se : dict
        Approximate standard errors of the mean parameters (Gauss-Newton information).
    """

    effects: tuple
    params: Params
    resp: np.ndarray
    loglik: float
    n_iter: int
    converged: bool
    path: str
    se: dict = field(default_factory=dict)
    history: list = field(default_factory=list)

    def magnitudes(self, data: Ranges) -> dict:
        """Signed magnitude of every effect switched on (see :data:`UNITS`), keyed by term."""
        p, out = self.params, {}
        if "range_bias" in self.effects:
            out["range_bias"] = p.bias
        if "sound_speed" in self.effects:
            out["sound_speed"] = p.scale
        if "plane_drift" in self.effects:
            out["plane_drift"] = p.drift
        if "second_reflector" in self.effects:
            out["second_reflector"] = p.plane2
        if "early_outliers" in self.effects:
            out["early_outliers"] = float(self.resp[:, 3].mean())
        if "nav_drift" in self.effects:
            out["nav_drift"] = float(np.hypot(*p.nav))
        for t in self.effects:  # per-beacon terms, "<effect>:<beacon>"
            name, bid = split_term(t)
            if bid is not None:
                j = data.ids.index(bid)
                out[t] = p.bbias[j] if name == "beacon_bias" else np.linalg.norm(p.bpos[j])
        return {k: float(v) for k, v in out.items()}

    def beacons(self, data: Ranges) -> dict:
        """Per-beacon parameters: ``n_ranges``, ``d0``, ``plane_depth``, scales and weights."""
        p, out = self.params, {}
        for j, bid in enumerate(data.ids):
            sel = data.bi == j
            entry = {
                "n_ranges": int(sel.sum()),
                "d0": float(data.bz[j] - p.plane[j]),
                "plane_depth": float(p.plane[j]),
                "sigma_dp": float(p.sigma[j, 0]),
                "sigma_mp": float(p.sigma[j, 1]),
                "weights": {"dp": float(p.weights[j, 0]), "mp": float(p.weights[j, 1]),
                            "ol": float(p.weights[j, 3])},
            }
            if f"beacon_position:{bid}" in self.effects:
                entry["position_correction"] = [float(v) for v in p.bpos[j, :2]]
            if f"beacon_bias:{bid}" in self.effects:
                entry["range_bias"] = float(p.bbias[j])
            if "plane_drift" in self.effects:
                entry["d0_last"] = entry["d0"] - float(p.drift)
            if "second_reflector" in self.effects:
                entry["weights"]["mp2"] = float(p.weights[j, 2])
                entry["sigma_mp2"] = float(p.sigma[j, 2])
            out[bid] = entry
        return out


def _run(d, p, effects, path, *, max_iter, tol, sigma_floor):
    """Run the ECM from ``p``; return its :class:`~bayes_mpem.mixture.em.EMRun`."""
    mp2_floor = np.maximum(sigma_floor, p.sigma[:, 0])
    if "second_reflector" in effects:
        p = p.copy()
        p.sigma[:, 2] = np.maximum(p.sigma[:, 2], mp2_floor)
    return run_em(_ECM(d, effects, path, sigma_floor, mp2_floor), _Fit(p, None),
                  tol=tol * d.n, max_iter=max_iter)


def _joint_fit(d, effects, path, run):
    """Build the :class:`JointFit` of a run, with the standard errors of its last M-step."""
    se, info, names = {}, run.params.info, mean_names(effects, d.ids)
    if info is not None:
        try:
            cov = np.linalg.inv(info + np.diag(1e-12 + 1e-9 * np.abs(np.diag(info))))
            for i, (k, j) in enumerate(names):
                key = k if j is None else f"{k}[{d.ids[j]}]"
                se[key] = float(np.sqrt(max(cov[i, i], 0.0)))
        except np.linalg.LinAlgError:
            pass
    return JointFit(effects=tuple(effects), params=run.params.p, resp=run.resp,
                    loglik=run.loglik, n_iter=run.n_iter, converged=run.converged, path=path,
                    se=se, history=run.history["loglik"])


def fit_joint(d: Ranges, effects, start: Params | list, *, path="triangle", max_iter=300,
              tol=1e-7, sigma_floor=0.05) -> JointFit:
    """Fit the joint model with ``effects`` from one or several starting points (best kept).

    Parameters
    ----------
    start : Params or list of them
        Infeasible starts are moved just inside the constraints.
    tol : float, default 1e-7
        Stop when the log-likelihood gains less than ``tol`` per reply.

    Raises
    ------
    ValueError
        When no start can be made feasible.
    """
    starts = [s if is_feasible(d, s, effects) else repair(d, s, effects)
              for s in (start if isinstance(start, list) else [start])]
    best = best_run(_run(d, s, effects, path, max_iter=max_iter, tol=tol,
                         sigma_floor=sigma_floor)
                    for s in starts if is_feasible(d, s, effects))
    if best is None:
        raise ValueError(f"no feasible starting point for the model with {sorted(effects)}")
    return _joint_fit(d, effects, path, best)


# --------------------------------------------------------------------------- selection


def heldout(d: Ranges, effects, full: JointFit, folds, path, **kw):
    """Score every range by K-fold cross-validation (held-out log density; warm starts at ``full``).

    Parameters
    ----------
    folds : numpy.ndarray
        Fold number of every range.
    **kw
        ``max_iter``, ``tol`` and ``sigma_floor`` of the ECM.
    """
    out = np.empty(d.n)
    for k in np.unique(folds):
        test = folds == k
        fit_k = _run(d.subset(~test), full.params.copy(), full.effects, path, **kw)
        dt = d.subset(test)
        _, ll_i, _ = e_step(dt, fit_k.params.p, effects, path)
        out[test] = ll_i
    return out
