"""Rank statistics of simulation-based calibration and their tests (``docs/bayes-calibration.md``).

References
----------
Talts, S., Betancourt, M., Simpson, D., Vehtari, A. and Gelman, A. (2018).
Validating Bayesian inference algorithms with simulation-based calibration.
arXiv:1804.06788.
"""

from __future__ import annotations

import numpy as np


def rank_statistic(draws, truth) -> int:
    """Count the posterior draws below the true value: the SBC rank, from 0 to ``len(draws)``.

    Parameters
    ----------
    draws : array_like
        ``L`` posterior draws of one parameter (independent, or thinned to be so).
    truth : float
        The value the data were simulated from.

    Returns
    -------
    int

    Examples
    --------
    >>> rank_statistic([0.1, 0.5, 0.9], 0.6)
    2
    """
    return int(np.sum(np.asarray(draws, float) < float(truth)))


def rank_histogram(ranks, n_draws: int, n_bins: int = 10) -> np.ndarray:
    """Count the ranks in ``n_bins`` equal bins of the range 0 to ``n_draws``.

    Parameters
    ----------
    ranks : array_like of int
        SBC ranks, each in ``0 .. n_draws``.
    n_draws : int
        ``L``, the number of posterior draws each rank was taken among.
    n_bins : int, default 10
        A divisor of ``n_draws + 1`` (equal expected counts under uniformity).

    Returns
    -------
    numpy.ndarray
        ``(n_bins,)`` counts.

    Raises
    ------
    ValueError
        When ``n_bins`` does not divide ``n_draws + 1``, or a rank is out of range.

    Examples
    --------
    >>> rank_histogram([0, 1, 5, 9], 9, n_bins=5).tolist()
    [2, 0, 1, 0, 1]
    """
    ranks = np.asarray(ranks, int)
    n_values = int(n_draws) + 1
    if n_bins < 1 or n_values % n_bins:
        raise ValueError(f"n_bins: expected a divisor of n_draws + 1 = {n_values}, got {n_bins}")
    if ranks.size and (ranks.min() < 0 or ranks.max() > n_draws):
        raise ValueError(f"ranks: expected integers in 0..{n_draws}, got "
                         f"{ranks.min()}..{ranks.max()}")
    return np.bincount(ranks // (n_values // n_bins), minlength=n_bins)


def rank_uniformity(ranks, n_draws: int, *, n_bins: int = 10, tails: float = 0.1) -> dict:
    """Test SBC ranks for uniformity: binned chi-square, and the share in the tails.

    Parameters
    ----------
    ranks : array_like of int
        SBC ranks of one parameter over the simulations, each in ``0 .. n_draws``.
    n_draws : int
        ``L``, the number of posterior draws each rank was taken among.
    n_bins : int, default 10
        Bins of the chi-square test (a divisor of ``n_draws + 1``).
    tails : float, default 0.1
        Share of the rank values in the two outer tails together (half at each
        end, rounded to whole rank values); their expected share of the ranks.

    Returns
    -------
    dict
        ``n``, ``counts`` (the histogram), ``chi2``, ``dof``, ``p_value``,
        ``tails`` (observed share of ranks in the tails), ``tails_expected``
        and ``tails_p_value`` (two-sided binomial test).

    Examples
    --------
    >>> out = rank_uniformity(np.arange(100), 99)
    >>> out["chi2"], out["tails"]
    (0.0, 0.1)
    """
    from scipy import stats

    ranks = np.asarray(ranks, int)
    counts = rank_histogram(ranks, n_draws, n_bins)
    n = int(ranks.size)
    expected = n / n_bins
    chi2 = float(np.sum((counts - expected) ** 2 / expected)) if n else 0.0
    dof = n_bins - 1
    n_values = int(n_draws) + 1
    k = max(1, int(round(0.5 * tails * n_values)))  # rank values in each tail
    in_tails = int(np.sum((ranks < k) | (ranks >= n_values - k)))
    p_tail = 2 * k / n_values
    return {"n": n, "counts": counts.tolist(), "chi2": chi2, "dof": dof,
            "p_value": float(stats.chi2.sf(chi2, dof)) if n else 1.0,
            "tails": in_tails / n if n else float("nan"), "tails_expected": p_tail,
            "tails_p_value": float(stats.binomtest(in_tails, n, p_tail).pvalue) if n else 1.0}


def rank_dispersion(ranks, n_draws: int) -> dict:
    """Test whether the ranks are too spread (draws too narrow) or too bunched (too wide).

    Each rank ``r`` becomes the squared normal score ``q = Phi^-1((r + 1/2) / (L + 1))^2``.
    Under uniform ranks its mean is known exactly (a little below 1, the ranks being
    discrete); draws ``s`` times too narrow raise it to about ``1 / s**2``. The scores
    are averaged over the parameters of each simulation (columns of ``ranks``), and the
    mean over simulations is compared with the null mean by a t-test: the parameters of
    one simulation are dependent, the simulations are not.

    Parameters
    ----------
    ranks : array_like of int
        ``(n_sims,)`` or ``(n_sims, n_params)`` ranks, each in ``0 .. n_draws``.
    n_draws : int

    Returns
    -------
    dict
        ``n``, ``mean`` (of the scores), ``null_mean``, ``ratio`` (mean over null mean),
        ``z`` (positive: the draws are too narrow) and ``p_value`` (two-sided).

    Examples
    --------
    >>> gen = np.random.default_rng(1)
    >>> ok = [[rank_statistic(gen.normal(size=99), gen.normal()) for _ in range(3)]
    ...       for _ in range(400)]
    >>> abs(rank_dispersion(ok, 99)["z"]) < 3
    True
    >>> narrow = [[rank_statistic(0.8 * gen.normal(size=99), gen.normal()) for _ in range(3)]
    ...           for _ in range(400)]
    >>> rank_dispersion(narrow, 99)["z"] > 5
    True
    """
    from scipy import stats

    ranks = np.asarray(ranks, float)
    ranks = ranks.reshape(len(ranks), -1)
    n_values = int(n_draws) + 1
    score = stats.norm.ppf((ranks + 0.5) / n_values) ** 2
    null = float(np.mean(stats.norm.ppf((np.arange(n_values) + 0.5) / n_values) ** 2))
    per = score.mean(axis=1)
    n = per.size
    se = float(per.std(ddof=1) / np.sqrt(n)) if n > 1 else float("inf")
    z = (float(per.mean()) - null) / se if se > 0 else 0.0
    return {"n": int(n), "mean": float(per.mean()), "null_mean": null,
            "ratio": float(per.mean() / null), "z": float(z),
            "p_value": float(2 * stats.norm.sf(abs(z)))}
