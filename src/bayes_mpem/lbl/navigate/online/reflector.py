"""Online EM of a beacon's reflector and weights, and of the pooled sigma_DP (``docs/stream.md``).

References
----------
Cappé, O. and Moulines, E. (2009). On-line expectation-maximization algorithm for
latent data models. *JRSS B* 71:593-613.

Examples
--------
>>> r = BeaconModel.start(d0=100.0, sigma_mp=5.0, weights=(0.5, 0.3, 0.2), n=10,
...                       double=False, mp_on=True, xyz=(0.0, 0.0, 100.0), d0_min=0.0,
...                       window=(10.0, 200.0))
>>> step_size(4, 1.0), round(r.d0, 6)
(0.25, 100.0)
"""

from __future__ import annotations

import math

#: Statistics of one beacon, in order: <g_dp>, <g_mp>, <g_ol>, <g_mp J^2>, <g_mp J u>, <g_mp u^2>.
BEACON_STATS = ("g_dp", "g_mp", "g_ol", "jj", "ju", "uu")


def step_size(n, alpha):
    """``gamma_n = n^-alpha``.

    Parameters
    ----------
    n : int
        The reply count, including the one being added (>= 1).
    alpha : float
        In (1/2, 1].

    Examples
    --------
    >>> round(step_size(100, 0.6), 6)
    0.063096
    """
    return n ** -alpha


class BeaconModel:
    """One beacon's reflector, weights and their running statistics.

    Attributes
    ----------
    xyz : tuple of float
        Beacon ``x``, ``y``, ``depth``.
    d0, sigma_mp : float
        Plane height and multipath scale (m).
    weights : list of float
        Mixing weights of dp, mp, ol.
    double, mp_on : bool
        Double bounce; the beacon has a multipath class.
    d0_ref : float
        Reference of the linearised statistic.
    stats : list of float
        :data:`BEACON_STATS`.
    n : int
        Replies so far (the step-size counter).
    sumsq : float
        ``sum_i w_i^2`` of the averaging weights (``N_eff = 1 / sumsq``).
    d0_min : float
        Lowest physical plane height (above every vehicle position so far).
    window : list of float
        Smallest and largest range so far (the outlier density's support).
    alt : BeaconModel or None
        The same beacon with the other multipath geometry, learned alongside
        (``path="auto"``; :meth:`switch`).
    evidence : float
        Running average of the log-likelihood of ``alt`` minus this model's, per reply.
    """

    __slots__ = ("alt", "d0", "d0_min", "d0_ref", "double", "evidence", "mp_on", "n", "sigma_mp",
                 "stats", "sumsq", "weights", "window", "xyz")

    @classmethod
    def start(cls, *, d0, sigma_mp, weights, n, double, mp_on, xyz, d0_min, window,
              stats=None):
        """Start a beacon whose first ``n`` replies had these parameters (or these statistics).

        Parameters
        ----------
        n : int
            Replies behind the statistics (a pseudo-count for a prior).
        stats : sequence of 6 float, optional
            :data:`BEACON_STATS` (``d0_ref = d0``); default the statistics of
            replies that fit ``d0``, ``sigma_mp`` exactly with ``J = 1``.
        """
        self = cls()
        self.xyz = tuple(float(v) for v in xyz)
        self.d0, self.d0_ref, self.sigma_mp = float(d0), float(d0), float(sigma_mp)
        self.weights = [float(w) for w in weights]
        self.double, self.mp_on = bool(double), bool(mp_on)
        if stats is None:
            g = self.weights[1]
            stats = (*self.weights, g, 0.0, g * self.sigma_mp ** 2)
        self.stats = [float(v) for v in stats]
        self.n = int(n)
        self.sumsq = 1.0 / max(self.n, 1)
        self.d0_min, self.window = float(d0_min), [float(v) for v in window]
        self.alt, self.evidence = None, 0.0
        return self

    def weigh(self, diff, alpha, margin):
        """Add one reply's log-likelihood difference (``alt`` minus this); switch if due.

        Parameters
        ----------
        diff : float
            ``log p(z | alt) - log p(z | this)`` of the reply.
        margin : float
            Switch when the ratio exceeds this many nats.

        Returns
        -------
        BeaconModel
            ``alt`` if it has won by ``margin``, else this model.
        """
        self.evidence += step_size(self.n, alpha) * (diff - self.evidence)
        if self.evidence <= margin * self.sumsq:
            return self
        new = self.alt
        new.alt, new.evidence, self.alt = self, -self.evidence, None
        return new

    def observe(self, z, depth):
        """Widen the outlier window and raise ``d0_min`` for a new reply.

        Parameters
        ----------
        z, depth : float
            The range and the vehicle's depth (m).
        """
        w = self.window
        if z < w[0]:
            w[0] = z
        if z > w[1]:
            w[1] = z
        low = self.xyz[2] - depth
        if low > self.d0_min:
            self.d0_min = low

    def log_outlier(self, min_width=1e-9):
        """Log-density of an outlier (uniform over the window)."""
        return -math.log(max(self.window[1] - self.window[0], min_width))

    def d0_variance(self):
        """Variance of ``d0`` (m^2): ``sigma_MP^2 / (N_eff <g_MP J^2>)``; 0 without a statistic."""
        jj = self.stats[3]
        return self.sigma_mp ** 2 * self.sumsq / jj if jj > 0.0 else 0.0

    def learn(self, g_dp, g_mp, g_ol, jac, u, u2, alpha, floor):
        """Add one reply's statistics and redo the M-step.

        Parameters
        ----------
        g_dp, g_mp, g_ol : float
            The reply's class probabilities.
        jac : float
            ``d f_MP / d d0`` at the reply.
        u, u2 : float
            The linearised multipath residual and its expected square.
        alpha : float
            Step-size exponent.
        floor : float
            Smallest ``sigma_MP`` (m).
        """
        self.n += 1
        gam = step_size(self.n, alpha)
        keep = 1.0 - gam
        self.sumsq = keep * keep * self.sumsq + gam * gam
        new = (g_dp, g_mp, g_ol, g_mp * jac * jac, g_mp * jac * u, g_mp * u2)
        s = self.stats
        for i in range(6):
            s[i] += gam * (new[i] - s[i])
        total = s[0] + s[1] + s[2]
        if total > 0.0:
            self.weights = [s[0] / total, s[1] / total, s[2] / total]
        if self.mp_on and s[3] > 0.0 and s[1] > 0.0:
            delta = s[4] / s[3]
            d0 = self.d0_ref + delta
            if d0 < self.d0_min:
                d0, delta = self.d0_min, self.d0_min - self.d0_ref
            var = (s[5] - 2.0 * delta * s[4] + delta * delta * s[3]) / s[1]
            self.d0 = d0
            self.sigma_mp = max(math.sqrt(max(var, 0.0)), floor)

    def to_dict(self) -> dict:
        """Return the beacon's model as a JSON-ready mapping."""
        out = {k: getattr(self, k) for k in self.__slots__}
        out["alt"] = None if self.alt is None else self.alt.to_dict()
        return out

    @classmethod
    def from_dict(cls, d: dict) -> BeaconModel:
        """Rebuild a model written by :meth:`to_dict`."""
        self = cls()
        for k in cls.__slots__:
            v = d[k]
            setattr(self, k, tuple(v) if k == "xyz" else v)
        if self.alt is not None:
            self.alt = cls.from_dict(self.alt)
        return self


