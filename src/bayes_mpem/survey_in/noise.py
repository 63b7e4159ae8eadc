"""Noise correlated in time and across transponders: GARPOS's data covariance.

The replies of a GNSS-A campaign are not independent: the transducer's GNSS error is
shared by the replies to one interrogation, and the water a ray crosses changes over
minutes, so a transponder's residuals stay on one side of zero for several shots
(measured on the SeaGap survey: a correlation of 0.57 between one transponder's
consecutive replies a minute apart, 0.19 at 5-10 minutes; ``docs/gnssa.md``). GARPOS
(Watanabe et al. 2020, *Front. Earth Sci.* 8:597532) models the replies' covariance as
``sigma^2 E`` with

``E_ij = exp(-|t_i - t_j| / mu_t) (mu_mt + (1 - mu_mt) [same transponder])``,

``mu_t`` a correlation time and ``mu_mt`` the share of it common to all transponders,
and chooses ``mu_t`` by ABIC (on log travel times weighted by ``1 / TT0``: in time
units, a constant variance, as here). Here a share ``white`` of the variance may also be
independent from reply to reply (timing noise): ``E = white I + (1 - white) E_GARPOS``;
without it, replies of one transponder 20 s apart are taken as almost fully correlated.
``E`` is multiplied by a Wendland taper that reaches zero at :data:`TAPER` ``mu_t``
(Furrer, Genton & Nychka 2006, *J. Comput. Graph. Stat.* 15:502): the product of
positive-definite functions stays positive definite, and in time order ``E`` is banded,
so LAPACK's banded Cholesky factors it in ``O(n b^2)``. The taper shortens the kernel
(at a lag of ``mu_t`` the correlation is 0.63 of ``exp(-1)``; its integral is 0.68
``mu_t``), so a ``mu_t`` here is not GARPOS's number for number.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import cholesky_banded
from scipy.linalg.lapack import dtbtrs

#: Taper range in correlation times: ``exp(-4)`` = 0.018 is where the taper reaches 0.
TAPER = 4.0
#: Correlation times (s) tried by ``correlation="auto"`` (0: independent replies), in
#: order until two in a row do worse than the best so far.
CORRELATION_TIMES = (0.0, 30.0, 60.0, 120.0, 180.0, 300.0, 600.0, 1200.0)
#: Shares common to all transponders tried by ``correlation="auto"`` (GARPOS's 0.5 and 0).
SHARES = (0.5, 0.0)
#: Shares of the variance independent from reply to reply tried (0: GARPOS's form): the
#: first four while scanning the times by the residuals' likelihood, all of them climbed by
#: the marginal likelihood at the time chosen (the residuals' likelihood alone prefers too
#: large a share, 0.85 against a true 0.6 on ``benchmarks/gnssa_correlated.py``).
WHITES = (0.0, 0.3, 0.5, 0.7, 0.85, 0.95)
SCAN_WHITES = WHITES[:4]
#: The evidence (nats) by which a correlated ``E`` must beat independent replies to be
#: chosen: the best of some 50 choices beats the independent one by chance (on white
#: noise, by up to 2.3 nats in 12 of 40 trials of the review, docs/gnssa.md).
MARGIN = 4.0
#: Groups of columns, by their first non-zero row, in which a matrix is whitened.
GROUPS = 16
#: The most replies within the taper's reach of one reply: the banded factor costs
#: ``n b^2`` and ``8 n b`` bytes, so a longer time on a dense campaign is not tried.
MAX_BAND = 500


def band_width(time, tau) -> int:
    """Return the most replies within the taper's reach (:data:`TAPER` ``tau``) after one.

    Parameters
    ----------
    time : array_like
        ``(n,)`` times (s), any order.
    tau : float
        Correlation time (s).

    Returns
    -------
    int
        0 for ``tau`` of 0 or fewer than two replies.
    """
    t = np.sort(np.asarray(time, float))
    if tau <= 0 or t.size < 2:
        return 0
    reach = np.searchsorted(t, t + TAPER * tau, side="left") - np.arange(t.size)
    return int(reach.max())


def _wendland(x):
    """Wendland's C2 taper ``(1 - x)^4 (4 x + 1)`` on ``[0, 1]``, 0 beyond."""
    y = np.clip(1.0 - x, 0.0, None)
    return y**4 * (4.0 * x + 1.0)


