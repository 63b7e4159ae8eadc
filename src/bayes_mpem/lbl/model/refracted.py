"""Refracted LBL ranges: direct and multipath returns through a sound-speed profile.

Details: ``docs/refraction.md``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from ...acoustics.profile import SoundSpeedProfile
from ...acoustics.profile_checks import check_profile, check_sound_speed
from ...acoustics.turning import NO_RAY, DirectRays, bounce_times, direct_times
from ...io.survey import BeaconData
from . import geometry
from .beacon_geometry import BeaconGeometry

#: Spacing (m) of the plane heights at which the bounce times are traced for a fit.
PLANE_STEP = 10.0


@dataclass(frozen=True)
class RefractedRanges:
    """Ranges an LBL system reports for refracted rays (one entry per ping).

    Attributes
    ----------
    direct, multipath : numpy.ndarray
        One-way ranges (m), ``c_nom`` times the travel times; NaN where no eigenray exists.
    direct_valid, multipath_valid, turning : numpy.ndarray of bool
    """

    direct: np.ndarray = field(repr=False)
    multipath: np.ndarray = field(repr=False)
    direct_valid: np.ndarray = field(repr=False)
    multipath_valid: np.ndarray = field(repr=False)
    turning: np.ndarray = field(repr=False)


def lbl_ranges(ssp: SoundSpeedProfile, sound_speed: float, horizontal, z_vehicle, z_beacon,
               plane_depth, path: str = "triangle", *, direct: DirectRays | None = None
               ) -> RefractedRanges:
    """Direct and multipath ranges of refracted rays, as an LBL system reports them.

    Parameters
    ----------
    sound_speed : float
        Nominal speed ``c_nom`` (m/s) that turns travel times into ranges.
    plane_depth : float or array_like
        Depth of the reflecting plane (m), above both ends.
    direct : DirectRays, optional
        Precomputed :func:`direct_times` of the same pairs.

    Raises
    ------
    ValueError
        An unknown path, a non-positive speed, or a plane below an end.
    """
    geometry.check_path(path)
    c_nom = check_sound_speed(sound_speed)
    if direct is None:
        direct = direct_times(ssp, z_vehicle, z_beacon, horizontal)
    t_sb, _, ok_sb = bounce_times(ssp, z_vehicle, z_beacon, horizontal, plane_depth)
    t_d = direct.time
    d = c_nom * t_d
    mp = c_nom * 0.5 * (t_d + t_sb) if path == "triangle" else c_nom * t_sb
    return RefractedRanges(d, mp, direct.valid, np.isfinite(mp), direct.turning)


# --------------------------------------------------------------------------- the model

class _BounceTable:
    """Bounce times of fixed ranges against plane height, traced lazily on a grid."""

    def __init__(self, ssp, h, z_vehicle, z_beacon, d0_min, step=PLANE_STEP):
        self.ssp = ssp
        self.h, self.z_vehicle, self.z_beacon = h, z_vehicle, float(z_beacon)
        self.d0_min, self.step = float(d0_min), float(step)
        self.nodes: dict[int, tuple] = {}

    @property
    def n_traced(self) -> int:
        """Number of planes traced so far."""
        return len(self.nodes)

    def node(self, k):
        k = int(k)
        if k not in self.nodes:
            d0 = self.d0_min + k * self.step
            # no plane below the vehicle: at d0_min it is at the shallowest vehicle depth
            zp = min(self.z_beacon - d0, float(np.min(self.z_vehicle)) if self.h.size else 0.0)
            t, s, ok = bounce_times(self.ssp, self.z_vehicle, self.z_beacon, self.h, zp)
            self.nodes[k] = (t, s, ok)
        return self.nodes[k]

    def _cell(self, k, s, j):
        """Hermite interpolant and its derivative in cell ``k`` at ``s`` in [0, 1], rows ``j``."""
        T0, m0, ok0 = self.node(k)
        T1, m1, ok1 = self.node(k + 1)
        T0, m0, T1, m1 = T0[j], m0[j], T1[j], m1[j]
        D = self.step
        s2 = s * s
        s3 = s2 * s
        v = ((2 * s3 - 3 * s2 + 1) * T0 + (s3 - 2 * s2 + s) * D * m0
             + (3 * s2 - 2 * s3) * T1 + (s3 - s2) * D * m1)
        dv = (6 * s2 - 6 * s) * (T0 - T1) / D + (3 * s2 - 4 * s + 1) * m0 + (3 * s2 - 2 * s) * m1
        ok = ok0[j] & ok1[j]
        return np.where(ok, v, np.nan), np.where(ok, dv, np.nan)

    def evaluate(self, d0, cols):
        """Bounce time and ``d0`` derivative of the ranges ``cols`` at plane heights ``d0``."""
        d0 = np.asarray(d0, float)
        if d0.ndim == 0:  # the EM's case
            u = (float(d0) - self.d0_min) / self.step
            k = max(np.floor(u), 0.0)
            return self._cell(k, u - k, cols)
        shape = np.broadcast_shapes(d0.shape, cols.shape)
        dd = np.broadcast_to(d0, shape)
        jj = np.broadcast_to(cols, shape)
        u = (dd - self.d0_min) / self.step
        kk = np.maximum(np.floor(u), 0.0)
        t = u - kk
        time = np.empty(shape)
        slope = np.empty(shape)
        for k in np.unique(kk):
            sel = kk == k
            time[sel], slope[sel] = self._cell(k, t[sel], jj[sel])
        return time, slope


@dataclass(frozen=True)
class RefractedBeaconGeometry(BeaconGeometry):
    """A :class:`~bayes_mpem.lbl.model.beacon_geometry.BeaconGeometry` predicting through a profile.

    Attributes
    ----------
    ssp : SoundSpeedProfile
    sound_speed : float
    direct_valid, turning : numpy.ndarray of bool
    direct_time : numpy.ndarray
        One-way direct time (s; NaN where invalid).
    table : _BounceTable
        The lazily traced bounce times (shared by subsets).
    cols : numpy.ndarray
        Rows of ``table`` these ranges are.
    """

    straight: ClassVar[bool] = False

    ssp: SoundSpeedProfile = None
    sound_speed: float = 0.0
    direct_valid: np.ndarray = None
    turning: np.ndarray = None
    direct_time: np.ndarray = None
    table: _BounceTable = None
    cols: np.ndarray = None

    @classmethod
    def from_data(cls, data: BeaconData, ssp: SoundSpeedProfile = None,
                  sound_speed: float | None = None, *, plane_step: float = PLANE_STEP
                  ) -> RefractedBeaconGeometry:
        """Trace the direct rays of ``data`` and set up the bounce table.

        Parameters
        ----------
        ssp : SoundSpeedProfile
            Must reach the deepest beacon or vehicle.
        plane_step : float, default PLANE_STEP
            Grid spacing of the bounce table (m).

        Raises
        ------
        TypeError, ValueError
        """
        base = BeaconGeometry.from_data(data)
        bz = float(data.position[2])
        zv = np.asarray(data.depth, float)
        deepest = max(bz, float(zv.max())) if zv.size else bz
        check_profile(ssp, deepest)
        if sound_speed is None:
            raise ValueError("sound_speed: with ssp=..., pass the nominal sound speed (m/s) "
                             "the navigation used to turn travel times into ranges (e.g. "
                             "refraction.nominal_sound_speed(ssp, beacon_depth))")
        c_nom = check_sound_speed(sound_speed)
        rays = direct_times(ssp, zv, bz, base.h)
        direct = np.where(rays.valid, c_nom * np.nan_to_num(rays.time), NO_RAY)
        table = _BounceTable(ssp, base.h, zv, bz, base.d0_min, plane_step)
        return cls(z=base.z, h=base.h, dz=base.dz, direct=direct, lo=base.lo, hi=base.hi,
                   d0_min=base.d0_min, ssp=ssp, sound_speed=c_nom, direct_valid=rays.valid,
                   turning=rays.turning, direct_time=rays.time, table=table,
                   cols=np.arange(base.z.size))

    def take(self, idx) -> RefractedBeaconGeometry:
        """Select the ranges ``idx`` (same window, ``d0_min`` and bounce table)."""
        return dataclasses.replace(
            self, z=self.z[idx], h=self.h[idx], dz=self.dz[idx], direct=self.direct[idx],
            direct_valid=self.direct_valid[idx], turning=self.turning[idx],
            direct_time=self.direct_time[idx], cols=self.cols[idx])

    def _bounce(self, d0):
        return self.table.evaluate(d0, self.cols)

    def multipath(self, d0, path: str = "triangle"):
        """Predicted multipath ranges at plane height ``d0`` (broadcasts); NO_RAY if none."""
        t_sb, _ = self._bounce(d0)
        if path == "triangle":
            t = 0.5 * (self.direct_time + t_sb)
        elif geometry.check_path(path) == "double":
            t = t_sb
        return np.where(np.isfinite(t), self.sound_speed * t, NO_RAY)

    def multipath_derivative(self, d0, path: str = "triangle"):
        """``d z_MP / d d0`` from the tabulated ray derivative; 0 where no ray."""
        t_sb, s = self._bounce(d0)
        d = self.sound_speed * s * (0.5 if geometry.check_path(path) == "triangle" else 1.0)
        if path == "triangle":
            d = np.where(self.direct_valid, d, np.nan)
        return np.where(np.isfinite(d), d, 0.0)

    def invert_plane_height(self, path: str = "triangle", *, max_iter: int = 8,
                            atol: float = 1e-3):
        """Per-range plane height that makes each range a multipath (Newton, traced).

        Parameters
        ----------
        atol : float
            Tolerance on the range (m).
        """
        geometry.check_path(path)
        dlow = np.maximum(self.dz, 0.0)
        direct = np.where(self.direct_valid, self.direct, np.nan)
        with np.errstate(invalid="ignore"):
            d0 = geometry.invert_plane_height(self.z, self.h, self.dz, path,
                                              direct=np.nan_to_num(direct, nan=0.0))
        zv = self.table.z_beacon - self.dz
        target = self.z / self.sound_speed
        if path == "triangle":
            target = 2.0 * target - self.direct_time
        out = np.full(self.n, np.nan)
        todo = np.flatnonzero(np.isfinite(d0) & np.isfinite(target))
        x = np.maximum(d0[todo], dlow[todo])
        for _ in range(max_iter):
            if todo.size == 0:
                break
            t, s, ok = bounce_times(self.ssp, zv[todo], self.table.z_beacon, self.h[todo],
                                    self.table.z_beacon - x)
            f = t - target[todo]
            conv = ok & (np.abs(f) * self.sound_speed <= atol)
            out[todo[conv]] = x[conv]
            keep = ok & ~conv & (s > 0)
            with np.errstate(invalid="ignore", divide="ignore"):
                x = np.maximum(x - f / s, dlow[todo])
            todo, x = todo[keep], x[keep]
        return out

    def ray_counts(self, d0: float, path: str = "triangle") -> dict:
        """How many ranges have no eigenray, at plane height ``d0``.

        Returns
        -------
        dict
            ``no_direct_ray``, ``no_multipath_ray``, ``no_ray`` (neither), ``turning_direct``,
            ``planes_traced``.
        """
        no_mp = self.multipath(d0, path) >= NO_RAY
        no_dp = ~self.direct_valid
        return {"no_direct_ray": int(no_dp.sum()), "no_multipath_ray": int(no_mp.sum()),
                "no_ray": int((no_dp & no_mp).sum()), "turning_direct": int(self.turning.sum()),
                "planes_traced": int(self.table.n_traced)}
