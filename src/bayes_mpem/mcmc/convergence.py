"""Rank-normalised ESS and R-hat (Vehtari et al. 2021) and the nearest-draws HDI.

The same estimators as ArviZ's ``ess(method="bulk")``, ``ess(method="mean")``,
``rhat(method="rank")`` and ``hdi(method="nearest")``, written here against the
paper because importing :mod:`arviz_stats` costs about 0.6 s (it imports
:mod:`scipy.stats`), more than sampling one beacon takes; for the same reason the
normal scores come from :func:`ndtri`, Wichura's (1988) algorithm AS241 vectorised
(the one Python's :class:`statistics.NormalDist` uses; :mod:`scipy.special` costs
0.1 s to import). ``tests/test_convergence.py`` checks every function against
:mod:`arviz_stats` to 1e-10 on random and autocorrelated chains, and :func:`ndtri`
against :func:`scipy.special.ndtri`, so ArviZ and SciPy stay the references.

References
----------
Vehtari, Gelman, Simpson, Carpenter and Buerkner (2021), Rank-normalization,
folding, and localization: an improved R-hat for assessing convergence of MCMC,
Bayesian Analysis 16(2), 667-718. Geyer (1992), Practical Markov chain Monte
Carlo, Statistical Science 7(4), 473-483. Wichura (1988), Algorithm AS241: the
percentage points of the normal distribution, Applied Statistics 37(3), 477-484.
"""

from __future__ import annotations

import numpy as np

# AS241 (PPND16): numerator and denominator coefficients, highest power first
_CENTRAL = (np.array([2.5090809287301226727e+3, 3.3430575583588128105e+4,
                      6.7265770927008700853e+4, 4.5921953931549871457e+4,
                      1.3731693765509461125e+4, 1.9715909503065514427e+3,
                      1.3314166789178437745e+2, 3.3871328727963666080e+0]),
            np.array([5.2264952788528545610e+3, 2.8729085735721942674e+4,
                      3.9307895800092710610e+4, 2.1213794301586595867e+4,
                      5.3941960214247511077e+3, 6.8718700749205790830e+2,
                      4.2313330701600911252e+1, 1.0]))
_NEAR = (np.array([7.7454501427834140764e-4, 2.2723844989269184583e-2,
                   2.4178072517745061177e-1, 1.2704582524523683826e+0,
                   3.6478483247632046050e+0, 5.7694972214606914055e+0,
                   4.6303378461565452959e+0, 1.4234371107496835773e+0]),
         np.array([1.0507500716444168432e-9, 5.4759380849953449460e-4,
                   1.5198666563616457197e-2, 1.4810397642748007459e-1,
                   6.8976733498510000455e-1, 1.6763848301838038494e+0,
                   2.0531916266377588219e+0, 1.0]))
_FAR = (np.array([2.0103343992922881327e-7, 2.7115555687434875782e-5,
                  1.2426609473880784386e-3, 2.6532189526576123093e-2,
                  2.9656057182850489123e-1, 1.7848265399172913358e+0,
                  5.4637849111641143699e+0, 6.6579046435011037772e+0]),
        np.array([2.0442631033899397856e-15, 1.4215117583164458887e-7,
                  1.8463183175100546818e-5, 7.8686913114561325910e-4,
                  1.4875361290850614853e-2, 1.3692988092273580531e-1,
                  5.9983220655588793769e-1, 1.0]))


