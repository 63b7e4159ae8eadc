"""The posterior of one beacon, vectorised over walkers (parameters and priors: docs/bayes.md)."""

from __future__ import annotations

from dataclasses import replace
from math import lgamma

import numpy as np

from ..._validate import check_choice, check_int, check_positive, check_range, check_sampled_ci
from ...io.survey import BeaconData
from ...mcmc.driver import place_walkers
from ...mixture.densities import CLASSES
from ..em.em_result import EMResult
from ..model.beacon_geometry import BeaconGeometry
from ..model.loglik_kernel import LoglikKernel

PRIORS = ("equal", "learned")
#: the samplers of :func:`~bayes_mpem.lbl.bayes.beacon_chains.beacon_chains`
SAMPLERS = ("auto", "independence", "ensemble")
PARAMS = ("d0", "sigma_mp", "sigma_dp", "w_dp", "w_mp", "w_ol")


def check_sample_options(*, priors="learned", ci=0.95, n_ensembles=None, concentration=1.0,
                         sigma_dp=None, path="triangle", min_ess=1000.0,
                         max_steps=20000, n_draws=2000, sampler="auto", n_walkers=None):
    """Validate the sampler's options before any work.

    Parameters
    ----------
    priors, ci, n_ensembles, concentration, sigma_dp, path, min_ess, max_steps, n_draws, \
sampler, n_walkers
        As for :func:`~bayes_mpem.lbl.bayes.beacon_sampling.sample_beacon`.

    Raises
    ------
    ValueError
        For the first invalid option, naming it.

    Examples
    --------
    >>> check_sample_options(ci=0.9)
    >>> check_sample_options(priors="flat")
    Traceback (most recent call last):
    ...
    ValueError: priors: expected one of ('equal', 'learned'), got 'flat'
    """
    from ..model.geometry import check_path

    check_path(path)
    check_choice("priors", priors, PRIORS)
    check_choice("sampler", sampler, SAMPLERS)
    check_sampled_ci(ci)
    check_positive("concentration", concentration)
    check_range("min_ess", min_ess, low=0, include_low=True)
    check_positive("sigma_dp", sigma_dp, allow_none=True, what="a positive number")
    for name, value in (("n_ensembles", n_ensembles), ("max_steps", max_steps),
                        ("n_draws", n_draws)):
        if value is not None or name != "n_ensembles":
            check_int(name, value, minimum=1)
    if n_walkers is not None:
        check_int("n_walkers", n_walkers, minimum=8)


