"""Posterior of a GNSS-A array with emcee (docs/gnssa.md, the array posterior)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .._rng import RNGLike, as_generator
from .._threads import with_one_blas_thread
from ..exceptions import InputError
from ..mcmc import (
    TProposal,
    bulk_ess,
    draw_moments,
    draw_summary,
    rhat,
    run_ensembles,
    thin_index,
)
from .array import (
    WEIGHT_GRID,
    ArrayLocateResult,
    ArrayTravelTimes,
    gradient_design,
    null_shifted,
    penalised_gauss_newton,
)
from .classes import log_classes, true_probability
from .noise import Whitener
from .posterior import (
    SIGMA_BOUNDS,
    SPEED_PRIOR_WIDTH,
    check_location_options,
    posterior_tree,
)
from .travel_times import speed_basis, speed_penalty

#: the pilot keeps the independence move at or above this bulk ESS per draw (docs/gnssa.md)
MIN_ESS_PER_DRAW = 0.05
#: ... and at or below this R-hat
MAX_PILOT_RHAT = 1.1
#: walkers and steps of the pilot (discarded)
PILOT_WALKERS, PILOT_STEPS = 32, 64
#: walkers of the independence move
N_WALKERS = 32
#: degrees of freedom of the Student-t ball that starts differential evolution
PROPOSAL_DF = 30.0
#: emcee's move and the proposal, as recorded in the diagnostics
MOVES_LABEL = ("MHMove 1.0 (independence proposal: log sigma, the shares, then the rest "
               "given sigma)")
#: ``log_smoothing``'s prior: flat over the EM's grid of smoothing weights (natural log)
SMOOTHING_RANGE = tuple(float(np.log(10.0) * x) for x in (WEIGHT_GRID[0], WEIGHT_GRID[-1]))
#: rows of parameters whose likelihood one call evaluates together (memory: rows x shots)
CHUNK = 256
#: differential evolution stops before its chain (kept whole by emcee) exceeds this
CHAIN_BYTES = 1e9
#: the three axes of a position
AXES = ("east", "north", "up")
#: units of the variables written (``units`` attributes)
UNITS = {"position": "m", "centre": "m", "sound_speed": "m/s", "sigma": "s", "weight": "1",
         "gradient": "(m/s)/km", "twtt": "s", "time": "s", "p_true": "1", "p_true_sd": "1",
         "smoothing_weight": "h^3 / (speed coefficient unit)^2",
         "lp": "1"}


class ArrayLogPosterior:
    """Log-posterior of an array's positions, sound speed, gradients and shot classes.

    Parameters
    ----------
    shots : pandas.DataFrame
        The shots the EM was fitted to (``fit.rows`` index it):
        :data:`~bayes_mpem.survey_in.array.SHOT_COLUMNS`.
    fit : ArrayLocateResult
        The EM solution: fixes the model (profile, speed basis and smoothing weight,
        gradients, windows, outlier density, which coordinates are free) and the start.

    Attributes
    ----------
    names : tuple of str
        The sampler's coordinates: the free position coordinates (``east_<id>``, ...;
        ``position_<j>`` along the free directions when some are fixed or the array
        moves as a rigid body), ``speed_<i>``, ``gradient_<i>``, ``log_sigma`` and
        ``logit_weight_<id>`` and, with the smooth speed, ``log_smoothing`` (the log of
        the smoothing weights' scale from the EM's choice).
    ndim : int
    label : str

    Raises
    ------
    TypeError
        When ``fit`` is not an :class:`ArrayLocateResult`.

    Notes
    -----
    Where ``fit`` was refitted under correlated noise (``fit.model["noise"]``,
    :mod:`.noise`), a reply the EM called true has as its true-class density the
    Gaussian of its residual given the residuals of the earlier such replies under
    ``sigma^2 E``: mean and variance from the banded Cholesky factor of ``E``
    (``L^-1`` of the residuals times ``L_ii``). Those conditionals multiply to the
    generalised least squares likelihood the EM's refit maximised; each stays in the
    mixture with the spurious class, so the classes are still sampled. The conditioning
    set is the EM's: a reply called spurious is no evidence about its neighbours, and for
    an ambiguous reply the EM's class and the posterior's may disagree (docs/gnssa.md).

    The positions' prior is the EM's: flat, or where the site file gave sigmas above 0 the
    Gaussian of ``fit.model["position_prior"]`` about the prior positions
    (:func:`~bayes_mpem.survey_in.array.locate_array`'s ``prior_sd`` and ``centre_sd``).

    Examples
    --------
    >>> from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa
    >>> from bayes_mpem.survey_in.array_survey import array_shots, locate_array_survey
    >>> sim = simulate_gnssa(rng=0, hours=0.5, shot_interval=30.0)
    >>> fit = locate_array_survey(sim.raw(), correlation="off").fits["array"]
    >>> post = ArrayLogPosterior(array_shots(sim.raw()), fit)
    >>> u = post.u_em()
    >>> bool(np.allclose(post.predict(u[None])[0], post.model.predict(post.theta_em),
    ...                  rtol=0, atol=1e-12))
    True
    """

    def __init__(self, shots: pd.DataFrame, fit: ArrayLocateResult):
        if not isinstance(fit, ArrayLocateResult):
            raise TypeError(f"fit: expected an ArrayLocateResult, got {type(fit).__name__}")
        m = fit.model
        self.fit, self.ids, self.K = fit, tuple(fit.ids), len(fit.ids)
        sub = shots.iloc[fit.rows].reset_index(drop=True)
        self.index = np.asarray(fit.index)
        self.t = sub["twtt"].to_numpy(float)
        self.n = self.t.size
        self.noise = m.get("noise") or {}
        #: the replies' correlation (:class:`~.noise.Whitener` of the EM's true replies
        #: ``self.keep``), None for independent replies
        self.whitener = None
        if self.noise.get("correlation_s"):
            keep = np.flatnonzero(np.asarray(fit.p_true, float) > 0.5)
            self.whitener = Whitener(sub["time"].to_numpy(float)[keep], self.index[keep],
                                     self.noise["correlation_s"], self.noise["share"],
                                     self.noise["white"])
            self.keep = keep
            #: the true replies in time order (the whitened rows) and ``log L_ii``
            self.keep_time = keep[self.whitener.order]
            self.log_lii = np.log(self.whitener.ab[0])
        basis = speed_basis(sub, m["speed_intervals"], m["time_range"], m.get("speed_breaks"))
        self.k = basis.shape[1]
        terms = tuple(fit.gradient_terms)
        design = (gradient_design(sub, self.index, fit.start, basis, terms)
                  if terms else None)
        self.kg = 0 if design is None else design.shape[1]
        self.model = ArrayTravelTimes(sub, self.index, self.K, basis, profile=m["profile"],
                                      surface_depth=m["surface_depth"], gradients=design,
                                      earth_radius=m.get("earth_radius"),
                                      along_sphere=m.get("along_sphere", False))
        self.basis_t = np.ascontiguousarray(basis.T)
        self.design_t = None if design is None else np.ascontiguousarray(design.T)
        self.unit = float(m["unit"])
        self.g = basis.mean(axis=0)  # the reported speed: the mean over the shots
        sm = m.get("smoothing") or {}
        self.lam = sm.get("weight")
        self.lam_g = sm.get("gradient_weight")
        self.H = None if self.lam is None else speed_penalty(
            m["speed_intervals"], m["time_range"], breaks=m.get("speed_breaks"))
        P = 3 * self.K
        theta = np.concatenate([np.asarray(fit.enu, float).ravel(), fit.speed_coef,
                                np.zeros(self.kg)])
        if self.kg:
            theta[P + self.k:] = self._gradients_at_em(theta, fit)
        self.theta_em = theta
        self.pos_em = theta[:P].reshape(self.K, 3)
        # geometry of the first-order ray bending about the EM solution
        self.tx = np.column_stack([sub[f"{c}_tx"].to_numpy(float) for c in "enu"])
        self.rx = np.column_stack([sub[f"{c}_rx"].to_numpy(float) for c in "enu"])
        s_em, gain_em = basis @ fit.speed_coef, self._gain(theta[None, P + self.k:])[0]
        T_em = self.model.predict(theta) * s_em / gain_em
        J = self.model.jac(theta)
        rows = np.arange(self.n)
        dT = np.column_stack([J[rows, 3 * self.index + c] for c in range(3)])
        dT *= (s_em / gain_em)[:, None]
        L_em, dL = self._chords(self.pos_em[self.index][None], derivatives=True)
        self.ratio = T_em / L_em[0]
        self.corr = dT - self.ratio[:, None] * dL[0]
        # the free directions of the positions: a fixed coordinate has a zero row in the
        # EM's covariance; a rigid shift moves every transponder alike
        # the EM's position parameters (``model["position_map"]``: the positions are the
        # priors plus ``G phi``); a rigid shift scaled to the sd of one transponder's move
        G = m.get("position_map")
        if G is None:  # a fit made before the map was recorded
            free = np.any(np.asarray(fit.cov, float)[:P, :P] != 0.0, axis=1)
            rigid = (m.get("positions") or {}).get("mode", "").startswith("rigid")
            G = np.tile(np.eye(3), (self.K, 1))[:, free[:3]] if rigid else np.eye(P)[:, free]
        rigid = (m.get("positions") or {}).get("mode", "").startswith("rigid")
        step = 1.0 / np.sqrt(self.K) if rigid else 1.0
        self.B = np.asarray(G, float) * step
        self.F = self.B.shape[1]
        #: the positions' prior (the EM's ``position_prior``, a precision of its parameters
        #: ``phi = phi_em + prior_map u``), None where flat
        self.prior = m.get("position_prior")
        if self.prior is not None:
            self.prior_map = step * np.eye(self.F)
            self.phi_em = np.asarray(m["position_params"], float)
        #: ``(K, 3)``: which coordinates are sampled (the others stay at the prior)
        self.free = np.any(self.B != 0.0, axis=1).reshape(self.K, 3)
        coordinates = self.F == P and np.array_equal(self.B, np.eye(P))  # u the positions
        pos_names = ([f"{a}_{t}" for t in self.ids for a in AXES] if coordinates
                     else [f"position_{j}" for j in range(self.F)])
        speed = ["speed"] if self.k == 1 else [f"speed_{i}" for i in range(self.k)]
        self.names = tuple(pos_names + speed + [f"gradient_{i}" for i in range(self.kg)]
                           + ["log_sigma"] + [f"logit_weight_{t}" for t in self.ids])
        self.coef_em = theta[P:P + self.k].copy()
        self.gc_em = theta[P + self.k:].copy()
        self.width = SPEED_PRIOR_WIDTH * np.abs(self.coef_em)
        cov = self._laplace(J, fit)
        # speed and gradient coordinates: offsets from the EM in units of their sds, so the
        # proposal's scale matrix is well conditioned
        sd = np.sqrt(np.maximum(np.diag(cov), 1e-300))
        self.scale = np.concatenate([np.ones(self.F), sd[self.F:]])
        self.cov_geo = cov / np.outer(self.scale, self.scale)
        #: the smoothing weights are sampled, as one scale ``exp(log_smoothing)`` of the EM's
        self.smooth = self.H is not None
        # H c and c'Hc without the round-off of coefficients near 1 (array.null_shifted)
        c0 = null_shifted(self.coef_em, self.H) if self.smooth else None
        self.Hc = None if c0 is None else self.H @ c0
        self.Hg = (None if self.H is None or not self.kg else
                   np.concatenate([self.H @ g for g in self.gc_em.reshape(-1, self.k)]))
        if self.smooth:
            # the second-derivative penalty's rank: k - 2 per block (a threshold on its
            # eigenvalues miscounts from about 600 knots)
            blocks = 1 + (self.kg // self.k if self.kg and self.lam_g is not None else 0)
            self.pen_rank = blocks * max(self.k - 2, 0)
            q = self.lam * c0 @ self.H @ c0
            if self.kg and self.lam_g is not None:
                q += self.lam_g * sum(g @ self.H @ g for g in self.gc_em.reshape(-1, self.k))
            self.pen_em = float(q)
            self.names += ("log_smoothing",)

    def _laplace(self, J, fit):
        """Return the Laplace covariance of (free positions, speed, gradients) at the EM.

        Also keeps its two precisions, of the data (at the EM's sigma and class
        probabilities) and of the smoothing prior, as ``self._precisions``: the positions'
        prior goes with the data's, which :class:`ConditionalProposal` scales by
        ``(sigma_EM / sigma)^2`` (near 1), not with the smoothing prior's scale ``kappa``
        (decades), of which it does not depend.
        """
        P, k, kg = 3 * self.K, self.k, self.kg
        M = np.zeros((P + k + kg, self.F + k + kg))
        M[:P, :self.F] = self.B
        M[P:, self.F:] = np.eye(k + kg)
        Jw = self._weighted(J @ M)
        data = Jw.T @ Jw / fit.sigma**2
        prior = np.zeros_like(data)
        if self.H is not None:
            prior[self.F:self.F + k, self.F:self.F + k] = self.lam * self.H
            if kg and self.lam_g is not None:
                for j in range(kg // k):
                    a = self.F + k + j * k
                    prior[a:a + k, a:a + k] = self.lam_g * self.H
        if self.prior is not None:
            data[:self.F, :self.F] += self.prior_map.T @ self.prior @ self.prior_map
        self._precisions = data, prior
        A = data + prior
        d = np.sqrt(np.maximum(np.diag(A), 1e-300))
        vals, vecs = np.linalg.eigh(A / np.outer(d, d))
        vals = np.maximum(vals, 1e-12 * vals.max())
        return (vecs / vals) @ vecs.T / np.outer(d, d)

    def _weighted(self, X):
        """Rows of ``X`` weighted as the data's precision sees them.

        By ``sqrt(p_true)`` for independent replies; whitened (``L^-1``, the EM's true
        replies only) for correlated ones.
        """
        if self.whitener is not None:
            return self.whitener.whiten(X[self.keep])
        return np.sqrt(np.asarray(self.fit.p_true, float)).reshape(-1, *[1] * (X.ndim - 1)) * X

    @property
    def ndim(self) -> int:
        """Number of sampled parameters."""
        return len(self.names)

    @property
    def label(self) -> str:
        """Progress-bar label."""
        return f"array ({self.K} transponders)"

    def _gradients_at_em(self, theta, fit):
        """Return the gradient coefficients at the EM's positions and speed (conditional mode)."""
        P, k = 3 * self.K, self.k

        def full(gc):
            return np.concatenate([theta[:P + k], gc])

        def resid(gc):
            return self._weighted(self.t - self.model.predict(full(gc)))

        def jac(gc):
            return -self._weighted(self.model.jac(full(gc))[:, P + k:])

        Q = np.zeros((self.kg, self.kg))
        if self.lam_g is not None:
            for j in range(self.kg // k):
                Q[j * k:(j + 1) * k, j * k:(j + 1) * k] = self.H
            Q *= fit.sigma**2 * self.lam_g
        return penalised_gauss_newton(resid, jac, np.zeros(self.kg), Q)

    def _chords(self, P, derivatives=False):
        """Transmit plus receive chord to ``P`` (``(W, n, 3)``), and its gradient in ``P``."""
        a, b = P - self.tx, P - self.rx
        la, lb = np.sqrt(np.einsum("...i,...i->...", a, a)), np.sqrt(np.einsum("...i,...i->...",
                                                                                b, b))
        if not derivatives:
            return la + lb
        return la + lb, a / la[..., None] + b / lb[..., None]

    def _gain(self, gc):
        """``exp(-gamma)`` of the gradient terms, ``(W, n)`` (1 without them)."""
        if self.design_t is None:
            return np.ones((gc.shape[0], self.n))
        return np.exp(-(gc @ self.design_t))

    def u_em(self) -> np.ndarray:
        """Return the EM solution in the sampler's coordinates.

        Returns
        -------
        numpy.ndarray
        """
        w = np.clip(np.asarray(self.fit.weights, float), 1e-6, 1 - 1e-6)
        return np.concatenate([np.zeros(self.F + self.k + self.kg), [np.log(self.fit.sigma)],
                               np.log(w) - np.log1p(-w), [0.0] * self.smooth])

    def split(self, u):
        """Positions ``(W, K, 3)``, speed ``(W, k)``, gradients ``(W, kg)``, sigma, weights.

        Parameters
        ----------
        u : array_like
            ``(W, ndim)`` in the order of :attr:`names` (or one ``(ndim,)`` point).

        Returns
        -------
        tuple of numpy.ndarray
        """
        u = np.atleast_2d(np.asarray(u, float))
        F, k, kg = self.F, self.k, self.kg
        pos = (self.theta_em[:3 * self.K] + u[:, :F] @ self.B.T).reshape(-1, self.K, 3)
        coef = self.coef_em + u[:, F:F + k] * self.scale[F:F + k]
        gc = self.gc_em + u[:, F + k:F + k + kg] * self.scale[F + k:]
        sigma = np.exp(u[:, F + k + kg])
        w = 1.0 / (1.0 + np.exp(-u[:, F + k + kg + 1:F + k + kg + 1 + self.K]))
        return pos, coef, gc, sigma, w

    def predict(self, u):
        """Predicted two-way travel times of a true reply, ``(W, n)``.

        Parameters
        ----------
        u : array_like
            ``(W, ndim)`` in the order of :attr:`names`.

        Returns
        -------
        numpy.ndarray
        """
        pos, coef, gc, _, _ = self.split(u)
        P = pos[:, self.index, :]  # (W, n, 3)
        T = (self.ratio * self._chords(P)
             + np.einsum("wni,ni->wn", P - self.pos_em[self.index], self.corr))
        return T / (coef @ self.basis_t) * self._gain(gc)

    def log_prior(self, u):
        """Log prior density (up to a constant), ``(W,)``; ``-inf`` outside the support.

        Parameters
        ----------
        u : array_like
            ``(W, ndim)`` in the order of :attr:`names`.

        Returns
        -------
        numpy.ndarray
        """
        u = np.atleast_2d(np.asarray(u, float))
        F, k, kg = self.F, self.k, self.kg
        # offsets from the EM's coefficients: the penalty c'Hc of a stiff spline, evaluated
        # directly, cancels to round-off (c near 1, H c near 0) times a weight of 1e13
        dc = u[:, F:F + k] * self.scale[F:F + k]
        dg = u[:, F + k:F + k + kg] * self.scale[F + k:]
        ls, lw = u[:, F + k + kg], u[:, F + k + kg + 1:F + k + kg + 1 + self.K]
        ok = np.all(np.isfinite(u), axis=1)
        ok &= np.all(np.abs(dc) <= self.width, axis=1)
        ok &= (ls >= np.log(SIGMA_BOUNDS[0])) & (ls <= np.log(SIGMA_BOUNDS[1]))
        lp = np.zeros(u.shape[0])
        if self.smooth:
            # the roughness at the EM's weights, lam c'Hc (+ the gradients'), as its
            # value at the EM plus the change
            q = self.lam * (2.0 * dc @ self.Hc + np.einsum("wi,ij,wj->w", dc, self.H, dc))
            if kg and self.lam_g is not None:
                q += 2.0 * self.lam_g * (dg @ self.Hg)
                for j in range(kg // k):
                    g = dg[:, j * k:(j + 1) * k]
                    q += self.lam_g * np.einsum("wi,ij,wj->w", g, self.H, g)
            # the weights times exp(lk), flat in lk over the EM's grid of weights: the
            # Gaussian prior's normalising term is rank/2 lk
            lk = u[:, -1]
            ok &= (lk >= SMOOTHING_RANGE[0]) & (lk <= SMOOTHING_RANGE[1])
            lp += 0.5 * self.pen_rank * lk - 0.5 * np.exp(np.where(ok, lk, 0.0)) * (
                self.pen_em + q)
        if self.prior is not None:  # the positions' Gaussian prior about the prior positions
            phi = self.phi_em + u[:, :F] @ self.prior_map.T
            lp -= 0.5 * np.einsum("wi,ij,wj->w", phi, self.prior, phi)
        # a flat prior on each share: the Jacobian of the logit
        lp -= np.sum(np.logaddexp(0.0, lw) + np.logaddexp(0.0, -lw), axis=1)
        return np.where(ok, lp, -np.inf)

    def class_log_densities(self, u):
        """Weighted log densities (true, spurious) of every shot, each ``(W, n)``.

        Parameters
        ----------
        u : array_like
            ``(W, ndim)`` in the order of :attr:`names`.

        Returns
        -------
        tuple of numpy.ndarray
        """
        pred = self.predict(u)
        _, _, _, sigma, w = self.split(u)
        ld, lu = np.empty_like(pred), np.empty_like(pred)
        for j, rows in enumerate(self.model.rows):
            # log_classes at a weight of 1/2, re-weighted here for an array of weights
            a, b = log_classes(self.t[rows], pred[:, rows], sigma[:, None], 0.5,
                               self.fit.windows[j], self.fit.outliers)
            ld[:, rows] = a + (np.log(w[:, [j]]) - np.log(0.5))
            lu[:, rows] = b + (np.log1p(-w[:, [j]]) - np.log(0.5))
        if self.whitener is not None:
            # each true reply given the earlier ones: z = L^-1 r, sd sigma L_ii
            rows = self.keep_time
            z = self.whitener.whiten(self.t[self.keep][:, None] - pred[:, self.keep].T).T
            ld[:, rows] = (np.log(w[:, self.index[rows]]) - 0.5 * (z / sigma[:, None]) ** 2
                           - np.log(sigma[:, None] * np.sqrt(2 * np.pi)) - self.log_lii)
        return ld, lu

    def loglik(self, u):
        """Log-likelihood, ``(W,)``.

        Parameters
        ----------
        u : array_like
            ``(W, ndim)`` in the order of :attr:`names`.

        Returns
        -------
        numpy.ndarray
        """
        return np.logaddexp(*self.class_log_densities(u)).sum(axis=1)

    def __call__(self, u):
        """Log posterior (up to a constant) of a ``(W, ndim)`` array: emcee's target.

        Evaluated :data:`CHUNK` rows at a time (each row costs the shots' predictions).

        Parameters
        ----------
        u : numpy.ndarray

        Returns
        -------
        numpy.ndarray
            ``(W,)``; ``-inf`` outside the prior.
        """
        u = np.atleast_2d(u)
        lp = self.log_prior(u)
        for i in range(0, u.shape[0], CHUNK):
            ok = np.flatnonzero(np.isfinite(lp[i:i + CHUNK])) + i
            if ok.size:
                lp[ok] += self.loglik(u[ok])
        return lp

    def natural(self, u) -> dict:
        """Convert ``(..., ndim)`` to the reported quantities.

        Parameters
        ----------
        u : array_like
            ``(..., ndim)``.

        Returns
        -------
        dict
            ``position`` ``(..., K, 3)`` (m), ``centre`` ``(..., 3)``, ``speed_coef``
            ``(..., k)``, ``sound_speed`` (m/s, the mean over the shots as the EM
            reports it), ``gradient`` ``(..., terms)`` ((m/s)/km, time averages; only when
            fitted), ``sigma`` (s), ``weight`` ``(..., K)`` and, with the smooth speed,
            ``smoothing_weight`` (the speed's; the gradients' is scaled alike).
        """
        u = np.asarray(u, float)
        shape = u.shape[:-1]
        pos, coef, gc, sigma, w = self.split(u.reshape(-1, self.ndim))
        speed = (coef @ self.g) * self.unit
        out = {"position": pos.reshape(*shape, self.K, 3),
               "centre": pos.mean(axis=1).reshape(*shape, 3),
               "speed_coef": coef.reshape(*shape, self.k), "sound_speed": speed.reshape(shape),
               "sigma": sigma.reshape(shape), "weight": w.reshape(*shape, self.K)}
        if self.kg:
            per = gc.reshape(-1, self.kg // self.k, self.k) @ self.g  # (W, terms)
            out["gradient"] = (per * speed[:, None]).reshape(*shape, self.kg // self.k)
        if self.smooth:
            out["smoothing_weight"] = self.lam * np.exp(u[..., -1])
        return out

    def _proposal_cov(self) -> np.ndarray:
        """Return the Laplace covariance at the EM solution, in the sampler's coordinates."""
        d = self.ndim
        C = np.zeros((d, d))
        ng = self.cov_geo.shape[0]
        C[:ng, :ng] = self.cov_geo
        p = np.asarray(self.fit.p_true, float)
        C[ng, ng] = 1.0 / (2.0 * max(p.sum(), 2.0))
        w = np.clip(np.asarray(self.fit.weights, float), 1e-3, 1 - 1e-3)
        counts = np.bincount(self.index, minlength=self.K)
        C[ng + 1:ng + 1 + self.K, ng + 1:ng + 1 + self.K] = np.diag(1.0 / (counts * w * (1 - w)))
        if self.smooth:
            C[-1, -1] = 2.0 / max(self.pen_rank, 1)
        return 0.5 * (C + C.T)

    def proposal(self) -> TProposal | None:
        """Return the Student-t proposal at the EM solution, scaled by the Laplace covariance.

        Returns
        -------
        TProposal or None
            None when the covariance is not positive definite.
        """
        try:
            chol = np.linalg.cholesky(self._proposal_cov())
        except np.linalg.LinAlgError:
            return None
        return TProposal(centre=self.u_em(), chol=chol, df=PROPOSAL_DF)


class ConditionalProposal:
    """Independence proposal of an array's posterior: the hyperparameters, then the rest.

    Given sigma, the smoothing scale ``kappa`` and the classes, the positions, speed and
    gradient coefficients are Gaussian to within a few thousandths of a nat over the
    posterior's width (the travel times are nearly linear in them): precision
    ``rho D + kappa P`` with ``D`` the data's precision at the EM's sigma, ``P`` the
    smoothing prior's at the EM's weights and ``rho = (sigma_EM / sigma)**2``, and a mean
    moved from the EM solution by one Newton step. That conditional is drawn exactly,
    through the generalised eigenvectors of ``(D, D + P)``; ``(log sigma, log kappa)`` are
    drawn from a Student-t fitted to their Laplace marginal on a grid, and each share from
    the Beta of its expected class counts. A joint Student-t
    (:class:`~bayes_mpem.mcmc.proposal.TProposal`) misses the coupling of sigma with every
    other coordinate, which in a hundred dimensions or more (a speed knot every 5 minutes
    of a long campaign) leaves independence sampling no accepted step.

    Parameters
    ----------
    post : ArrayLogPosterior
        The target; its EM solution is the expansion point.

    Raises
    ------
    numpy.linalg.LinAlgError
        When ``D + P`` is not positive definite.
    ValueError
        When the hyperparameters' marginal cannot be evaluated (the conditional mean
        leaves the prior's support).
    """

    #: degrees of freedom of the hyperparameters' proposal
    DF = 30.0
    #: grid points per hyperparameter (its marginal's moments)
    GRID = 21

    def __init__(self, post: ArrayLogPosterior):
        import scipy.linalg
        from scipy import special

        self.ng = ng = post.F + post.k + post.kg
        self.K, self.smooth = post.K, post.smooth
        self.centre = post.u_em()
        S = post.scale
        data, prior = (m * np.outer(S, S) for m in post._precisions)
        g, V = scipy.linalg.eigh(data, data + prior)  # V' (D + P) V = I
        self.g = np.clip(g, 0.0, 1.0)
        self.V = V
        self.W = V.T @ (data + prior)  # V^-1
        # gradient of the log posterior at the EM solution, split into data and prior
        h = 0.1 * np.sqrt(np.diag(post.cov_geo))
        pts = np.repeat(self.centre[None], 2 * ng, axis=0)
        pts[np.arange(ng), np.arange(ng)] += h
        pts[ng + np.arange(ng), np.arange(ng)] -= h
        lp = post(pts)
        total = (lp[:ng] - lp[ng:]) / (2.0 * h)
        pen = np.zeros(ng)
        if post.smooth:
            pen[post.F:post.F + post.k] = -post.lam * post.Hc * S[post.F:post.F + post.k]
            if post.kg and post.lam_g is not None:
                pen[post.F + post.k:] = -post.lam_g * post.Hg * S[post.F + post.k:]
        self.a_data, self.a_prior = V.T @ (total - pen), V.T @ pen
        # the Newton step, shortened where the posterior is not quadratic along it (a ridge
        # of the geometry against the speed, on a short circling track)
        one = np.ones(1)
        step = V @ self._mean(one, one)[0]
        frac = np.array([1.0, 0.5, 0.25, 0.125, 0.0625, 0.0])
        pts = np.repeat(self.centre[None], frac.size, axis=0)
        pts[:, :ng] += frac[:, None] * step
        along = post(pts)
        best = float(frac[np.nanargmax(np.where(np.isfinite(along), along, -np.inf))])
        # shorten the step at the EM's sigma and weights, keep how the mean moves with them
        self.a_data = best * (self.a_data + self.a_prior) - self.a_prior
        self.hyper = self._hyper_proposal(post)
        # the shares: Beta of the expected counts (a flat prior on each share)
        p = np.asarray(post.fit.p_true, float)
        counts = np.bincount(post.index, weights=p, minlength=self.K)
        n = np.bincount(post.index, minlength=self.K).astype(float)
        self.a, self.b = counts + 1.0, n - counts + 1.0
        self.lbeta = special.betaln(self.a, self.b)

    def _hyper_proposal(self, post) -> TProposal:
        """Student-t of ``log sigma`` (and ``log kappa``) from the moments of their marginal.

        The grid spans 8 sds either way (of ``log sigma`` with everything else known, and of
        ``log kappa`` given the coefficients, ``sqrt(2 / rank)``); an axis whose outer points
        hold more than 1e-4 of the mass is made twice as wide, twice at most, each axis on
        its own (``log kappa`` is often several times less determined than assumed; widening
        ``log sigma`` with it spaces its grid too coarsely for its moments: docs/gnssa.md).
        """
        p = np.asarray(post.fit.p_true, float)
        sds = [1.0 / np.sqrt(2.0 * max(p.sum(), 2.0))]
        if self.smooth:
            sds.append(np.sqrt(2.0 / max(post.pen_rank, 1)))
        span = np.full(len(sds), 8.0)
        for attempt in range(3):
            grid, w = self._hyper_marginal(post, span * np.asarray(sds))
            wide = np.zeros(len(sds), bool)
            for j in range(grid.shape[1]):  # an edge at the prior's bound is no reason
                bounds = SMOOTHING_RANGE if j == 1 else (-np.inf, np.inf)
                lo, hi = grid[:, j].min(), grid[:, j].max()
                outer = ((grid[:, j] <= lo) & (lo > bounds[0])) | (
                    (grid[:, j] >= hi) & (hi < bounds[1]))
                wide[j] = w[outer].sum() > 1e-4
            if attempt == 2 or not wide.any():
                break
            span[wide] *= 2.0
        mean = w @ grid
        cov = ((grid - mean).T * w) @ (grid - mean)
        return TProposal(centre=mean, chol=np.linalg.cholesky(np.atleast_2d(cov)), df=self.DF)

    def _hyper_marginal(self, post, half):
        """Grid of the hyperparameters (half-widths ``half``) and their marginal's weights."""
        ng = self.ng
        base = [self.centre[ng], 0.0][:len(half)]
        axes = [b + np.linspace(-h, h, self.GRID) for b, h in zip(base, half, strict=True)]
        if self.smooth:
            axes[1] = np.unique(np.clip(axes[1], *SMOOTHING_RANGE))
        grid = np.stack([a.ravel() for a in np.meshgrid(*axes, indexing="ij")], axis=1)
        rho, kappa = self._scales(grid)
        pts = np.repeat(self.centre[None], grid.shape[0], axis=0)
        pts[:, :ng] += self._mean(rho, kappa) @ self.V.T
        pts[:, ng] = grid[:, 0]
        if self.smooth:
            pts[:, -1] = grid[:, 1]
        lm = post(pts) - 0.5 * np.sum(np.log(self._d(rho, kappa)), axis=1)
        if np.sum(np.isfinite(lm)) < 3:
            raise ValueError("the hyperparameters' marginal has fewer than 3 points inside "
                             "the support")
        w = np.exp(lm - np.max(lm[np.isfinite(lm)]))
        w[~np.isfinite(w)] = 0.0
        return grid, w / w.sum()

    def _scales(self, hyper):
        """``rho`` and ``kappa`` of ``(n, 1 or 2)`` hyperparameters (log sigma, log kappa)."""
        rho = np.exp(2.0 * (self.centre[self.ng] - hyper[:, 0]))
        return rho, (np.exp(hyper[:, 1]) if self.smooth else np.ones_like(rho))

    def _d(self, rho, kappa):
        """Eigenvalues of the conditional precision in the ``V`` basis, ``(n, ng)``."""
        return rho[:, None] * self.g + kappa[:, None] * (1.0 - self.g)

    def _mean(self, rho, kappa):
        """Conditional mean in the ``V`` basis, ``(n, ng)`` (offsets from the EM)."""
        return ((rho[:, None] * self.a_data + kappa[:, None] * self.a_prior)
                / self._d(rho, kappa))

    def _hyper_columns(self):
        return [self.ng] + ([self.centre.size - 1] if self.smooth else [])

    def draw(self, n: int, gen) -> np.ndarray:
        """Draw ``n`` points.

        Parameters
        ----------
        n : int
        gen : numpy.random.Generator or numpy.random.RandomState

        Returns
        -------
        numpy.ndarray
            ``(n, ndim)``.
        """
        ng = self.ng
        hyper = self.hyper.draw(n, gen)
        rho, kappa = self._scales(hyper)
        d = self._d(rho, kappa)
        y = self._mean(rho, kappa) + gen.standard_normal((n, ng)) / np.sqrt(d)
        out = np.empty((n, self.centre.size))
        out[:, :ng] = self.centre[:ng] + y @ self.V.T
        out[:, self._hyper_columns()] = hyper
        # logit of a Beta(a, b) draw: log X - log Y with X ~ Gamma(a), Y ~ Gamma(b)
        out[:, ng + 1:ng + 1 + self.K] = (
            np.log(gen.standard_gamma(self.a, size=(n, self.K)))
            - np.log(gen.standard_gamma(self.b, size=(n, self.K))))
        return out

    def log_density(self, u) -> np.ndarray:
        """Log density up to a constant.

        Parameters
        ----------
        u : array_like
            ``(n, ndim)`` points.

        Returns
        -------
        numpy.ndarray
            ``(n,)``.
        """
        u = np.atleast_2d(np.asarray(u, float))
        ng = self.ng
        hyper = u[:, self._hyper_columns()]
        out = self.hyper.log_density(hyper)
        rho, kappa = self._scales(hyper)
        d = self._d(rho, kappa)
        y = (u[:, :ng] - self.centre[:ng]) @ self.W.T - self._mean(rho, kappa)
        out += 0.5 * np.sum(np.log(d), axis=1) - 0.5 * np.einsum("ij,ij,ij->i", d, y, y)
        lw = u[:, ng + 1:ng + 1 + self.K]
        out += np.sum(-self.a * np.logaddexp(0.0, -lw) - self.b * np.logaddexp(0.0, lw)
                      - self.lbeta, axis=1)
        return out


def _proposal_start(post, proposal, n, gen, rounds=1000):
    """``n`` proposal draws inside the support."""
    out = proposal.draw(n, gen)
    for _ in range(rounds):
        bad = np.flatnonzero(~np.isfinite(post(out)))
        if bad.size == 0:
            return out
        out[bad] = proposal.draw(bad.size, gen)
    raise ValueError(f"the proposal put {rounds} draws in a row outside the support")


def _series(post: ArrayLogPosterior, chain) -> dict:
    """Return the ``(steps, walkers)`` series whose ESS and R-hat the stopping rule checks."""
    nat = post.natural(chain)
    out = {}
    for j, tid in enumerate(post.ids):  # fixed coordinates are constants: no ESS
        for a, axis in enumerate(AXES):
            if post.free[j, a]:
                out[f"{axis}_{tid}"] = nat["position"][..., j, a]
    for a, axis in enumerate(AXES):
        if post.free[:, a].any():
            out[f"centre_{axis}"] = nat["centre"][..., a]
    out["sound_speed"] = nat["sound_speed"]
    out["sigma"] = nat["sigma"]
    if "smoothing_weight" in nat:
        out["log_smoothing"] = np.log(nat["smoothing_weight"])
    return out


@dataclass(frozen=True)
class ArrayPosterior:
    """Posterior of an array: positions, centre, sound speed, gradients, shot classes.

    Attributes
    ----------
    ids : tuple of str
        The transponders, in the order of the ``transponder`` axis.
    names : tuple of str
        The sampler's coordinates.
    draws : dict
        Thinned draws, ``(walker, draw, ...)``: ``position`` (``..., K, 3``, m),
        ``centre`` (``..., 3``), ``speed_coef``, ``sound_speed`` (m/s), ``gradient``
        (when fitted), ``sigma`` (s), ``weight`` (``..., K``), ``smoothing_weight`` (with
        the smooth speed), ``lp``, and ``theta`` in the sampler's coordinates.
    p_true, p_true_sd : numpy.ndarray
        Per shot used: mean and sd over the draws of the probability of a true reply.
    rows : numpy.ndarray
        Positions of those shots in the input table.
    shots : pandas.DataFrame
        ``line``, ``time`` (s), ``transponder``, ``twtt`` (s) of those shots.
    ess, rhat : dict
        ArviZ's bulk ESS and R-hat of the written draws (walkers as chains): keys
        ``<axis>_<id>``, ``centre_<axis>``, ``sound_speed``, ``sigma`` and, with the
        smooth speed, ``log_smoothing``.
    em : ArrayLocateResult
    diagnostics : dict
    ci : float
    """

    ids: tuple
    names: tuple
    draws: dict = field(repr=False)
    p_true: np.ndarray = field(repr=False)
    p_true_sd: np.ndarray = field(repr=False)
    rows: np.ndarray = field(repr=False)
    shots: pd.DataFrame = field(repr=False)
    ess: dict = field(default_factory=dict)
    rhat: dict = field(default_factory=dict)
    em: ArrayLocateResult = field(default=None, repr=False)
    diagnostics: dict = field(default_factory=dict)
    ci: float = 0.95

    @property
    def converged(self) -> bool:
        """Whether the chain met its stopping rule before ``max_steps``."""
        return bool(self.diagnostics.get("converged", False))

    def describe(self, x, ci: float | None = None) -> dict:
        """``mean``, ``sd`` and equal-tailed ``interval`` of draws ``x``.

        Parameters
        ----------
        x : numpy.ndarray
            Draws (all axes pooled).
        ci : float, optional
            Default: the probability the posterior was summarised with.

        Returns
        -------
        dict
        """
        return draw_summary(x, self.ci if ci is None else float(ci))

    def position(self, tid: str, ci: float | None = None) -> dict:
        """East, north, up of one transponder, each described (:meth:`describe`).

        Parameters
        ----------
        tid : str
        ci : float, optional

        Returns
        -------
        dict
        """
        j = self.ids.index(str(tid))
        return {a: self.describe(self.draws["position"][..., j, i], ci)
                for i, a in enumerate(AXES)}

    def centre(self, ci: float | None = None) -> dict:
        """East, north, up of the array centre, each described (:meth:`describe`).

        Parameters
        ----------
        ci : float, optional

        Returns
        -------
        dict
        """
        return {a: self.describe(self.draws["centre"][..., i], ci) for i, a in enumerate(AXES)}

    def to_inference_data(self):
        """ArviZ data of the kept draws, walkers as chains; units and shot times attached.

        Returns
        -------
        xarray.DataTree
            ``posterior`` (``position`` over ``transponder`` and ``axis``, ``centre``,
            ``speed_coef`` over ``knot``, ``sound_speed``, ``gradient`` over
            ``gradient_term`` when fitted, ``sigma``, ``weight``), ``sample_stats``
            (``lp``), ``observed_data`` (``twtt`` over ``shot``: the input row, with the
            shot's ``time``, ``transponder`` and file ``line``) and ``class_probabilities``
            (``p_true``, ``p_true_sd`` per shot, averaged over the draws); the chain
            coordinate ``ensemble`` (one ensemble: all 0), by
            :func:`~.posterior.posterior_tree`.
        """
        import emcee

        d = self.draws
        post = {k: d[k] for k in ("position", "centre", "speed_coef", "sound_speed",
                                  "gradient", "sigma", "weight", "smoothing_weight") if k in d}
        dims = {"position": ["transponder", "axis"], "centre": ["axis"],
                "speed_coef": ["knot"], "gradient": ["gradient_term"],
                "weight": ["transponder"]}
        coords = {"transponder": list(self.ids), "axis": list(AXES),
                  "knot": np.arange(d["speed_coef"].shape[-1]),
                  "gradient_term": list(self.em.gradient_terms)}
        return posterior_tree(
            post, d["lp"], self.shots, self.p_true, self.p_true_sd, self.rows, units=UNITS,
            dims=dims, coords=coords, n_ensembles=1,
            attrs={"kind": "GNSS-A array", "transponders": ",".join(self.ids),
                   "sampler": f"emcee {emcee.__version__} ({self.diagnostics.get('moves')})",
                   "frame": "local east, north, up (m) of the survey",
                   "speed_coef_unit": self.diagnostics.get("speed_coef_unit", ""),
                   "noise": self.diagnostics.get("noise", ""),
                   "position_prior": self.diagnostics.get("position_prior", ""),
                   "ci": self.ci})

    def to_dict(self, ci: float | None = None) -> dict:
        """JSON-ready summary: positions, centre, sound speed, gradients, diagnostics.

        Parameters
        ----------
        ci : float, optional

        Returns
        -------
        dict
        """
        ci = self.ci if ci is None else float(ci)
        d = self.draws
        out = {"transponders": {t: self.position(t, ci) for t in self.ids},
               "array_centre": self.centre(ci),
               "sound_speed": {**self.describe(d["sound_speed"], ci), "unit": "m/s"},
               "sigma_ms": {k: (1e3 * v if k != "interval" else [1e3 * x for x in v])
                            for k, v in self.describe(d["sigma"], ci).items()},
               "weight_true": {t: self.describe(d["weight"][..., j], ci)
                               for j, t in enumerate(self.ids)},
               "ess": dict(self.ess), "rhat": dict(self.rhat),
               "diagnostics": dict(self.diagnostics), "ci": ci}
        if "gradient" in d:
            out["gradients"] = {name: self.describe(d["gradient"][..., j], ci)
                                for j, name in enumerate(self.em.gradient_terms)}
        if "smoothing_weight" in d:
            out["log10_smoothing_weight"] = self.describe(np.log10(d["smoothing_weight"]), ci)
        return out


@with_one_blas_thread
def sample_array(shots: pd.DataFrame, fit: ArrayLocateResult, *, n_walkers: int | None = None,
                 ci: float = 0.95, min_ess: float = 1000.0, max_steps: int = 20000,
                 n_draws: int = 4000, sampler: str = "auto", rng: RNGLike = None,
                 progress="auto") -> ArrayPosterior:
    """Sample the posterior of an array and its shot classes, from the EM solution.

    Parameters
    ----------
    shots : pandas.DataFrame
        The shots ``fit`` was located from
        (:func:`~bayes_mpem.survey_in.array_survey.array_shots`).
    fit : ArrayLocateResult
        The EM solution (:func:`~bayes_mpem.survey_in.array.locate_array`).
    n_walkers : int, optional
        Default :data:`N_WALKERS` (independence move) or ``max(32, 2 ndim + 2)``
        (differential evolution).
    ci : float, default 0.95
        Probability of the equal-tailed intervals.
    min_ess : float, default 1000
        Run until the smallest bulk ESS (positions, centre, mean speed, sigma, smoothing
        weight) reaches this and R-hat < 1.01.
    max_steps : int, default 20000
    n_draws : int, default 4000
        Draws kept at least (a longer chain is thinned evenly).
    sampler : {"auto", "independence", "ensemble"}
        The independence move from :class:`ConditionalProposal`, differential evolution, or
        the first unless a discarded pilot finds it fits poorly (the default).
    rng : None, int or numpy.random.Generator
        Same seed, same chain.
    progress : bool or {"auto", "bar", "log"}

    Returns
    -------
    ArrayPosterior

    Raises
    ------
    TypeError
        When ``fit`` is not an :class:`ArrayLocateResult`.
    ValueError
        For invalid options.

    Warns
    -----
    SamplingWarning
        When the chain reaches ``max_steps`` before its stopping rule.

    Examples
    --------
    >>> from bayes_mpem.survey_in.gnssa_simulate import simulate_gnssa
    >>> from bayes_mpem.survey_in.array_survey import array_shots, locate_array_survey
    >>> sim = simulate_gnssa(rng=0, hours=0.5, shot_interval=30.0)
    >>> fit = locate_array_survey(sim.raw(), correlation="off").fits["array"]
    >>> post = sample_array(array_shots(sim.raw()), fit, min_ess=200, rng=0, progress=False)
    >>> post.draws["position"].shape[-2:], post.converged
    ((4, 3), True)
    """
    from ..mcmc.moves import independence_move
    from ..mcmc.progress import progress_mode, say

    check_location_options(n_walkers=n_walkers, ci=ci, min_ess=min_ess, max_steps=max_steps,
                           n_draws=n_draws)
    if sampler not in ("auto", "independence", "ensemble"):
        raise ValueError(f"sampler: expected one of auto, independence, ensemble, got "
                         f"{sampler!r}")
    post = ArrayLogPosterior(shots, fit)
    gen = as_generator(rng)
    t0 = time.perf_counter()

    def natural(chain):
        return _series(post, chain)

    opts = {"gen": gen, "min_ess": float(min_ess), "n_draws": int(n_draws), "natural": natural,
            "label": post.label, "stacklevel": 3}  # past the thread-limiting decorator
    info = {"fallback": None}
    proposal = None
    if sampler != "ensemble":
        try:
            proposal = ConditionalProposal(post)
            start = _proposal_start(post, proposal, PILOT_WALKERS, gen)
        except (np.linalg.LinAlgError, ValueError) as exc:
            proposal, info["fallback"] = None, f"no proposal at the EM solution ({exc})"
    run = None
    if sampler == "auto" and proposal is not None:
        pilot = run_ensembles(post, [start],
                              moves=independence_move(proposal), gen=gen, min_ess=np.inf,
                              max_steps=PILOT_STEPS, n_draws=PILOT_WALKERS * PILOT_STEPS,
                              natural=natural, progress=False, warn=False)
        per_draw = pilot.ess / (PILOT_WALKERS * PILOT_STEPS)
        info["pilot"] = {"ess_per_draw": per_draw, "rhat": pilot.rhat,
                         "acceptance": pilot.acceptance,
                         "draws": PILOT_WALKERS * PILOT_STEPS}
        if per_draw < MIN_ESS_PER_DRAW or not pilot.rhat <= MAX_PILOT_RHAT:
            info["fallback"] = (f"the proposal fits poorly (pilot: ESS {per_draw:.2f} "
                                f"per draw, R-hat {pilot.rhat:.3f}, acceptance "
                                f"{pilot.acceptance:.2f})")
    if sampler != "ensemble" and info["fallback"] is None:
        # the pilot decides: an independence move that mixes but has not met the stopping
        # rule goes on (differential evolution after 2,000 such steps did far worse:
        # ESS 122 and R-hat 1.8 in 20,000 steps, where 1,000 more independence steps met it)
        walkers = int(n_walkers or N_WALKERS)
        run = run_ensembles(post, [_proposal_start(post, proposal, walkers, gen)],
                            moves=independence_move(proposal), progress=progress,
                            max_steps=int(max_steps), **opts)
        info["moves"] = MOVES_LABEL
    if run is None:
        if progress_mode(progress) == "log" and info["fallback"]:
            say(post.label, f"{info['fallback']}; differential evolution instead")
        walkers = int(n_walkers or max(32, 2 * post.ndim + 2))
        run = _differential_evolution(post, walkers, int(max_steps), info, progress, opts)
    seconds = time.perf_counter() - t0
    idx, thin = thin_index(run.chain.shape[0], walkers, n_draws)
    theta = np.swapaxes(run.chain[idx], 0, 1)  # (walker, draw, ndim)
    draws = {k: np.ascontiguousarray(v) for k, v in post.natural(theta).items()}
    draws["lp"] = np.ascontiguousarray(np.swapaxes(run.log_prob[idx], 0, 1))
    draws["theta"] = theta
    series = _series(post, theta)
    ess = bulk_ess(series)
    flat = theta.reshape(-1, post.ndim)
    _, p, p_sd = draw_moments(
        flat, lambda u: (None, [true_probability(*post.class_log_densities(u))]))
    sub = shots.iloc[fit.rows]
    table = pd.DataFrame({"line": (sub["line"].to_numpy() if "line" in sub.columns
                                   else np.asarray(fit.rows)),
                          "time": sub["time"].to_numpy(float),
                          "transponder": sub["transponder"].astype(str).to_numpy(),
                          "twtt": sub["twtt"].to_numpy(float)})
    refracted = fit.model.get("profile") is not None
    diagnostics = {
        "n_walkers": walkers, "n_steps": run.n_steps, "burn": int(run.burn), "thin": int(thin),
        "n_draws": int(flat.shape[0]), "converged": bool(run.converged),
        "acceptance": run.acceptance, "seconds": float(seconds), "min_ess": float(min_ess),
        "ndim": post.ndim, **{k: v for k, v in info.items() if v is not None},
        "smoothing_weight": post.lam, "gradient_weight": post.lam_g,
        "hyperparameters": (
            "the smoothing weights sampled: one scale of the EM's speed and gradient weights, "
            "flat in log over the EM's grid (2 decades either way)" if post.smooth else
            "none (the speed's intervals are fixed)"),
        "speed_coef_unit": ("scale of the profile (dimensionless)" if refracted else "m/s"),
        "noise": _noise_label(post),
        "position_prior": _prior_label(post),
        "travel_times": ("refracted rays: ray bending to first order about the EM solution"
                         if refracted else "straight rays (exact)")}
    return ArrayPosterior(ids=post.ids, names=post.names, draws=draws, p_true=p[:, 0],
                          p_true_sd=p_sd[:, 0], rows=np.asarray(fit.rows), shots=table,
                          ess=ess, rhat={k: rhat(v) for k, v in series.items()}, em=fit,
                          diagnostics=diagnostics, ci=float(ci))


def _prior_label(post: ArrayLogPosterior) -> str:
    """Return the positions' prior the posterior assumed, in words (diagnostics, the file)."""
    if post.prior is None:
        return "flat (no sigmas above 0)"
    sds = 1.0 / np.sqrt(np.diag(post.prior)[np.diag(post.prior) > 0])
    span = f"{sds.min():g} m" if sds.min() == sds.max() else f"{sds.min():g}-{sds.max():g} m"
    scaled = (((post.fit.model.get("positions") or {}).get("prior") or {}).get("sd_factor")
              or 1.0)
    what = ("its sigmas, GARPOS's a priori covariance" if scaled == 1.0 else
            f"its sigmas scaled up {scaled:.4g} times, where the fit moved the positions farther "
            "than they allow")
    return (f"Gaussian about the site file's positions on {sds.size} of {post.F} position "
            f"parameters (sds {span}: {what})")


def _noise_label(post: ArrayLogPosterior) -> str:
    """Return the replies' noise the posterior assumed, in words (diagnostics, the file)."""
    if post.whitener is None:
        return "independent replies"
    n = post.noise
    return (f"correlated: mu_t {n['correlation_s']:g} s, mu_mt {n['share']:g}, white "
            f"{n['white']:g} (GARPOS's covariance, tapered); each reply the EM called true "
            "given the earlier ones")


def _differential_evolution(post, walkers, max_steps, info, progress, opts):
    """Run emcee's differential evolution from a ball about the EM solution (the fallback).

    emcee keeps the whole chain: the steps are capped so that it stays within
    :data:`CHAIN_BYTES` (recorded in ``info``, with the moves).
    """
    from ..mcmc.moves import DEFAULT_MOVES_LABEL, default_moves

    q = post.proposal() or TProposal(centre=post.u_em(), chol=np.diag(np.sqrt(np.maximum(
        np.abs(np.diag(post._proposal_cov())), 1e-30))), df=PROPOSAL_DF)
    ball = TProposal(centre=q.centre, chol=0.5 * q.chol, df=q.df)
    steps = min(max_steps, max(1000, int(CHAIN_BYTES / (8 * walkers * post.ndim))))
    if steps < max_steps:
        info["max_steps"] = f"{steps} (the chain's memory capped at {CHAIN_BYTES / 1e9:g} GB)"
    info["moves"] = DEFAULT_MOVES_LABEL
    return run_ensembles(post, [_proposal_start(post, ball, walkers, opts["gen"])],
                         moves=default_moves(), burn_in=True, progress=progress,
                         max_steps=steps, **{**opts, "stacklevel": opts["stacklevel"] + 1})


def _covariance(x) -> dict:
    """``{"names", "matrix"}`` of the sample covariance of ``(..., 3)`` east, north, up draws."""
    C = np.cov(np.asarray(x).reshape(-1, 3), rowvar=False)
    return {"names": list(AXES), "matrix": [[float(v) for v in row] for row in C]}


def _with_posterior(em: dict, enu: dict, origin) -> dict:
    """Return an EM entry with its east, north, up (depth, lat, lon) from the posterior."""
    from ..io.geodesy import enu_to_geodetic

    out = dict(em)
    out["enu"] = {a: {**enu[a], "interval_method": "posterior"} for a in AXES}
    if "east" in em:
        out["east"], out["north"] = out["enu"]["east"], out["enu"]["north"]
        up = enu["up"]
        out["depth"] = {"mean": -up["mean"], "sd": up["sd"],
                        "interval": [-up["interval"][1], -up["interval"][0]],
                        "interval_method": "posterior"}
    if origin:
        lat, lon, h = enu_to_geodetic(enu["east"]["mean"], enu["north"]["mean"],
                                      enu["up"]["mean"], origin["lat"], origin["lon"],
                                      origin["height"])
        out.update(lat=float(lat), lon=float(lon), height=float(h))
    return out


def _check_forced_gradients(shots, raw, gradients, speed_intervals):
    """Refuse to sample gradient terms forced on where the track does not determine them.

    Their constant and trend are unpenalised: where the gate leaves them out, the posterior
    is all but flat along them and no chain converges (a 0.5-hour campaign: R-hat 2.2 after
    10,700 steps, 2.4 GB, stopped at 400 s; docs/gnssa.md). The EM still fits them if asked.
    """
    from .array_survey import gradient_choice, gradient_gate

    asked = gradient_choice(gradients)
    if asked not in ("on", "shallow"):
        return
    ok, why = gradient_gate(shots, raw.header["transponders"], speed_intervals)
    if not ok:
        raise InputError(f"--gradients {asked} with --sample (gradients={asked!r}): the gate "
                         f"would leave the gradients out ({why}); their unpenalised constant "
                         "and trend are then all but undetermined and the posterior cannot be "
                         "sampled. "
                         "Sample with --gradients auto or off, or fit them by EM without "
                         "--sample")


def locate_array_survey_bayes(raw, *, ci=0.95, outliers="uniform", ssp=None,
                              speed_intervals=None, gradients="auto", knot_minutes=None,
                              flags="honour", n_walkers=None, min_ess=1000.0, max_steps=20000,
                              n_draws=4000, rng: RNGLike = None, progress="auto",
                              correlation="auto", position_prior="auto"):
    """Locate a GNSS-A array by EM, then sample its posterior (``locate --sample``).

    Parameters
    ----------
    raw : RawSurvey
        A GARPOS or GNATSS survey (or a SeaGap survey of several transponders).
    ci, outliers, ssp, speed_intervals, gradients, knot_minutes, flags, position_prior
        As for :func:`~bayes_mpem.survey_in.array_survey.locate_array_survey`
        (``knot_minutes=None``: its default).
    n_walkers, min_ess, max_steps, n_draws, progress
        As for :func:`sample_array`.
    rng : None, int or numpy.random.Generator
    correlation : {"auto", "off"} or tuple, default "auto"
        The replies' noise, as for ``locate_array_survey``: where the EM's fit models it
        correlated, so does the posterior (:class:`ArrayLogPosterior`, Notes).

    Returns
    -------
    SurveyInResult
        As ``locate_array_survey``'s, every position, the array centre, the sound
        speed (and the gradients) from the posterior (mean, sd and equal-tailed
        interval, ``"interval_method": "posterior"``, the EM's entry kept under
        ``em``; each transponder's bulk ESS and R-hat under ``posterior``), the
        classes from the posterior (with ``p_true_sd``), and ``posteriors``
        ``{"array": ArrayPosterior}`` (written as ``posterior_array.nc``).
    """
    import copy

    from .array_survey import array_shots
    from .result import SurveyInResult
    from .survey import locate_survey

    check_location_options(n_walkers=n_walkers, ci=ci, min_ess=min_ess, max_steps=max_steps,
                           n_draws=n_draws)
    shots = array_shots(raw)
    _check_forced_gradients(shots, raw, gradients, speed_intervals)
    located = locate_survey(raw, ci=ci, outliers=outliers, ssp=ssp,
                            speed_intervals=speed_intervals, gradients=gradients, flags=flags,
                            knot_minutes=knot_minutes, correlation=correlation,
                            position_prior=position_prior)
    fit = located.fits["array"]
    post = sample_array(shots, fit, n_walkers=n_walkers, ci=ci, min_ess=min_ess,
                        max_steps=max_steps, n_draws=n_draws, rng=rng, progress=progress)
    s = copy.deepcopy(located.summary)
    origin = s["geometry"].get("origin")
    d = post.draws
    for j, tid in enumerate(post.ids):
        em = s["transponders"][tid]
        entry = _with_posterior(em, post.position(tid, ci), origin)
        true = post.p_true[fit.index == j]
        entry.update(
            covariance=_covariance(d["position"][..., j, :]),
            sigma_ms=1e3 * float(np.mean(d["sigma"])),
            weight_true=float(np.mean(d["weight"][..., j])), n_spurious=int(np.sum(true < 0.5)),
            sound_speed={**post.describe(d["sound_speed"], ci), "interval_method": "posterior"},
            interval_method="posterior", converged=post.converged,
            posterior={"ess": {a: post.ess[f"{a}_{tid}"] for a in AXES
                               if f"{a}_{tid}" in post.ess},
                       "rhat": {a: post.rhat[f"{a}_{tid}"] for a in AXES
                                if f"{a}_{tid}" in post.rhat},
                       "diagnostics": dict(post.diagnostics)},
            em=em)
        s["transponders"][tid] = entry
    cen = s["array_centre"]
    s["array_centre"] = {**_with_posterior(cen, post.centre(ci), origin),
                         "covariance": _covariance(d["centre"]),
                         "ess": {a: post.ess[f"centre_{a}"] for a in AXES
                                 if f"centre_{a}" in post.ess},
                         "rhat": {a: post.rhat[f"centre_{a}"] for a in AXES
                                  if f"centre_{a}" in post.rhat}, "em": cen}
    ss = s["sound_speed"]
    s["sound_speed"] = {**ss, **post.describe(d["sound_speed"], ci),
                        "interval_method": "posterior",
                        "em": {k: ss[k] for k in ("mean", "sd", "interval")}}
    if "gradient" in d:
        g = s["gradients"]
        s["gradients"] = {**g, **{name: {**post.describe(d["gradient"][..., j], ci),
                                         "em": g.get(name)}
                                  for j, name in enumerate(fit.gradient_terms)}}
    summary_post = post.to_dict(ci)
    s["posterior"] = {k: summary_post[k] for k in ("sigma_ms", "weight_true", "ess", "rhat",
                                                    "diagnostics", "log10_smoothing_weight")
                      if k in summary_post}
    s["posterior"]["file"] = "posterior_array.nc"
    s["method"] = (s["method"] + "; emcee posterior from the EM solution (smoothing weights "
                   "sampled), equal-tailed intervals")
    s["interval_method"] = "posterior"
    s["ci"] = ci
    s["position_region"] = (f"posterior sds and equal-tailed {100 * ci:g} % intervals; "
                            "covariances from the draws")
    cls = located.classified.copy()
    # a line may hold the replies of several transponders (GNATSS): the shot is its file,
    # line, transponder and travel time
    keys = [c for c in ("file", "line") if c in cls.columns and c in shots.columns]
    sub = shots.iloc[fit.rows]
    used = sub[keys + ["twtt"]].reset_index(drop=True)
    used.insert(len(keys), "transponder", sub["transponder"].astype(str).to_numpy())
    keys += ["transponder", "twtt"]
    at = pd.MultiIndex.from_frame(cls[keys]).get_indexer(pd.MultiIndex.from_frame(used))
    if np.any(at < 0):
        raise RuntimeError("array posterior: a located shot was not found in the classified "
                           "table (a bug: please report it)")
    p_sd = np.full(len(cls), np.nan)
    p_true = cls["p_true"].to_numpy(float).copy()
    p_true[at], p_sd[at] = post.p_true, post.p_true_sd
    located_rows = np.zeros(len(cls), bool)
    located_rows[at] = True
    cls["p_true"], cls["p_spurious"] = p_true, 1.0 - p_true
    cls.loc[located_rows, "label"] = np.where(p_true[located_rows] >= 0.5, "true", "spurious")
    cls.insert(cls.columns.get_loc("p_spurious") + 1, "p_true_sd", p_sd)
    return SurveyInResult(summary=s, classified=cls, posteriors={"array": post},
                          fits={"array": fit})