def ndtri(p) -> np.ndarray:
    """Inverse of the standard normal distribution function, for ``p`` in ``(0, 1)``.

    Wichura's AS241 (relative error about 1e-16), vectorised.

    Parameters
    ----------
    p : array_like

    Returns
    -------
    numpy.ndarray
        ``-inf`` at 0, ``inf`` at 1, NaN outside ``[0, 1]``.

    Examples
    --------
    >>> ndtri([0.5, 0.975]).round(6).tolist()
    [0.0, 1.959964]
    """
    p = np.asarray(p, dtype=float)
    q = p - 0.5
    out = np.empty_like(p)
    central = np.abs(q) <= 0.425
    r = 0.180625 - q[central] ** 2
    out[central] = q[central] * np.polyval(_CENTRAL[0], r) / np.polyval(_CENTRAL[1], r)
    tail = ~central
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.sqrt(-np.log(np.where(q[tail] < 0, p[tail], 1.0 - p[tail])))
        x = np.where(r <= 5.0,
                     np.polyval(_NEAR[0], r - 1.6) / np.polyval(_NEAR[1], r - 1.6),
                     np.polyval(_FAR[0], r - 5.0) / np.polyval(_FAR[1], r - 5.0))
    out[tail] = np.where(q[tail] < 0, -x, x)
    out[p == 0] = -np.inf
    out[p == 1] = np.inf
    out[(p < 0) | (p > 1) | np.isnan(p)] = np.nan
    return out


def _chains(a) -> np.ndarray:
    """``(chain, draw)`` float array of ``a`` (a 1-D array is one chain)."""
    a = np.asarray(a, dtype=float)
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2:
        raise ValueError(f"expected a (chain, draw) array, got shape {a.shape}")
    return a


def _usable(a, *, min_chains: int):
    """``(chain, draw)`` array of ``a``, or None with too few chains or draws, or non-finite."""
    a = _chains(a)
    if a.shape[0] < min_chains or a.shape[1] < 4 or not np.all(np.isfinite(a)):
        return None
    return a


def split_chains(a) -> np.ndarray:
    """Each chain cut into its first and last halves (the middle draw of an odd length dropped).

    Parameters
    ----------
    a : array_like
        ``(chain, draw)``.

    Returns
    -------
    numpy.ndarray
        ``(2 chain, draw // 2)``.

    Examples
    --------
    >>> split_chains([[1, 2, 3, 4, 5]]).tolist()
    [[1.0, 2.0], [4.0, 5.0]]
    """
    a = _chains(a)
    half = a.shape[1] // 2
    return np.vstack((a[:, :half], a[:, a.shape[1] - half:]))


def average_ranks(x) -> np.ndarray:
    """Ranks 1..n of the values of ``x`` (any shape), ties given their average rank.

    Parameters
    ----------
    x : array_like

    Returns
    -------
    numpy.ndarray
        The ranks, the shape of ``x``.

    Examples
    --------
    >>> average_ranks([3.0, 1.0, 3.0, 2.0]).tolist()
    [3.5, 1.0, 3.5, 2.0]
    """
    x = np.asarray(x, dtype=float)
    flat = x.ravel()
    order = np.argsort(flat, kind="mergesort")
    xs = flat[order]
    start = np.flatnonzero(np.r_[True, xs[1:] != xs[:-1]])
    end = np.r_[start[1:], xs.size]  # each run of ties is positions start..end-1
    ranks = np.empty(xs.size)
    ranks[order] = np.repeat((start + 1 + end) / 2.0, end - start)
    return ranks.reshape(x.shape)


def z_scale(a) -> np.ndarray:
    """Rank-normalise: pooled average ranks to normal scores, ``Phi^-1((r - 3/8) / (S + 1/4))``.

    Parameters
    ----------
    a : array_like

    Returns
    -------
    numpy.ndarray
        The same shape.
    """
    a = np.asarray(a, dtype=float)
    return ndtri((average_ranks(a) - 0.375) / (a.size + 0.25))


def _autocov(a: np.ndarray) -> np.ndarray:
    """Biased autocovariance of each chain at every lag (FFT), ``(chain, draw)``."""
    n = a.shape[1]
    m = 1 << int(2 * n - 1).bit_length()  # a power of two >= 2n: no circular wrap
    f = np.fft.rfft(a - a.mean(axis=1, keepdims=True), n=m, axis=1)
    return np.fft.irfft(f * np.conjugate(f), n=m, axis=1)[:, :n] / n


