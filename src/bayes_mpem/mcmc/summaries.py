"""Summaries of a kept chain: thinning, ESS, intervals, moments over draws, ArviZ objects.

Used by both posteriors after :func:`bayes_mpem.mcmc.driver.run_ensembles`.
"""

from __future__ import annotations

import numpy as np

from .convergence import ess_bulk, hdi_nearest, rhat_rank


def thin_index(kept: int, n_chains: int, n_draws: int) -> tuple[np.ndarray, int]:
    """Evenly spaced steps, ending at the last, giving about ``n_draws`` draws over all chains.

    Parameters
    ----------
    kept : int
        Steps in the kept chain.
    n_chains : int
        Chains (walkers, over all ensembles) sharing the draws.
    n_draws : int
        Draws wanted in all.

    Returns
    -------
    idx : numpy.ndarray
        Steps to keep.
    thin : int
        Their spacing.

    Examples
    --------
    >>> idx, thin = thin_index(1000, 50, 400)
    >>> idx.tolist(), thin
    ([124, 249, 374, 499, 624, 749, 874, 999], 125)
    """
    per_chain = max(1, min(kept, int(np.ceil(n_draws / n_chains))))
    thin = max(1, kept // per_chain)
    idx = np.arange(kept - (per_chain - 1) * thin - 1, kept, thin)[-per_chain:]
    return idx, thin


def autocorr_ess(series) -> tuple[float, float]:
    """Integrated autocorrelation time (emcee, steps) of a ``(steps, walkers)`` series.

    Parameters
    ----------
    series : numpy.ndarray
        ``(steps, walkers)`` values of one parameter.

    Returns
    -------
    tau : float
        Integrated autocorrelation time, in steps.
    ess : float
        ``steps x walkers / tau``.
    """
    import emcee

    tau = float(emcee.autocorr.integrated_time(series[:, :, None], tol=0, quiet=True)[0])
    return tau, float(series.shape[0] * series.shape[1] / tau)


def bulk_ess(series: dict) -> dict:
    """Rank-normalised bulk ESS (ArviZ's estimator, :mod:`.convergence`) of each array of a dict.

    Parameters
    ----------
    series : dict of str to array_like
        ``(chain, draw)`` arrays (walkers as chains).

    Returns
    -------
    dict of str to float
    """
    return {k: ess_bulk(v) for k, v in series.items()}


def hdi(x, ci: float) -> list:
    """Highest-density interval ``[lower, upper]`` (ArviZ's nearest-draws method) of ``x``.

    Parameters
    ----------
    x : array_like
        Draws (all axes pooled).
    ci : float
        Probability of the interval, in ``(0, 1)``.

    Returns
    -------
    list of float
    """
    return hdi_nearest(x, ci)


def equal_tailed(x, ci: float) -> list:
    """Equal-tailed interval ``[lower, upper]`` of all values of ``x``, probability ``ci``.

    The ``(1 - ci) / 2`` and ``(1 + ci) / 2`` quantiles.

    Parameters
    ----------
    x : array_like
        Draws (all axes pooled).
    ci : float
        Probability of the interval, in ``(0, 1)``.

    Returns
    -------
    list of float

    Examples
    --------
    >>> equal_tailed(range(101), 0.5)
    [25.0, 75.0]
    """
    lo, hi = np.quantile(np.ravel(x), [0.5 - ci / 2, 0.5 + ci / 2])
    return [float(lo), float(hi)]


def draw_moments(flat, fn, *, chunk: int = 64):
    """Pointwise values and the mean and sd of per-item probabilities over draws, in chunks.

    One pass over chunks of draws: never a draws x items x classes array.

    Parameters
    ----------
    flat : numpy.ndarray
        ``(draws, ndim)``.
    fn : callable
        ``fn(theta)`` of a ``(W, ndim)`` chunk returns ``(pointwise, probs)``:
        a ``(W, n)`` array (e.g. the log-likelihood of each item) or None, and a
        sequence of ``k`` probability arrays, each ``(W, n)``.
    chunk : int, default 64
        Draws per call of ``fn``.

    Returns
    -------
    pointwise : numpy.ndarray or None
        ``(draws, n)``, when ``fn`` returns one.
    mean, sd : numpy.ndarray
        ``(n, k)``, over the draws.

    Examples
    --------
    >>> flat = np.array([[0.2], [0.4]])
    >>> _, m, s = draw_moments(flat, lambda t: (None, [np.repeat(t, 3, axis=1)]))
    >>> m[:, 0].round(3).tolist(), s[:, 0].round(3).tolist()
    ([0.3, 0.3, 0.3], [0.1, 0.1, 0.1])
    """
    n_draws = flat.shape[0]
    pointwise = s1 = s2 = None
    for i in range(0, n_draws, chunk):
        values, probs = fn(flat[i:i + chunk])
        if s1 is None:
            n = probs[0].shape[1]
            s1, s2 = np.zeros((n, len(probs))), np.zeros((n, len(probs)))
            if values is not None:
                pointwise = np.empty((n_draws, n))
        if values is not None:
            pointwise[i:i + chunk] = values
        for j, r in enumerate(probs):
            s1[:, j] += r.sum(axis=0)
            s2[:, j] += np.einsum("ij,ij->j", r, r)  # no (W, n) temporary
    m = s1 / n_draws
    return pointwise, m, np.sqrt(np.maximum(s2 / n_draws - m * m, 0.0))


#: groups without the (chain, draw) dimensions (ArviZ's convention)
_NO_SAMPLE_DIMS = ("observed_data", "constant_data", "predictions_constant_data")


def to_datatree(groups: dict, *, dims: dict | None = None, coords: dict | None = None):
    """ArviZ data from a dict of groups, walkers (or chains) as chains.

    The structure :func:`arviz_base.from_dict` makes (``chain`` and ``draw``
    leading every variable of a sampled group, numbered; the ``dims`` and ``coords``
    given; ``var_dim_i`` for unnamed axes; the creation attributes on every group),
    built with xarray directly: :mod:`arviz_base` imports matplotlib (0.1 s, a
    tenth of sampling a beacon end to end). ``tests/test_mcmc.py`` compares the
    two, array for array.

    Parameters
    ----------
    groups : dict
        Group name -> {variable -> ``(chain, draw, ...)`` array} (``observed_data``
        and ``constant_data``: no chain and draw axes).
    dims : dict, optional
        Variable -> names of its axes after ``chain`` and ``draw``.
    coords : dict, optional
        Dimension -> coordinate values.

    Returns
    -------
    xarray.DataTree
    """
    import datetime as dt

    import xarray as xr

    from .. import __version__

    dims, coords = dims or {}, coords or {}
    attrs = {"created_at": dt.datetime.now(dt.UTC).isoformat(),
             "creation_library": "bayes_mpem", "creation_library_version": __version__,
             "creation_library_language": "Python"}
    tree = {}
    for group, variables in groups.items():
        lead = () if group in _NO_SAMPLE_DIMS else ("chain", "draw")
        data = {}
        for name, value in variables.items():
            value = np.asarray(value)
            rest = value.ndim - len(lead)
            names = list(dims.get(name, []))[:rest]
            names += [f"{name}_dim_{i}" for i in range(len(names), rest)]
            data[name] = (lead + tuple(names), value)
        ds = xr.Dataset(data, attrs=dict(attrs))
        ds = ds.assign_coords({d: coords.get(d, np.arange(n)) for d, n in ds.sizes.items()})
        tree[group] = ds
    return xr.DataTree.from_dict(tree)


def rhat_across_ensembles(ds, n_ens: int) -> dict:
    """Rank-normalised split R-hat (ArviZ's estimator) across independent ensembles.

    The walkers of one ensemble are not independent chains: each ensemble's
    walkers are regrouped into one chain (draws = walkers x kept draws) first.

    Parameters
    ----------
    ds : xarray.Dataset
        ``(chain, draw)`` variables, the walkers of each ensemble consecutive.
    n_ens : int
        Number of ensembles (at least 2).

    Returns
    -------
    dict
        Variable -> R-hat.
    """
    out = {}
    for k, v in ds.data_vars.items():
        a = v.values  # (chain, draw)
        a = a.reshape(n_ens, -1, a.shape[1])  # (ensemble, walker, draw)
        out[k] = rhat_rank(a.transpose(0, 2, 1).reshape(n_ens, -1))
    return out
