"""Geodesy (moved from ``locate``, ``acoustics``, ``readers``)."""

from __future__ import annotations

import numpy as np


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
    """Gaussian mean radius of the WGS84 ellipsoid at latitude ``lat`` (m)."""
    a, b = 6378137.0, 6356752.314245
    e2 = 1.0 - (b / a) ** 2
    s2 = np.sin(np.radians(lat)) ** 2
    return float(a * np.sqrt(1.0 - e2) / (1.0 - e2 * s2))
EARTH_RADIUS_KM = 6371.0

# WGS84
_A = 6378137.0
_F = 1.0 / 298.257223563
_E2 = _F * (2.0 - _F)


def _ecef(lat, lon, height):
    """WGS84 geodetic (degrees, m) to Earth-centred Earth-fixed (m)."""
    la, lo = np.radians(lat), np.radians(lon)
    nu = _A / np.sqrt(1.0 - _E2 * np.sin(la) ** 2)
    return np.array([(nu + height) * np.cos(la) * np.cos(lo),
                     (nu + height) * np.cos(la) * np.sin(lo),
                     (nu * (1.0 - _E2) + height) * np.sin(la)], dtype=float)


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
    lat = np.arctan2(z, p * (1 - _E2))
    for _ in range(10):
        nu = _A / np.sqrt(1 - _E2 * np.sin(lat) ** 2)
        h = p / np.cos(lat) - nu
        lat = np.arctan2(z, p * (1 - _E2 * nu / (nu + h)))
    return float(np.degrees(lat)), float(np.degrees(lon)), float(h)