def _ess(a: np.ndarray) -> float:
    """ESS of a ``(chain, draw)`` array: Geyer's initial monotone sequence over the chains."""
    n_chain, n = a.shape
    if np.ptp(a) < np.finfo(float).resolution:
        return float(a.size)
    acov = _autocov(a)
    within = acov[:, 0].mean() * n / (n - 1.0)  # W: mean within-chain variance
    var_plus = within * (n - 1.0) / n
    if n_chain > 1:
        var_plus += np.var(a.mean(axis=1), ddof=1)
    rho = 1.0 - (within - acov.mean(axis=0)) / var_plus  # combined autocorrelation by lag
    rho[0] = 1.0
    kept = np.zeros(n)
    kept[:2] = rho[:2]
    # initial positive sequence: pairs (rho[t+1], rho[t+2]) while the previous pair is > 0
    t, even, odd = 1, 1.0, rho[1]
    while t < n - 3 and even + odd > 0.0:
        even, odd = rho[t + 1], rho[t + 2]
        if even + odd >= 0.0:
            kept[t + 1], kept[t + 2] = even, odd
        t += 2
    last = t - 2
    if even > 0.0:
        kept[last + 1] = even
    # initial monotone sequence: no pair larger than the one before
    for t in range(1, last - 1, 2):
        if kept[t + 1] + kept[t + 2] > kept[t - 1] + kept[t]:
            kept[t + 1] = kept[t + 2] = (kept[t - 1] + kept[t]) / 2.0
    tau = -1.0 + 2.0 * kept[:last + 1].sum() + kept[last + 1:last + 2].sum()
    tau = max(tau, 1.0 / np.log10(a.size))
    return float("nan") if np.isnan(kept).any() else float(a.size / tau)


def ess_bulk(a) -> float:
    """Bulk ESS: the ESS of the rank-normalised split chains.

    Parameters
    ----------
    a : array_like
        ``(chain, draw)`` (at least 4 draws).

    Returns
    -------
    float
        NaN for fewer than 4 draws or non-finite values.
    """
    a = _usable(a, min_chains=1)
    return float("nan") if a is None else _ess(z_scale(split_chains(a)))


def ess_mean(a) -> float:
    """ESS of the mean: of the split chains as they are (no rank normalisation).

    Parameters
    ----------
    a : array_like
        ``(chain, draw)`` (at least 4 draws).

    Returns
    -------
    float
    """
    a = _usable(a, min_chains=1)
    return float("nan") if a is None else _ess(split_chains(a))


def _rhat(a: np.ndarray) -> float:
    n = a.shape[1]
    between = n * np.var(a.mean(axis=1), ddof=1)
    within = np.mean(np.var(a, axis=1, ddof=1))
    return float(np.sqrt((between / within + n - 1) / n))


def rhat_rank(a) -> float:
    """Rank-normalised split R-hat: the larger of the bulk and the folded (tail) R-hat.

    Parameters
    ----------
    a : array_like
        ``(chain, draw)``, at least 2 chains of 4 draws.

    Returns
    -------
    float
        NaN when there are too few chains or draws.
    """
    a = _usable(a, min_chains=2)
    if a is None:
        return float("nan")
    s = split_chains(a)
    return max(_rhat(z_scale(s)), _rhat(z_scale(np.abs(s - np.median(s)))))


def hdi_nearest(x, prob: float) -> list:
    """Highest-density interval: the narrowest interval between draws holding ``prob`` of them.

    Parameters
    ----------
    x : array_like
        Draws (all axes pooled).
    prob : float
        In ``(0, 1)``.

    Returns
    -------
    list of float
        ``[lower, upper]``.

    Examples
    --------
    >>> hdi_nearest([0.0, 1.0, 1.1, 1.2, 5.0], 0.5)
    [1.0, 1.2]
    """
    xs = np.sort(np.ravel(np.asarray(x, dtype=float)))
    k = int(np.floor(prob * xs.size))
    if k >= xs.size or xs.size == 0:
        raise ValueError(f"too few draws ({xs.size}) for a {prob:g} interval")
    i = int(np.argmin(xs[k:] - xs[:xs.size - k]))
    return [float(xs[i]), float(xs[i + k])]
