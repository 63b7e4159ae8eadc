"""Geodesy: the WGS84 ellipsoid, local east-north-up frames, and the transducer lever arm.

Every constant of the Earth's figure used by the package is defined here (and
imported from here):

* :data:`WGS84_A`, :data:`WGS84_F`, :data:`WGS84_E2`: the WGS84 semi-major axis
  (m), flattening and first eccentricity squared, for the exact geodetic <->
  ECEF <-> local east-north-up transforms (:func:`geodetic_to_enu`,
  :func:`enu_to_geodetic`);
* :data:`WGS84_B`: the semi-minor axis (m) to the precision SeaGap uses, for
  :func:`earth_radius` (the local Gaussian mean radius);
* :data:`MEAN_EARTH_RADIUS_M` (and :data:`MEAN_EARTH_RADIUS_KM`): the mean
  radius of a spherical Earth, 6,371 km, for great-circle distances between
  profile casts and as the default radius of a spherical survey frame.

Examples
--------
>>> round(earth_radius(0.0) / 1000.0, 3)
6356.752
>>> MEAN_EARTH_RADIUS_M == 1000.0 * MEAN_EARTH_RADIUS_KM
True
"""

from __future__ import annotations

import numpy as np

#: WGS84 semi-major axis (m).
WGS84_A = 6378137.0
#: WGS84 flattening.
WGS84_F = 1.0 / 298.257223563
#: WGS84 first eccentricity squared, ``f (2 - f)``.
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)
#: WGS84 semi-minor axis (m), as SeaGap writes it (``a (1 - f)`` rounded to 1e-6 m).
WGS84_B = 6356752.314245
#: Mean radius of a spherical Earth (km).
MEAN_EARTH_RADIUS_KM = 6371.0
#: Mean radius of a spherical Earth (m).
MEAN_EARTH_RADIUS_M = 6371000.0


def antenna_to_transducer(east, north, up, heading, pitch, roll, offset):
    """Transducer positions from antenna positions, attitude and the lever arm.

    SeaGap's convention (its ``anttena2tr``): the offset ``(x, y, z)`` is in the
    local frame at zero attitude; it is rotated by ``-heading`` about the
    vertical, then by ``pitch`` about the horizontal axis at azimuth
    ``-heading``, then by ``roll`` about the axis at azimuth ``90 - heading``
    tilted up by ``pitch``, and added to the antenna position.

    Parameters
    ----------
    east, north, up : array_like
        Antenna positions (m).
    heading, pitch, roll : array_like
        Degrees.
    offset : array_like
        The three components of ``tr-ant.inp`` (m).

    Returns
    -------
    east, north, up : numpy.ndarray
    """
    from scipy.spatial.transform import Rotation

    h, p, r = (np.radians(np.asarray(v, float)) for v in (heading, pitch, roll))
    zero = np.zeros_like(h)
    steps = [np.stack([zero, zero, -h], axis=-1),
             p[:, None] * np.stack([np.cos(-h), np.sin(-h), zero], axis=-1),
             r[:, None] * np.stack([np.cos(p) * np.cos(np.pi / 2 - h),
                                    np.cos(p) * np.sin(np.pi / 2 - h), np.sin(p)], axis=-1)]
    v = np.tile(np.asarray(offset, float), (h.size, 1))
    for rotvec in steps:
        v = Rotation.from_rotvec(rotvec).apply(v)
    return (np.asarray(east, float) + v[:, 0], np.asarray(north, float) + v[:, 1],
            np.asarray(up, float) + v[:, 2])


def earth_radius(lat: float) -> float:
    """Gaussian mean radius of the WGS84 ellipsoid at latitude ``lat`` (m).

    ``a sqrt(1 - e2) / (1 - e2 sin(lat)**2)`` with ``e2 = 1 - (b / a)**2``
    from :data:`WGS84_A` and :data:`WGS84_B` (SeaGap's radius of its spherical
    frame).

    Parameters
    ----------
    lat : float
        Latitude (degrees).

    Returns
    -------
    float
        Radius (m).

    Examples
    --------
    >>> round(earth_radius(45.0), 1)
    6378101.0
    """
    a, b = WGS84_A, WGS84_B
    e2 = 1.0 - (b / a) ** 2
    s2 = np.sin(np.radians(lat)) ** 2
    return float(a * np.sqrt(1.0 - e2) / (1.0 - e2 * s2))

def _ecef(lat, lon, height):
    """WGS84 geodetic (degrees, m) to Earth-centred Earth-fixed (m)."""
    la, lo = np.radians(lat), np.radians(lon)
    nu = WGS84_A / np.sqrt(1.0 - WGS84_E2 * np.sin(la) ** 2)
    return np.array([(nu + height) * np.cos(la) * np.cos(lo),
                     (nu + height) * np.cos(la) * np.sin(lo),
                     (nu * (1.0 - WGS84_E2) + height) * np.sin(la)], dtype=float)


def _enu_rotation(lat0, lon0):
    """Rows: the local east, north and up unit vectors at the origin, in ECEF."""
    la, lo = np.radians(lat0), np.radians(lon0)
    return np.array([[-np.sin(lo), np.cos(lo), 0.0],
                     [-np.sin(la) * np.cos(lo), -np.sin(la) * np.sin(lo), np.cos(la)],
                     [np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)]])


def geodetic_to_enu(lat, lon, height, lat0, lon0, height0=0.0):
    """Local east, north, up (m) of WGS84 points relative to an origin.

    Exact: geodetic -> Earth-centred Earth-fixed -> rotation to the local
    tangent plane at the origin.

    Parameters
    ----------
    lat, lon : array_like
        Degrees.
    height : array_like
        Height above the ellipsoid (m).
    lat0, lon0, height0 : float
        The origin.

    Returns
    -------
    e, n, u : numpy.ndarray

    Examples
    --------
    >>> e, n, u = geodetic_to_enu(0.0, 0.001, 0.0, 0.0, 0.0)
    >>> round(float(e), 3), round(float(n), 6)
    (111.319, 0.0)
    """
    lat, lon, height = np.broadcast_arrays(*(np.asarray(v, float) for v in (lat, lon, height)))
    d = _ecef(lat, lon, height) - _ecef(float(lat0), float(lon0), float(height0)).reshape(
        (3,) + (1,) * lat.ndim)
    e, n, u = np.tensordot(_enu_rotation(lat0, lon0), d, axes=1)
    return e, n, u


def enu_to_geodetic(east, north, up, lat0, lon0, height0=0.0):
    """Inverse of :func:`geodetic_to_enu` (WGS84, exact to < 1 mm).

    Parameters
    ----------
    east, north, up : float
        Local coordinates (m).
    lat0, lon0, height0 : float
        The origin.

    Returns
    -------
    lat, lon, height : float
    """
    x, y, z = _ecef(float(lat0), float(lon0), float(height0)) + _enu_rotation(lat0, lon0).T @ \
        np.array([east, north, up], dtype=float)
    lon = np.arctan2(y, x)
    p = np.hypot(x, y)
    lat = np.arctan2(z, p * (1 - WGS84_E2))
    for _ in range(10):
        nu = WGS84_A / np.sqrt(1 - WGS84_E2 * np.sin(lat) ** 2)
        h = p / np.cos(lat) - nu
        lat = np.arctan2(z, p * (1 - WGS84_E2 * nu / (nu + h)))
    return float(np.degrees(lat)), float(np.degrees(lon)), float(h)
