"""Summaries of a kept chain: thinning, moments over draws, and ArviZ's diagnostics."""

from __future__ import annotations

import numpy as np


def _array_stats():
    """ArviZ's array functions, imported on first use."""
    from arviz_stats.base import array_stats

    return array_stats


def thin_index(kept: int, n_chains: int, n_draws: int) -> tuple[np.ndarray, int]:
    """Pick steps ending at the last, at the largest spacing keeping ``n_draws`` draws or more.

    Parameters
    ----------
    kept : int
        Steps in the kept chain.
    n_chains : int
        Chains (walkers, over all ensembles) sharing the draws.
    n_draws : int
        Draws wanted at least, over all chains (all steps when there are fewer).

    Returns
    -------
    idx : numpy.ndarray
        Steps to keep.
    thin : int
        Their spacing.

    Examples
    --------
    >>> idx, thin = thin_index(1000, 50, 400)
    >>> idx[:3].tolist(), idx.size, thin
    ([124, 249, 374], 8, 125)
    >>> thin_index(80, 32, 2000)[1]
    1
    """
    per_chain = max(1, min(kept, int(np.ceil(n_draws / n_chains))))
    thin = max(1, kept // per_chain)
    return np.arange(kept - 1, -1, -thin)[::-1], thin


def ess(x, method: str = "bulk") -> float:
    """ArviZ's ESS (:func:`arviz_stats.base.array_stats.ess`) of a ``(chain, draw)`` array.

    Parameters
    ----------
    x : array_like
        ``(chain, draw)``.
    method : str, default "bulk"

    Returns
    -------
    float
    """
    return float(_array_stats().ess(np.asarray(x, float), method=method))


def rhat(x) -> float:
    """ArviZ's rank-normalised split R-hat of a ``(chain, draw)`` array.

    Parameters
    ----------
    x : array_like
        ``(chain, draw)``.

    Returns
    -------
    float
    """
    return float(_array_stats().rhat(np.asarray(x, float)))


def ess_and_rhat(series: dict, n_ens: int = 1) -> tuple[dict, dict]:
    """ArviZ's bulk ESS and R-hat of each ``(walker, draw)`` series, walkers as chains.

    Parameters
    ----------
    series : dict of str to array_like
        ``(walker, draw)`` arrays, the walkers of each ensemble consecutive.
    n_ens : int, default 1
        Ensembles: with more than one, R-hat compares them (the walkers of one ensemble
        are not independent chains), each ensemble's draws pooled into one chain.

    Returns
    -------
    ess, rhat : dict
    """
    ess_by, rhat_by = {}, {}
    for k, v in series.items():
        x = np.asarray(v)
        ess_by[k] = ess(x)
        if n_ens > 1:
            x = x.reshape(n_ens, -1, x.shape[1]).transpose(0, 2, 1).reshape(n_ens, -1)
        rhat_by[k] = rhat(x)
    return ess_by, rhat_by


def bulk_ess(series: dict) -> dict:
    """ArviZ's bulk ESS of each ``(chain, draw)`` array of a dict.

    Parameters
    ----------
    series : dict of str to array_like

    Returns
    -------
    dict of str to float
    """
    return {k: ess(v) for k, v in series.items()}


def hdi(x, ci: float) -> list:
    """Highest-density interval ``[lower, upper]`` of all values of ``x`` (ArviZ's nearest).

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
    lo, hi = _array_stats().hdi(np.ravel(np.asarray(x, float)), ci)
    return [float(lo), float(hi)]


def equal_tailed(x, ci: float) -> list:
    """Equal-tailed interval ``[lower, upper]`` of all values of ``x``, probability ``ci``.

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


def draw_summary(x, ci: float) -> dict:
    """``mean``, ``sd`` (ddof 1) and equal-tailed ``interval`` of all values of ``x``.

    Parameters
    ----------
    x : array_like
        Draws (all axes pooled).
    ci : float
        Probability of the interval, in ``(0, 1)``.

    Returns
    -------
    dict

    Examples
    --------
    >>> draw_summary([1.0, 2.0, 3.0], 0.5)
    {'mean': 2.0, 'sd': 1.0, 'interval': [1.5, 2.5]}
    """
    x = np.ravel(np.asarray(x, float))
    return {"mean": float(np.mean(x)), "sd": float(np.std(x, ddof=1)),
            "interval": equal_tailed(x, ci)}


def draw_moments(flat, fn, *, chunk: int = 64):
    """Pointwise values and the mean and sd of per-item probabilities over draws, in chunks.

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


#: the root attribute ``diagnostics`` of a posterior file: how ``summary.json``'s ESS and
#: R-hat are computed from its draws (``docs/bayes.md``, Diagnostics from the file)
DIAGNOSTICS_NOTE = {
    False: "summary.json's bulk ESS and R-hat: ArviZ's, the walkers (the chains) as chains",
    True: ("summary.json's bulk ESS: ArviZ's, the walkers (the chains) as chains; its R-hat: "
           "ArviZ's across the ensembles, each ensemble's walkers (the chain coordinate "
           "'ensemble') pooled step by step into one chain"),
}


def to_datatree(groups: dict, *, dims: dict | None = None, coords: dict | None = None,
                attrs: dict | None = None, n_ensembles: int | None = None):
    """ArviZ data (:func:`arviz_base.from_dict`), walkers (or chains) as chains.

    Parameters
    ----------
    groups : dict
        Group name -> {variable -> ``(chain, draw, ...)`` array} (``observed_data``:
        no chain and draw axes).
    dims : dict, optional
        Variable -> names of its axes after ``chain`` and ``draw``.
    coords : dict, optional
        Dimension -> coordinate values.
    attrs : dict, optional
        Root attributes.
    n_ensembles : int, optional
        The chains are the walkers of this many ensembles, one ensemble after the other
        (:func:`run_ensembles`): every group over ``chain`` gets the coordinate
        ``ensemble`` (each walker's ensemble, from 0), and the root the attributes
        ``n_ensembles`` and ``diagnostics`` (:data:`DIAGNOSTICS_NOTE`: how
        :func:`ess_and_rhat` reads the draws).

    Returns
    -------
    xarray.DataTree

    Examples
    --------
    >>> x = np.zeros((4, 3))
    >>> tree = to_datatree({"posterior": {"a": x}, "sample_stats": {"lp": x}}, n_ensembles=2)
    >>> tree["posterior"]["ensemble"].values.tolist(), tree.attrs["n_ensembles"]
    ([0, 0, 1, 1], 2)
    """
    from arviz_base import from_dict

    tree = from_dict(groups, dims=dims, coords=coords, check_conventions=False)
    tree.attrs.update(attrs or {})
    if n_ensembles is not None:
        import xarray as xr

        n = int(n_ensembles)
        for name in list(tree.children):
            ds = tree[name].to_dataset()
            if "chain" not in ds.dims:
                continue
            if ds.sizes["chain"] % n:
                raise ValueError(f"{ds.sizes['chain']} chains are not the walkers of {n} "
                                 "ensembles of equal size")
            ds = ds.assign_coords(ensemble=("chain", np.repeat(np.arange(n),
                                                               ds.sizes["chain"] // n)))
            ds["ensemble"].attrs["long_name"] = "the ensemble of each walker (chain)"
            tree[name] = xr.DataTree(ds)
        tree.attrs.update(n_ensembles=n, diagnostics=DIAGNOSTICS_NOTE[n > 1])
    return tree