class Whitener:
    """The Cholesky factor ``L`` of ``E`` (``E = L L'``) and products with ``L^-1``.

    Parameters
    ----------
    time : array_like
        ``(n,)`` transmit time of each reply (s).
    index : array_like of int
        ``(n,)`` the transponder of each reply.
    tau : float
        Correlation time ``mu_t`` (s); 0 for independent replies (``E = I``).
    share : float
        ``mu_mt``, in [0, 1].
    white : float, default 0
        The share of the variance independent from reply to reply, in [0, 1).

    Raises
    ------
    numpy.linalg.LinAlgError
        Where ``E`` is singular: two replies at one time fully correlated without a
        white share (one transponder heard twice, or ``share`` 1).
    ValueError
        Where more than :data:`MAX_BAND` replies lie within the taper's reach of one.

    Examples
    --------
    >>> w = Whitener([0.0, 10.0, 10.0, 600.0], [0, 0, 1, 1], 60.0, 0.5)
    >>> round(w.logdet, 3)
    -1.471
    >>> bool(np.allclose(w.whiten(w.matrix() @ w.whiten(np.eye(4)).T), np.eye(4)))
    True
    """

    def __init__(self, time, index, tau, share, white=0.0):
        time = np.asarray(time, float)
        self.order = np.argsort(time, kind="stable")
        self.n = time.size
        self.tau, self.share, self.white = float(tau), float(share), float(white)
        if self.tau <= 0.0:
            self.ab, self.logdet = None, 0.0
            return
        t, k = time[self.order], np.asarray(index)[self.order]
        cut = TAPER * self.tau
        width = band_width(t, self.tau)
        if width > MAX_BAND:
            raise ValueError(f"{width} replies within {cut:g} s of one (the taper's reach at "
                             f"mu_t {self.tau:g} s): more than {MAX_BAND}")
        bands = [np.ones(t.size)]
        for d in range(1, width):
            dt = t[d:] - t[:-d]
            v = ((1.0 - self.white) * np.exp(-dt / self.tau) * _wendland(dt / cut)
                 * (self.share + (1.0 - self.share) * (k[d:] == k[:-d])))
            bands.append(np.concatenate([v, np.zeros(d)]))
        self.ab = cholesky_banded(np.array(bands), lower=True)
        self.logdet = float(2.0 * np.sum(np.log(self.ab[0])))

    def whiten(self, X):
        """Return ``L^-1 X``: the rows made independent, of unit variance under ``E``.

        Parameters
        ----------
        X : array_like
            ``(n,)`` or ``(n, m)``, rows in the caller's order.

        Returns
        -------
        numpy.ndarray
            The same shape, rows in time order.

        Raises
        ------
        numpy.linalg.LinAlgError
            Where LAPACK's triangular solve fails (not expected once ``L`` exists).
        """
        X = np.asarray(X, float)
        if self.ab is None or (X.ndim == 2 and X.shape[1] == 0):  # LAPACK: no empty matrix
            return X[self.order]
        if X.ndim == 2 and X.shape[1] > 1:
            return self._whiten_columns(X[self.order])
        out = _band_solve(self.ab, X[self.order, None] if X.ndim == 1 else X[self.order])
        return out if X.ndim == 2 else out[:, 0]

    def _whiten_columns(self, Y):
        """``L^-1 Y`` for rows in time order, each column solved from its first non-zero row.

        Above a column's first non-zero ``L^-1`` leaves it zero, so the solve starts there
        (``L``'s trailing block is the band's trailing columns): a spline coefficient's
        column of a Jacobian is zero before its knots. The columns go in :data:`GROUPS`
        groups by their first row. The arithmetic on the rows solved is the full solve's.
        """
        n, m = Y.shape
        live = Y != 0  # NaN counts as non-zero
        first = np.where(live.any(axis=0), live.argmax(axis=0), n)
        if not first.any():  # every column from the first row (the sampler's walkers): one call
            return _band_solve(self.ab, Y)
        order = np.argsort(first, kind="stable")
        out = np.zeros((n, m))
        for cols in np.array_split(order, min(GROUPS, m)):
            start = int(first[cols[0]])
            if start >= n:  # columns of zeros stay zero (and so do the later groups')
                break
            out[start:, cols] = _band_solve(self.ab[:, start:],
                                            np.asfortranarray(Y[start:][:, cols]))
        return out

    def matrix(self) -> np.ndarray:
        """Return ``E`` densely, in the caller's order (for tests and small surveys).

        Returns
        -------
        numpy.ndarray
            ``(n, n)``.
        """
        if self.ab is None:
            return np.eye(self.n)
        b = self.ab.shape[0]
        L = np.zeros((self.n, self.n))
        for d in range(b):
            L[np.arange(d, self.n), np.arange(self.n - d)] = self.ab[d, :self.n - d]
        E = L @ L.T
        inv = np.empty(self.n, int)
        inv[self.order] = np.arange(self.n)
        return E[np.ix_(inv, inv)]


