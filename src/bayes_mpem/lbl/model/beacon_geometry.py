"""What the likelihood of one beacon needs of its geometry, computed once."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ...io.survey import BeaconData
from ...mixture.densities import uniform_logpdf
from . import geometry


@dataclass(frozen=True)
class BeaconGeometry:
    """Per-range quantities of one beacon that do not depend on parameters.

    Attributes
    ----------
    z : numpy.ndarray
        Reported ranges (m).
    h, dz, direct : numpy.ndarray
        Horizontal distance, ``z_beacon - z_vehicle`` and direct-path length (m).
    lo, hi : float
        Outlier window: the smallest and largest reported range (m).
    d0_min : float
        Lowest physical plane height (the plane above the vehicle): ``max(0, max(dz))``.
    """

    straight: ClassVar[bool] = True

    z: np.ndarray
    h: np.ndarray
    dz: np.ndarray
    direct: np.ndarray
    lo: float
    hi: float
    d0_min: float

    @classmethod
    def from_data(cls, data: BeaconData) -> BeaconGeometry:
        """Precompute the geometry of ``data``."""
        bx, by, bz = (float(v) for v in data.position)
        h = geometry.horizontal_distance(data.x, data.y, bx, by)
        dz = bz - np.asarray(data.depth, float)
        z = np.asarray(data.range, float)
        lo, hi = (float(z.min()), float(z.max())) if z.size else (0.0, 1.0)
        return cls(
            z=z,
            h=h,
            dz=dz,
            direct=geometry.direct_path(h, dz),
            lo=lo,
            hi=hi,
            d0_min=max(0.0, float(dz.max())) if z.size else 0.0,
        )

    @property
    def n(self) -> int:
        """Number of ranges."""
        return int(self.z.size)

    @property
    def log_ol_density(self) -> float:
        """Log of the uniform outlier density over ``[lo, hi]`` (1/m)."""
        return float(uniform_logpdf(self.lo, self.hi))

    def multipath(self, d0, path: str = "triangle"):
        """Predicted multipath range (m) of every range for plane height ``d0`` (broadcasts)."""
        return geometry.multipath_range(self.h, self.dz, d0, path, direct=self.direct)

    def multipath_derivative(self, d0, path: str = "triangle"):
        """``d z_MP / d d0`` of every range (:func:`.geometry.multipath_derivative`)."""
        return geometry.multipath_derivative(self.h, self.dz, d0, path)

    def invert_plane_height(self, path: str = "triangle"):
        """Per-range plane heights (:func:`~bayes_mpem.lbl.model.geometry.invert_plane_height`)."""
        return geometry.invert_plane_height(self.z, self.h, self.dz, path, direct=self.direct)

    def take(self, idx) -> BeaconGeometry:
        """Keep the ranges ``idx``, with the same outlier window and ``d0_min``."""
        return BeaconGeometry(self.z[idx], self.h[idx], self.dz[idx], self.direct[idx],
                              self.lo, self.hi, self.d0_min)