class BeaconPosterior:
    """Log-posterior of one beacon, vectorised over walkers.

    Parameters
    ----------
    priors : {"learned", "equal"}
        Dirichlet-distributed mixing weights, or the paper's equal weights.
    sigma_dp : float, optional
        Fix the direct-path scatter (m) instead of sampling it.
    concentration : float, default 1
        Dirichlet concentration of the learned weights.
    sigma_bounds : tuple of float, default (0.05, 500)
        Support (m) of the log-uniform scale priors.
    em : EMResult, optional
        The EM fit :meth:`start` centres the walkers on (or set :attr:`em` later).
    d0_bounds : tuple of float, optional
        ``(a, b)``: a proper prior of ``d0``, uniform on ``[max(a, d0_min), b]``
        (``d0_min = max(0, max dz)``, the plane above the vehicle); default the
        EM's bounds, whose upper end is the largest range.
    window : tuple of float, optional
        ``(lo, hi)``: the outliers are uniform over this listening window (m),
        which must hold every range; default the smallest and largest range.
    precision : {"auto", "float32", "float64"}
        Of the likelihood kernel (:class:`~bayes_mpem.lbl.model.loglik_kernel.LoglikKernel`):
        ``"auto"`` uses float32 where its rounding error is known to be harmless.

    Attributes
    ----------
    names : tuple of str
        The sampler's coordinates, in the order of the columns of ``theta``.
    label : str
        ``"beacon <name> (<priors> priors)"``, for the progress bar.
    em : EMResult or None
        The start of the walkers.
    kernel : LoglikKernel
        The likelihood of the beacon's ranges, for a batch of walkers.

    Examples
    --------
    >>> import numpy as np
    >>> from bayes_mpem.lbl.simulation.simulate import simulate_survey
    >>> post = BeaconPosterior(simulate_survey("abe58", rng=0).survey.for_beacon("4"))
    >>> post.names
    ('d0', 'log_sigma_mp', 'log_sigma_dp', 'w_dp', 'w_mp')
    >>> theta = np.array([[2472.0, np.log(7.0), np.log(4.0), 0.5, 0.35]])
    >>> bool(np.isfinite(post(theta))[0])
    True
    """

    def __init__(self, data: BeaconData, *, priors="learned", sigma_dp=None, path="triangle",
                 concentration=1.0, sigma_bounds=(0.05, 500.0), em: EMResult | None = None,
                 d0_bounds=None, window=None, precision="auto"):
        check_choice("priors", priors, PRIORS)
        check_positive("concentration", concentration)
        self.geom = _with_window(BeaconGeometry.from_data(data), window)
        self.beacon = data.beacon
        self.priors = priors
        self.label = f"beacon {self.beacon} ({priors} priors)"
        self.em = em
        self.path = path
        self.kernel = LoglikKernel(self.geom, path, precision=precision)
        self.sigma_dp = None if sigma_dp is None else float(sigma_dp)
        self.concentration = float(concentration)
        self.log_sigma_bounds = (np.log(sigma_bounds[0]), np.log(sigma_bounds[1]))
        self.d0_bounds = _d0_bounds(self.geom, d0_bounds)
        names = ["d0", "log_sigma_mp"]
        if self.sigma_dp is None:
            names.append("log_sigma_dp")
        if priors == "learned":
            names += ["w_dp", "w_mp"]
        self.names = tuple(names)
        c = self.concentration
        self._dirichlet_norm = lgamma(3 * c) - 3 * lgamma(c)
        width = self.log_sigma_bounds[1] - self.log_sigma_bounds[0]
        n_scales = 2 if self.sigma_dp is None else 1
        self._log_prior_const = -np.log(self.d0_bounds[1] - self.d0_bounds[0]) - n_scales * np.log(
            width)

    @property
    def ndim(self) -> int:
        """Number of sampled parameters."""
        return len(self.names)

    def draw_prior(self, n, gen):
        """Draw ``n`` parameter sets from the prior, in the sampler's coordinates.

        Returns
        -------
        numpy.ndarray
            ``(n, ndim)`` (with the default ``d0`` bounds the prior depends on the ranges).

        Examples
        --------
        >>> from bayes_mpem.lbl.simulation.simulate import simulate_survey
        >>> post = BeaconPosterior(simulate_survey("abe58", rng=0).survey.for_beacon("4"),
        ...                        d0_bounds=(2442.0, 2502.0))
        >>> theta = post.draw_prior(5, np.random.default_rng(0))
        >>> theta.shape, bool(np.all(np.isfinite(post.log_prior(theta))))
        ((5, 5), True)
        """
        lo, hi = self.log_sigma_bounds
        cols = {"d0": gen.uniform(*self.d0_bounds, size=n),
                "log_sigma_mp": gen.uniform(lo, hi, size=n)}
        if self.sigma_dp is None:
            cols["log_sigma_dp"] = gen.uniform(lo, hi, size=n)
        if self.priors == "learned":
            w = gen.dirichlet(np.full(3, self.concentration), size=n)
            cols["w_dp"], cols["w_mp"] = w[:, 0], w[:, 1]
        return np.column_stack([cols[name] for name in self.names])

    def unpack(self, theta):
        """Natural parameters of a ``(W, ndim)`` array, each of shape ``(W, 1)``.

        Returns
        -------
        dict
            ``d0``, ``sigma_mp``, ``sigma_dp``, ``w_dp``, ``w_mp``, ``w_ol``.
        """
        theta = np.atleast_2d(theta)
        col = {n: theta[:, [i]] for i, n in enumerate(self.names)}
        out = {"d0": col["d0"], "sigma_mp": np.exp(col["log_sigma_mp"])}
        out["sigma_dp"] = (np.exp(col["log_sigma_dp"]) if self.sigma_dp is None
                           else np.full_like(col["d0"], self.sigma_dp))
        if self.priors == "learned":
            out["w_dp"], out["w_mp"] = col["w_dp"], col["w_mp"]
            out["w_ol"] = 1.0 - col["w_dp"] - col["w_mp"]
        else:
            for c in CLASSES:
                out["w_" + c] = np.full_like(col["d0"], 1.0 / 3.0)
        return out

    def log_prior(self, theta):
        """Log prior density of a ``(W, ndim)`` array (``-inf`` outside the support).

        Parameters
        ----------
        theta : array_like
            ``(W, ndim)`` walkers in the order of :attr:`names` (or one ``(ndim,)`` point).

        Returns
        -------
        numpy.ndarray
            ``(W,)`` log prior densities.
        """
        theta = np.atleast_2d(theta)
        lo, hi = self.log_sigma_bounds
        d0 = theta[:, 0]
        ok = (d0 >= self.d0_bounds[0]) & (d0 <= self.d0_bounds[1])
        scales = theta[:, 1:3 if self.sigma_dp is None else 2]  # the log scales
        ok &= np.all((scales >= lo) & (scales <= hi), axis=1)
        out = np.full(theta.shape[0], self._log_prior_const)
        if self.priors == "learned":
            w = np.column_stack([theta[:, -2], theta[:, -1], 1.0 - theta[:, -2] - theta[:, -1]])
            ok &= np.all(w > 0, axis=1)
            if self.concentration != 1.0:
                with np.errstate(invalid="ignore", divide="ignore"):
                    out += (self.concentration - 1.0) * np.log(np.where(w > 0, w, 1.0)).sum(
                        axis=1)
            out += self._dirichlet_norm
        out[~ok] = -np.inf
        return out

    def outside_prior(self, params: dict) -> list:
        """Which natural parameters of ``params`` (e.g. an EM result) lie outside the prior.

        Parameters
        ----------
        params : dict
            ``d0``, ``sigma_mp``, ``sigma_dp`` and ``weights`` (as ``EMResult.params``).

        Returns
        -------
        list of str
            One message per parameter outside the prior's support (empty when none is).
        """
        lo, hi = np.exp(self.log_sigma_bounds)
        out = []
        if not self.d0_bounds[0] <= params["d0"] <= self.d0_bounds[1]:
            out.append(f"d0 = {params['d0']:.1f} m outside [{self.d0_bounds[0]:.1f}, "
                       f"{self.d0_bounds[1]:.1f}]")
        for k in ("sigma_mp", "sigma_dp"):
            if (k == "sigma_mp" or self.sigma_dp is None) and not lo <= params[k] <= hi:
                out.append(f"{k} = {params[k]:.3g} m outside [{lo:g}, {hi:g}]")
        if self.priors == "learned" and min(params["weights"].values()) <= 0:
            out.append(f"a mixing weight is 0 ({params['weights']})")
        return out

    def __call__(self, theta):
        """Log posterior (up to a constant) of a ``(W, ndim)`` array: emcee's target."""
        theta = np.atleast_2d(theta)
        lp = self.log_prior(theta)
        ok = np.isfinite(lp)
        if ok.any():
            p = self.unpack(theta[ok])
            lp[ok] += self.kernel(p["d0"], p["sigma_dp"], p["sigma_mp"], p["w_dp"], p["w_mp"],
                                  p["w_ol"])
        return lp

    def loglik_and_classes(self, theta):
        """Log-likelihood and class probabilities of every range, at each row of ``theta``.

        Parameters
        ----------
        theta : numpy.ndarray
            ``(W, ndim)``, inside the support.

        Returns
        -------
        loglik : numpy.ndarray
            ``(W, n)``.
        probs : list of numpy.ndarray
            Per class (dp, mp, ol), ``(W, n)``.
        """
        p = self.unpack(theta)
        return self.kernel.pointwise(p["d0"], p["sigma_dp"], p["sigma_mp"], p["w_dp"],
                                     p["w_mp"], p["w_ol"])

    def pointwise_moments(self, theta):
        """Per-range log-likelihood at every draw, and the class probabilities' mean and sd.

        Parameters
        ----------
        theta : numpy.ndarray
            ``(W, ndim)`` draws, inside the support.

        Returns
        -------
        loglik : numpy.ndarray
            ``(W, n)``.
        mean, sd : numpy.ndarray
            ``(n, 3)``, classes dp, mp, ol.
        """
        p = self.unpack(theta)
        return self.kernel.pointwise_moments(p["d0"], p["sigma_dp"], p["sigma_mp"], p["w_dp"],
                                             p["w_mp"], p["w_ol"])

    def theta_from(self, params: dict):
        """Sampler coordinates of a dict of natural parameters (e.g. an EM result).

        Parameters
        ----------
        params : dict
            ``d0``, ``sigma_mp``, ``sigma_dp`` and ``weights`` (as ``EMResult.params``).

        Returns
        -------
        numpy.ndarray
            ``(ndim,)``, in the order of :attr:`names`.
        """
        vals = {"d0": params["d0"], "log_sigma_mp": np.log(params["sigma_mp"]),
                "log_sigma_dp": np.log(params["sigma_dp"]),
                "w_dp": params["weights"]["dp"], "w_mp": params["weights"]["mp"]}
        return np.array([vals[n] for n in self.names], float)

    def _inside(self, centre):
        """``centre`` moved just inside the prior's support (unchanged when inside)."""
        if np.isfinite(self.log_prior(centre[None, :])[0]):
            return centre
        out = centre.copy()
        col = {n: i for i, n in enumerate(self.names)}
        lo, hi = self.d0_bounds
        pad = 1e-6 * (hi - lo)
        out[col["d0"]] = np.clip(out[col["d0"]], lo + pad, hi - pad)
        lo, hi = self.log_sigma_bounds
        for name in ("log_sigma_mp", "log_sigma_dp"):
            if name in col:
                out[col[name]] = np.clip(out[col[name]], lo + 1e-6, hi - 1e-6)
        if "w_dp" in col:
            w = np.maximum([out[col["w_dp"]], out[col["w_mp"]],
                            1.0 - out[col["w_dp"]] - out[col["w_mp"]]], 1e-3)
            out[col["w_dp"]], out[col["w_mp"]] = w[:2] / w.sum()
        return out

    def rough_sd(self) -> np.ndarray:
        """Large-sample standard errors at the EM solution :attr:`em`, no wider than the prior.

        Returns
        -------
        numpy.ndarray
            ``(ndim,)``, in the order of :attr:`names`.
        """
        em = self.em
        n = em.n
        frac = {c: max(em.weights[c], 1e-3) for c in CLASSES}
        width = {"d0": em.d0_se if em.d0_se and np.isfinite(em.d0_se) else 1.0,
                 "log_sigma_mp": 1.0 / np.sqrt(2 * max(frac["mp"] * n, 2)),
                 "log_sigma_dp": 1.0 / np.sqrt(2 * max(frac["dp"] * n, 2)),
                 "w_dp": np.sqrt(frac["dp"] * (1 - frac["dp"]) / n),
                 "w_mp": np.sqrt(frac["mp"] * (1 - frac["mp"]) / n)}
        # no wider than the prior: an EM with no multipath reports an astronomical d0_se
        extent = {"d0": self.d0_bounds[1] - self.d0_bounds[0],
                  "log_sigma_mp": self.log_sigma_bounds[1] - self.log_sigma_bounds[0],
                  "log_sigma_dp": self.log_sigma_bounds[1] - self.log_sigma_bounds[0],
                  "w_dp": 1.0, "w_mp": 1.0}
        return np.array([min(width[name], extent[name]) for name in self.names])

    def start(self, n_walkers, gen):
        """Walkers around the EM solution, scattered by half :meth:`rough_sd`, inside the prior.

        Returns
        -------
        numpy.ndarray
            ``(n_walkers, ndim)``.

        Raises
        ------
        ValueError
            When no EM solution was given.
        RuntimeError
            When 100 rounds of candidates leave walkers unplaced.
        """
        em = self.em
        if em is None:
            raise ValueError(f"beacon {self.beacon}: start needs the EM solution to start "
                             "from (BeaconPosterior(..., em=...)), got None")
        centre = self._inside(self.theta_from(em.to_dict()))
        scale = 0.5 * self.rough_sd()
        out = place_walkers(lambda sc: centre + sc * gen.standard_normal((n_walkers, self.ndim)),
                            lambda cand: np.isfinite(self(cand)), n_walkers, self.ndim,
                            scale=scale, rounds=100)
        if out is not None:
            return out
        raise RuntimeError(f"beacon {self.beacon}: could not place walkers inside the prior "
                           "around the EM solution "
                           f"{dict(zip(self.names, centre, strict=True))}")


