"""The forward filter of the position: an extended Kalman filter in plain floats.

State ``(x, y, beta, s)``; the covariance as its 10 distinct entries (``docs/stream.md``).

Examples
--------
>>> f = PositionFilter.start(0.0, 0.0, 0.0, 1.0, [[100.0, 0.0], [0.0, 100.0]], 0.0, 0.0)
>>> f.predict(10.0, 0.0, 100.0, 0.01)
>>> round(f.x, 6), round(f.p[0], 6)
(10.0, 101.0)
>>> f.update(1.0, 1.0, 0.0, 1.0)
>>> round(f.x, 4), round(f.p[0], 4)
(10.9902, 0.9902)
"""

from __future__ import annotations

import math

from .kernel import dr_step

#: Names of the 10 covariance entries kept, in order (upper triangle by rows).
COV_NAMES = ("xx", "xy", "xb", "xs", "yy", "yb", "ys", "bb", "bs", "ss")


class PositionFilter:
    """Position, heading bias and speed scale, with their covariance.

    Attributes
    ----------
    x, y : float
        Position (m).
    beta : float
        Heading bias (rad).
    scale : float
        Speed scale.
    p : list of float
        The covariance's upper triangle (:data:`COV_NAMES`).
    beta_walk, scale_walk : float
        Random-walk levels of ``beta`` (rad / sqrt(s)) and ``s`` (1 / sqrt(s)).
    """

    __slots__ = ("beta", "beta_walk", "p", "scale", "scale_walk", "x", "y")

    def __init__(self, x, y, beta, scale, p, beta_walk, scale_walk):
        self.x, self.y, self.beta, self.scale = float(x), float(y), float(beta), float(scale)
        self.p = [float(v) for v in p]
        self.beta_walk, self.scale_walk = float(beta_walk), float(scale_walk)

    @classmethod
    def start(cls, x, y, beta, scale, cov, var_beta=None, var_scale=None, *, beta_walk=0.0,
              scale_walk=0.0):
        """Start from a joint 4 x 4 covariance, or a 2 x 2 one and independent nuisances.

        Parameters
        ----------
        cov : array_like
            ``(4, 4)`` covariance of ``(x, y, beta, s)`` (a smoother's at its
            last epoch, with the correlations of the position with the nuisances),
            or ``(2, 2)`` of the position alone (m^2).
        var_beta, var_scale : float, optional
            With a ``(2, 2)`` ``cov``: variances of the heading bias (rad^2) and
            the speed scale, uncorrelated with the position.

        Raises
        ------
        ValueError
            ``cov`` of another shape, or ``(2, 2)`` without ``var_beta`` and ``var_scale``.
        """
        c = [[float(v) for v in row] for row in cov]
        if len(c) == 2 and var_beta is not None and var_scale is not None:
            c = [c[0] + [0.0, 0.0], c[1] + [0.0, 0.0], [0.0, 0.0, float(var_beta), 0.0],
                 [0.0, 0.0, 0.0, float(var_scale)]]
        if len(c) != 4 or any(len(row) != 4 for row in c):
            raise ValueError("cov: expected a (4, 4) covariance of (x, y, beta, s), or (2, 2) "
                             f"with var_beta and var_scale; got {len(c)} rows")
        return cls(x, y, beta, scale, [0.5 * (c[i][j] + c[j][i]) for i in range(4)
                                       for j in range(i, 4)], beta_walk, scale_walk)

    def predict(self, dx, dy, dt, q2):
        """Move by the dead-reckoned displacement ``(dx, dy)`` over ``dt`` seconds.

        Parameters
        ----------
        dx, dy : float
            Dead-reckoned displacement (m).
        dt : float
            Time step (s, >= 0).
        q2 : float
            ``q^2``: the random walk's variance per second (m^2 / s, per axis).
        """
        sx, sy, ax, ay, bx, by = dr_step(dx, dy, self.beta, self.scale)
        self.x += sx
        self.y += sy
        pxx, pxy, pxb, pxs, pyy, pyb, pys, pbb, pbs, pss = self.p
        # F = [[I, G], [0, I]], G = [[ax, bx], [ay, by]]; P' = F P F^T + Q
        gxb = ax * pbb + bx * pbs  # (G Pgg) entries
        gxs = ax * pbs + bx * pss
        gyb = ay * pbb + by * pbs
        gys = ay * pbs + by * pss
        nxb, nxs, nyb, nys = pxb + gxb, pxs + gxs, pyb + gyb, pys + gys
        wp = q2 * dt
        self.p = [
            pxx + 2.0 * (ax * pxb + bx * pxs) + ax * gxb + bx * gxs + wp,
            pxy + ay * pxb + by * pxs + ax * pyb + bx * pys + ax * gyb + bx * gys,
            nxb, nxs,
            pyy + 2.0 * (ay * pyb + by * pys) + ay * gyb + by * gys + wp,
            nyb, nys,
            pbb + self.beta_walk * self.beta_walk * dt, pbs,
            pss + self.scale_walk * self.scale_walk * dt]

    def update(self, resid, gx, gy, var):
        """Correct by one range: residual ``z - f(p)``, gradient ``(gx, gy)``, variance ``var``.

        Parameters
        ----------
        resid : float
            Measured minus predicted range (m), at the current state.
        gx, gy : float
            Derivatives of the predicted range with respect to ``x``, ``y``.
        var : float
            The range's variance (m^2).
        """
        pxx, pxy, pxb, pxs, pyy, pyb, pys, pbb, pbs, pss = self.p
        k0 = pxx * gx + pxy * gy
        k1 = pxy * gx + pyy * gy
        k2 = pxb * gx + pyb * gy
        k3 = pxs * gx + pys * gy
        s = gx * k0 + gy * k1 + var
        a = resid / s
        self.x += k0 * a
        self.y += k1 * a
        self.beta += k2 * a
        self.scale += k3 * a
        i = 1.0 / s
        self.p = [pxx - k0 * k0 * i, pxy - k0 * k1 * i, pxb - k0 * k2 * i, pxs - k0 * k3 * i,
                  pyy - k1 * k1 * i, pyb - k1 * k2 * i, pys - k1 * k3 * i,
                  pbb - k2 * k2 * i, pbs - k2 * k3 * i, pss - k3 * k3 * i]

    def range_variance(self, gx, gy):
        """``g^T P_pp g``: the variance a range inherits from the position's uncertainty."""
        p = self.p
        return gx * gx * p[0] + 2.0 * gx * gy * p[1] + gy * gy * p[4]

    def position_sd(self):
        """``(sd_x, sd_y, cov_xy)`` of the position."""
        p = self.p
        return math.sqrt(max(p[0], 0.0)), math.sqrt(max(p[4], 0.0)), p[1]

    def to_dict(self) -> dict:
        """Return the state as a JSON-ready mapping (floats round-trip exactly)."""
        return {"x": self.x, "y": self.y, "beta": self.beta, "scale": self.scale,
                "cov": dict(zip(COV_NAMES, self.p, strict=True)),
                "beta_walk": self.beta_walk, "scale_walk": self.scale_walk}

    @classmethod
    def from_dict(cls, d: dict) -> PositionFilter:
        """Rebuild a filter written by :meth:`to_dict`."""
        return cls(d["x"], d["y"], d["beta"], d["scale"], [d["cov"][k] for k in COV_NAMES],
                   d["beta_walk"], d["scale_walk"])
