"""Geodesy: the WGS84 ellipsoid, local east-north-up frames, and the transducer lever arm."""

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


def atd_offset_enu(forward, rightward, downward, heading, pitch, roll):
    """East, north, up of a vessel-frame offset (forward, rightward, downward) under an attitude.

    GARPOS's ``ATDoffset`` convention: ``R = Rz(heading) Ry(pitch) Rx(roll)``, heading
    clockwise from north, pitch bow up, roll starboard down.

    Parameters
    ----------
    forward, rightward, downward : float or array_like
        The offset in the vessel frame (m).
    heading, pitch, roll : array_like
        Degrees, one value per epoch.
    """
    from scipy.spatial.transform import Rotation

    h, p, r = np.broadcast_arrays(*(np.atleast_1d(np.asarray(v, float))
                                    for v in (heading, pitch, roll)))
    rot = Rotation.from_euler("ZYX", np.column_stack([h, p, r]), degrees=True)
    frd = np.column_stack(np.broadcast_arrays(*(np.atleast_1d(np.asarray(v, float))
                                                for v in (forward, rightward, downward))))
    ned = rot.apply(np.repeat(frd, h.size, axis=0) if frd.shape[0] == 1 else frd)
    return ned[:, 1], ned[:, 0], -ned[:, 2]


def earth_radius(lat: float) -> float:
    """Gaussian mean radius (m) of the WGS84 ellipsoid at latitude ``lat`` (degrees)."""
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
    """Local east, north, up (m) of WGS84 points relative to an origin (exact, through ECEF).

    Parameters
    ----------
    lat, lon, height : array_like
        Degrees, degrees, m above the ellipsoid.
    """
    return ecef_to_enu(*geodetic_to_ecef(lat, lon, height), lat0, lon0, height0)


def geodetic_to_ecef(lat, lon, height):
    """Earth-centred Earth-fixed coordinates (m) of WGS84 points.

    Parameters
    ----------
    lat, lon, height : array_like
        Degrees, degrees, m above the ellipsoid.
    """
    lat, lon, height = np.broadcast_arrays(*(np.asarray(v, float) for v in (lat, lon, height)))
    x, y, z = _ecef(lat, lon, height)
    return x, y, z


def ecef_to_enu(x, y, z, lat0, lon0, height0=0.0):
    """Local east, north, up (m) of Earth-centred Earth-fixed points relative to an origin."""
    x, y, z = np.broadcast_arrays(*(np.asarray(v, float) for v in (x, y, z)))
    d = np.stack([x, y, z]) - _ecef(float(lat0), float(lon0), float(height0)).reshape(
        (3,) + (1,) * x.ndim)
    e, n, u = np.tensordot(_enu_rotation(lat0, lon0), d, axes=1)
    return e, n, u


def enu_to_ecef(east, north, up, lat0, lon0, height0=0.0):
    """Earth-centred Earth-fixed coordinates (m) of local east, north, up points."""
    e, n, u = np.broadcast_arrays(*(np.asarray(v, float) for v in (east, north, up)))
    xyz = np.tensordot(_enu_rotation(lat0, lon0).T, np.stack([e, n, u]), axes=1)
    x0 = _ecef(float(lat0), float(lon0), float(height0)).reshape((3,) + (1,) * e.ndim)
    x, y, z = xyz + x0
    return x, y, z


def enu_to_geodetic(east, north, up, lat0, lon0, height0=0.0):
    """Inverse of :func:`geodetic_to_enu` (WGS84, exact to < 1 mm)."""
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
