"""The WGS84 constants and frames of bayes_mpem.io.geodesy."""

import numpy as np

from bayes_mpem.io import geodesy


def test_constants_agree():
    g = geodesy
    assert g.WGS84_A == 6378137.0
    assert abs(g.WGS84_B - g.WGS84_A * (1 - g.WGS84_F)) < 1e-6
    assert g.WGS84_E2 == g.WGS84_F * (2.0 - g.WGS84_F)
    assert g.MEAN_EARTH_RADIUS_M == 1000.0 * g.MEAN_EARTH_RADIUS_KM == 6371000.0


def test_earth_radius_between_axes():
    r = [geodesy.earth_radius(lat) for lat in (0.0, 30.0, 60.0, 90.0)]
    assert np.all(np.diff(r) > 0)
    assert abs(r[0] - geodesy.WGS84_B) < 1e-6  # sqrt(M N) = b at the equator
    assert r[-1] < geodesy.WGS84_A ** 2 / geodesy.WGS84_B + 1e-6


def test_enu_round_trip():
    e, n, u = geodesy.geodetic_to_enu(-4.9, -132.7, -4700.0, -4.88, -132.69)
    lat, lon, h = geodesy.enu_to_geodetic(float(e), float(n), float(u), -4.88, -132.69)
    assert abs(lat + 4.9) < 1e-9 and abs(lon + 132.7) < 1e-9 and abs(h + 4700.0) < 1e-3
