"""Closed-form ray integrals through the constant-gradient layers of a profile."""

from __future__ import annotations

import numpy as np


def _artanh_ratio(x):
    """``artanh(x) / x``, 1 at ``x = 0`` (series below ``|x| = 0.01``, error < 1e-20)."""
    x2 = x * x
    if x2.size and x2.max() < 1e-8:  # |x| < 1e-4: two terms are exact to 2e-17
        x2 *= 1 / 3
        x2 += 1.0
        return x2
    out = 1.0 + x2 * (1 / 3 + x2 * (1 / 5 + x2 * (1 / 7 + x2 / 9)))
    big = np.abs(x) >= 1e-2
    if big.any():
        out[big] = np.arctanh(x[big]) / x[big]
    return out


class Legs:
    """Vertical legs ``[top, bot]`` of a block of rays, as per-ray knot arrays.

    Parameters
    ----------
    profile : SoundSpeedProfile
        The profile whose knots (``ray_knots``) and speeds build the layers.
    legs : sequence of (ndarray, ndarray)
        Per leg, the top and bottom depth (m) of every ray, each of shape ``(rays,)``.

    Attributes
    ----------
    C, H, A, B, R2 : list of ndarray
        Per leg, ``(rays, knots)`` (``H`` and ``A``: ``(rays, knots - 1)``) arrays as
        above.
    cmax : ndarray
        The fastest speed met by each ray over all its legs, ``(rays,)``.
    """

    def __init__(self, profile, legs):
        self.C, self.H = [], []
        z, c = profile.ray_knots
        for top, bot in legs:
            inside = (z > top.min()) & (z < bot.max())
            zk, ck = z[inside], c[inside]
            n, m = top.size, zk.size
            t, b = top[:, None], bot[:, None]
            zc = np.empty((n, m + 2))
            zc[:, :1], zc[:, -1:] = t, b
            np.clip(zk, t, b, out=zc[:, 1:-1])
            cc = np.empty((n, m + 2))
            cc[:, 0], cc[:, -1] = profile.speed(top), profile.speed(bot)
            mid = cc[:, 1:-1]
            mid[:] = ck
            np.copyto(mid, cc[:, :1], where=zk <= t)
            np.copyto(mid, cc[:, -1:], where=zk >= b)
            self.C.append(cc)
            self.H.append(np.diff(zc, axis=1))
        self.cmax = np.max([cc.max(axis=1) for cc in self.C], axis=0)
        m = self.cmax[:, None]
        self.A, self.B, self.R2 = [], [], []
        for cc, hh in zip(self.C, self.H, strict=True):
            a = cc[:, :-1] + cc[:, 1:]
            a *= hh
            self.A.append(a)
            bb = m - cc
            bb *= m + cc
            bb *= 1.0 / (m * m)
            self.B.append(bb)
            r2 = cc * (1.0 / m)
            r2 *= r2
            self.R2.append(r2)

    def take(self, idx, names=("C", "H", "A", "B", "R2")):
        """Return the same legs for the rays ``idx`` only.

        Parameters
        ----------
        idx : array_like of int or bool
            The rays to keep.
        names : tuple of str
            The per-leg arrays to carry over (fewer for a cheaper copy).

        Returns
        -------
        Legs
        """
        new = object.__new__(Legs)
        for name in names:
            setattr(new, name, [a[idx] for a in getattr(self, name)])
        new.cmax = self.cmax[idx]
        return new

    def cosines(self, sin2):
        """``s = cos(theta)`` at every knot for grazing angles with ``sin(phi)**2 = sin2``.

        Parameters
        ----------
        sin2 : ndarray
            ``sin(phi)**2`` of each ray's grazing angle at its fastest knot, ``(rays,)``.

        Returns
        -------
        list of ndarray
            Per leg, the cosines at its knots, ``(rays, knots)``.
        """
        out = []
        for b, r2 in zip(self.B, self.R2, strict=True):
            s = np.multiply(r2, sin2[:, None])
            s += b
            out.append(np.sqrt(s, out=s))
        return out

    def cosines_from_p(self, p):
        """``s`` at every knot for ray parameters ``p`` (0 where ``p c >= 1``).

        Parameters
        ----------
        p : ndarray
            Ray parameter (s/m) of each ray, ``(rays,)``.

        Returns
        -------
        list of ndarray
            Per leg, ``sqrt(1 - (p c)**2)`` at its knots, ``(rays, knots)``.
        """
        out = []
        for cc in self.C:
            pc = p[:, None] * cc
            out.append(np.sqrt(np.maximum((1.0 - pc) * (1.0 + pc), 0.0)))
        return out

    def sums(self, S, deriv=True, safe=False):
        """``sum A / (s0 + s1)`` (= X / p) and ``sum A / ((s0 + s1) s0 s1)`` (= dX/dp).

        Parameters
        ----------
        S : list of ndarray
            Per leg, the cosines at the knots (:meth:`cosines`).
        deriv : bool
            Also sum the derivative term.
        safe : bool
            Count zero-thickness layers as 0 even where both their ends graze
            (``s0 = s1 = 0``, 0/0); needed only at ``p = 1 / c_max``.

        Returns
        -------
        x, d : ndarray or None
            The two sums per ray, ``(rays,)``; ``d`` is None when ``deriv`` is false.
        """
        x = np.zeros(S[0].shape[0])
        d = np.zeros_like(x) if deriv else None
        for a, s in zip(self.A, S, strict=True):
            s0, s1 = s[:, :-1], s[:, 1:]
            term = s0 + s1
            np.divide(a, term, out=term)
            if safe:
                term[a == 0] = 0.0
            x += term.sum(axis=1)
            if deriv:
                term /= np.multiply(s0, s1)
                d += term.sum(axis=1)
        return x, d

    def x_grazing(self):
        """``X`` at ``p = 1 / c_max`` (inf if the fastest speed holds over a finite layer)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            x, _ = self.sums(self.cosines(np.zeros(self.cmax.size)), deriv=False, safe=True)
        return x / self.cmax

    def times(self, S):
        """Travel time summed over the layers, for knot cosines ``S``.

        Parameters
        ----------
        S : list of ndarray
            Per leg, the cosines at the knots (:meth:`cosines`).

        Returns
        -------
        ndarray
            One-way travel time (s) of each ray, ``(rays,)``.
        """
        t = np.zeros(S[0].shape[0])
        with np.errstate(divide="ignore", invalid="ignore"):
            for cc, hh, s in zip(self.C, self.H, S, strict=True):
                c0, c1, s0, s1 = cc[:, :-1], cc[:, 1:], s[:, :-1], s[:, 1:]
                den = c0 * s1
                den *= den
                den += c1 * c1
                den *= s0 + s1
                w = s0 * s1
                w += 1.0
                w *= c0 + c1
                w /= den
                x = c1 - c0
                x *= w
                w *= hh
                w *= _artanh_ratio(x)
                tt = w.sum(axis=1)
                bad = np.isnan(tt)  # 0/0 of zero-thickness layers at grazing incidence
                if bad.any():
                    tt[bad] = np.where(hh[bad] > 0, w[bad], 0.0).sum(axis=1)
                t += tt
        return t