def _band_solve(ab, B):
    """``L^-1 B`` by LAPACK's banded triangular solve, ``L`` lower in band storage ``ab``."""
    out, info = dtbtrs(ab, B, uplo="L")
    if info:
        raise np.linalg.LinAlgError(f"dtbtrs: info {info}")
    return out


def residual_log_likelihood(whitener, r) -> float:
    """Profile log likelihood of residuals ``r ~ N(0, sigma^2 E)``, ``sigma`` at its best.

    ``-(n/2) log(r' E^-1 r / n) - log|E| / 2`` (constants dropped): the criterion by
    which :func:`choose_correlation` compares correlation times at a fixed fit.

    Parameters
    ----------
    whitener : Whitener
    r : numpy.ndarray
        ``(n,)`` residuals (s), in the caller's order.

    Returns
    -------
    float
    """
    rw = whitener.whiten(r)
    n = rw.size
    return float(-0.5 * n * np.log(rw @ rw / n) - 0.5 * whitener.logdet)


def choose_correlation(time, index, r, times=CORRELATION_TIMES, shares=SHARES,
                       whites=SCAN_WHITES, evidence=None, margin=MARGIN, refine=WHITES):
    """Choose GARPOS's correlation of the replies: ``(tau, share, white)`` and the table.

    The scan: for each correlation time, the share (at a white share of 0.5) and then the
    white share of largest :func:`residual_log_likelihood`; between the times, the
    largest ``evidence`` of that pair, or the same residual likelihood without one. With
    ``evidence``, at the time chosen each share's white shares of ``refine`` are then
    climbed by the evidence, from the scan's to the better neighbour while it rises. A
    correlated ``E`` is chosen only where it beats
    independent replies by ``margin`` nats. The residuals' likelihood alone prefers too
    short a time and too large a white share: the fit's smooth terms have absorbed the
    slowest part of the correlation; the marginal likelihood of the whole linearised model
    (GARPOS's ABIC) does not have that bias (docs/gnssa.md).

    Parameters
    ----------
    time, index : array_like
        As for :class:`Whitener`.
    r : numpy.ndarray
        Residuals of the direct replies at the independent-noise fit (s); finite.
    times, shares, whites : sequence of float
        The grid (``tau = 0`` is tried once: independent replies), ``times``
        increasing; the search stops after two times in a row that do worse than the
        best so far (the criterion is taken as unimodal in ``tau``; the longer times
        cost the most), and before a time whose band exceeds :data:`MAX_BAND`.
    evidence : callable, optional
        ``evidence(whitener)``: the log marginal likelihood of the model under that
        covariance.
    margin : float, default :data:`MARGIN`
    refine : sequence of float, default :data:`WHITES`
        The white shares compared by ``evidence`` at the time chosen (empty: none; the
        scan's choice stands).

    Returns
    -------
    best : tuple of float
        ``(tau, share, white)``; ``(0, 0, 0)`` for independent replies.
    table : list of dict
        One row per time scanned (``stage`` "scan"), then one per pair the climb evaluated
        (``stage`` "refine"): ``correlation_s``, ``share``, ``white``, ``log_likelihood``
        (the residuals'; the scan's) and ``log_evidence`` (with ``evidence``), each
        relative to its best (None where singular or not computed).

    Raises
    ------
    ValueError
        For residuals that are not finite.

    Examples
    --------
    >>> gen = np.random.default_rng(1)
    >>> t = np.arange(2000) * 20.0
    >>> ou = np.zeros(2000)
    >>> for i in range(1, 2000):
    ...     ou[i] = ou[i - 1] * np.exp(-20 / 120) + gen.normal(0, np.sqrt(1 - np.exp(-40 / 120)))
    >>> choose_correlation(t, np.zeros(2000, int), ou)[0]
    (120.0, 0.5, 0.0)
    """
    if not np.all(np.isfinite(r)):
        raise ValueError("residuals: not all finite")
    rows, worse = [], 0
    for tau in times:
        if band_width(time, tau) > MAX_BAND:
            break
        if tau > 0:
            mid = 0.5 if 0.5 in whites else whites[len(whites) // 2]
            tried = {(m, mid): _try(time, index, r, tau, m, mid) for m in shares}
            share = max(shares, key=lambda m: tried[(m, mid)][0])
            for v in whites:
                if (share, v) not in tried:
                    tried[(share, v)] = _try(time, index, r, tau, share, v)
            ll, w = max((tried[(share, v)] for v in whites), key=lambda x: x[0])
        else:
            ll, w = _try(time, index, r, 0.0, 0.0, 0.0)
        row = {"stage": "scan", "correlation_s": float(tau),
               "share": None if w is None or tau <= 0 else w.share,
               "white": None if w is None or tau <= 0 else w.white, "log_likelihood": ll,
               "log_evidence": None}
        if evidence is not None:
            row["log_evidence"] = -np.inf if w is None else float(evidence(w))
        worse = worse + 1 if rows and _level(row) < max(_level(x) for x in rows) else 0
        rows.append(row)
        if worse == 2:
            break
    levels = np.array([_level(x) for x in rows])
    best = rows[int(np.argmax(levels))]
    if evidence is not None and best["correlation_s"] > 0:
        rows += _refine(time, index, best, shares, refine, evidence)
        levels = np.array([_level(x) for x in rows])
        best = rows[int(np.argmax(levels))]
    if levels.max() < levels[0] + margin:  # not enough to leave independent replies
        best = rows[0]
    for key in ("log_likelihood", "log_evidence"):  # relative to the best; None: singular
        finite = [x[key] for x in rows if x[key] is not None and np.isfinite(x[key])]
        for x in rows:
            ok = x[key] is not None and np.isfinite(x[key])
            x[key] = float(x[key] - max(finite)) if ok else None
    if best["correlation_s"] <= 0:
        return (0.0, 0.0, 0.0), rows
    return (best["correlation_s"], best["share"], best["white"]), rows


def _refine(time, index, scanned, shares, whites, evidence):
    """Rows of other shares and white shares at the time of ``scanned`` (its row).

    For each share, a climb over ``whites`` from the white share nearest the scan's: to the
    better neighbour while the evidence rises (taken as unimodal in the white share, as the
    scan takes it in the time). Each evaluation whitens and multiplies the whole Jacobian;
    on the SeaGap survey the climb makes 4 of the 11 that every pair would.
    """
    tau = scanned["correlation_s"]
    known = {(scanned["share"], scanned["white"]): scanned["log_evidence"]}
    out = []

    def level(share, white):
        if (share, white) not in known:
            w = _whitener(time, index, tau, share, white)
            known[(share, white)] = -np.inf if w is None else float(evidence(w))
            if w is not None:
                out.append({"stage": "refine", "correlation_s": tau, "share": float(share),
                            "white": float(white), "log_likelihood": None,
                            "log_evidence": known[(share, white)]})
        return known[(share, white)]

    if len(whites) == 0:  # nothing to refine over: the scan's row stands
        return out
    start = int(np.argmin(np.abs(np.asarray(whites, float) - scanned["white"])))
    for share in shares:
        i, best = start, level(share, whites[start])
        while True:
            near = [j for j in (i - 1, i + 1) if 0 <= j < len(whites)]
            if not near:  # one white share: nothing to climb to
                break
            j = max(near, key=lambda j: level(share, whites[j]))
            if not level(share, whites[j]) > best:
                break
            i, best = j, level(share, whites[j])
    return out


def _whitener(time, index, tau, share, white):
    """Return the :class:`Whitener`, or None where ``E`` is singular."""
    try:
        return Whitener(time, index, tau, share, white)
    except np.linalg.LinAlgError:  # two replies at one time fully correlated
        return None


def _try(time, index, r, tau, share, white):
    """Return ``(residual log likelihood, whitener)``; ``(-inf, None)`` where singular."""
    w = _whitener(time, index, tau, share, white)
    return (-np.inf, None) if w is None else (residual_log_likelihood(w, r), w)


def _level(row):
    """Return a row's criterion: its evidence where there is one, else its likelihood."""
    v = row["log_evidence"] if row["log_evidence"] is not None else row["log_likelihood"]
    return -np.inf if v is None else v