def _with_window(geom: BeaconGeometry, window) -> BeaconGeometry:
    """``geom`` with the outliers' window ``(lo, hi)`` (None: the observed ranges)."""
    if window is None:
        return geom
    lo, hi = (float(v) for v in window)
    if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
        raise ValueError(f"window: expected (lo, hi) with lo < hi, got {window!r}")
    if geom.n and (geom.lo < lo or geom.hi > hi):
        raise ValueError(f"window: ({lo:g}, {hi:g}) m must hold every range; the ranges "
                         f"span {geom.lo:g}-{geom.hi:g} m")
    return replace(geom, lo=lo, hi=hi)


def _d0_bounds(geom: BeaconGeometry, bounds) -> tuple:
    """Return the support of the ``d0`` prior: the EM's bounds, or ``bounds`` above ``d0_min``."""
    if bounds is None:
        return (geom.d0_min, geom.hi + geom.d0_min + 1.0)
    a, b = (float(v) for v in bounds)
    lo = max(a, geom.d0_min)
    if not (np.isfinite(lo) and np.isfinite(b) and lo < b):
        raise ValueError(f"d0_bounds: expected (a, b) with max(a, {geom.d0_min:g}) < b (the "
                         f"plane above the vehicle), got {bounds!r}")
    return (lo, b)
