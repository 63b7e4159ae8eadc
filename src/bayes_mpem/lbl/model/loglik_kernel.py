"""The sampler's kernel: the total log-likelihood of one beacon for many parameter sets."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..._validate import check_choice
from ...mixture.densities import LOG_SQRT_2PI
from .beacon_geometry import BeaconGeometry
from .geometry import check_path

#: beyond this many standard deviations exp(-x^2 / 2) is exactly 0 in float64 (38.6)
ZERO_SIGMAS = 40.0
#: the largest rounding error (nats, worst case) accepted from the float32 kernel
FLOAT32_MAX_ERROR = 0.01
#: worst-case float32 error per range, in units of float32's epsilon 2^-24 (a few
#: roundings of terms of order one in the density, its logarithm and the exponent)
_F32_ULPS_PER_RANGE = 8.0
#: "auto" uses float32 up to this many ranges: n x 8 x 2^-24 <= FLOAT32_MAX_ERROR
FLOAT32_MAX_RANGES = int(FLOAT32_MAX_ERROR / (_F32_ULPS_PER_RANGE * 2.0**-24))
PRECISIONS = ("auto", "float32", "float64")
#: the envelope's margins: sigmas up to this factor above the batch that made it ...
_SIGMA_MARGIN = 1.5
#: ... and plane heights within max(this many metres, twice the batch's spread) of its centre
_D0_MARGIN = 1.0
#: below this outlier weight the float32 terms could underflow: the batch is done in float64
_F32_MIN_OL = 1e-25


@dataclass(frozen=True)
class _Screen:
    """The ranges that can have a non-zero Gaussian term inside an envelope of parameters."""

    sigma_dp: float
    sigma_mp: float
    d0_lo: float
    d0_hi: float
    d_ref: float
    n_dp: int  # columns with a direct-path term: [0, n_dp)
    mp_from: int  # columns with a multipath term: [mp_from, n_cols)
    n_cols: int
    cols: np.ndarray
    r2_dp: np.ndarray  # squared direct-path residuals of columns [0, n_dp)
    u_ref: np.ndarray  # 2 d_ref - dz of the multipath columns
    l_ref: np.ndarray  # reflected leg at d_ref
    h2: np.ndarray
    r_ref: np.ndarray  # multipath residual at d_ref

    def holds(self, d0, sigma_dp, sigma_mp) -> bool:
        """Whether every parameter set of a batch lies inside this envelope."""
        return bool(sigma_dp.max() <= self.sigma_dp and sigma_mp.max() <= self.sigma_mp
                    and d0.min() >= self.d0_lo and d0.max() <= self.d0_hi)


class LoglikKernel:
    """Total log-likelihood of one beacon's ranges for a batch of parameter sets (straight rays).

    Parameters
    ----------
    precision : {"auto", "float32", "float64"}
        Of the per-range terms (the sum is float64); ``"auto"``: float32 up to
        :data:`FLOAT32_MAX_RANGES` ranges.

    Attributes
    ----------
    dtype : numpy.dtype
    n_screens : int
        Envelopes made so far (a diagnostic of the cache).

    Raises
    ------
    NotImplementedError, ValueError
        A refracted geometry; an unknown ``path`` or ``precision``.
    """

    def __init__(self, geom: BeaconGeometry, path: str = "triangle", *, precision="auto"):
        if not geom.straight:
            raise NotImplementedError("the sampler's kernel: straight-ray geometry only (its "
                                      "multipath bound is the image method's); use "
                                      "loglik_per_range for a refracted geometry")
        check_path(path)
        check_choice("precision", precision, PRECISIONS)
        if precision == "auto":
            precision = "float32" if geom.n <= FLOAT32_MAX_RANGES else "float64"
        self.geom, self.path = geom, path
        self.dtype = np.dtype(precision)
        self.n_screens = 0
        self._share = 0.5 if path == "triangle" else 1.0  # s: r = z - s L - (1 - s) direct
        self._slope = 2.0 * self._share  # |d z_MP / d d0| <= 1 (triangle) or 2 (double)
        self._r_dp = geom.z - geom.direct
        self._abs_r_dp = np.abs(self._r_dp)
        self._c_ol = float(np.exp(geom.log_ol_density + LOG_SQRT_2PI))
        self._screens = {}

    def _screen(self, d0, sigma_dp, sigma_mp, dtype) -> _Screen:
        """Return the cached screen if its envelope holds the batch, else make one around it."""
        old = self._screens.get(dtype)
        if old is not None and old.holds(d0, sigma_dp, sigma_mp):
            return old
        g = self.geom
        s_dp = _SIGMA_MARGIN * float(sigma_dp.max())
        s_mp = _SIGMA_MARGIN * float(sigma_mp.max())
        lo, hi = float(d0.min()), float(d0.max())
        d_ref = 0.5 * (lo + hi)
        half = max(_D0_MARGIN, hi - lo)  # the batch's spread on each side of the centre
        near_dp = self._abs_r_dp < ZERO_SIGMAS * s_dp
        l_ref = np.sqrt(g.h * g.h + (2.0 * d_ref - g.dz) ** 2)
        r_ref = g.z - self._share * l_ref - (1.0 - self._share) * g.direct
        near_mp = np.abs(r_ref) - self._slope * half < ZERO_SIGMAS * s_mp
        only_dp = np.flatnonzero(near_dp & ~near_mp)
        both = np.flatnonzero(near_dp & near_mp)
        only_mp = np.flatnonzero(~near_dp & near_mp)
        cols = np.concatenate([only_dp, both, only_mp])
        n_dp = only_dp.size + both.size
        m = cols[only_dp.size:]
        screen = _Screen(
            sigma_dp=s_dp, sigma_mp=s_mp, d0_lo=d_ref - half, d0_hi=d_ref + half, d_ref=d_ref,
            n_dp=n_dp, mp_from=only_dp.size, n_cols=cols.size, cols=cols,
            r2_dp=(self._r_dp[cols[:n_dp]] ** 2).astype(dtype),
            u_ref=(2.0 * d_ref - g.dz[m]).astype(dtype), l_ref=l_ref[m].astype(dtype),
            h2=(g.h[m] ** 2).astype(dtype), r_ref=r_ref[m].astype(dtype))
        self._screens[dtype] = screen
        self.n_screens += 1
        return screen

    def _dtype_for(self, ol):
        if self.dtype == np.float32 and float(ol.min()) < _F32_MIN_OL:
            return np.dtype(np.float64)
        return self.dtype

    def _terms(self, sc: _Screen, dtype, d0, sigma_dp, sigma_mp, w_dp, w_mp, out):
        """Write the direct-path terms into ``out[:, :n_dp]``; return them and the multipath terms.

        Both without the factor ``1 / sqrt(2 pi)``, in ``dtype``.
        """
        def col(v):
            return np.asarray(v, dtype)[:, None]

        dp = out[:, :sc.n_dp]
        np.multiply(col(-0.5 / (sigma_dp * sigma_dp)), sc.r2_dp, out=dp)
        np.exp(dp, out=dp)
        dp *= col(w_dp / sigma_dp)
        delta = col(2.0 * (d0 - sc.d_ref))
        u = np.add(sc.u_ref, delta)  # 2 d0 - dz
        r = np.add(u, sc.u_ref)
        r *= delta  # u^2 - u_ref^2
        np.multiply(u, u, out=u)
        u += sc.h2
        np.sqrt(u, out=u)
        u += sc.l_ref  # L + L_ref
        r /= u  # L - L_ref
        r *= -self._share
        r += sc.r_ref  # the multipath residual
        r *= r
        r *= col(-0.5 / (sigma_mp * sigma_mp))
        np.exp(r, out=r)
        r *= col(w_mp / sigma_mp)
        return dp, r

    def __call__(self, d0, sigma_dp, sigma_mp, w_dp, w_mp, w_ol):
        """Log-likelihood (``(W,)`` float64) of every parameter set of a batch.

        Parameters
        ----------
        d0, sigma_dp, sigma_mp, w_dp, w_mp, w_ol : numpy.ndarray
            ``(W,)`` (or ``(W, 1)``) each.
        """
        d0, sigma_dp, sigma_mp, w_dp, w_mp, w_ol = (
            np.asarray(v, float).ravel() for v in (d0, sigma_dp, sigma_mp, w_dp, w_mp, w_ol))
        ol = w_ol * self._c_ol
        dtype = self._dtype_for(ol)
        sc = self._screen(d0, sigma_dp, sigma_mp, dtype)
        dens = np.empty((d0.size, sc.n_cols), dtype)
        _, mp = self._terms(sc, dtype, d0, sigma_dp, sigma_mp, w_dp, w_mp, dens)
        ol_col = np.asarray(ol, dtype)[:, None]
        dens[:, :sc.n_dp] += ol_col
        dens[:, sc.n_dp:] = ol_col
        dens[:, sc.mp_from:] += mp
        n_rest = self.geom.n - sc.n_cols
        with np.errstate(divide="ignore"):
            np.log(dens, out=dens)
            out = dens.sum(axis=1, dtype=np.float64)
            if n_rest:  # (0 * log(0) would be NaN when w_ol = 0 and nothing is left)
                out += n_rest * np.log(ol)
        return out - self.geom.n * LOG_SQRT_2PI

    def _full(self, d0, dtype) -> _Screen:
        """Return the screen of every range in input order (valid for any parameters)."""
        key = ("all", dtype)
        if key not in self._screens:
            g = self.geom
            d_ref = float(np.median(d0))
            l_ref = np.sqrt(g.h * g.h + (2.0 * d_ref - g.dz) ** 2)
            r_ref = g.z - self._share * l_ref - (1.0 - self._share) * g.direct
            self._screens[key] = _Screen(
                sigma_dp=np.inf, sigma_mp=np.inf, d0_lo=-np.inf, d0_hi=np.inf, d_ref=d_ref,
                n_dp=g.n, mp_from=0, n_cols=g.n, cols=np.arange(g.n),
                r2_dp=(self._r_dp ** 2).astype(dtype), u_ref=(2.0 * d_ref - g.dz).astype(dtype),
                l_ref=l_ref.astype(dtype), h2=(g.h * g.h).astype(dtype),
                r_ref=r_ref.astype(dtype))
        return self._screens[key]

    def pointwise(self, d0, sigma_dp, sigma_mp, w_dp, w_mp, w_ol):
        """Log-likelihood and class probabilities of every range, in float64 (for PSIS-LOO).

        Parameters
        ----------
        d0, sigma_dp, sigma_mp, w_dp, w_mp, w_ol : numpy.ndarray
            ``(W,)`` each.

        Returns
        -------
        loglik : numpy.ndarray
            ``(W, n)``.
        probs : list of numpy.ndarray
            Per class (dp, mp, ol), ``(W, n)``.
        """
        d0, sigma_dp, sigma_mp, w_dp, w_mp, w_ol = (
            np.asarray(v, float).ravel() for v in (d0, sigma_dp, sigma_mp, w_dp, w_mp, w_ol))
        ol = w_ol * self._c_ol
        dtype = np.dtype(np.float64)
        sc = self._full(d0, dtype)
        dp, mp = self._terms(sc, dtype, d0, sigma_dp, sigma_mp, w_dp, w_mp,
                             np.empty((d0.size, sc.n_cols), dtype))
        total = dp + mp
        ol_col = np.asarray(ol, dtype)[:, None]
        total += ol_col
        with np.errstate(divide="ignore"):
            loglik = np.log(total)
        loglik -= dtype.type(LOG_SQRT_2PI)
        inv = np.divide(1.0, total, out=total)
        dp *= inv
        mp *= inv
        inv *= ol_col
        return loglik, [dp, mp, inv]

    def pointwise_moments(self, d0, sigma_dp, sigma_mp, w_dp, w_mp, w_ol, *, chunk=64):
        """Make the per-range pass after sampling: :meth:`pointwise` for many draws, with moments.

        Parameters
        ----------
        d0, sigma_dp, sigma_mp, w_dp, w_mp, w_ol : numpy.ndarray
            ``(W,)`` each: the draws.
        chunk : int, default 64
            Draws per block.

        Returns
        -------
        loglik : numpy.ndarray
            ``(W, n)``.
        mean, sd : numpy.ndarray
            ``(n, 3)`` mean and sd over the draws of each range's class probabilities.
        """
        d0, sigma_dp, sigma_mp, w_dp, w_mp, w_ol = (
            np.asarray(v, float).ravel() for v in (d0, sigma_dp, sigma_mp, w_dp, w_mp, w_ol))
        f64 = np.dtype(np.float64)
        sc = self._screen(d0, sigma_dp, sigma_mp, f64)  # one envelope holds every draw
        n_dp, mp_from, n_cols, n = sc.n_dp, sc.mp_from, sc.n_cols, self.geom.n
        n_draws = d0.size
        ol_all = w_ol * self._c_ol
        rest = np.setdiff1d(np.arange(n), sc.cols, assume_unique=True)  # outlier term only
        ll = np.empty((n_draws, n))
        s1, s2 = np.zeros((n_cols, 3)), np.zeros((n_cols, 3))
        with np.errstate(divide="ignore"):
            for i in range(0, n_draws, chunk):
                sl = slice(i, i + chunk)
                rows = d0[sl].size
                dp, mp = self._terms(sc, f64, d0[sl], sigma_dp[sl], sigma_mp[sl], w_dp[sl],
                                     w_mp[sl], np.empty((rows, n_cols)))
                ol = ol_all[sl][:, None]
                total = np.empty((rows, n_cols))
                np.add(dp, ol, out=total[:, :n_dp])
                total[:, n_dp:] = ol
                total[:, mp_from:] += mp
                block = ll[sl]  # this block's rows, in input order
                block[:, sc.cols] = np.log(total)
                block[:, rest] = np.log(ol)
                inv = np.divide(1.0, total, out=total)
                dp *= inv[:, :n_dp]
                mp *= inv[:, mp_from:]
                inv *= ol
                for j, (lo, hi, r) in enumerate(((0, n_dp, dp), (mp_from, n_cols, mp),
                                                 (0, n_cols, inv))):
                    s1[lo:hi, j] += r.sum(axis=0)
                    s2[lo:hi, j] += np.einsum("ij,ij->j", r, r)  # no (W, n) temporary
        ll -= LOG_SQRT_2PI
        m, sd = np.zeros((n, 3)), np.zeros((n, 3))
        m[rest, 2] = 1.0  # outlier only: probability 1 in every draw
        m[sc.cols] = s1 / n_draws
        sd[sc.cols] = np.sqrt(np.maximum(s2 / n_draws - m[sc.cols] ** 2, 0.0))
        return ll, m, sd