class DirectPathScale:
    """The pooled sigma_DP: running ``<g_DP>`` and ``<g_DP r^2>`` over every reply.

    Attributes
    ----------
    sigma : float
    stats : list of float
    n : int
    fixed : bool
        Keep ``sigma`` as given.
    """

    __slots__ = ("fixed", "n", "sigma", "stats")

    def __init__(self, sigma, n, *, stats=None, fixed=False):
        self.sigma, self.n, self.fixed = float(sigma), int(n), bool(fixed)
        self.stats = [1.0, self.sigma ** 2] if stats is None else [float(v) for v in stats]

    def learn(self, g_dp, r2, alpha, floor):
        """Add one reply's ``g_DP`` and expected squared direct-path residual.

        Parameters
        ----------
        floor : float
            Smallest sigma_DP (m).
        """
        self.n += 1
        gam = step_size(self.n, alpha)
        s = self.stats
        s[0] += gam * (g_dp - s[0])
        s[1] += gam * (g_dp * r2 - s[1])
        if not self.fixed and s[0] > 0.0:
            self.sigma = max(math.sqrt(s[1] / s[0]), floor)

    def to_dict(self) -> dict:
        """JSON-ready mapping."""
        return {k: getattr(self, k) for k in self.__slots__}

    @classmethod
    def from_dict(cls, d: dict) -> DirectPathScale:
        """Rebuild from :meth:`to_dict`."""
        return cls(d["sigma"], d["n"], stats=d["stats"], fixed=d["fixed"])
