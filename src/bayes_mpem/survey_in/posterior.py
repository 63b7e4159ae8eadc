"""The log-posterior of a transponder location and of the class of every ping (docs/cli.md)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from .._validate import check_choice, check_int, check_range, check_sampled_ci
from ..mcmc.driver import place_walkers
from .classes import log_classes
from .location import LocateResult
from .travel_times import chord

#: Support of the log-uniform prior on sigma (s).
SIGMA_BOUNDS = (1e-6, 1.0)
#: Half-width of the flat prior on each speed coefficient, relative to the EM's value.
SPEED_PRIOR_WIDTH = 0.10
#: Support of the flat prior on a fitted turn-around time (s).
TAT_BOUNDS = (0.0, 1.0)
#: Ray-bending corrections (:class:`LocationLogPosterior`).
BENDING = ("linear", "fixed")
#: Reported parameters, in order (``tat`` only when fitted).
PARAMS = ("east", "north", "depth", "sound_speed", "tat", "sigma", "weight")


def check_location_options(*, n_walkers=None, ci=0.95, min_ess=1000.0, max_steps=20000,
                           n_draws=4000):
    """Validate the sampler's options before any work (``ValueError`` naming the option).

    Parameters
    ----------
    n_walkers : int, optional
    ci : float
    min_ess : float
    max_steps, n_draws : int

    Raises
    ------
    ValueError
    """
    check_sampled_ci(ci)
    check_range("min_ess", min_ess, low=0, include_low=True)
    ints = [("max_steps", max_steps, 1), ("n_draws", n_draws, 1)]
    if n_walkers is not None:
        ints.append(("n_walkers", n_walkers, 4))
    for name, value, least in ints:
        check_int(name, value, minimum=least)


class LocationLogPosterior:
    """Log-posterior of one transponder's location and ping classes, vectorised over walkers.

    Parameters
    ----------
    pings : pandas.DataFrame
        The table the EM was fitted to (``fit.rows`` index it).
    fit : LocateResult
        The EM solution: fixes the model (profile, geometry, time basis, outlier
        density, window, whether ``tat`` is fitted), the ray-bending correction
        and the bounds of the speed prior.
    bending : {"linear", "fixed"}
        Refracted rays only: the ray-bending correction at the EM solution with
        its gradient (default), or held fixed (OBSrange's); docs/measured-data.md.

    Attributes
    ----------
    names : tuple of str
        The sampler's coordinates, in ``theta`` order.
    ndim : int
        ``len(names)``.
    label : str
        Short description for the sampler's progress bar.
    beacon : str
        The transponder.

    Notes
    -----
    The sampler's protocol (:mod:`bayes_mpem.mcmc`): ``names``, ``ndim``,
    ``label``, :meth:`start` (walkers inside the prior) and the call on a
    ``(W, ndim)`` array returning ``W`` log-probabilities.

    Examples
    --------
    >>> import numpy as np, pandas as pd
    >>> from bayes_mpem.survey_in.location import locate
    >>> rng = np.random.default_rng(0)
    >>> a = np.linspace(0, 2 * np.pi, 60)
    >>> x, y = 3000 * np.cos(a), 3000 * np.sin(a)
    >>> t = 2 * np.sqrt((x - 30) ** 2 + (y + 50) ** 2 + 4000.0**2) / 1505 + 0.013
    >>> pings = pd.DataFrame({"beacon": "T", "twtt": t + rng.normal(0, 1e-3, 60),
    ...                       "x": x, "y": y, "depth": 0.0})
    >>> beacons = pd.DataFrame({"beacon": ["T"], "x": [0.0], "y": [0.0], "depth": [4100.0]})
    >>> fit = locate(pings, beacons)
    >>> post = LocationLogPosterior(pings, fit)
    >>> post.names
    ('east', 'north', 'depth', 'speed', 'log_sigma', 'weight')
    >>> theta = post.theta_em()
    >>> bool(np.isclose(post.loglik(theta[None])[0], fit.logpdf(pings).sum()))
    True
    """

    def __init__(self, pings: pd.DataFrame, fit: LocateResult, *, bending="linear"):
        check_choice("bending", bending, BENDING)
        sub = pings.iloc[fit.rows]
        self.fit = fit
        self.beacon = fit.transponder
        self.t = sub["twtt"].to_numpy(float)
        self.n = self.t.size
        self.tt, theta = fit.travel_times(sub)  # exact travel times (tat fixed at fit.tat)
        self.theta_geo = theta  # [east, north, depth, *speed_coef] at the EM solution
        self.k = self.tt.basis.shape[1]
        self.basis_t = np.ascontiguousarray(self.tt.basis.T)  # (k, n)
        self.fit_tat = bool(fit.fit_tat)
        m = fit.model
        self.profile = m.get("ssp")
        self.surface_depth = float(m.get("surface_depth", 0.0))
        self.z_mean = float(np.mean(self.tt.z))
        self.bending = bending
        self.pos0 = np.asarray(theta[:3], float)
        self.sx, self.sy = self.tt.ship()  # at the fit's lag (the logged track when 0)
        self.v, self.delta, self.grad = 1.0, np.zeros(self.n), None
        if self.profile is not None:  # the ray-bending correction, at the EM solution
            L, *dL = chord(self.sx, self.sy, self.tt.z, *theta[:3], self.tt.R,
                           derivatives=True)
            T, *dT = self.tt.rays(theta)[:4]
            self.v = float(self._unit(theta[2]))
            self.delta = T - L / self.v
            if bending == "linear":  # (3, n): d(delta)/d(east, north, depth)
                self.grad = np.array([a - b / self.v for a, b in zip(dT, dL, strict=True)])
        self.window, self.outliers = fit.window, fit.outliers
        speed = ["speed"] if self.k == 1 else [f"speed_{i}" for i in range(self.k)]
        self.names = tuple(["east", "north", "depth", *speed] + (["tat"] if self.fit_tat else [])
                           + ["log_sigma", "weight"])
        coef = np.asarray(theta[3:3 + self.k], float)
        self.speed_bounds = (coef * (1 - SPEED_PRIOR_WIDTH), coef * (1 + SPEED_PRIOR_WIDTH))
        self.g = self.tt.basis.mean(axis=0)  # the reported speed: the mean over the pings

    @property
    def ndim(self) -> int:
        """Number of sampled parameters."""
        return len(self.names)

    @property
    def label(self) -> str:
        """Progress-bar label: the transponder."""
        return f"transponder {self.beacon}"

    def _unit(self, depth):
        """Speed of a unit coefficient (m/s): 1, or the profile's harmonic mean to ``depth``."""
        if self.profile is None:
            return np.ones_like(np.asarray(depth, float))
        return self.profile.harmonic_mean(self.z_mean - self.surface_depth,
                                          np.asarray(depth, float) - self.surface_depth)

    def theta_em(self) -> np.ndarray:
        """Return the EM solution in the sampler's coordinates."""
        f = self.fit
        return np.concatenate([self.theta_geo, [f.tat] if self.fit_tat else [],
                               [np.log(f.sigma), f.weight]]).astype(float)

    def _split(self, theta):
        theta = np.atleast_2d(theta)
        pos = theta[:, :3]
        coef = theta[:, 3:3 + self.k]
        tat = theta[:, [3 + self.k]] if self.fit_tat else self.fit.tat
        return pos, coef, tat, np.exp(theta[:, [-2]]), theta[:, [-1]]

    def log_prior(self, theta):
        """Log prior density (up to a constant) of a ``(W, ndim)`` array; ``-inf`` outside.

        Parameters
        ----------
        theta : array_like
            ``(W, ndim)`` walkers in the order of :attr:`names` (or one ``(ndim,)`` point).

        Returns
        -------
        numpy.ndarray
            ``(W,)``.
        """
        theta = np.atleast_2d(theta)
        coef = theta[:, 3:3 + self.k]
        lo, hi = np.log(SIGMA_BOUNDS[0]), np.log(SIGMA_BOUNDS[1])
        ok = np.all(np.isfinite(theta), axis=1)
        ok &= np.all((coef >= self.speed_bounds[0]) & (coef <= self.speed_bounds[1]), axis=1)
        ok &= (theta[:, -2] >= lo) & (theta[:, -2] <= hi)
        ok &= (theta[:, -1] > 0) & (theta[:, -1] < 1)
        if self.fit_tat:
            tat = theta[:, 3 + self.k]
            ok &= (tat >= TAT_BOUNDS[0]) & (tat <= TAT_BOUNDS[1])
        return np.where(ok, 0.0, -np.inf)

    def predict(self, theta):
        """Predicted two-way travel times, ``(W, n)``, with the ray-bending correction.

        Parameters
        ----------
        theta : array_like
            ``(W, ndim)`` walkers in the order of :attr:`names` (or one ``(ndim,)`` point).

        Returns
        -------
        numpy.ndarray
            ``(W, n)`` travel times (s).
        """
        pos, coef, tat, _, _ = self._split(theta)
        L = chord(self.sx, self.sy, self.tt.z, pos[:, [0]], pos[:, [1]], pos[:, [2]], self.tt.R)
        if self.profile is None:
            T = L
        elif self.grad is None:
            T = L / self.v + self.delta
        else:
            T = L / self.v + self.delta + (pos - self.pos0) @ self.grad
        return 2.0 * T / (coef @ self.basis_t) + tat

    def class_log_densities(self, theta):
        """Log densities (true, spurious), each ``(W, n)``.

        Parameters
        ----------
        theta : array_like
            ``(W, ndim)`` walkers in the order of :attr:`names` (or one ``(ndim,)`` point).

        Returns
        -------
        tuple of numpy.ndarray
            The weighted log densities of the true and the spurious class.
        """
        _, _, _, sigma, w = self._split(theta)
        # log_classes with a scalar weight of 1/2, re-weighted here: the same densities
        # as the EM, for an array of weights
        ld, lu = log_classes(self.t, self.predict(theta), sigma, 0.5, self.window,
                              self.outliers)
        return ld + (np.log(w) - np.log(0.5)), lu + (np.log1p(-w) - np.log(0.5))

    def pointwise(self, theta):
        """Log-likelihood of every ping, ``(W, n)``.

        Parameters
        ----------
        theta : array_like
            ``(W, ndim)`` walkers in the order of :attr:`names` (or one ``(ndim,)`` point).

        Returns
        -------
        numpy.ndarray
        """
        return np.logaddexp(*self.class_log_densities(theta))

    def loglik(self, theta):
        """Log-likelihood of a ``(W, ndim)`` array (travel times as the sampler uses them).

        Parameters
        ----------
        theta : array_like
            ``(W, ndim)`` walkers in the order of :attr:`names` (or one ``(ndim,)`` point).

        Returns
        -------
        numpy.ndarray
            ``(W,)``.
        """
        return self.pointwise(theta).sum(axis=1)

    def exact_loglik(self, theta):
        """Log-likelihood with the refracted rays solved at each row (slow; for checks).

        Equal to :meth:`loglik` for straight rays.

        Parameters
        ----------
        theta : array_like
            ``(W, ndim)`` walkers in the order of :attr:`names` (or one ``(ndim,)`` point).

        Returns
        -------
        numpy.ndarray
            ``(W,)``.
        """
        theta = np.atleast_2d(theta)
        out = np.empty(theta.shape[0])
        for i, row in enumerate(theta):
            pos, coef, tat, sigma, w = self._split(row)
            geo = np.concatenate([pos[0], coef[0]])
            tat = float(np.ravel(tat)[0])
            pred = 2.0 * self.tt.rays(geo)[0] / self.tt.speed(geo) + tat
            ld, lu = log_classes(self.t, pred, float(sigma[0, 0]), float(w[0, 0]), self.window,
                                  self.outliers)
            out[i] = np.logaddexp(ld, lu).sum()
        return out

    def __call__(self, theta):
        """Log posterior (up to a constant) of a ``(W, ndim)`` array: emcee's target.

        Parameters
        ----------
        theta : numpy.ndarray
            ``(W, ndim)`` (a single ``(ndim,)`` row is taken as ``W = 1``).

        Returns
        -------
        numpy.ndarray
            ``(W,)``; ``-inf`` outside the prior.
        """
        theta = np.atleast_2d(theta)
        lp = self.log_prior(theta)
        ok = np.isfinite(lp)
        if ok.any():
            lp[ok] += self.loglik(theta[ok])
        return lp

    def natural(self, theta):
        """Convert a ``(..., ndim)`` array to the reported parameters, each of shape ``(...)``.

        Parameters
        ----------
        theta : array_like
            ``(..., ndim)``, in the order of :attr:`names`.

        Returns
        -------
        dict
            ``east``, ``north``, ``depth``, ``sound_speed`` (as :func:`locate` reports it:
            the mean over the pings, times the profile's harmonic mean), ``sigma`` (s),
            ``weight`` (and ``tat`` when fitted).
        """
        theta = np.asarray(theta, float)
        out = {k: theta[..., i] for i, k in enumerate(("east", "north", "depth"))}
        out["sound_speed"] = (theta[..., 3:3 + self.k] @ self.g) * self._unit(out["depth"])
        if self.fit_tat:
            out["tat"] = theta[..., 3 + self.k]
        out["sigma"] = np.exp(theta[..., -2])
        out["weight"] = theta[..., -1]
        return out

    def start(self, n_walkers, gen):
        """Place walkers in a small ball around the EM solution, inside the prior.

        Position, speed (and tat) from the Gauss-Newton covariance at the EM
        solution (so the depth-speed correlation is respected), sigma and weight
        from their large-sample widths; half those widths.

        Parameters
        ----------
        n_walkers : int
        gen : numpy.random.Generator

        Returns
        -------
        numpy.ndarray
            ``(n_walkers, ndim)``.

        Raises
        ------
        RuntimeError
            No place inside the prior was found after 60 halvings of the ball.
        """
        f = self.fit
        centre = self.theta_em()
        geo = np.concatenate([self.theta_geo, [f.tat] if self.fit_tat else []])
        J = self.tt.jac(self.theta_geo)
        if self.fit_tat:
            J = np.column_stack([J, np.ones(self.n)])
        Jw = np.sqrt(f.p_true)[:, None] * J
        cov = np.linalg.pinv(Jw.T @ Jw) * f.sigma**2
        # in units of each parameter's sd, so that a floor on the eigenvalues is scale-free
        d = np.sqrt(np.maximum(np.diag(cov), (1e-9 * np.maximum(np.abs(geo), 1.0)) ** 2))
        vals, vecs = np.linalg.eigh(cov / np.outer(d, d))
        root = d[:, None] * vecs * np.sqrt(np.maximum(vals, 1e-8))
        n_true = max(float(f.p_true.sum()), 2.0)
        sd_ls = 1.0 / np.sqrt(2.0 * n_true)
        sd_w = max(np.sqrt(f.weight * (1.0 - f.weight) / self.n), 1.0 / self.n)

        def draw(scale):
            cand = np.empty((n_walkers, self.ndim))
            cand[:, :geo.size] = geo + scale * gen.standard_normal((n_walkers, geo.size)) @ root.T
            cand[:, -2] = centre[-2] + scale * sd_ls * gen.standard_normal(n_walkers)
            cand[:, -1] = centre[-1] + scale * sd_w * gen.standard_normal(n_walkers)
            return cand

        out = place_walkers(draw, lambda cand: np.isfinite(self.log_prior(cand)), n_walkers,
                            self.ndim, scale=0.5, rounds=60)
        if out is not None:
            return out
        at = dict(zip(self.names, centre, strict=True))
        raise RuntimeError(f"transponder {self.beacon}: could not place walkers inside the "
                           f"prior around the EM solution {at}")


#: gzip with byte shuffling (netCDF4's deflate) on every variable of a posterior file
GZIP = {"compression": "gzip", "compression_opts": 4, "shuffle": True}


def posterior_file(name) -> str:
    """Return the file name of a survey-in posterior: ``posterior_<name>.nc``.

    One file per located transponder (``locate --sample`` one at a time) or one for a
    GNSS-A array (``posterior_array.nc``), each an ArviZ DataTree.

    Parameters
    ----------
    name : str
        The transponder, or ``"array"``.

    Returns
    -------
    str

    Examples
    --------
    >>> posterior_file("array"), posterior_file("../x y")
    ('posterior_array.nc', 'posterior_.._x_y.nc')
    """
    import re

    return f"posterior_{re.sub(r'[^A-Za-z0-9._-]', '_', str(name))}.nc"


def posterior_tree(posterior: dict, lp, shots: pd.DataFrame, p_true, p_true_sd, rows, *,
                   units: dict, dims: dict | None = None, coords: dict | None = None,
                   attrs: dict | None = None, n_ensembles: int = 1):
    """ArviZ data of a survey-in posterior (an array or one transponder), walkers as chains.

    The one layout of :func:`write_posterior`'s files (``docs/gnssa.md``, The array
    posterior).

    Parameters
    ----------
    posterior : dict
        Variable -> ``(walker, draw, ...)`` draws (the ``posterior`` group).
    lp : numpy.ndarray
        ``(walker, draw)`` log density of the draws (``sample_stats``).
    shots : pandas.DataFrame
        ``line``, ``time`` (s), ``transponder``, ``twtt`` (s) of the shots (pings) used.
    p_true, p_true_sd : numpy.ndarray
        Per shot: mean and sd over the draws of the probability of a true reply.
    rows : numpy.ndarray
        Positions of the shots in the input table (the ``shot`` coordinate).
    units : dict
        Variable or coordinate -> its ``units`` attribute.
    dims, coords : dict, optional
        Of the posterior's variables (:func:`~bayes_mpem.mcmc.to_datatree`).
    attrs : dict, optional
        Root attributes.
    n_ensembles : int, default 1
        Ensembles whose walkers the chains are (the chain coordinate ``ensemble``).

    Returns
    -------
    xarray.DataTree
        ``posterior``, ``sample_stats`` (``lp``), ``observed_data`` (``twtt`` over
        ``shot``: the input row, with the shot's ``time``, ``shot_transponder`` and file
        ``line``) and ``class_probabilities`` (``p_true``, ``p_true_sd`` per shot); units
        as attributes.
    """
    import xarray as xr

    from ..mcmc import to_datatree

    rows = np.asarray(rows)
    tree = to_datatree(
        {"posterior": posterior, "sample_stats": {"lp": lp},
         "observed_data": {"twtt": shots["twtt"].to_numpy(float)}},
        dims={**(dims or {}), "twtt": ["shot"]}, coords={**(coords or {}), "shot": rows},
        attrs=attrs, n_ensembles=n_ensembles)
    tree["class_probabilities"] = xr.DataTree(xr.Dataset(
        {"p_true": ("shot", np.asarray(p_true)), "p_true_sd": ("shot", np.asarray(p_true_sd))},
        coords={"shot": rows}))
    for name in tree.children:
        ds = tree[name].to_dataset()
        if "shot" in ds.dims:
            ds = ds.assign_coords(
                time=("shot", shots["time"].to_numpy(float)),
                shot_transponder=("shot", shots["transponder"].astype(str).to_numpy()),
                line=("shot", shots["line"].to_numpy()))
            ds["shot"].attrs.update(long_name="input row")
        for var in list(ds.data_vars) + list(ds.coords):
            if var in units:
                ds[var].attrs["units"] = units[var]
        tree[name] = xr.DataTree(ds)
    return tree


def write_posterior(path, tree) -> None:
    """Write an ArviZ DataTree as NetCDF4 (h5netcdf), every variable gzip-compressed.

    The file opens with :func:`arviz_base.from_netcdf` and :func:`xarray.open_datatree`.

    Parameters
    ----------
    path : str or pathlib.Path
    tree : xarray.DataTree
    """
    enc = {}
    for node in tree.subtree:
        ds = node.dataset
        variables = {name: dict(GZIP) for name, var in ds.variables.items()
                     if var.ndim and name not in ds.dims and var.dtype.kind in "fiub"}
        if variables:
            enc[node.path] = variables
    tree.to_netcdf(path, engine="h5netcdf", encoding=enc)
